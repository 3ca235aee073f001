"""Issue 22's findings on bounded work, each reproduced: the bodies that held a worker
(``output_interval`` 1e4, ``max_stage_time`` 1e12 with ``settle_ke`` 1e-300,
``output_interval`` 1e-12) are refused naming the field; the 730-run body is refused before
any packing is placed; the caps count the worst case the bounds allow; a token's
submissions are rate-limited (429 + Retry-After); progress never goes back; and with a real
worker, a study whose curve samples each take seconds is cancelled within 2 s, drains on
SIGTERM at once, and a run past the per-run wall-time limit fails with that reason."""

from __future__ import annotations

import copy
import signal
import time
import uuid

import pytest

import engine
from service import cost
from service.execute import StudyExecution
from service.models import Study
from service.ratelimit import Buckets

from .conftest import RUN_TIMEOUT, TINY, study_getter, wait_for


def tiny(**reference) -> dict:
    body = copy.deepcopy(TINY)
    body["reference"].update(reference)
    return body


#: A reference of about 500 particles whose curve samples (output_interval 0.3 s, the most
#: its bounds allow: 1 % strain at 2 mm/s of a 60 mm cell) take seconds of wall time each.
LONG_SAMPLES = tiny(cell=[0.03, 0.03, 0.06], platen_speed=0.002, output_interval=0.3)
LONG_SAMPLES["name"] = "long-samples"


# --- the bodies that held a worker are refused ------------------------------------------

HELD = [
    ("a sample of 1e9 steps", {"output_interval": 1e4}, ["output_interval"]),
    # settle_ke's bound is in the schema: pydantic names it first
    ("a fill that never settles", {"max_stage_time": 1e12, "settle_ke": 1e-300}, ["settle_ke"]),
    ("a stage bound of 1e12 s", {"max_stage_time": 1e12}, ["max_stage_time"]),
    ("a sample every step", {"output_interval": 1e-12}, ["output_interval"]),
]


@pytest.mark.timeout(60)
@pytest.mark.parametrize("what,reference,fields", HELD, ids=[h[0] for h in HELD])
def test_bodies_that_held_a_worker_are_refused_naming_the_field(client, what, reference, fields):
    r = client.post("/studies", json=tiny(**reference))
    assert r.status_code == 422, r.text
    locs = [e["loc"] for e in r.json()["detail"]]
    for f in fields:
        assert ["body", "reference", f] in locs, locs
    assert client.get("/studies").json()["count"] == 0


@pytest.mark.timeout(60)
def test_work_bounds_are_relative_to_dt_and_the_stages(client):
    # output_interval: at least dt, at most 1 % strain (TINY: H 0.03 m at 0.02 m/s: 15 ms)
    r = client.post("/studies", json=tiny(dt=2e-5, output_interval=2e-5, max_stage_time=1.0))
    assert r.status_code == 202, r.text  # a sample every step: within the samples' cap
    assert client.post("/studies", json=tiny(output_interval=0.015)).status_code == 202
    assert client.post("/studies", json=tiny(output_interval=0.0151)).status_code == 422
    r = client.post("/studies", json=tiny(dt=2e-5, output_interval=1.5e-5))
    assert r.status_code == 422 and "dt = 2e-05" in r.text
    # max_stage_time: 10 x the slower of the fall and the platen travel (0.06 m / 0.02 m/s)
    assert client.post("/studies", json=tiny(max_stage_time=30.0)).status_code == 202
    r = client.post("/studies", json=tiny(max_stage_time=31.0))
    assert r.status_code == 422 and "max_stage_time" in r.text
    assert client.post("/studies", json=tiny(settle_ke=1e-8)).status_code == 202
    assert client.post("/studies", json=tiny(settle_ke=1e-9)).status_code == 422


# --- admission in milliseconds --------------------------------------------------------

#: 10 reference seeds, 10 seeds, 8 radii, 8 rules: 730 runs with the 80 resolution controls.
MANY_RUNS = {
    "reference": {"preset": "quick"},
    "reference_seeds": list(range(1, 11)),
    "seeds": list(range(11, 21)),
    "coarse_radii": [3e-3 + 5e-4 * i for i in range(8)],
    "rules": [
        "paper",
        "unscaled",
        *({"name": f"r{i}", "adhesion_exponent": 1 + i / 10} for i in range(6)),
    ],
}


