"""``demscale calibrate``: a contact law calibrated to laboratory data (engine.calibrate),
written with its report; with ``--then-study``, a scaling study of the calibrated law
(:func:`demscale.commands.study.study_from_file`)."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

from ..options import add_out, add_workers, command, workers_error

CALIBRATE_HELP = """\
Calibrate the pair law of TEST.json to the laboratory data in TARGETS.json (an
engine.calibration.LabTargets: porosity against stress, loading and unloading stiffness,
K0, unconfined strength at one or several consolidation stresses, and a shear tester's
yield loci ("shear": sigma_pre, points of sigma_n and tau, tau_pre, bulk density), each
with its 1-sd uncertainty and the tester named) over the law parameters given with --param,
with Gaussian-process emulators, history-matching waves and a posterior
(docs/CALIBRATION.md).
Uniaxial data are matched by TEST.json's uniaxial test, each yield locus by a shear test of
its material (--shear-test SHEAR.json, else the default shear cell). Every run is stored
in DIR/runs as it finishes, and a rerun finds them. Writes:

  calibration.json      the calibrated law, each parameter (median, 90 % interval,
                        determined or free), every target met or not, the Sobol indices,
                        every run
  law.json              the calibrated law (an engine contact law as JSON)
  law.liggghts          the law as a LIGGGHTS edinburgh/stiffness fragment (if it maps)
  calibration.png       the compression curve and flow function against the lab points

