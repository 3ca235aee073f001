"""``demscale export-test`` and ``demscale judge-liggghts``: a uniaxial test (or a hopper) out
as a LIGGGHTS 3.8 deck, and LIGGGHTS' runs of a uniaxial deck back, judged against demscale's
own (docs/LIGGGHTS_DECK.md; the hopper's deck: docs/HOPPER.md).

    demscale export-test --study my_study.json --run r5mm-paper-s1 --seeds 1 2 3 --out deck/
    (cd deck/s1 && liggghts -in in.demscale)       # and s2, s3
    demscale judge-liggghts deck/s1 deck/s2 deck/s3 --reference results/mine/results.h5

The engine side is engine.io.liggghts_deck (the deck), engine.io.liggghts_hopper (the
hopper's) and engine.io.liggghts_read (the reader and the verdict); this module parses the
command lines and prints.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from ..options import add_out, attempt, command

EXPORT_HELP = """\
Write a uniaxial test as a complete LIGGGHTS 3.8 input deck: the cell with its periodic
axes, demscale's own poured cloud (read_data), the pair law (edinburgh/stiffness for the
bilinear and EEPA laws, hertz for Hertz-Mindlin), Hertz platens, every stage with demscale's
targets and stopping rules, the time step and the output demscale's reader needs.

The test comes from a JSON file (an engine.UniaxialTest; "preset": "quick" and
"protocol": "seed" with overrides as for `demscale run`), from --preset with --law and
--protocol, or from a study (--study SPEC.json --run
KEY: any reference, coarse run or control of its plan). --seeds writes one deck per packing
seed (folders s1, s2, ... under --out). Run each unmodified in its folder:

    cd OUT && liggghts -in in.demscale

and read it back with `demscale judge-liggghts OUT --reference ...`.

A hopper (TEST.json with "type": "HopperTest", or a study whose reference is one) is written
as its own deck (in.hopper: demscale's lattice fill read in, the walls and the gate as STL
meshes, the catch floor a plane, the settling behind the closed gate, the gate moved away,
discharge.txt with the discharged mass every output_interval and particle dumps in dump/):

    cd OUT && liggghts -in in.hopper

The deck's comments say
what LIGGGHTS does differently; what it cannot express (an adhesive branch kadh > 0 with n
or chi != 1, a platen speed held to an inertial number, as the default protocol loads) is
refused, naming the field: export a test at the seed's protocol (--protocol seed) or one
whose "inertial_number" is null."""

JUDGE_HELP = """\
Read LIGGGHTS runs of exported decks back into demscale's run record (curves and scalars in
the HDF5 layout of a run: liggghts.h5 in each folder, or --store DIR) and judge them, as a
study judges a coarse variant, against demscale's own runs of the test they stand for: the
verdict metrics (interior density, loading and unloading stiffness, interior coordination,
unconfined strength), each with its error, its interval at the study's confidence and a
verdict, equivalent, differs or undecided.