@pytest.mark.timeout(60)
def test_the_730_run_body_is_refused_before_any_packing(client, monkeypatch):
    assert client.post("/studies", json=TINY).status_code == 202  # warm: the first request
    placed = []
    monkeypatch.setattr(
        engine.uniaxial.spec,
        "_packing",
        lambda *a: placed.append(a) or pytest.fail("a packing was placed"),
    )
    t0 = time.perf_counter()
    r = client.post("/studies", json=MANY_RUNS)
    took = time.perf_counter() - t0
    assert r.status_code == 422, r.text
    (err,) = r.json()["detail"]
    # 10 reference seeds, 10 seeds x 8 radii x 8 rules, 10 x 8 resolution controls
    assert "730 runs" in err["msg"] and err["input"] == 730
    assert placed == []
    print(f"730-run body refused in {took * 1e3:.1f} ms")
    assert took < 1.0  # the issue asks for < 100 ms; measured ~5 ms (a generous margin here)


def test_the_particle_cap_counts_the_raw_fields_as_the_engine_does(client, settings, monkeypatch):
    """The pre-check counts a request's particles from its raw fields
    (engine.uniaxial.spec.particle_count), before the study is planned; the count is the
    engine's n_particles of the record the plan builds, so the cap refuses at exactly one
    particle over it."""
    body = {k: v for k, v in copy.deepcopy(TINY).items() if k != "name"}
    plan = engine.plan(engine.StudySpec.from_dict(body))
    n = plan.runs[0].test.n_particles
    assert plan.runs[0].rule is None and n == max(r.test.n_particles for r in plan.runs)
    settings.max_particles_per_run = n - 1
    planned, plan_study = [], engine.plan
    with monkeypatch.context() as m:
        m.setattr(engine, "plan", lambda *a: planned.append(a) or plan_study(*a))
        r = client.post("/studies", json=TINY)
    assert r.status_code == 422, r.text
    assert planned == [], "the particle cap was left to the planned study"
    (err,) = r.json()["detail"]
    # named at the field of the reference the client gave that sets its particles
    assert err["loc"][1:3] == ["reference", "cell"] and err["input"] == n, err
    settings.max_particles_per_run = n
    assert client.post("/studies", json=TINY).status_code == 202


@pytest.mark.timeout(60)
def test_a_costly_body_within_the_run_count_is_refused_before_any_packing(
    client, settings, monkeypatch
):
    monkeypatch.setattr(
        engine.uniaxial.spec, "_packing", lambda *a: pytest.fail("a packing was placed")
    )
    body = {
        **MANY_RUNS,
        "reference_seeds": [1, 2, 3, 4],
        "seeds": [5, 6, 7, 8],
        "coarse_radii": [3e-3, 4e-3],
        "rules": ["paper", "unscaled", "similarity"],
    }
    body = {**body, "reference": {"preset": "quick"}}
    settings.max_runs = 64
    settings.max_particles_per_run = 50_000  # the service's default: the quick preset's 6,875 pass
    # refused from the spec's estimate, before any packing is placed (the patch above fails
    # the test if one is); no wall-clock bound, which a loaded machine breaks (1.7 s seen)
    r = client.post("/studies", json=body)
    assert r.status_code == 422 and "particle-steps" in r.text, r.text


@pytest.mark.timeout(60)
def test_the_caps_count_the_worst_case_the_bounds_allow(client, settings):
    costs = cost.worst_case(TINY)
    worst = sum(c.particle_steps for c in costs)
    typical = engine.plan(
        engine.StudySpec.from_dict({k: v for k, v in TINY.items() if k != "name"})
    ).estimated_particle_steps()
    assert worst > 3 * typical  # max_stage_time for the fill, the platen travel, ...
    settings.max_particle_steps = (worst + typical) / 2  # the typical estimate would pass
    r = client.post("/studies", json=TINY)
    assert r.status_code == 422 and "at worst" in r.text, r.text
    settings.max_particle_steps = 1.01 * worst
    r = client.post("/studies", json=TINY)
    assert r.status_code == 202, r.text
    row = client.get(f"/studies/{r.json()['id']}").json()
    assert row["estimated_particle_steps"] == pytest.approx(worst)
    # a lower max_stage_time lowers the worst case
    assert sum(c.particle_steps for c in cost.worst_case(tiny(max_stage_time=1.0))) < worst


