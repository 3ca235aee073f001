"""``demscale study`` on a hopper (docs/HOPPER.md): a spec whose reference is ``"type":
"HopperTest"`` runs, its summary, HDF5 file (every run read back as an engine.HopperResult,
and the study loaded again from it), discharge curves and verdict figures written; a bad
hopper reference is refused naming its field (exit 2)."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

import engine
from demscale.cli import main
from engine.io.store import load_study, read_run_group

#: A slot hopper of outlet 6 diameters at R = 2.5 mm, half-angle 30 degrees, the default laws
#: (tests/engine/test_hopper_run.py's scene, so that the compiled kernel is shared), filled
#: to 3 cm: 390 grains; against the paper's rule at R = 3.1 mm (205 grains). Two runs.
HOPPER_STUDY = {
    "name": "tiny hopper",
    "reference": {
        "type": "HopperTest",
        "outlet_width": 0.03,
        "depth": 0.03,
        "particles": None,
        "fill_height": 0.03,
        "pair_law": {"type": "BilinearAdhesive", "k1": 5e3, "k2": 2.5e4, "f0": 0.0},
    },
    "coarse_radii": [3.1e-3],
    "rules": ["paper"],
    "seeds": [1],
    "reference_seeds": [1],
    "controls": False,
    "protocol_check": False,
}
DESIGN = {k: v for k, v in HOPPER_STUDY.items() if k != "name"}


def _write(path, value) -> str:
    path.write_text(json.dumps(value))
    return str(path)


def test_a_hopper_study_runs_from_the_command_line(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["study", _write(tmp_path / "hopper.json", DESIGN), "-o", str(out), "-q"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["spec"]["reference"]["type"] == "HopperTest"
    assert set(summary["advisor"]["noise_floor"]) == {"discharge_number", "bulk_density"}
    # the discharge rate against time and the verdicts (no controls: no resolution plot)
    assert summary["files"]["plots"] == ["plots/discharge.png", "plots/error_vs_runtime.png"]
    assert summary["files"]["snapshots"] == {}  # a hopper keeps none
    head = (out / "curves" / "ref-s1.csv").read_text().splitlines()[0]
    assert head.startswith("stage,") and "discharged_mass [kg]" in head
    rows = {r["run"]: r for r in summary["table"]}
    with h5py.File(out / "results.h5") as f:
        assert set(f["runs"]) == {"ref-s1", "r3.1mm-paper-s1"}
        assert f["runs/ref-s1/wall_stress/fill"].attrs["units"] == "Pa"
        runs = {k: read_run_group(g) for k, g in f["runs"].items()}
    for key, run in runs.items():
        assert isinstance(run, engine.HopperResult), key
        assert run.scalars["discharge_number"] == pytest.approx(
            rows[key]["discharge_number"], nan_ok=True
        )
        c = run.curves
        assert np.allclose(c["discharged_mass"] + c["remaining_mass"], run.scalars["total_mass"])
        assert len(run.wall_stress_fill) == run.test.wall_bins == len(run.wall_edges) - 1
    assert runs["ref-s1"].test.n_particles == 390 and runs["r3.1mm-paper-s1"].test.radius == 3.1e-3
    # the study read back from its file judges as it did when it ran
    back = load_study(out / "results.h5").to_summary()
    assert [v["verdict"] for v in back["advisor"]["verdicts"]] == [
        v["verdict"] for v in summary["advisor"]["verdicts"]
    ]
    assert [r["discharge_number"] for r in back["table"]] == pytest.approx(
        [r["discharge_number"] for r in summary["table"]], nan_ok=True
    )


def test_a_bad_hopper_reference_is_refused_naming_the_field(tmp_path, capsys):
    out = str(tmp_path / "out")
    ref = HOPPER_STUDY["reference"]
    no_law = {k: v for k, v in ref.items() if k != "pair_law"}
    spec = _write(tmp_path / "a.json", {**DESIGN, "reference": no_law})
    assert main(["study", spec, "-o", out]) == 2
    assert "reference.pair_law: required" in capsys.readouterr().err
    spec = _write(tmp_path / "b.json", {**DESIGN, "reference": {**ref, "half_angle": 95.0}})
    assert main(["study", spec, "-o", out]) == 2
    assert "HopperTest.half_angle" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_hopper_runs_alone_with_snapshots_curves_and_its_plot(tmp_path, capsys):
    """``demscale run`` of a HopperTest: the discharge with its snapshots (the walls and the
    gate among them), curves.csv, discharge.png and result.json; a bad field refused (2)."""
    test = _write(
        tmp_path / "hopper.json", {"type": "HopperTest", "outlet_width": 0.03, "particles": 120}
    )
    out = tmp_path / "run"
    assert main(["run", test, "--out", str(out), "--snapshot-interval", "0.02", "-q"]) == 0
    result = json.loads((out / "result.json").read_text())
    s = result["scalars"]
    assert result["test"]["type"] == "HopperTest" and result["units"]["discharge_rate"] == "kg/s"
    assert s["discharged_mass"] == pytest.approx(s["total_mass"]) and s["discharge_rate"] > 0
    assert (out / "discharge.png").stat().st_size > 10_000
    head = (out / "curves.csv").read_text().splitlines()[0]
    assert head.startswith("stage,time [s]") and "discharged_mass [kg]" in head
    files = set(result["snapshots"]["files"])
    assert {"snapshots/particles.vtkhdf", "snapshots/walls.vtkhdf"} <= files
    # the opening, at least two of the discharge's intervals, the end
    assert len(result["snapshots"]["time_steps"]) >= 4
    assert "discharged" in capsys.readouterr().err
    bad = _write(tmp_path / "bad.json", {"type": "HopperTest", "outlet_width": -1})
    assert main(["run", bad, "--out", str(tmp_path / "bad")]) == 2
    assert "HopperTest.outlet_width" in capsys.readouterr().err


def test_run_refuses_a_test_kind_it_does_not_run(tmp_path, capsys):
    shear = _write(tmp_path / "shear.json", {"type": "ShearTest"})
    assert main(["run", shear, "--out", str(tmp_path / "s")]) == 2
    assert "UniaxialTest or a HopperTest" in capsys.readouterr().err
    odd = _write(tmp_path / "odd.json", {"type": "Silo"})
    assert main(["run", odd, "--out", str(tmp_path / "o")]) == 2
    assert "test.type" in capsys.readouterr().err
