"""``demscale plan``: how coarse a process may be coarse-grained, per feature kind, from the
stored size series (engine.process; docs/RESOLUTION.md).

    demscale plan --default-powder --diameter 50e-6 --width 0.2 --kind bulk_shear --stress 2e4
    demscale plan --law calibration.json --diameter 80e-6 --width 0.05 --kind free_surface

This module parses the command line and prints; the planner is engine.process.planner.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..laws import law_from_json
from ..options import command

PLAN_HELP = """\
The largest coarse-graining factor s_max = L / (N_req d0) a process allows, per feature kind:
N_req is the number of coarse particles across a feature that keeps each property of its
kind within its tolerance of the bulk, measured for the fine law by the size series
(docs/RESOLUTION.md; `python -m benchmarks.size_series`). For the bilinear law with K ~ R and
f0 ~ R^2 coarse-graining is an exact similarity, so a coarse model of a feature L wide is
the fine law in a feature L / s wide: its whole error is that size effect.

The fine law: --law FILE (a law's JSON with "type", or a calibration's calibration.json;
with "reference_radius" it is scaled by the similarity to --diameter, without it it is taken
as the law of particles of --diameter), or --default-powder (the main job's law, R = 2.5 mm,
f0 = -0.4 N, scaled by the similarity to --diameter: its counterpart of that size).

A stored series applies when the law's dimensionless groups at the feature's stress (the
stiffness number k1 / (sigma d), the cohesion number |f0| / (sigma d^2), K2 / K1, friction,
restitution) match it within 10 %; otherwise the plan says "not measured" and which series
would decide it, never a number inferred from another law, stress or feature kind.

For each feature kind the plan prints N_req (point estimate and 95 % bound), s_max, and the
coarse model at s_max: its law (scaled by the similarity), time step, inertial and Bond
numbers, particles per cubic metre, the cost of a run of --volume for --duration, and the
LIGGGHTS fragment (--liggghts).

Exit status: 0 planned; 2 an option or the law file is not valid (the message names it)."""


#: The feature the main job plans the default powder for: 200 mm wide (an outlet's, a
#: channel's width) at 20 kPa, the size series' consolidation stress, so that the series'
#: evidence applies to the default powder's law and its similarity counterparts.
MAIN_JOB_FEATURE = {"feature_width": 0.2, "stress": 2e4, "feature_kind": "bulk_shear"}
#: The powders the main job plans: the default powder (5 mm) and its 50 um counterpart.
MAIN_JOB_DIAMETERS = (5e-5, 5e-3)


def main_job_processes() -> list[dict]:
    """The processes the main job plans (as POST /plans bodies): the default powder's law
    scaled by the similarity to each of :data:`MAIN_JOB_DIAMETERS`, in the feature
    :data:`MAIN_JOB_FEATURE`."""
    import engine
    from engine.core.records import to_dict

    base = engine.default_study().reference
    out = []
    for d0 in MAIN_JOB_DIAMETERS:
        law = engine.similar(base.pair_law, d0 / (2 * base.radius))
        out.append(
            {
                "pair_law": {"type": type(law).__name__, **to_dict(law)},
                "diameter": d0,
                "density": base.density,
                **MAIN_JOB_FEATURE,
            }
        )
    return out


def plan_line(plan: dict) -> str:
    """:func:`engine.process.answer_line` of a plan's JSON (POST /plans)."""
    import engine
    from engine.process import answer_line
    from engine.process.planner import FeaturePlan, ProcessPlan

    process = engine.Process.from_dict(plan["process"])
    feats = [FeaturePlan(**f) for f in plan["features"]]
    return answer_line(
        ProcessPlan(process, plan["groups"], plan["matched_series"], plan["mismatches"], feats)
    )