@pytest.mark.timeout(60)
def test_a_vanishing_time_step_is_refused_by_the_caps_not_a_500(client):
    r = client.post("/studies", json=tiny(dt=5e-324, output_interval=1e-3))
    assert r.status_code == 422, r.text
    assert "particle-steps" in r.text or "dt" in r.text


@pytest.mark.timeout(60)
def test_curve_samples_are_capped_per_study(client, settings):
    samples = sum(c.samples for c in cost.worst_case(TINY))
    settings.max_curve_samples = int(samples) - 1
    r = client.post("/studies", json=TINY)
    assert r.status_code == 422, r.text
    (err,) = r.json()["detail"]
    assert err["loc"] == ["body", "reference", "output_interval"]
    assert "DEMSCALE_MAX_CURVE_SAMPLES" in err["msg"]
    settings.max_curve_samples = int(samples)
    assert client.post("/studies", json=TINY).status_code == 202


# --- storage quota ---------------------------------------------------------------------


@pytest.mark.timeout(60)
def test_a_token_over_its_storage_quota_gets_507(client, settings):
    one = cost.output_bytes(cost.worst_case(TINY))
    settings.max_storage_per_token = 1.5 * one

    def post():
        return client.post("/studies", json=TINY)

    a = post()
    assert a.status_code == 202, a.text
    r = post()  # the queued study counts its worst case: it has yet to write
    assert r.status_code == 507, r.text
    assert "DEMSCALE_MAX_STORAGE_PER_TOKEN" in r.json()["detail"]
    a = a.json()["id"]
    assert client.post(f"/studies/{a}/cancel").status_code == 202
    c = post()  # a cancelled study counts what it holds: nothing
    assert c.status_code == 202, c.text
    assert client.post(f"/studies/{c.json()['id']}/cancel").status_code == 202
    d = settings.study_dir(a)
    d.mkdir(parents=True, exist_ok=True)
    (d / "results.h5").write_bytes(b"x" * int(0.6 * one))
    assert post().status_code == 507  # files on disk count
    assert client.delete(f"/studies/{a}").status_code == 204
    assert post().status_code == 202


@pytest.mark.timeout(60)
def test_concurrent_submissions_cannot_both_slip_under_the_quota(settings):
    """Eight submissions at once against a quota with room for two: the quota is checked
    inside the insert's transaction, so exactly two are queued."""
    import httpx

    from service.app import create_app

    from .conftest import AUTH

    one = cost.output_bytes(cost.worst_case(TINY))
    settings.max_storage_per_token = 2.5 * one
    app = create_app(settings)
    import threading

    import uvicorn

    from .conftest import free_port

    port = free_port()
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    try:
        while not server.started:
            time.sleep(0.02)
        start = threading.Barrier(8)

        def post(_):
            with httpx.Client(base_url=f"http://127.0.0.1:{port}", headers=AUTH, timeout=30) as c:
                start.wait()
                return c.post("/studies", json=TINY).status_code

        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(8) as pool:
            codes = sorted(pool.map(post, range(8)))
    finally:
        server.should_exit = True
        thread.join(10)
    assert codes == [202, 202] + [507] * 6, codes


# --- rate limit -------------------------------------------------------------------------


