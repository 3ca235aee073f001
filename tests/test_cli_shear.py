"""`demscale calibrate` with a shear tester's data (issue 41): TARGETS.json holds yield loci
the way it holds uniaxial data; bad shear data is refused with exit status 2 and one line
naming the file and the field, before anything is written; the shear part of a calibration
runs through the command (with the shear test replaced by its closed-form stand-in of
tests/engine/test_calibrate_shear.py: the command's plumbing is tested here, the shear test
in tests/engine/test_shear.py)."""

from __future__ import annotations

import copy
import importlib
import json
from pathlib import Path

import pytest

from engine.calibration import LabTargets
from engine.calibration.calibrate import check_request
from engine.uniaxial.spec import uniaxial_from_json

pytest.importorskip("rich")  # the cli extra
from demscale.cli import main
from tests.engine.test_calibrate_shear import _lab, _stand_in_shear, quicker_posterior

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "calibration"
cal_module = importlib.import_module("engine.calibration.calibrate")


def test_the_example_shear_data_is_a_labelled_format_example_the_calibration_takes():
    raw = json.loads((EXAMPLE / "ring_shear_lab.json").read_text())
    assert raw["material"].startswith("SYNTHETIC format example")
    targets = LabTargets.from_dict(raw)
    assert [locus.sigma_pre for locus in targets.shear] == [5e3, 1e4]
    test = uniaxial_from_json(json.loads((EXAMPLE / "test.json").read_text()))
    # the example test's law can be consolidated to each locus's sigma_pre: the request
    # is valid as it stands
    assert check_request(test, targets, {"mu_s": (0.2, 0.8)}, 4) == ()


def _argv(tmp_path, lab: dict, *extra) -> list[str]:
    (tmp_path / "lab.json").write_text(json.dumps(lab))
    test = ["calibrate", str(tmp_path / "lab.json"), "--test", str(EXAMPLE / "test.json")]
    return [*test, "--out", str(tmp_path / "cal"), "--param", "mu_s=0.2:0.8", *extra]


@pytest.mark.parametrize(
    "change, words",
    [
        (
            lambda t: t["shear"][1]["points"][3].__setitem__("sigma_n", 12000.0),
            "(LabTargets.shear[1].points[3].sigma_n): not valid",
        ),
        (lambda t: t["shear"][0].__setitem__("points", t["shear"][0]["points"][:1]), "no line"),
        (lambda t: t["shear"][0]["points"][2].__setitem__("tau", -5.0), "points[2].tau"),
        (lambda t: t["shear"][0].pop("tau_pre_sd"), "shear[0].tau_pre_sd"),
    ],
)
def test_bad_shear_data_is_refused_naming_the_file_and_field(tmp_path, capsys, change, words):
    lab = json.loads((EXAMPLE / "ring_shear_lab.json").read_text())
    change(lab)
    assert main(_argv(tmp_path, lab)) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"{tmp_path / 'lab.json'} (LabTargets.shear[") and words in err, err
    assert err.count("\n") == 1 and not (tmp_path / "cal").exists()  # nothing written


def test_a_shear_test_of_another_radius_is_refused_at_its_flag(tmp_path, capsys):
    (tmp_path / "shear.json").write_text(json.dumps({"radius": 2e-3}))
    lab = json.loads((EXAMPLE / "ring_shear_lab.json").read_text())
    assert main(_argv(tmp_path, lab, "--shear-test", str(tmp_path / "shear.json"))) == 2
    err = capsys.readouterr().err
    assert err.startswith("--shear-test: not valid: calibrate.shear_test.radius"), err
    assert not (tmp_path / "cal").exists()


def test_a_calibration_to_shear_data_through_the_command(tmp_path, capsys, monkeypatch):
    ran = []

    def shear(tests, progress=None):
        ran.append(tests)
        return _stand_in_shear(tests, progress)

    monkeypatch.setattr(cal_module, "run_shear_tests", shear)
    quicker_posterior(monkeypatch)
    lab = copy.deepcopy(_lab(mixed=False).to_dict())
    argv = _argv(tmp_path, lab, "--runs", "4", "--waves", "0")
    assert main(argv) == 0, capsys.readouterr().err
    assert len({t[0].seed for t in ran}) == 1  # one packing unless --vary-seed
    out = tmp_path / "cal"
    summary = json.loads((out / "calibration.json").read_text())
    assert [q["name"] for q in summary["targets_met"]] == [
        "tau@2000Pa:10000Pa",
        "tau@7000Pa:10000Pa",
        "bulk_density@10000Pa",
    ]
    assert summary["curves"]["yield_loci"][0]["sigma_pre"] == 1e4
    assert summary["shear_test"]["radius"] == summary["reference_radius"]
    assert len(ran) == 5 and (out / "law.json").exists()
    assert len(list((out / "runs").glob("*-shear-10000Pa.json"))) == 5
    printed = capsys.readouterr().out
    assert "tau@7000Pa:10000Pa" in printed and "bulk_density@10000Pa" in printed