--reference takes demscale runs: run files (.h5, engine.io.store layout), folders of them,
or a study's results.h5 (its reference runs, or those named by --runs). They must be runs of
the test the decks were exported from: the same in every field but the seed, the radius and
the pair law (a coarse model judged against the fine reference), the time step, the
sampling interval and the stage time bound; otherwise the command refuses, naming the
fields that differ. A LIGGGHTS deck that stopped at a stage's bound counts as a failed run
and is left out of the verdict."""

#: Fields of a test in which LIGGGHTS' runs may differ from demscale's references: the
#: coarse model (radius, pair law), numerics (time step, sampling) and the stage bound.
FREE_FIELDS = ("seed", "radius", "pair_law", "dt", "dt_fraction", "output_interval")
FREE_FIELDS += ("max_stage_time",)


def _differences(want, got, free=FREE_FIELDS) -> list[str]:
    """The fields of test ``got`` that differ from ``want``'s, but ``free``, as
    ``field X (want Y)``."""
    a, b = want.to_dict(), got.to_dict()
    return [f"{k} {b[k]} (want {a[k]})" for k in a if k not in free and a[k] != b[k]]


def _check_same_test(runs, refs) -> None:
    """Refuse (ValueError naming --reference) references that are not runs of one test, or
    LIGGGHTS runs of another test than theirs (but for :data:`FREE_FIELDS`)."""
    tests = [r.test for r in refs if not isinstance(r, str)]
    if not tests:
        return
    base = tests[0]
    for t in tests[1:]:
        if diff := _differences(base, t, ("seed",)):
            raise ValueError(f"--reference: its runs are not of one test: {'; '.join(diff)}")
    for r in runs:
        if isinstance(r, str):
            continue
        if diff := _differences(base, r.test):
            raise ValueError(
                "--reference: demscale's runs are of another test than the LIGGGHTS runs "
                f"(deck {'; '.join(diff)}): judge against runs of the deck's test, e.g. a "
                "study's results.h5 and a deck exported from it (--study SPEC --run KEY)"
            )


def _decked(test):
    """``test`` if export-test writes a deck of its kind (:func:`demscale.options.single_test`)."""
    from ..options import single_test

    return single_test(test, "export-test", " (the ring shear deck: benchmarks/annular_shear)")


def _read_test(args):
    import engine
    from engine.study.kinds import test_from_json

    if args.study is not None:
        from engine.study.plan import plan

        spec = engine.StudySpec.from_dict(json.loads(Path(args.study).read_text()))
        runs = {p.key: p for p in plan(spec).runs}
        if args.run not in runs:
            raise ValueError(
                f"--run {args.run!r}: not a run of the study; its runs: {', '.join(runs)}"
            )
        return _decked(runs[args.run].test)
    if args.test is not None:
        fields = json.loads(Path(args.test).read_text())
        if not isinstance(fields, dict):
            raise ValueError("the test file must hold a JSON object of the test's fields")
        return _decked(test_from_json(fields))
    if args.preset is None:
        raise ValueError("give a test: TEST.json, --preset NAME [--law LAW.json] or --study")
    fields = engine.preset(args.preset, args.protocol).to_dict()
    if args.law is not None:  # {"type": ..., fields}: the law as a test's JSON holds it
        law = json.loads(Path(args.law).read_text())
        if isinstance(law, dict) and "reference_radius" in law:  # demscale calibrate's law.json
            law = dict(law)
            radius = law.pop("reference_radius")
            if radius is not None and not (
                isinstance(radius, (int, float)) and math.isclose(radius, fields["radius"])
            ):
                raise ValueError(
                    f"--law {args.law}: the law is for R = {radius} m (its reference_radius), "
                    f"the test's particles are R = {fields['radius']:g} m: give a TEST.json "
                    'with that "radius" and the law as its "pair_law"'
                )
        fields["pair_law"] = law
    return engine.UniaxialTest.from_dict(fields)


def _is_hopper(test) -> bool:
    from engine.hopper.spec import HopperTest

    return isinstance(test, HopperTest)


def _dt(test) -> float:
    """The time step demscale runs ``test`` with [s]."""
    if _is_hopper(test):
        from engine.hopper.driver import resolved_dt

        return resolved_dt(test)
    return test.resolved_dt()


def _write_decks(args):
    """The test of ``export-test``'s arguments, scaled to --radius where given, and the deck
    files written for it (one per --seeds seed)."""
    from dataclasses import replace

    import engine
    from engine.io.liggghts_deck import write_deck
    from engine.io.liggghts_hopper import write_hopper_deck

    test = _read_test(args)
    if args.run is not None and args.study is None:
        raise ValueError("--run needs --study")
    if args.radius is not None:
        rule = engine.ScalingRule.named(args.rule)
        test = rule.apply(test, args.radius, _dt(test))
    write = write_hopper_deck if _is_hopper(test) else write_deck
    seeds = args.seeds or [None]
    out = Path(args.out)
    written = []
    for seed in seeds:
        t = test if seed is None else replace(test, seed=seed)
        folder = out if seed is None else out / f"s{seed}"
        written.append(write(t, folder, skin=args.skin))
    return test, written


def export_test(args) -> int:
    """``demscale export-test``: the deck folder(s) of one test."""
    from engine.io.liggghts_deck import differences
    from engine.io.liggghts_hopper import hopper_differences

    decks, why = attempt(
        lambda: _write_decks(args), "cannot read the input", "not valid", refused=(KeyError,)
    )
    if why is not None:
        print(why, file=sys.stderr)
        return 2
    test, written = decks
    print(
        f"{test.n_particles} particles, R = {test.radius:g} m, {type(test.pair_law).__name__}, "
        f"dt = {_dt(test):g} s"
    )
    for path in written:
        print(f"wrote {path}   run it: (cd {path.parent} && liggghts -in {path.name})")
    print("LIGGGHTS does differently:")
    for d in (hopper_differences if _is_hopper(test) else differences)(test):
        print(f"  - {d}")
    return 0


def _references(paths, runs) -> list:
    """demscale's runs: run files, folders of run files, or a study's results.h5."""
    import h5py

    from engine.io.store import load_run, read_run_group

    out = []
    for p in map(Path, paths):
        files = sorted(p.glob("*.h5")) if p.is_dir() else [p]
        for f in files:
            with h5py.File(f, "r") as h:
                if "runs" in h:  # a study's file
                    for key, g in h["runs"].items():
                        if (key in runs) if runs else bool(g.attrs.get("reference", False)):
                            out.append(read_run_group(g))
                    continue
            out.append(load_run(f))
    return out


def _judge(args) -> dict:
    """``judge-liggghts``' deck folders read back (stored as runs), checked against the
    references' test and judged."""
    from engine.io.liggghts_read import judge_runs, save_output
    from engine.io.store import load_run

    tolerances = {}
    for item in args.tolerance:
        name, _, value = item.partition("=")
        tolerances[name.strip()] = float(value)
    runs = []
    for folder in map(Path, args.decks):
        name = folder.name if args.store else "liggghts.h5"
        path = (Path(args.store) / f"{name}.h5") if args.store else folder / name
        save_output(folder, path)
        runs.append(load_run(path))
        print(f"read {folder} -> {path}")
    refs = _references(args.reference, set(args.runs))
    _check_same_test(runs, refs)
    return judge_runs(runs, refs, tolerances, args.confidence)