@pytest.mark.timeout(60)
def test_submissions_of_a_token_are_rate_limited_with_retry_after(settings, tmp_path):
    from fastapi.testclient import TestClient

    from service.app import create_app

    from .conftest import AUTH, TOKEN

    other = "other-token-0123456789abcdef"
    token_file = tmp_path / "tokens"
    token_file.write_text(f"{TOKEN}\n{other}\n")
    token_file.chmod(0o600)
    settings.api_token, settings.api_token_file = None, token_file
    settings.submit_rate, settings.submit_burst = 1.0, 3  # one a minute, bursts of 3
    with TestClient(create_app(settings)) as c:
        assert c.post("/studies", json=TINY, headers=AUTH).status_code == 202
        # refused submissions count as well
        assert c.post("/studies", json=MANY_RUNS, headers=AUTH).status_code == 422
        # a calibration is a submission too: one bucket for both
        assert c.post("/calibrations", json={}, headers=AUTH).status_code == 422
        r = c.post("/studies", json=TINY, headers=AUTH)
        assert r.status_code == 429, r.text
        assert c.post("/calibrations", json={}, headers=AUTH).status_code == 429
        assert 1 <= int(r.headers["retry-after"]) <= 60
        assert "DEMSCALE_SUBMIT_RATE" in r.json()["detail"]
        # reading is not limited, nor is another token
        assert c.get("/studies", headers=AUTH).status_code == 200
        theirs = {"Authorization": f"Bearer {other}"}
        assert c.post("/studies", json=TINY, headers=theirs).status_code == 202


def test_wrong_tokens_from_one_address_are_limited_with_retry_after(settings):
    """Guessing tokens (header or login form, one bucket per client address) gets 429 past
    the burst; the right token still passes, and reading with it is not limited."""
    from fastapi.testclient import TestClient

    from service.app import create_app

    from .conftest import AUTH

    settings.auth_failure_rate, settings.auth_failure_burst = 1.0, 3
    wrong = {"Authorization": "Bearer guess-0123456789"}
    with TestClient(create_app(settings)) as c:
        assert [c.get("/studies", headers=wrong).status_code for _ in range(2)] == [401, 401]
        origin = {"Origin": "http://testserver"}
        r = c.post("/login", data={"token": "guess"}, headers=origin, follow_redirects=False)
        assert r.status_code == 401  # the third wrong token, from the form
        r = c.get("/studies", headers=wrong)
        assert r.status_code == 429, r.text
        assert 1 <= int(r.headers["retry-after"]) <= 60
        assert "DEMSCALE_AUTH_FAILURE_RATE" in r.json()["detail"]
        r = c.post("/login", data={"token": "guess"}, headers=origin, follow_redirects=False)
        assert r.status_code == 429 and "retry-after" in r.headers
        assert c.get("/studies", headers=AUTH).status_code == 200
        # no token at all is not a guess: still the plain 401
        assert c.get("/studies").status_code == 401


def test_buckets_refill_at_the_rate():
    now = [0.0]
    b = Buckets(per_minute=6.0, burst=2, clock=lambda: now[0])
    assert b.take("a") == 0 and b.take("a") == 0
    assert b.take("a") == pytest.approx(10.0)  # one every 10 s
    now[0] = 10.0
    assert b.take("a") == 0
    assert b.take("b") == 0  # a bucket per token


# --- progress, the run limit --------------------------------------------------------------


def _execution(settings) -> StudyExecution:
    import threading

    study = Study(id=uuid.uuid4(), owner="x", spec={}, n_runs=2)
    ex = StudyExecution(settings, "w", study, threading.Event())
    ex.current_run = "ref-s1"  # no bookkeeping write
    return ex


def test_progress_never_goes_back(settings):
    ex = _execution(settings)
    for f in (0.1, 0.568, 0.623, 0.603, 0.7):
        ex.progress(engine.StudyProgress(f, 0, 2, "ref-s1", "fill", 0.0))
    seen = []
    ex2 = _execution(settings)
    for f in (0.568, 0.623, 0.603):
        ex2.progress(engine.StudyProgress(f, 0, 2, "ref-s1", "fill", 0.0))
        seen.append(ex2.latest.fraction)
    assert seen == [0.568, 0.623, 0.623] and ex.latest.fraction == 0.7


# --- with a real worker ---------------------------------------------------------------------


def _in_a_long_sample(client, settings, workers) -> str:
    settings.max_particle_steps = 1e11
    r = client.post("/studies", json=LONG_SAMPLES)
    assert r.status_code == 202, r.text
    sid = r.json()["id"]
    workers.start()
    wait_for(
        study_getter(client, sid),
        lambda s: s["status"] == "running" and s["current_stage"] == "fill",
        RUN_TIMEOUT,
        "the fill to start",
        workers,
    )
    time.sleep(1.0)  # well inside the first curve sample (seconds long)
    return sid


