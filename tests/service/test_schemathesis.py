"""A bounded schemathesis run against the app, in process (ASGI): every operation of the
OpenAPI document gets its examples, coverage cases and fuzzed requests, valid and invalid,
and every answer is checked: no server error, a documented status, a body and headers that
match the documented schema and content type, invalid data refused, valid data accepted,
no answer without the token.

No engine run is started: no worker runs, and admission caps the runs at 3,000 particles
(the quick preset has 2,300) so that the engine's checks of a generated study (which place
its packing) stay quick. Valid-by-schema studies may still be refused with 422 by the
engine's cross-field rules (e.g. consolidation_stress > pre_stress), which a JSON schema
cannot state, or by the size caps: that is the one 422 counted as an acceptance, and only
for ``POST /studies``, ``POST /calibrations`` (whose engine rules, e.g. runs >= parameters
+ 2, a schema cannot state either) and ``POST /plans`` (a feature narrower than a
particle). Set DEMSCALE_SCHEMATHESIS_LOG=<file> to log each request's
operation, generation mode and status.
"""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile

import hypothesis
import pytest
import schemathesis
from fastapi.testclient import TestClient
from schemathesis.config import SchemathesisConfig

from service.app import create_app
from service.settings import Settings

from .conftest import AUTH, TINIEST, TOKEN

#: Examples per operation and generation mode (positive, negative): bounded for CI.
MAX_EXAMPLES = 40

# the store of the run: its own directory, no worker, small studies only
_tmp = tempfile.mkdtemp(prefix="demscale-schemathesis-")
atexit.register(shutil.rmtree, _tmp, ignore_errors=True)
SETTINGS = Settings(
    data_dir=f"{_tmp}/data",
    database_url=f"sqlite:///{_tmp}/db.sqlite",
    embedded_worker=False,
    api_token=TOKEN,
    max_particles_per_run=3000,
    max_particle_steps=2e10,
    max_active=100_000,
    max_active_per_token=100_000,
    submit_rate=1e9,  # the rate limit has its own test (test_limits.py)
    submit_burst=10**9,
    max_storage_per_token=1e18,  # as is the storage quota
    auth_failure_rate=1e9,  # and the limit on wrong tokens (schemathesis sends many)
    auth_failure_burst=10**9,
)
APP = create_app(SETTINGS)

with TestClient(APP, headers=AUTH) as _client:
    _r = _client.post("/studies", json=TINIEST)
    assert _r.status_code == 202, _r.text
    #: A real (queued) study, so that the study routes answer more than 404.
    STUDY_ID = _r.json()["id"]
    _r = _client.post(
        "/calibrations",
        json={
            "test": TINIEST["reference"],
            "targets": {
                "tester": "uniaxial",
                "loading_stiffness": 1e6,
                "loading_stiffness_sd": 1e5,
            },
            "parameters": {"k1": [3e3, 2e4]},
            "runs": 3,
            "waves": 0,
        },
    )
    assert _r.status_code == 202, _r.text
    #: A real (queued) calibration, for the calibration routes.
    CALIBRATION_ID = _r.json()["id"]

CONFIG = SchemathesisConfig.from_dict(
    {
        "headers": {"Authorization": f"Bearer {TOKEN}"},
        "generation": {"mode": "all", "max-examples": MAX_EXAMPLES},
        "parameters": {"study_id": STUDY_ID, "calibration_id": CALIBRATION_ID},
        "operations": [
            {
                "include-name": name,
                "checks": {
                    "positive_data_acceptance": {
                        "expected-statuses": ["202", "401", "422", "429", "507"]
                    }
                },
            }
            for name in ("POST /studies", "POST /calibrations")
        ]
        + [
            # a plan's cross-field rules (a feature at least one particle wide, a law the
            # planner can scale, a stress where there is no gravity) a schema cannot state
            {
                "include-name": "POST /plans",
                "checks": {
                    "positive_data_acceptance": {"expected-statuses": ["200", "401", "422", "429"]}
                },
            }
        ],
    }
)
schema = schemathesis.openapi.from_asgi("/openapi.json", APP, config=CONFIG)


@pytest.mark.timeout(300)
# deterministic (the same requests every run); no health check that times data generation
# on a loaded CI machine
@hypothesis.settings(
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=list(hypothesis.HealthCheck),
)
@schema.parametrize()
def test_api_conforms_to_its_openapi_document(case):
    response = case.call_and_validate()
    if os.environ.get("DEMSCALE_SCHEMATHESIS_LOG"):  # what the run exercised, one line each
        mode = case.meta.generation.mode.value if case.meta else "-"
        with open(os.environ["DEMSCALE_SCHEMATHESIS_LOG"], "a") as f:
            f.write(f"{case.operation.label}\t{mode}\t{response.status_code}\n")