def judge_liggghts(args) -> int:
    """``demscale judge-liggghts``: LIGGGHTS runs read back, stored and judged."""
    from engine.io.liggghts_read import OutputError

    result, why = attempt(
        lambda: _judge(args),
        "cannot read",
        "not valid",
        unreadable=(OSError, OutputError),
        refused=(KeyError,),
    )
    if why is not None:
        print(why, file=sys.stderr)
        return 2
    print(
        f"\nLIGGGHTS ({result['seeds']} run(s), {len(result['failed'])} stopped) against "
        f"demscale ({result['reference_seeds']} run(s)): {result['verdict']}"
    )
    print(f"  {result['reason']}")
    for m in result["metrics"]:
        err = "" if m["error"] is None else f"{100 * m['signed_error']:+.1f} %"
        iv = m.get("interval")
        ivs = "" if iv is None else f"[{100 * iv[0]:+.1f}, {100 * iv[1]:+.1f}] %"
        print(
            f"  {m['metric']:20s} {err:>9s}  {ivs:>20s}  "
            f"(tolerance {100 * m['tolerance']:g} %)  {m['verdict']}"
        )
    for f in result["failed"]:
        print(f"  stopped: {f}")
    if args.json:
        from engine.io.store import strict_json

        Path(args.json).write_text(strict_json(result) + "\n")
    return 0


def add_commands(sub) -> None:
    """The two subcommands, on the ``demscale`` parser's subparsers ``sub``."""
    p = command(
        sub,
        "export-test",
        "a uniaxial test or a hopper as a complete LIGGGHTS 3.8 deck",
        EXPORT_HELP,
        export_test,
    )
    p.add_argument(
        "test",
        nargs="?",
        metavar="TEST.json",
        help='the test (engine.UniaxialTest, or engine.HopperTest with "type": "HopperTest")',
    )
    p.add_argument("--preset", help="a named test (quick, paper) instead of TEST.json")
    p.add_argument(
        "--law", metavar="LAW.json", help='with --preset: {"type": "BilinearAdhesive", ...}'
    )
    p.add_argument(
        "--protocol",
        choices=("default", "seed"),
        default="default",
        help="with --preset: the preset's protocol (the deck needs a constant platen speed: "
        'seed, or a TEST.json with "inertial_number": null)',
    )
    p.add_argument("--study", metavar="SPEC.json", help="a study spec; with --run KEY")
    p.add_argument("--run", metavar="KEY", help="the study's run (ref-s1, r5mm-paper-s2, ...)")
    p.add_argument("--radius", type=float, help="scale the test to this radius [m] (--rule)")
    p.add_argument("--rule", default="paper", help="the scaling rule of --radius (default paper)")
    p.add_argument("--seeds", type=int, nargs="*", help="one deck per packing seed (OUT/sN)")
    p.add_argument("--skin", type=float, help="LIGGGHTS' Verlet skin [m] (default R/2)")
    add_out(p, "the deck's folder")

    p = command(
        sub,
        "judge-liggghts",
        "LIGGGHTS runs of exported decks judged against demscale's runs",
        JUDGE_HELP,
        judge_liggghts,
    )
    p.add_argument("decks", nargs="+", metavar="DECK_DIR", help="folders LIGGGHTS ran a deck in")
    p.add_argument(
        "--reference",
        nargs="+",
        required=True,
        metavar="PATH",
        help="demscale's runs: .h5 run files, folders of them, or a study's results.h5",
    )
    p.add_argument("--runs", nargs="*", default=[], metavar="KEY", help="a study's runs to use")
    p.add_argument("--store", metavar="DIR", help="store the read runs here (default: each folder)")
    p.add_argument(
        "--tolerance",
        action="append",
        default=[],
        metavar="METRIC=VALUE",
        help="a tolerance other than the default (repeat: --tolerance strength=0.1)",
    )
    p.add_argument("--confidence", type=float, help="the verdicts' confidence (default 0.95)")
    p.add_argument("--json", metavar="FILE", help="also write the verdict as JSON")
