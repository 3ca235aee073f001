"""The main job end to end: API with its embedded worker, a study, progress, URLs, table."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from sqlmodel import Session, select

from service.db import engine_for
from service.models import Status, Study

from .conftest import REPO, TINIEST, free_port, worker_env


@pytest.mark.timeout(300)
def test_main_job_runs_a_study_with_the_embedded_worker(settings, tmp_path):
    spec = tmp_path / "study.json"
    spec.write_text(json.dumps(TINIEST))
    port = free_port()
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "demscale",
            "job",
            "--exit",
            "--port",
            str(port),
            "--study",
            str(spec),
        ],
        cwd=REPO,
        env=worker_env(settings),  # no token configured: the main job makes one
        capture_output=True,
        text=True,
        timeout=280,
    )
    out = proc.stdout
    assert proc.returncode == 0, out + proc.stderr
    assert "submitted study" in out and "succeeded" in out and "%]" in out
    token = (settings.data_dir / "api-token").read_text().strip()
    assert f"api-token): {token}" in out and f"Authorization: Bearer {token}" in out
    base = f"http://127.0.0.1:{port}/studies/"
    for name in (
        "summary",
        "curves",
        "results.h5",
        "stress_strain.png",
        "error_vs_runtime.png",
        "coordination.png",
        "stress_porosity.png",
    ):
        assert base in out and name in out, name
    # only the plots the study has: no unconfined stage in TINIEST, no shear plot
    assert not any(k in out for k in ("unconfined.png", "yield_locus", "preshear")), out
    assert "ref-s1" in out and "r3.1mm-paper-s1" in out and "speed-up" in out
    # the answer first: the plans of the default powder (from the stored size series), then
    # in the report the plans again and the study's answer, before the verdicts and tables
    lines = out.splitlines()
    assert lines[0].startswith("How coarse: 50 um powder, bulk_shear 200 mm wide"), out
    assert lines[1].startswith("How coarse: 5000 um powder"), out
    answer = next(i for i, line in enumerate(lines) if line.startswith("Answer: "))
    assert lines[answer - 2].startswith("How coarse: 50 um powder"), out
    assert answer < next(i for i, line in enumerate(lines) if "speed-up" in line)
    # a short line per (radius, rule): its verdict and the metrics that make it
    assert any(
        line.startswith("R = 3.1 mm, paper: ")
        and line.split(": ")[1].split()[0].rstrip(",") in ("EQUIVALENT", "DIFFERS", "UNDECIDED")
        for line in lines
    ), out
    with Session(engine_for(settings)) as s:
        (study,) = s.exec(select(Study)).all()
    assert study.status is Status.succeeded and study.attempts == 1
    assert settings.results_path(study.id).is_file()
