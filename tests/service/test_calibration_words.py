"""The calibration page and the API say first when the data determine none of the
parameters (issue 53 item 7), naming which target would determine each: the page's
template rendered from a made-up result (tests/engine/test_determination.py's), no run."""

from __future__ import annotations

import re
import uuid
from types import SimpleNamespace

from engine.calibration.calibrate import determination
from service.models import TERMINAL, CalibrationPublic, Kind, Status, Study
from service.routes.calibrations import outcome
from service.web import cell, templates
from tests.engine.test_determination import summary


def test_the_page_opens_with_what_the_data_leave_free(tmp_path, monkeypatch):
    result = {
        **summary(),
        "law": {"type": "BilinearAdhesive"},
        "posterior": {},
        "not_met": [],
        "curves": {},
    }
    row = Study(
        id=uuid.uuid4(),
        kind=Kind.calibration,
        spec={"targets": {"tester": "uniaxial"}},
        status=Status.succeeded,
        progress=1.0,
        n_runs=13,
    )
    # the API's outcome of a stored result without "determination" (an earlier version's)
    import service.routes.calibrations as calibrations

    monkeypatch.setattr(calibrations, "read_result", lambda job, settings: result)
    said = outcome(row, None)
    assert said["all_free"] is True and said["all_targets_met"] is True
    assert said["outcome"].startswith("the data determine none of its parameters (k1, k2 free)")
    job = CalibrationPublic.model_validate(row, update=said)
    html = templates.get_template("calibration.html").render(
        {
            "request": SimpleNamespace(scope={}),
            "job": job,
            "asked": row.spec,
            "runs": [],
            "result": result,
            "determination": determination(result),
            "missing": None,
            "study_id": None,
            "terminal": TERMINAL,
            "fmt": cell,
            "target_unit": lambda name: "",
        }
    )
    text = re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", html))
    head = text[: text.index("Parameters Posterior median")]
    # said first, once: the status line leaves it to the page's own words
    assert head.count("determine none") == 1
    assert "The data determine none of the parameters: k1, k2 are all free" in head
    assert "The targets: all met by the check run" in head
    assert "k1: porosity@16000Pa moves it most (Sobol index 0.83)" in head
    assert "k2: unloading_stiffness moves it most (Sobol index 0.61)" in head
    assert "The calibrated law meets its targets" not in text
