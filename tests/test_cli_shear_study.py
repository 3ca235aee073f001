"""``demscale study`` on a shear test (issue 41): a spec whose reference is ``"type":
"ShearTest"``, or ``--shear TEST.json`` beside a spec; the study's summary, HDF5 file, shear
curves and yield-locus figures written; clear errors (exit 2) for a bad shear reference."""

from __future__ import annotations

import json

import h5py
import pytest

import engine
from demscale.cli import main
from engine.io.store import read_run_group
from tests.service.test_shear_study import SHEAR_STUDY

#: The tests' 120-grain shear cell with a short pre-shear, and its design: two reference
#: seeds and one coarse run, three runs, seconds (tests/service/test_shear_study.py).
SHEAR = {k: v for k, v in SHEAR_STUDY["reference"].items() if k != "type"}
DESIGN = {k: v for k, v in SHEAR_STUDY.items() if k not in ("name", "reference")}


def _write(path, value) -> str:
    path.write_text(json.dumps(value))
    return str(path)


def test_a_shear_study_runs_from_the_command_line(tmp_path, capsys):
    spec = _write(tmp_path / "design.json", DESIGN)  # no reference: --shear gives it
    shear = _write(tmp_path / "shear.json", SHEAR)
    out = tmp_path / "out"
    assert main(["study", spec, "--shear", shear, "--out", str(out), "-q"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["spec"]["reference"]["type"] == "ShearTest"
    assert set(summary["advisor"]["noise_floor"]) == set(engine.study.metrics.SHEAR_METRICS)
    assert sorted(summary["files"]["plots"]) == [
        "plots/error_vs_runtime.png",
        "plots/preshear.png",
        "plots/yield_locus.png",
    ]
    assert summary["files"]["snapshots"] == {}  # the shear stages keep none
    # the report's columns are the shear metrics'
    err = capsys.readouterr().err
    assert "locus" in err and "sig_c" in err and "UCS" not in err
    # the shear curves with their units; the runs read back from the HDF5 file
    head = (out / "curves" / "ref-s1.csv").read_text().splitlines()[0]
    assert "shear_stress [Pa]" in head and "lid_height [m]" in head
    with h5py.File(out / "results.h5") as f:
        assert set(f["runs"]) == {"ref-s1", "ref-s2", "r3.1mm-paper-s1"}
        assert f["summary/cohesion"].attrs["units"] == "Pa"
        run = read_run_group(f["runs/ref-s1"])
    assert isinstance(run, engine.ShearResult) and run.test.normal_stresses == (3e3, 7e3)
    row = next(r for r in summary["table"] if r["run"] == "ref-s1")
    assert run.scalars["cohesion"] == pytest.approx(row["cohesion"])
    assert set(run.consolidation) == {"fill", "pre_compression"}


def test_the_shear_reference_in_the_spec_and_its_errors(tmp_path, capsys):
    out = str(tmp_path / "out")
    ref = {"type": "ShearTest", **SHEAR}
    # a shear reference without its pair law: refused, naming it
    no_law = {k: v for k, v in ref.items() if k != "pair_law"}
    assert (
        main(["study", _write(tmp_path / "a.json", {**DESIGN, "reference": no_law}), "-o", out])
        == 2
    )
    assert "reference.pair_law: required" in capsys.readouterr().err
    # a normal stress above the pre-shear stress: the engine's field and limit
    bad = {**ref, "normal_stresses": [3e3, 12e3]}
    assert (
        main(["study", _write(tmp_path / "b.json", {**DESIGN, "reference": bad}), "-o", out]) == 2
    )
    err = capsys.readouterr().err
    assert "ShearTest.normal_stresses[1]" in err and "< preshear_stress = 10000 Pa" in err
    # --shear: a file of another type, and one whose radius is not the spec's reference's
    spec = _write(tmp_path / "c.json", {**DESIGN, "reference": {"preset": "quick"}})
    ring = _write(tmp_path / "ring.json", {**SHEAR, "type": "RingShear"})
    assert main(["study", spec, "--shear", ring, "-o", out]) == 2
    assert "--shear" in (err := capsys.readouterr().err) and "'RingShear'" in err
    other = _write(tmp_path / "other.json", {**SHEAR, "radius": 2e-3})
    assert main(["study", spec, "--shear", other, "-o", out]) == 2
    assert "the study's reference radius 0.0025 m" in capsys.readouterr().err
    assert main(["study", spec, "--shear", str(tmp_path / "missing.json"), "-o", out]) == 2
    assert "cannot read" in capsys.readouterr().err
    # a study spec given as the shear test: said so, not "pair_law: required"
    assert main(["study", spec, "--shear", spec, "-o", out]) == 2
    err = capsys.readouterr().err
    assert "the study fields ['coarse_radii'" in err and "required" not in err
    # a spec's uniaxial reference with --shear: the same design on the shear test (its
    # radius); the shear test runs on the CPU only
    same = _write(tmp_path / "same.json", SHEAR)
    with pytest.raises(SystemExit):  # argparse: --shear needs its file
        main(["study", spec, "--shear"])
    assert main(["study", spec, "--shear", same, "-o", out, "--backend", "cuda", "-q"]) == 2
    assert "RunOptions.backend" in capsys.readouterr().err
