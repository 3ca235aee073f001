"""Many submissions at once through a live server: all accepted, each run exactly once by
two competing workers."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import httpx
import pytest

from .conftest import AUTH, TINIEST, wait_for

#: Submissions at once: 8 queue four studies per worker (20 until 0.2.0, then 12; among the
#: suite's longest tests, cut to keep CI under ten minutes: two competing workers claiming
#: from one queue is what it checks, and four claims each race as often as six)
N = 8


@pytest.mark.timeout(300)
def test_many_concurrent_submissions_all_run_once(live_server, workers):
    def post(i: int) -> httpx.Response:
        with httpx.Client(base_url=live_server, timeout=60, headers=AUTH) as c:
            return c.post("/studies", json={**TINIEST, "name": f"study-{i}"})

    with ThreadPoolExecutor(N) as pool:
        answers = list(pool.map(post, range(N)))
    assert [r.status_code for r in answers] == [202] * N, [r.text for r in answers]
    ids = {r.json()["id"] for r in answers}
    assert len(ids) == N
    workers.start()
    workers.start()
    with httpx.Client(base_url=live_server, timeout=60, headers=AUTH) as c:

        def listing() -> dict:
            return c.get("/studies", params={"limit": 100}).json()

        final = wait_for(
            listing,
            lambda d: all(s["status"] not in ("queued", "running") for s in d["data"]),
            240,
            "every study to finish",
            workers,
        )
        assert final["count"] == N and {s["id"] for s in final["data"]} == ids
        assert {s["status"] for s in final["data"]} == {"succeeded"}, [
            s["error"] for s in final["data"] if s["error"]
        ]
        assert {s["attempts"] for s in final["data"]} == {1}  # nobody ran a study twice
        assert {s["name"] for s in final["data"]} == {f"study-{i}" for i in range(N)}
        assert c.get("/healthz").json()["studies"]["succeeded"] == N
    logs = workers.logs(tail=None)
    assert all(logs.count(f"claimed study {i}") == 1 for i in ids)
    # both workers took part
    assert sum("claimed study" in w.read_text() for w in workers.log_dir.glob("worker-*.log")) == 2
