"""The ``demscale`` command: help texts, spec errors, the progress bars' arithmetic, and
``demscale study`` end to end on a small study (four runs) in a subprocess (outputs read back)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import engine

pytest.importorskip("rich")  # the cli extra
from demscale.cli import main
from demscale.progress import StudyBars

ROOT = Path(__file__).resolve().parent.parent
TINY = {
    "reference": {
        "cell": [0.015, 0.015, 0.015],
        "platen_speed": 0.02,
        "inertial_number": None,  # the constant platen speed above: a third of the steps
        "output_interval": 0.001,
        "pair_law": {
            "type": "BilinearAdhesive",
            "k1": 5e3,
            "k2": 2.5e4,
            "f0": -0.4,
            "mu_s": 0.5,
            "mu_r": 0.001,
            "restitution": 0.4,
        },
    },
    "coarse_radii": [0.003],
    "rules": ["paper"],
}


def _strict(text: str):
    def refuse(c):
        raise ValueError(f"not strict JSON: {c}")

    return json.loads(text, parse_constant=refuse)


@pytest.mark.parametrize(
    "argv",
    [[], ["study"], ["run"], ["serve"], ["worker"], ["job"], ["calibrate"], ["export"]],
)
def test_help_explains_every_command(argv, capsys):
    with pytest.raises(SystemExit) as e:
        main([*argv, "--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: demscale")
    want = {
        (): ("study", "run", "serve", "worker", "job", "examples"),
        ("job",): ("--exit", "--study", "--port", "default study"),
        ("run",): ("TEST.json", "--snapshot-interval", "ParaView", "Exit status"),
        ("study",): (
            "SPEC.json",
            "--out",
            "--workers",
            "summary.json",
            "results.h5",
            "ParaView",
            "Exit status",
        ),
        ("serve",): ("--host", "--port", "--no-worker", "/docs", "studies page"),
        ("worker",): ("--once", "DEMSCALE_DATA_DIR"),
        ("calibrate",): ("TARGETS.json", "--param", "--then-study", "calibration.json"),
        ("export",): ("LAW.json", "--radius", "liggghts", "csv"),
    }[tuple(argv)]
    for w in want:
        assert w in out, w


def test_example_spec_is_a_valid_small_study():
    from demscale.commands.study import STUDY_HELP

    spec = engine.StudySpec.from_dict(json.loads((ROOT / "examples/quick_study.json").read_text()))
    runs = engine.plan(spec).runs
    assert len(spec.reference_seeds) == 2  # a noise floor exists
    assert [p.key for p in runs if p.control] == ["ctl-r3.75mm-s1"]  # its resolution control
    # what `demscale study --help` says of it is its plan
    said = re.search(r"quick_study.json is one \((\d+) runs of at most (\d+)", STUDY_HELP)
    count, most = said.groups()
    assert (int(count), int(most)) == (len(runs), max(p.test.n_particles for p in runs))


def test_invalid_spec_exits_2(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({**TINY, "coarse_radii": [0.5]}))
    assert main(["study", str(bad), "--out", str(tmp_path / "o"), "-q"]) == 2
    assert "coarse_radii" in capsys.readouterr().err
    bad.write_text("{not json")
    assert main(["study", str(bad), "--out", str(tmp_path / "o"), "-q"]) == 2


def test_run_bars_follow_each_run():
    """Each run's bar is its share of the study's fraction, from its start to its end."""
    from rich.console import Console

    spec = engine.StudySpec.from_dict(TINY)
    planned = engine.plan(spec).runs
    bars = StudyBars(planned, Console(file=open(os.devnull, "w")), enabled=False)
    assert sum(bars.weights) == pytest.approx(1.0)
    for i, p in enumerate(planned):
        for run_fraction in (0.0, 0.5, 1.0):
            f = bars.bases[i] + run_fraction * bars.weights[i]
            bars.update(engine.StudyProgress(f, i, len(planned), p.key, "consolidation", 0.1))
            task = bars.progress.tasks[bars.runs[p.key]]
            assert task.completed == pytest.approx(run_fraction)
            assert bars.progress.tasks[bars.study].completed == pytest.approx(f)


def test_run_streams_interval_snapshots(tmp_path, capsys):
    h5py = pytest.importorskip("h5py")
    test = tmp_path / "tiny_test.json"
    test.write_text(json.dumps(TINY["reference"]))
    out = tmp_path / "one"
    assert main(["run", str(test), "--out", str(out), "--snapshot-interval", "0.05"]) == 0
    assert "done:" in capsys.readouterr().err
    result = _strict((out / "result.json").read_text())
    assert result["units"]["unconfined_strength"] == "Pa"
    assert engine.UniaxialTest.from_dict(result["test"]).to_dict() == result["test"]
    stages = result["snapshots"]["time_steps"]
    assert [s for i, s in enumerate(stages) if i == 0 or stages[i - 1] != s] == list(
        engine.uniaxial.driver.stages_of(engine.UniaxialTest.from_dict(result["test"]))
    )  # every stage, in order, with interval steps within
    assert len(stages) > 12
    with h5py.File(out / "snapshots" / "particles.vtkhdf", "r") as f:
        assert int(f["VTKHDF/Steps"].attrs["NSteps"]) == len(stages)
        assert np.all(np.diff(f["VTKHDF/Steps/Values"][()]) > 0)
    for p in result["snapshots"]["files"]:
        assert (out / p).is_file(), p
    bad = tmp_path / "bad_test.json"
    bad.write_text(json.dumps({"radius": -1.0}))
    assert main(["run", str(bad), "--out", str(out)]) == 2
    assert "radius" in capsys.readouterr().err


def test_example_test_is_small():
    fields = json.loads((ROOT / "examples/quick_test.json").read_text())
    base = engine.preset(fields.pop("preset")).to_dict()
    assert engine.UniaxialTest.from_dict({**base, **fields}).n_particles < 400


@pytest.mark.slow
def test_study_end_to_end(tmp_path):
    spec = tmp_path / "tiny.json"
    spec.write_text(json.dumps(TINY))
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "demscale", "study", str(spec), "--out", str(out)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr
    assert "ref-s1 done" in proc.stderr and "verdicts" in proc.stderr

    summary = _strict((out / "summary.json").read_text())
    keys = [p.key for p in engine.plan(engine.StudySpec.from_dict(TINY)).runs]
    assert [row["run"] for row in summary["table"]] == keys
    assert summary["advisor"]["verdicts"][0]["rule"] == "paper"
    assert engine.StudySpec.from_dict(summary["spec"]).to_dict() == summary["spec"]

    h5py = pytest.importorskip("h5py")
    with h5py.File(out / summary["files"]["results"], "r") as f:
        assert list(f["runs"]) == keys
        assert np.all(np.isfinite(f["runs/ref-s1/stages/consolidation/stress_top"][()]))

    from matplotlib.image import imread

    # with the resolution curve: the study has its resolution controls (on by default)
    assert (
        len(summary["files"]["plots"]) == 6 and "plots/resolution.png" in summary["files"]["plots"]
    )
    for p in summary["files"]["plots"]:
        assert imread(out / p).shape[0] > 100
    for key in keys:
        files = summary["files"]["snapshots"][key]
        assert f"snapshots/{key}/particles.vtkhdf" in files
        with h5py.File(out / "snapshots" / key / "particles.vtkhdf", "r") as f:
            assert f["VTKHDF"].attrs["Type"] == b"PolyData"
            assert int(f["VTKHDF/Steps"].attrs["NSteps"]) == 6
            row = next(r for r in summary["table"] if r["run"] == key)
            assert int(f["VTKHDF/NumberOfPoints"][0]) == row["particles"]
        assert imread(out / "snapshots" / key / "unconfined.png").shape[1] > 400


def test_study_decide_adds_seeds_and_reports_them(tmp_path):
    # without the protocol check (its half-step reference was a third of this test's time):
    # the seeds the rule adds are what is checked; the check is test_study_end_to_end's
    body = {**TINY, "max_seeds": 3, "max_reference_seeds": 3, "rounds": 1, "protocol_check": False}
    spec = tmp_path / "tiny.json"
    spec.write_text(json.dumps(body))
    out = tmp_path / "out"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "demscale",
            "study",
            str(spec),
            "--out",
            str(out),
            "--decide",
            "--no-snapshots",
            "--quiet",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode in (0, 1), proc.stderr
    summary = _strict((out / "summary.json").read_text())
    adaptive = summary["advisor"]["adaptive"]
    planned = [p.key for p in engine.plan(engine.StudySpec.from_dict(body)).runs]
    added = [a["run"] for a in adaptive["added_runs"]]
    assert adaptive["planned_runs"] == len(planned) and adaptive["looks"] == 2
    assert added and all(a["reason"].startswith("round 1:") for a in adaptive["added_runs"])
    rows = [row["run"] for row in summary["table"]]
    assert set(rows) <= set(planned + added)
    assert all(k in rows or k in summary["failed"] for k in added)
    assert "seeds until decided" in proc.stderr and added[0] in proc.stderr


TINY_TEST = {
    "cell": [0.015, 0.015, 0.015],
    "platen_speed": 0.02,
    "inertial_number": None,
    "output_interval": 0.001,
    "unconfined": False,
    "pair_law": {"type": "BilinearAdhesive", "k1": 5e3, "k2": 4.5e4},
}


def test_calibrate_then_export(tmp_path, capsys):
    # demscale calibrate: targets made by the engine from K1 = 8e3 N/m, the calibration told
    # only a box; then demscale export of the law it wrote
    truth = engine.UniaxialTest.from_dict(
        {**TINY_TEST, "pair_law": {**TINY_TEST["pair_law"], "k1": 8e3}}
    )
    r = engine.run_uniaxial(truth)
    lo = r.scalars["loading_stiffness"]
    (tmp_path / "lab.json").write_text(
        json.dumps(
            {"tester": "uniaxial", "loading_stiffness": lo, "loading_stiffness_sd": 0.1 * lo}
        )
    )
    (tmp_path / "test.json").write_text(json.dumps(TINY_TEST))
    out = tmp_path / "cal"
    argv = ["calibrate", str(tmp_path / "lab.json"), "--test", str(tmp_path / "test.json")]
    # 3 design runs and a wave of 2 (5 and 3 before): the fewest a wave's plumbing needs
    argv += ["--param", "k1=3e3:2e4", "--out", str(out), "--runs", "3", "--waves", "1"]
    code = main([*argv, "--wave-runs", "2"])
    text = capsys.readouterr()
    assert "k1 = " in text.out and "loading_stiffness" in text.out and "[5/5]" in text.err
    summary = _strict((out / "calibration.json").read_text())
    # a target the check run did not meet: exit status 1, said on stderr and in the JSON
    met = all(q["met"] for q in summary["targets_met"])
    assert code == (0 if met else 1) and summary["all_targets_met"] == met
    assert met or "NOT met" in text.err
    radius = engine.UniaxialTest.from_dict(TINY_TEST).radius
    assert summary["reference_radius"] == radius
    assert json.loads((out / "law.json").read_text())["reference_radius"] == radius
    # the command's plumbing; the recovery of the untold law is tests/engine/test_calibrate.py's
    # (one run's value in this 31-particle cell is one draw of a wide spread)
    k1 = summary["parameters"]["k1"]
    assert 3e3 <= k1["interval"][0] <= k1["median"] <= k1["interval"][1] <= 2e4
    assert k1["unit"] == "N/m" and len(summary["runs"]) == 5
    assert "LoadingStiffness" in (out / "law.liggghts").read_text()
    assert (out / "calibration.png").read_bytes()[:4] == b"\x89PNG"
    assert main(["export", str(out / "law.json"), "--format", "csv"]) == 0
    assert capsys.readouterr().out.startswith("name,value,unit,doc\ntype,BilinearAdhesive")
    # a box the law cannot take is refused with the field named
    assert main([*argv[:-6], "--param", "E=1:2", "--out", str(out)]) == 2
    assert "calibrate.parameters.E" in capsys.readouterr().err
    # --then-study: the calibrated law's scaling study follows (a small one here)
    (tmp_path / "then.json").write_text(
        json.dumps(
            {
                "coarse_radii": [3.1e-3],
                "rules": ["paper"],
                "controls": False,
                "protocol_check": False,
            }
        )
    )
    then = [*argv, "--wave-runs", "2", "--then-study", "--study", str(tmp_path / "then.json")]
    assert main(then) in (0, 1)  # 1: a target not met, or a run failed
    study = json.loads((out / "study.json").read_text())
    law = json.loads((out / "law.json").read_text())
    law.pop("reference_radius")
    assert study["reference"]["pair_law"] == law and study["coarse_radii"] == [3.1e-3]
    assert (out / "study" / "summary.json").is_file()
    capsys.readouterr()
    # --resolution: a study without controls has no curve to correct by; a bad kind is named
    (tmp_path / "study.json").write_text(json.dumps({"advisor": {"resolution_curve": None}}))
    assert main([*argv, "--resolution", str(tmp_path / "study.json")]) == 2
    assert "no resolution curve" in capsys.readouterr().err
    (tmp_path / "res.json").write_text(json.dumps({"k0": [1.0, 0.1]}))
    assert main([*argv, "--resolution", str(tmp_path / "res.json")]) == 2
    assert "calibrate.resolution.k0" in capsys.readouterr().err


def test_a_target_no_law_of_the_box_reaches_is_said_not_met(tmp_path, capsys):
    """Issue 42 item 2: a calibration whose check run misses a target says so: exit status
    1, "NOT met" with the target's z on stderr, all_targets_met false in the JSON. The
    target is a loading stiffness of 1 kPa +- 10 Pa, four decades below what any law of the
    box gives in this cell (MPa), so no run can meet it."""
    lab = {"tester": "uniaxial", "loading_stiffness": 1e3, "loading_stiffness_sd": 10.0}
    (tmp_path / "lab.json").write_text(json.dumps(lab))
    (tmp_path / "test.json").write_text(json.dumps(TINY_TEST))
    out = tmp_path / "cal"
    argv = ["calibrate", str(tmp_path / "lab.json"), "--test", str(tmp_path / "test.json")]
    argv += ["--param", "k1=3e3:2e4", "--out", str(out), "--runs", "3", "--waves", "0"]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "NOT met" in err and "loading_stiffness" in err and "z = +" in err, err
    summary = _strict((out / "calibration.json").read_text())
    assert summary["all_targets_met"] is False
    (q,) = summary["targets_met"]
    assert q["met"] is False and q["z"] > 2


def test_bad_inputs_exit_2_naming_the_flag_or_field(tmp_path, capsys):
    """The command-line half of issue 42's replay: each bad input exits 2 with one message
    that names the flag (or the file and its field) the user gave, before anything runs."""
    law = {"type": "BilinearAdhesive", "k1": 5e3, "k2": 2.5e4, "f0": -0.4}
    (tmp_path / "law.json").write_text(json.dumps(law))
    (tmp_path / "law_r.json").write_text(json.dumps({**law, "reference_radius": 2.5e-3}))
    (tmp_path / "test.json").write_text(json.dumps(TINY_TEST))
    lab = {"tester": "uniaxial", "loading_stiffness": 1e6, "loading_stiffness_sd": 1e5}
    (tmp_path / "lab.json").write_text(json.dumps(lab))
    (tmp_path / "lab_nosd.json").write_text(json.dumps({**lab, "loading_stiffness_sd": None}))
    spec = {k: v for k, v in TINY.items() if k != "reference"}
    (tmp_path / "noref.json").write_text(json.dumps(spec))
    cal = ["calibrate", str(tmp_path / "lab.json"), "--test", str(tmp_path / "test.json")]
    cal += ["--out", str(tmp_path / "cal")]
    cases = [
        (["export", str(tmp_path / "law_r.json"), "--radius", "-1"], "--radius -1"),
        (["export", str(tmp_path / "law.json"), "--radius", "5e-3"], "--reference-radius"),
        (["export", str(tmp_path / "law_r.json"), "--radius", "5e-3", "--rule", "x"], "--rule x"),
        (["export", str(tmp_path / "law_r.json"), "--reference-radius", "1e-3"], "--reference"),
        ([*cal, "--param", "k1=3e3:1e300"], "--param k1=3e3:1e300"),
        ([*cal, "--param", "k1=3e3:2e4", "--runs", "2"], "--runs"),
        ([*cal[:1], str(tmp_path / "lab_nosd.json"), *cal[2:], "--param", "k1=3e3:2e4"], "_sd"),
        (["study", str(tmp_path / "noref.json"), "--out", str(tmp_path / "s")], "reference"),
    ]
    for argv, word in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert word in err and err.count("\n") == 1, (argv, err)
    assert not (tmp_path / "cal" / "runs").exists()  # nothing ran


def test_export_into_a_closed_pipe_is_quiet(tmp_path):
    # `demscale export law.json | head -1`: the reader goes away; no "Broken pipe" message,
    # the status of a program SIGPIPE stopped
    law = {"type": "BilinearAdhesive", "k1": 5e3, "k2": 2.5e4, "reference_radius": 2.5e-3}
    (tmp_path / "law.json").write_text(json.dumps(law))
    p = subprocess.Popen(
        [sys.executable, "-m", "demscale", "export", str(tmp_path / "law.json")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        cwd=ROOT,
    )
    p.stdout.close()  # before the command writes
    err = p.stderr.read().decode()
    assert p.wait(60) == 141 and err == "", err


def test_the_exported_fragment_says_what_each_value_is(tmp_path, capsys):
    law = {"type": "BilinearAdhesive", "k1": 5e3, "k2": 4.8883e4, "reference_radius": 2.5e-3}
    (tmp_path / "law.json").write_text(json.dumps(law))
    assert main(["export", str(tmp_path / "law.json")]) == 0
    lines = capsys.readouterr().out.splitlines()
    fixes = [i for i, line in enumerate(lines) if line.startswith("fix ")]
    for i in fixes:  # each value's meaning and unit on the line above it
        name = lines[i].split()[4]
        assert lines[i - 1].startswith(f"# {name}: ") and "[" in lines[i - 1], lines[i - 1]
    ratio = next(lines[i - 1] for i in fixes if "UnloadingStiffness" in lines[i])
    assert "RATIO K2 / K1" in ratio and "48883" in ratio
    assert any("R = 0.0025 m" in line for line in lines)