@pytest.mark.timeout(RUN_TIMEOUT + 60)
def test_a_study_of_long_curve_samples_is_cancelled_within_2_s(client, settings, workers):
    sid = _in_a_long_sample(client, settings, workers)
    t0 = time.perf_counter()
    assert client.post(f"/studies/{sid}/cancel").status_code == 202
    wait_for(
        study_getter(client, sid), lambda s: s["status"] == "cancelled", 30, "the cancel", workers
    )
    took = time.perf_counter() - t0
    print(f"cancelled {took:.2f} s after the request")
    assert took < 2.0, workers.logs()


@pytest.mark.timeout(RUN_TIMEOUT + 60)
def test_sigterm_during_a_long_curve_sample_drains_at_once(client, settings, workers):
    settings.shutdown_grace = 60.0  # the engine must stop by itself, long before that
    sid = _in_a_long_sample(client, settings, workers)
    (proc,) = workers.procs
    t0 = time.perf_counter()
    proc.send_signal(signal.SIGTERM)
    proc.wait(30)
    took = time.perf_counter() - t0
    print(f"worker exited {took:.2f} s after SIGTERM")
    # the engine stopped at its next report (about 0.8 s on an idle machine; the process's
    # own exit takes some more on a loaded one), not at the end of the grace period
    assert took < 10.0 < settings.shutdown_grace
    assert client.get(f"/studies/{sid}").json()["status"] == "queued"
    assert "did not stop within" not in workers.logs(tail=None)


@pytest.mark.timeout(RUN_TIMEOUT + 60)
@pytest.mark.parametrize("where", ["worker", "process pool"])
def test_a_run_past_the_wall_time_limit_fails_with_that_reason(client, settings, workers, where):
    settings.max_run_wall_time = 1.0
    settings.max_particle_steps = 1e11
    if where == "process pool":  # the limit holds where the worker cannot see the run
        settings.run_workers = 2
    r = client.post("/studies", json=LONG_SAMPLES)
    sid = r.json()["id"]
    workers.start()
    done = wait_for(
        study_getter(client, sid),
        lambda s: s["status"] in ("failed", "succeeded", "cancelled"),
        RUN_TIMEOUT,
        "the study to end",
        workers,
    )
    # the reference ran past the limit, so nothing can be compared: the study fails with it
    assert done["status"] == "failed"
    assert "DEMSCALE_MAX_RUN_WALL_TIME" in done["error"], done["error"]


def test_a_law_too_soft_to_carry_the_stress_is_refused_by_name(client):
    # k1 = k2 = 5e-324 N/m passes every bound a field declares (> 0) but carries no stress:
    # the engine's runnable check refuses it before anything is queued, naming the field
    body = copy.deepcopy(TINY)
    body["reference"]["pair_law"] = {"type": "BilinearAdhesive", "k1": 5e-324, "k2": 5e-324}
    r = client.post("/studies", json=body)
    assert r.status_code == 422, r.text
    assert "pair_law" in r.text and "k1" in r.text and "overlap" in r.text, r.text


def test_a_reference_at_the_seeds_protocol_is_costed_at_it(client, settings):
    """``"protocol": "seed"`` gives the preset's seed fields (dt = 1e-5 s, 10 mm/s) to the
    cost estimate and to the engine alike; an unknown protocol is refused naming the field."""
    from service.cost import reference_fields

    fields = reference_fields({"reference": {"preset": "quick", "protocol": "seed"}})
    assert fields == engine.preset("quick", protocol="seed").to_dict()
    body = {k: v for k, v in MANY_RUNS.items() if k not in ("rules", "coarse_radii")}
    body = {
        **body,
        "reference": {"preset": "quick", "protocol": "fast"},
        "reference_seeds": [1, 2],
        "seeds": [1, 2],
        "coarse_radii": [5e-3],
    }
    r = client.post("/studies", json=body)
    assert r.status_code == 422 and "protocol" in r.text, r.text
