"""``demscale export``: a contact law, fine or scaled to another particle radius by a rule,
as a LIGGGHTS fragment or a JSON or CSV table, on standard output."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from ..laws import law_from_json
from ..options import command

EXPORT_HELP = """\
Write a contact law (LAW.json: {"type": "BilinearAdhesive" or "EEPA", fields...,
"reference_radius": R}), or the law scaled to --radius by a rule, as a LIGGGHTS
edinburgh/stiffness fragment (each value's meaning and unit in a comment above it), or as a
JSON or CSV table of its parameters with units, to standard output. A law is calibrated for
one particle radius: LAW.json's reference_radius [m] (demscale calibrate writes it), or
--reference-radius; --radius without either is refused.

Exit status: 0 written; 2 LAW.json or an option is not valid (the message names it).
"""


def add_commands(sub) -> None:
    """``export`` on the ``demscale`` parser's subparsers ``sub``."""
    p = command(
        sub,
        "export",
        "a law (fine or scaled) as a LIGGGHTS fragment or a table",
        EXPORT_HELP,
        export,
    )
    p.add_argument("law", metavar="LAW.json", help='{"type": "BilinearAdhesive", ...}')
    p.add_argument("--format", choices=("liggghts", "json", "csv"), default="liggghts")
    p.add_argument("--radius", type=float, help="scale the law to this radius [m]")
    p.add_argument("--rule", default="paper", help="the scaling rule (default paper)")
    p.add_argument(
        "--reference-radius",
        type=float,
        default=None,
        metavar="R",
        help="the radius the law is for [m]; needed with --radius when LAW.json has no "
        "reference_radius (demscale calibrate writes it)",
    )


def _radius_flag(flag: str, value) -> str | None:
    """Why ``value`` of ``flag`` is not a particle radius, or None."""
    if value is None or (math.isfinite(value) and value > 0):
        return None
    return f"{flag} {value:g}: must be a particle radius > 0 m"


def export(args) -> int:
    """``demscale export``: a law, fine or scaled, for LIGGGHTS or as a table."""
    import engine
    from engine.io.liggghts import law_table, to_liggghts

    def refuse(msg: str) -> int:
        print(f"demscale export: {msg}", file=sys.stderr)
        return 2

    try:
        raw = json.loads(Path(args.law).read_text())
    except (OSError, json.JSONDecodeError) as e:
        return refuse(f"cannot read the law {args.law}: {e}")
    try:
        law, own_radius = law_from_json(raw)
    except (engine.ParameterError, TypeError, ValueError) as e:
        return refuse(f"{args.law} is not a law: {e}")
    for flag, value in (("--radius", args.radius), ("--reference-radius", args.reference_radius)):
        if (why := _radius_flag(flag, value)) is not None:
            return refuse(why)
    if (
        args.reference_radius is not None
        and own_radius is not None
        and not math.isclose(args.reference_radius, own_radius, rel_tol=1e-12)
    ):
        return refuse(
            f"--reference-radius {args.reference_radius:g}: {args.law} says the law is for "
            f"R = {own_radius:g} m (its reference_radius); leave the flag out"
        )
    radius = args.reference_radius if args.reference_radius is not None else own_radius
    note = ""
    if args.radius is not None:
        if radius is None:
            return refuse(
                f"--radius {args.radius:g}: scaling needs the radius the law is for, and "
                f"{args.law} has no reference_radius: give --reference-radius R [m]"
            )
        try:
            rule = engine.ScalingRule.named(args.rule)
        except (engine.ParameterError, KeyError, ValueError) as e:
            return refuse(f"--rule {args.rule}: {e}")
        try:
            ref = engine.UniaxialTest(radius=radius, pair_law=law)
            law = rule.apply(ref, args.radius, ref.dt).pair_law
        except engine.ParameterError as e:
            return refuse(
                f"--radius {args.radius:g}: the law scaled from R = {radius:g} m by rule "
                f"{args.rule!r} is not valid: {e}"
            )
        note = f"scaled from R = {radius:g} m to R = {args.radius:g} m by rule {args.rule!r}"
        radius = args.radius
    try:
        if args.format == "liggghts":
            text = to_liggghts(law, note=note, radius=radius)
        elif args.format == "csv":
            text = law_table(law, "csv", radius=radius)
        else:
            text = json.dumps(law_table(law, radius=radius), indent=1) + "\n"
    except engine.ParameterError as e:
        return refuse(f"--format {args.format}: {e}")
    sys.stdout.write(text)
    sys.stdout.flush()
    return 0
