"""The request rules of engine.core.inputs, one copy applied by the command line and the
job service: what a study's, a test's and a calibration's JSON must give beyond what the
records check, each refusal naming the field and the limit."""

from __future__ import annotations

import json
import pickle

import pytest

from engine.core.errors import MissingField, ParameterError
from engine.core.inputs import (
    DESIGN_MINIMUM,
    PRESET_OR_PAIR_LAW,
    REQUIRED_GIVEN,
    check_design,
    check_study_json,
    check_test_json,
)

LAW = {"type": "BilinearAdhesive", "k1": 5e3, "k2": 2.5e4}


def test_a_study_needs_its_reference_and_the_reference_its_law():
    with pytest.raises(MissingField) as e:
        check_study_json({"coarse_radii": [5e-3]})
    assert e.value.field == "reference" and str(e.value).startswith("reference: required (")
    assert "no study runs a default reference" in str(e.value)
    # a shear reference: its pair law, under the study's path in the request
    with pytest.raises(MissingField) as e:
        check_study_json({"reference": {"type": "ShearTest"}}, "body")
    assert e.value.field == "body.reference.pair_law"
    assert str(e.value).startswith("body.reference.pair_law: required (the shear test's")
    # a uniaxial reference of the record's defaults alone: neither a preset nor a law
    with pytest.raises(MissingField) as e:
        check_study_json({"reference": {"radius": 2.5e-3}})
    assert e.value.field == "reference" and e.value.limit == PRESET_OR_PAIR_LAW
    assert str(e.value).startswith("reference: give a preset (quick or paper) or the pair law")
    for ok in ({"preset": "quick"}, {"pair_law": LAW}, {"type": "ShearTest", "pair_law": LAW}):
        check_study_json({"reference": ok})  # accepted
    with pytest.raises(MissingField):  # a preset given as null is no preset
        check_test_json({"preset": None, "radius": 2.5e-3}, "test")
    # anything but an object is the record reader's to refuse
    check_study_json([1, 2])
    check_test_json("quick", "reference")


def test_a_missing_field_is_a_parameter_error_that_pickles():
    e = MissingField("reference.pair_law", why="because")
    assert isinstance(e, ParameterError) and e.limit == "given"
    back = pickle.loads(pickle.dumps(e))
    assert str(back) == str(e) == "reference.pair_law: required (because)"
    assert back.field == e.field


@pytest.mark.parametrize(
    "design,field,limit",
    [
        ((2, 2, 15), "calibrate.runs", ">= 3"),
        ((25, -1, 15), "calibrate.waves", ">= 0"),
        ((25, 2, 0), "calibrate.wave_runs", ">= 1"),
        ((25, True, 15), "calibrate.waves", ">= 0"),
        ((25.0, 2, 15), "calibrate.runs", ">= 3"),
    ],
)
def test_a_calibration_design_below_its_minimum_is_refused(design, field, limit):
    with pytest.raises(ParameterError) as e:
        check_design(*design)
    assert e.value.field == field and e.value.limit.endswith(limit), str(e.value)


def test_the_design_minimum_admits_its_own_values():
    check_design(DESIGN_MINIMUM["runs"], DESIGN_MINIMUM["waves"], DESIGN_MINIMUM["wave_runs"])


def test_the_service_takes_the_engines_rules():
    pytest.importorskip("pydantic")
    pytest.importorskip("fastapi")
    from pydantic import ValidationError

    from service.spec import SERVICE_REQUIRED, CalibrationCreate, StudyCreate

    assert frozenset(REQUIRED_GIVEN) == SERVICE_REQUIRED
    with pytest.raises(ValidationError) as e:
        StudyCreate.model_validate({"reference": {"radius": 2.5e-3}})
    (err,) = e.value.errors()
    assert err["type"] == "preset_or_pair_law" and err["loc"][0] == "reference"
    assert err["msg"].startswith(PRESET_OR_PAIR_LAW)
    schema = CalibrationCreate.model_json_schema()["properties"]
    for name, low in DESIGN_MINIMUM.items():
        assert schema[name]["minimum"] == low, name


def test_the_command_line_takes_the_engines_rules(tmp_path, capsys):
    pytest.importorskip("rich")
    from demscale.cli import main

    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps({"reference": {"radius": 2.5e-3}, "coarse_radii": [5e-3]}))
    assert main(["study", str(spec), "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert "reference: give a preset (quick or paper) or the pair law" in err, err
    # a calibration's design below its minimum: the flag named, nothing run
    (tmp_path / "lab.json").write_text(
        json.dumps({"tester": "uniaxial", "loading_stiffness": 1e6, "loading_stiffness_sd": 1e5})
    )
    (tmp_path / "test.json").write_text(json.dumps({"preset": "quick", "pair_law": LAW}))
    argv = ["calibrate", str(tmp_path / "lab.json"), "--test", str(tmp_path / "test.json")]
    argv += ["--param", "k1=3e3:2e4", "--out", str(tmp_path / "cal")]
    assert main([*argv, "--wave-runs", "0"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("--wave-runs: not valid: calibrate.wave_runs = 0") and ">= 1" in err
    assert not (tmp_path / "cal").exists()
