"""Tokens, owners, bounds: 401 without a valid token everywhere but the health check and
the API description, one token's studies invisible to another, the queue bound (429 with
Retry-After), the body size cap (413), bounded paging, 405 with the full Allow header, and
the refusal to serve without a token."""

from __future__ import annotations

import subprocess
import sys

import pytest
from fastapi.testclient import TestClient

from service.app import create_app
from service.settings import ConfigError, fingerprint, with_local_token

from .conftest import AUTH, REPO, TINY, TOKEN, worker_env

OTHER = "another-token-fedcba9876543210"

PROTECTED = [
    ("GET", "/studies"),
    ("POST", "/studies"),
    ("GET", "/studies/00000000-0000-0000-0000-000000000000"),
    ("DELETE", "/studies/00000000-0000-0000-0000-000000000000"),
    ("POST", "/studies/00000000-0000-0000-0000-000000000000/cancel"),
    ("GET", "/studies/00000000-0000-0000-0000-000000000000/summary"),
    ("GET", "/studies/00000000-0000-0000-0000-000000000000/curves"),
    ("GET", "/studies/00000000-0000-0000-0000-000000000000/plots/stress_strain.png"),
    ("GET", "/studies/00000000-0000-0000-0000-000000000000/results.h5"),
    ("GET", "/no/such/path"),
    ("PUT", "/studies"),
]


@pytest.fixture
def anonymous(settings):
    with TestClient(create_app(settings)) as c:
        yield c


@pytest.mark.timeout(60)
@pytest.mark.parametrize("method,url", PROTECTED, ids=[f"{m} {u}" for m, u in PROTECTED])
@pytest.mark.parametrize(
    "header",
    [None, "Bearer wrong-token-wrong-token", f"Basic {TOKEN}", "Bearer", f"bearer  {TOKEN}x"],
)
def test_no_valid_token_is_401_with_a_bearer_challenge(anonymous, method, url, header):
    headers = {} if header is None else {"Authorization": header}
    r = anonymous.request(method, url, headers=headers, json=TINY if method == "POST" else None)
    assert r.status_code == 401, r.text
    assert r.headers["www-authenticate"].startswith("Bearer")
    assert "bearer token" in r.json()["detail"]


@pytest.mark.timeout(60)
def test_health_and_api_description_need_no_token(anonymous):
    assert anonymous.get("/healthz").json() == {"status": "ok"}  # no queue counts
    assert anonymous.get("/docs").status_code == 200
    doc = anonymous.get("/openapi.json").json()
    assert doc["components"]["securitySchemes"]["HTTPBearer"]["scheme"] == "bearer"
    # the scheme is case-insensitive
    lower = {"Authorization": f"bearer {TOKEN}"}
    assert anonymous.get("/studies", headers=lower).status_code == 200


def two_tokens(settings, tmp_path, text: str) -> None:
    """Serve the tokens of a private token file holding ``text`` instead of one token."""
    token_file = tmp_path / "tokens"
    token_file.write_text(text)
    token_file.chmod(0o600)
    settings.api_token = None
    settings.api_token_file = token_file


@pytest.mark.timeout(60)
def test_one_tokens_studies_are_invisible_to_another(settings, tmp_path):
    two_tokens(settings, tmp_path, f"# two users\n{TOKEN}\n\n{OTHER}\n")
    with TestClient(create_app(settings)) as c:
        mine = c.post("/studies", json=TINY, headers=AUTH)
        assert mine.status_code == 202, mine.text
        sid = mine.json()["id"]
        theirs = {"Authorization": f"Bearer {OTHER}"}
        assert c.get("/studies", headers=theirs).json() == {"data": [], "count": 0}
        for method, url in (
            ("GET", ""),
            ("GET", "/summary"),
            ("GET", "/results.h5"),
            ("POST", "/cancel"),
            ("DELETE", ""),
        ):
            r = c.request(method, f"/studies/{sid}{url}", headers=theirs)
            assert r.status_code == 404, (method, url, r.text)
        assert c.get(f"/studies/{sid}", headers=AUTH).json()["status"] == "queued"
        assert c.get("/studies", headers=AUTH).json()["count"] == 1
    from sqlmodel import Session, select

    from service.db import engine_for
    from service.models import Study

    with Session(engine_for(settings)) as s:
        (row,) = s.exec(select(Study)).all()
    assert row.owner == fingerprint(TOKEN) and TOKEN not in row.owner