With --then-study, a scaling study of the calibrated law follows (its coarse radii and
rules: --study SPEC.json, else the default study's), written to DIR/study.

Exit status: 0 every target met; 1 the calibration finished but some target is not met by
the check run (named, with its z; everything is still written) or the then-study had a
failed run; 2 the input is not valid (the message names the flag or the file's field).

Laboratory values are bulk values; a small cell loses some of each property (the
resolution curve of a study with controls says how much). --resolution SUMMARY.json
corrects each run's values to the bulk by the curve of a study whose reference is TEST.json
(docs/CALIBRATION.md), so that the law does not absorb the cell's loss.
"""


def add_commands(sub) -> None:
    """``calibrate`` on the ``demscale`` parser's subparsers ``sub``."""
    p = command(
        sub,
        "calibrate",
        "calibrate a law to laboratory data (then, optionally, study it)",
        CALIBRATE_HELP,
        calibrate_cmd,
    )
    p.add_argument("targets", metavar="TARGETS.json", help="the laboratory data (LabTargets)")
    p.add_argument("--test", required=True, metavar="TEST.json", help="the base test and law")
    p.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=LOW:HIGH",
        help="a law parameter to calibrate and its box (repeat: --param k1=3e3:2e4 ...)",
    )
    add_out(p, "folder for the results")
    p.add_argument("--runs", type=int, default=25, help="design runs (default 25)")
    p.add_argument("--waves", type=int, default=2, help="history-matching waves (default 2)")
    p.add_argument("--wave-runs", type=int, default=15, help="runs per wave (default 15)")
    add_workers(p, "runs side by side")
    p.add_argument(
        "--then-study", action="store_true", help="then a scaling study of the calibrated law"
    )
    p.add_argument("--study", metavar="SPEC.json", help="with --then-study: its radii and rules")
    p.add_argument(
        "--resolution",
        metavar="SUMMARY.json",
        help="correct the cell's values to the bulk by the resolution curve of a study whose "
        "reference is this test (its summary.json), or by {kind: [factor, sd of log]}",
    )
    p.add_argument(
        "--shear-test",
        metavar="SHEAR.json",
        help="with shear data: the shear cell (engine.ShearTest's fields but pair_law, "
        "preshear_stress and normal_stresses, which are the calibrated law and the data's; "
        "default: docs/SHEAR.md's cell, 10 x 5 x 15 diameters of the test's particles)",
    )
    p.add_argument(
        "--vary-seed",
        action="store_true",
        help="each run packs its own sample (the test's seed plus the run's index), so that "
        "the emulators' noise holds the packing scatter; default: every run on the test's "
        "one packing (docs/CALIBRATION.md)",
    )


#: Where a command-line user gave what an engine field names: the flags of ``calibrate``.
_CALIBRATE_FLAGS = {
    "calibrate.parameters": "--param",
    "calibrate.runs": "--runs",
    "calibrate.waves": "--waves",
    "calibrate.wave_runs": "--wave-runs",
    "calibrate.resolution": "--resolution",
    "calibrate.targets": "TARGETS.json",
    "calibrate.shear_test": "--shear-test",
}


def _calibrate_where(field: str, args) -> str:
    """The flag or file of ``demscale calibrate`` that holds the engine's ``field``."""
    head = field.split(".")[0]
    if field.startswith("calibrate.parameters."):
        name = field.split(".")[2]
        box = next((p for p in args.param if p.partition("=")[0].strip() == name), name)
        return f"--param {box}"
    for prefix, flag in _CALIBRATE_FLAGS.items():
        if field.startswith(prefix):
            return flag
    if head in ("LabTargets", "CompressionPoint", "StrengthPoint", "ShearLocus", "LocusPoint"):
        return f"{args.targets} ({field})"
    return f"--test {args.test} ({field})"


def _resolution(raw) -> dict:
    """--resolution: a study's summary.json (its report's resolution curve, under
    ``advisor``), or the corrections themselves ({kind: [factor, sd of its log]})."""
    from engine.calibration.calibrate import resolution_corrections
    from engine.study.report import StudyReport

    if isinstance(raw, dict) and "advisor" in raw:
        curve = StudyReport.from_dict(raw["advisor"]).resolution_curve
        if curve is None:
            raise ValueError("--resolution: the study has no resolution curve (no controls)")
        return resolution_corrections(curve.to_dict())
    if not isinstance(raw, dict):
        raise ValueError("--resolution: a study's summary.json or {kind: [factor, sd]}")
    return raw


def _param_box(text: str) -> tuple[str, tuple[float, float]]:
    name, _, box = text.partition("=")
    lo, _, hi = box.partition(":")
    try:
        return name.strip(), (float(lo), float(hi))
    except ValueError:
        raise ValueError(f"--param {text!r}: write NAME=LOW:HIGH, e.g. k1=3e3:2e4") from None


def _read_request(args):
    """The calibration request of the command line, checked whole before anything is
    written (engine.core.inputs: the test and the design, as the service checks them;
    engine.calibration.calibrate.check_request): (test, targets, boxes, resolution,
    shear_test)."""
    from engine.calibration import LabTargets
    from engine.calibration.calibrate import check_request
    from engine.core.inputs import check_design, check_test_json
    from engine.uniaxial.spec import uniaxial_from_json

    targets = LabTargets.from_dict(json.loads(Path(args.targets).read_text()))
    fields = json.loads(Path(args.test).read_text())
    check_test_json(fields, "")  # a preset or the pair law
    test = uniaxial_from_json(fields)
    boxes = dict(_param_box(p) for p in args.param)
    if not boxes:
        raise ValueError("give the parameters to calibrate: --param k1=3e3:2e4 ...")
    resolution = None
    if args.resolution:
        resolution = _resolution(json.loads(Path(args.resolution).read_text()))
    shear_test = None  # the shear cell's fields (judged with each locus's stresses)
    if args.shear_test:
        shear_test = json.loads(Path(args.shear_test).read_text())
    check_request(test, targets, boxes, args.runs, shear_test)
    check_design(args.runs, args.waves, args.wave_runs)
    return test, targets, boxes, resolution, shear_test


def calibrate_cmd(args) -> int:
    """``demscale calibrate``: calibrate a law to laboratory data, then (optionally) study it."""
    import concurrent.futures as cf
    import multiprocessing as mp

    import engine
    from engine.calibration import calibrate

    try:
        test, targets, boxes, resolution, shear_test = _read_request(args)
    except (OSError, json.JSONDecodeError) as e:
        print(f"cannot read the input: {e}", file=sys.stderr)
        return 2
    except engine.ParameterError as e:
        print(f"{_calibrate_where(e.field, args)}: not valid: {e}", file=sys.stderr)
        return 2
    except (TypeError, ValueError) as e:
        print(f"not valid: {e}", file=sys.stderr)
        return 2
    if (why := workers_error(args.workers)) is not None:
        print(why, file=sys.stderr)
        return 2
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    total = args.runs + args.waves * args.wave_runs  # on_run: the design and wave runs

    def on_run(i, quantities):
        if isinstance(quantities, str):  # a run that failed: left out
            print(f"[{i + 1}/{total}] run failed: {quantities}", file=sys.stderr, flush=True)
            return
        q = ", ".join(f"{x['name']} {x['value']:.4g}" for x in quantities)
        print(f"[{i + 1}/{total}] run done: {q}", file=sys.stderr, flush=True)

    pool = None
    if args.workers > 1:
        pool = cf.ProcessPoolExecutor(args.workers, mp_context=mp.get_context("spawn"))
    try:
        cal = calibrate(
            test,
            targets,
            boxes,
            runs=args.runs,
            waves=args.waves,
            wave_runs=args.wave_runs,
            store=out / "runs",
            executor=pool,
            on_run=on_run,
            resolution=resolution,
            shear_test=shear_test,
            vary_seed=args.vary_seed,
        )
    except engine.ParameterError as e:
        print(f"{_calibrate_where(e.field, args)}: not valid: {e}", file=sys.stderr)
        return 2
    finally:
        if pool is not None:
            pool.shutdown()
    code = _write_calibration(cal, test, out)
    if not args.then_study:
        return code
    return max(
        code, then_study(cal, test, out, Path(args.study) if args.study else None, args.workers)
    )


def _write_calibration(cal, test, out: Path) -> int:
    """Write the calibration into ``out`` (calibration.json, law.json with the radius it is
    for, law.liggghts where the law maps, calibration.png) and print its report; returns 1
    where a target is not met, else 0."""
    import engine
    from engine.core.records import to_dict
    from engine.io.liggghts import to_liggghts

    from ..report import calibration_lines

    summary = cal.to_summary()
    (out / "calibration.json").write_text(json.dumps(summary, indent=1))
    # the law with the particle radius it is calibrated for: `demscale export --radius`
    # scales it from there
    law = {"type": type(cal.law).__name__, **to_dict(cal.law), "reference_radius": test.radius}
    (out / "law.json").write_text(json.dumps(law, indent=1))
    try:
        (out / "law.liggghts").write_text(
            to_liggghts(cal.law, note="calibrated by demscale", radius=test.radius)
        )
    except engine.ParameterError as e:
        print(f"no LIGGGHTS fragment: {e}", file=sys.stderr)
    for line in calibration_lines(cal, summary, test.radius):
        print(line)
    if importlib.util.find_spec("matplotlib") is not None:
        from engine.io.figures import calibration_figure

        calibration_figure(summary).savefig(out / "calibration.png", format="png")
    print(f"written to {out}/calibration.json, calibration.png, law.json, law.liggghts")
    if cal.all_met:
        return 0
    n = len(cal.targets_met)
    print(
        f"calibration finished, but {len(cal.not_met)} of {n} targets NOT met (exit "
        "status 1): " + "; ".join(cal.not_met),
        file=sys.stderr,
    )
    return 1


def then_study(cal, test, out: Path, spec_path: Path | None, workers: int) -> int:
    """The scaling study of the calibrated law ``cal`` (its reference: ``test`` with that
    law; its radii and rules: the study in ``spec_path``, else the default study's), written
    as ``out``/study.json and run into ``out``/study on ``workers`` processes; returns
    :func:`demscale.commands.study.study_from_file`'s exit status."""
    import engine

    from .study import study_from_file

    spec = None
    if spec_path is not None:  # its radii and rules; its reference is the calibrated test
        body = json.loads(spec_path.read_text())
        body["reference"] = test.to_dict()
        spec = engine.StudySpec.from_dict(body)
    (out / "study.json").write_text(json.dumps(cal.study(spec).to_dict(), indent=1))
    return study_from_file(out / "study.json", out / "study", workers=workers, snapshots=False)