def add_commands(sub) -> None:
    """``plan`` on the ``demscale`` parser's subparsers ``sub``."""
    from engine.process import FEATURE_KINDS

    p = command(
        sub,
        "plan",
        "how coarse a process may go, per feature kind (from the size series)",
        PLAN_HELP,
        plan_cmd,
    )
    law = p.add_mutually_exclusive_group(required=True)
    law.add_argument("--law", type=Path, metavar="FILE", help="the fine law (JSON)")
    law.add_argument(
        "--default-powder",
        action="store_true",
        help="the main job's powder scaled by the similarity to --diameter",
    )
    p.add_argument("--diameter", type=float, required=True, help="fine particle diameter d0 [m]")
    p.add_argument("--width", type=float, required=True, help="the feature's width L [m]")
    p.add_argument(
        "--kind",
        default="bulk_shear",
        choices=tuple(FEATURE_KINDS),
        help="the feature's kind (default bulk_shear)",
    )
    p.add_argument(
        "--stress",
        type=float,
        default=None,
        help="stress in the feature [Pa] (default: solid_fraction rho g L)",
    )
    p.add_argument("--density", type=float, default=2000.0, help="particle density [kg/m^3]")
    p.add_argument("--velocity", type=float, default=0.1, help="velocity scale [m/s]")
    p.add_argument("--gravity", type=float, default=9.81, help="gravity [m/s^2]")
    p.add_argument("--volume", type=float, default=1e-3, help="material simulated [m^3]")
    p.add_argument("--duration", type=float, default=1.0, help="process time simulated [s]")
    p.add_argument("--json", action="store_true", help="print the plan as JSON")
    p.add_argument("--liggghts", action="store_true", help="print the coarse law's fragments")


def _fine_law(args):
    """The fine law at --diameter, and where it came from."""
    import engine

    d0 = args.diameter
    if args.default_powder:
        base = engine.default_study().reference
        ref_d = 2 * base.radius
        law = base.pair_law
        return engine.similar(law, d0 / ref_d), f"the default powder scaled x {d0 / ref_d:.4g}"
    try:
        raw = json.loads(args.law.read_text())
    except OSError as e:
        raise ValueError(f"--law {args.law}: {e.strerror}") from None
    except json.JSONDecodeError as e:
        raise ValueError(f"--law {args.law}: not JSON ({e})") from None
    if isinstance(raw, dict) and isinstance(raw.get("law"), dict):  # a calibration.json
        raw = {**raw["law"], "reference_radius": raw.get("reference_radius")}
    try:
        law, radius = law_from_json(raw, "law", " (or a calibration.json with its law)")
    except engine.ParameterError:
        raise  # a field of the law, named
    except ValueError as e:  # the file's type or its reference_radius
        raise ValueError(f"--law {args.law}: {e}") from None
    if radius is None:
        return law, f"{args.law} (taken at d0)"
    s = d0 / (2 * radius)
    return engine.similar(law, s), f"{args.law} (R = {radius:g} m) scaled x {s:.4g}"


#: The arguments that are the process's fields of the same names.
_PROCESS_ARGS = ("stress", "density", "velocity", "gravity", "volume", "duration")


def plan_cmd(args) -> int:
    import engine
    from engine.process import answer_line

    try:
        law, source = _fine_law(args)
        process = engine.Process(
            pair_law=law,
            diameter=args.diameter,
            feature_width=args.width,
            feature_kind=args.kind,
            **{f: getattr(args, f) for f in _PROCESS_ARGS},
        )
        plan = engine.plan_process(process)
    except (ValueError, engine.ParameterError) as e:
        print(f"demscale plan: {e}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(plan.to_dict(), indent=1, default=float))
        return 0
    print(answer_line(plan))
    print(f"fine law: {source}")
    g = plan.groups
    print(
        f"groups at {process.feature_stress:.4g} Pa: stiffness number "
        f"{g['stiffness_number']:.3g}, cohesion number {g['cohesion_number']:.3g}; "
        + (
            f"matches stored series {plan.matched}"
            if plan.matched
            else "no stored series matches ("
            + "; ".join(f"{k}: {', '.join(v)}" for k, v in plan.mismatches.items())
            + ")"
        )
    )
    for f in plan.features:
        print(f"- {f.kind}: {f.why}")
        c = f.coarse
        if c:
            at = "at the limit " if f.bound == "more_than" else "at "
            print(
                f"    coarse model {at}s = {c['factor']:.4g}: d = {c['diameter']:.4g} m, "
                f"dt = {c['time_step']:.3g} s, inertial number {c['inertial_number']:.2g}, "
                f"Bond number {c['bond_number']:.3g}, {c['particles_per_m3']:.3g} "
                f"particles/m^3, {c['core_hours']:.3g} core-hours for {process.volume:g} m^3 "
                f"over {process.duration:g} s ({c['speed_up']:.3g}x fewer particle-steps "
                "than the fine model)"
            )
            for w in c.get("warnings", []):
                print(f"    note: {w}")
            if args.liggghts:
                print("    " + c["liggghts"].replace("\n", "\n    "))
    return 0