@pytest.mark.timeout(60)
def test_queue_bound_in_all_and_per_token_is_429_with_retry_after(settings, tmp_path):
    two_tokens(settings, tmp_path, f"{TOKEN}\n{OTHER}\n")
    settings.max_active, settings.max_active_per_token, settings.retry_after = 3, 2, 17
    theirs = {"Authorization": f"Bearer {OTHER}"}
    with TestClient(create_app(settings)) as c:
        first = [c.post("/studies", json=TINY, headers=AUTH) for _ in range(2)]
        assert [r.status_code for r in first] == [202, 202]
        r = c.post("/studies", json=TINY, headers=AUTH)
        assert r.status_code == 429 and r.headers["retry-after"] == "17"
        assert "of this token" in r.json()["detail"]
        assert c.post("/studies", json=TINY, headers=theirs).status_code == 202
        r = c.post("/studies", json=TINY, headers=theirs)
        assert r.status_code == 429 and "in all" in r.json()["detail"]
        assert c.get("/studies", headers=AUTH).json()["count"] == 2
        # a finished study frees its place
        sid = first[0].json()["id"]
        assert c.post(f"/studies/{sid}/cancel", headers=AUTH).status_code == 202
        assert c.post("/studies", json=TINY, headers=theirs).status_code == 202


@pytest.mark.timeout(60)
def test_body_size_cap_is_413(client, settings):
    big = {**TINY, "name": "x" * (settings.max_body_bytes + 10)}
    r = client.post("/studies", json=big)
    assert r.status_code == 413 and "DEMSCALE_MAX_BODY_BYTES" in r.json()["detail"]

    def chunks():  # no Content-Length: counted while read
        yield b'{"name": "'
        for _ in range(settings.max_body_bytes // 1000 + 2):
            yield b"x" * 1000
        yield b'"}'

    r = client.post("/studies", content=chunks(), headers={"Content-Type": "application/json"})
    assert r.status_code == 413
    assert client.get("/studies").json()["count"] == 0


@pytest.mark.timeout(60)
@pytest.mark.parametrize(
    "params,status",
    [
        ({"offset": 652732056507143152374753787904}, 422),
        ({"offset": -1}, 422),
        ({"limit": -5}, 422),
        ({"limit": 0}, 422),
        ({"limit": 1001}, 422),
        ({"limit": 1000, "offset": 2**31 - 1}, 200),
        ({"limit": "many"}, 422),
    ],
)
def test_paging_is_bounded(client, params, status):
    assert client.get("/studies", params=params).status_code == status


@pytest.mark.timeout(60)
def test_long_names_are_refused(client):
    r = client.post("/studies", json={**TINY, "name": "n" * 101})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "name"]
    r = client.post("/studies", json={**TINY, "rules": [{"name": "r" * 41}]})
    assert r.status_code == 422


@pytest.mark.timeout(60)
@pytest.mark.parametrize(
    "method,url,allow",
    [
        ("PUT", "/studies", "GET, POST"),
        ("OPTIONS", "/studies/00000000-0000-0000-0000-000000000000", "DELETE, GET"),
        ("PATCH", "/studies/00000000-0000-0000-0000-000000000000/cancel", "POST"),
        ("POST", "/healthz", "GET"),
    ],
)
def test_405_lists_every_method_of_the_path(client, method, url, allow):
    r = client.request(method, url)
    assert r.status_code == 405 and r.headers["allow"] == allow


@pytest.mark.timeout(60)
def test_no_token_no_app(settings, tmp_path):
    settings.api_token = None
    with pytest.raises(ConfigError, match="DEMSCALE_API_TOKEN"):
        create_app(settings)
    settings.api_token = "short"
    with pytest.raises(ConfigError, match="16"):
        create_app(settings)
    settings.api_token = None
    with pytest.raises(ConfigError, match="refusing to listen on 0.0.0.0"):
        with_local_token(settings, "0.0.0.0")
    local, token = with_local_token(settings, "127.0.0.1")
    path = settings.data_dir / "api-token"
    assert path.read_text().strip() == token and path.stat().st_mode & 0o777 == 0o600
    assert with_local_token(settings, "localhost")[1] == token  # kept across starts
    assert local.tokens() == (token,)


@pytest.mark.timeout(60)
def test_api_command_refuses_a_public_address_without_a_token(settings):
    env = worker_env(settings)
    env.update(DEMSCALE_HOST="0.0.0.0", DEMSCALE_PORT="1")
    env.pop("DEMSCALE_API_TOKEN", None)
    proc = subprocess.run(
        [sys.executable, "-m", "service", "api"],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=50,
    )
    assert proc.returncode != 0 and "without an API token" in proc.stderr
