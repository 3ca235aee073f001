"""A calibration that pins nothing says so first (issue 53 item 7): where the data leave
every parameter free, the report, the outcome line, the API and the page open with it, and
name from the Sobol indices which target would determine each parameter. Made-up
calibration summaries (the shape of engine.Calibration.to_summary), and the stored twin
benchmark's (both parameters determined); no run."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import engine
from engine.calibration.calibrate import MOVES, Calibration, determination

STORED = Path(__file__).resolve().parents[2] / "benchmarks" / "results"


def param(status: str, lo: float, hi: float) -> dict:
    return {
        "median": 0.5 * (lo + hi),
        "interval": [lo, hi],
        "box": [lo, hi],
        "spread_ratio": 0.9 if status == "free" else 0.2,
        "status": status,
        "unit": "N/m",
    }


def summary(k1: str = "free", k2: str = "free") -> dict:
    """Two targets and two parameters: the loading stiffness moves k1, the unloading
    stiffness k2 (the examples/calibration shape), neither pinned by their lab sd."""
    return {
        "parameters": {"k1": param(k1, 3e3, 2e4), "k2": param(k2, 2.5e4, 8e4)},
        "sensitivity": {
            "porosity@16000Pa": {"k1": 0.83, "k2": 0.04},
            "unloading_stiffness": {"k1": 0.1, "k2": 0.61},
        },
        "targets_met": [
            {
                "name": "porosity@16000Pa",
                "lab": 0.49,
                "sd": 0.0119,
                "value": 0.49,
                "z": 0.1,
                "met": True,
            },
            {
                "name": "unloading_stiffness",
                "lab": 1.715e6,
                "sd": 2.6e5,
                "value": 1.7e6,
                "z": -0.1,
                "met": True,
            },
        ],
    }


def test_all_free_is_said_first_with_the_target_that_would_determine_each():
    d = determination(summary())
    assert d["all_free"] and d["free"] == ["k1", "k2"]
    first, *rest = d["lines"]
    assert first.startswith("The data determine none of the parameters: k1, k2 are all free")
    assert "some law in the box" in first
    assert rest[0].startswith("k1: porosity@16000Pa moves it most (Sobol index 0.83)")
    assert "now +/- 2.43 %" in rest[0]
    assert rest[1].startswith("k2: unloading_stiffness moves it most (Sobol index 0.61)")
    assert d["parameters"]["k2"]["target"] == "unloading_stiffness"
    # the outcome line (API, page, figure title) opens with it too
    from engine.io.figures import calibration_status

    assert calibration_status(summary()).startswith(
        "the data determine none of its parameters (k1, k2 free): all 2 targets met"
    )


def test_a_parameter_no_target_moves_is_told_to_need_a_new_target():
    s = summary(k1="determined")
    s["sensitivity"]["unloading_stiffness"]["k2"] = MOVES / 2
    d = determination(s)
    assert not d["all_free"] and d["free"] == ["k2"]
    assert d["lines"][0].startswith("The data leave k2 free")
    assert "k2: no target of this calibration moves it" in d["lines"][1]
    assert d["parameters"]["k2"]["target"] is None


def test_determined_parameters_need_no_words():
    d = determination(summary("determined", "determined"))
    assert d == {**d, "all_free": False, "free": [], "lines": []}
    stored = json.loads((STORED / "calibration_shear_tiny" / "result.json").read_text())
    assert determination(stored)["lines"] == [] and not determination(stored)["all_free"]
    from engine.io.figures import calibration_status

    assert calibration_status(stored).startswith("all 10 targets met")


def test_the_summary_and_the_command_line_say_it_first(tmp_path, monkeypatch, capsys):
    pytest.importorskip("matplotlib")
    import engine.calibration as calibration_module
    from demscale.cli import main

    examples = Path(__file__).resolve().parents[2] / "examples" / "calibration"
    test = engine.UniaxialTest.from_dict(json.loads((examples / "test.json").read_text()))
    s = summary()
    cal = Calibration(
        law=test.pair_law,
        parameters=s["parameters"],
        targets_met=s["targets_met"],
        sensitivity=s["sensitivity"],
        runs=[],
        test=test,
    )
    assert cal.to_summary()["determination"]["all_free"]
    monkeypatch.setattr(calibration_module, "calibrate", lambda *a, **k: cal)
    code = main(
        [
            "calibrate",
            str(examples / "lab.json"),
            "--test",
            str(examples / "test.json"),
            "--param",
            "k1=3e3:2e4",
            "--param",
            "k2=2.5e4:8e4",
            "--runs",
            "8",
            "--out",
            str(tmp_path / "cal"),
        ]
    )
    out = capsys.readouterr().out.splitlines()
    assert code == 0
    assert out[0].startswith("The data determine none of the parameters: k1, k2 are all free")
    assert out[1].startswith("k1: porosity@16000Pa moves it most")
    assert out.index(next(x for x in out if x.startswith("parameters ("))) == 3
    written = json.loads((tmp_path / "cal" / "calibration.json").read_text())
    assert written["determination"]["lines"][0] == out[0]
