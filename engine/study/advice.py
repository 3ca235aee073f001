r"""The study's report built from its judged look (docs/PHYSICS.md section 7), and the
report in words.

:func:`build_report` is the one place a study's final look (engine.study.look.judge_look),
its runs and groups become the typed :class:`engine.study.report.StudyReport`: each
variant's verdict with its speed-up, cell size, failure kinds and missing runs; per rule
the coarsest radius judged ``equivalent`` in a fixed sequence (so that the stated
confidence holds for the radius a user acts on); the controls' lines; the resolution
curve; the protocol check; the adhesion exponent (engine.study.adhesion); the finite-size
warnings; the references' summary. :func:`answer_lines` and :func:`verdict_line` put a
report in the words the command line and the service print.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..uniaxial.spec import MIN_THICKNESS_DIAMETERS
from .adhesion import adhesion_advice
from .kinds import kind_of
from .metrics import metric_values
from .reasons import _pct, interval_words
from .report import (
    AdaptiveSummary,
    MetricVerdict,
    ReferenceSummary,
    ResolutionCurve,
    RuleAnswer,
    StoppedAt,
    StudyReport,
    Verdict,
)
from .resolution import curve_lines, diameters_needed, resolution_curves


def finite_size_warnings(groups: list[dict], controlled: bool = False) -> list[str]:
    """Warnings for radii whose cell is under :data:`MIN_THICKNESS_DIAMETERS` diameters
    thick and, in a study without resolution controls (``controlled`` False), for radii
    under 10: there part of the error may be the sample's size in diameters, which only a
    control tells apart from the rule's."""
    out, seen = [], set()
    for g in groups:
        if g["radius"] in seen:
            continue
        seen.add(g["radius"])
        t = g["thickness_diameters"]
        if t < MIN_THICKNESS_DIAMETERS:
            out.append(
                f"R = {g['radius'] * 1e3:g} mm: the cell is {t:.1f} particle "
                f"diameters thick, under the {MIN_THICKNESS_DIAMETERS:g} a bulk sample "
                "needs (Thakur et al. 2013): wall and periodic-image effects may dominate"
            )
        elif t < 10 and not controlled:
            out.append(
                f"R = {g['radius'] * 1e3:g} mm: the cell is {t:.1f} particle diameters "
                "thick and no resolution control of it has run (StudySpec.controls): part "
                "of this radius's error may be the sample's size in diameters, not the rule"
            )
    return out


def _interval_words(m: MetricVerdict) -> str:
    if m.interval is None:
        if m.signed_error is None:
            return f"{m.metric} not compared (no failed run on a side)"
        return f"{m.metric} {_pct(m.signed_error)}"
    pairs = " (paired)" if m.paired else ""
    return f"{m.metric} {_pct(m.level_error)} {interval_words(m.interval)}{pairs}"


def _scaled_law(spec, rule, radius: float) -> dict:
    """The reference's pair law scaled by ``rule`` to ``radius`` [m], as JSON (its ``type``
    and fields in SI units): what to run at the coarsest radius."""
    from ..core.records import to_dict

    base = spec.reference.pair_law
    law = base.scaled(radius / spec.reference.radius, *rule.exponents(base))
    return {"type": type(law).__name__, **to_dict(law)}


def _law_text(law: dict) -> str:
    """A scaled law's stiffness and adhesion parameters in words."""
    units = {"k1": "N/m", "k2": "N/m", "f0": "N", "kadh": "N/m"}
    parts = [
        f"{k.upper() if k != 'kadh' else 'kadh'} = {law[k]:.4g} {u}"
        for k, u in units.items()
        if k in law
    ]
    return ", ".join(parts) or law["type"]


def resolution_lines(
    resolution: tuple[Verdict, ...], rule_errors: tuple[Verdict, ...], spec
) -> list[str]:
    """The report's lines on the controls: per rule and radius whether a coarse run agrees
    with its control (for a rule that is the law's exact similarity, a check of units that
    cannot test the rule), and per radius what a sample that many diameters across loses
    against the reference."""
    lines = []
    law = spec.reference.pair_law
    similarity = getattr(law, "similarity_exponents", None)
    exact = (
        {rule.name for rule in spec.rules if tuple(rule.exponents(law)) == tuple(similarity())}
        if rule_errors and similarity is not None
        else set()
    )
    says = {"equivalent": "agrees", "differs": "differs", "undecided": "is undecided"}
    for v in rule_errors:
        parts = "; ".join(_interval_words(m) for m in v.metrics)
        text = (
            f"{v.rule} at R = {v.radius * 1e3:g} mm against its resolution control: "
            f"{says[v.verdict]} ({parts})"
        )
        if v.rule in exact:
            # docs/PHYSICS.md section 5.1: for this law the coarse run is its control in
            # other units, so the comparison can only see what the rule leaves unscaled
            fixed = kind_of(spec.reference).clock_constants
            held = [n for n in ("hold_time", "hold_quiet") if getattr(spec.reference, n, None)]
            if held:  # a hold's times are in seconds too
                fixed += f", and the hold's {' and '.join(held)} in seconds"
            text += (
                "; a check of units, not evidence for the rule: for this law the rule is an "
                "exact similarity (the coarse run is its control in other units), so this "
                f"compares only {fixed}"
            )
        lines.append(text)
    for v in resolution:
        d = v.diameters_across
        across = f"{d:.1f} diameters across" if d else "the coarse cell's size in diameters"
        parts = "; ".join(_interval_words(m) for m in v.metrics)
        lines.append(
            f"resolution at R = {v.radius * 1e3:g} mm: the reference law in a sample "
            f"{across} against the reference: {v.verdict} ({parts}); the size effect of "
            "this test's sample at that many diameters across (other features, a free "
            "surface, a shear band, an outlet, need their own numbers: docs/RESOLUTION.md)"
        )
    return lines


def rule_answers(spec, groups: list[dict], verdicts: tuple[Verdict, ...]) -> dict:
    """Per rule its :class:`RuleAnswer`: the coarsest radius judged ``equivalent`` in a
    fixed sequence.

    The coarsest radius is a choice among radii, each verdict right at its own confidence:
    acting on the largest of several ``equivalent`` radii could be wrong more often than
    one verdict is. So a rule's radii are tested from fine to coarse and the sequence stops
    at the first one not ``equivalent`` (fixed-sequence testing, Maurer, Hothorn and Lehmacher
    1995): every verdict is made at the full rate, and the chance that any radius up to the
    one reported is not truly within tolerance is still at most 1 - confidence. An
    ``equivalent`` radius past the first one not ``equivalent`` is listed
    (``radii_equivalent``) but not reported as the coarsest."""
    rules = {}
    for rule in spec.rules:
        mine = sorted((v for v in verdicts if v.rule == rule.name), key=lambda v: v.radius)
        best, stopped_at = None, None
        for v in mine:
            if v.verdict != "equivalent":
                stopped_at = v
                break
            best = v
        g = next(
            (g for g in groups if best and g["rule"] == rule.name and g["radius"] == best.radius),
            None,
        )
        rules[rule.name] = RuleAnswer(
            coarsest_radius=best.radius if best else None,
            coarsest_law=_scaled_law(spec, rule, best.radius) if best else None,
            speedup=g["speedup"] if g else None,
            radii_equivalent=tuple(v.radius for v in mine if v.verdict == "equivalent"),
            sequence_stopped_at=None
            if stopped_at is None
            else StoppedAt(stopped_at.radius, stopped_at.verdict),
        )
    return rules


def advice_lines(rules: dict, verdicts: tuple[Verdict, ...]) -> list[str]:
    """The lines of advice: each verdict, each rule's coarsest radius and the radii past
    where its sequence stopped."""
    lines = [f"R = {v.radius * 1e3:g} mm, {v.rule}: {v.verdict}" for v in verdicts]
    for name, a in rules.items():
        if a.coarsest_radius is not None:
            lines.append(
                f"{name}: equivalent up to R = {a.coarsest_radius * 1e3:g} mm "
                f"({a.speedup:.1f}x faster); the law there: {_law_text(a.coarsest_law)}"
            )
        last = a.coarsest_radius
        beyond = [r for r in a.radii_equivalent if last is None or r > last]
        stop = a.sequence_stopped_at
        if beyond and stop is not None:
            lines.append(
                f"{name}: R = {', '.join(f'{r * 1e3:g}' for r in beyond)} mm equivalent but "
                f"not reported as the coarsest: R = {stop.radius * 1e3:g} mm, finer, is "
                f"{stop.verdict} (radii are tested fine to coarse)"
            )
    return lines


def _adhesion_lines(adhesion, fieller: bool) -> list[str]:
    """Per radius the closest and fitted adhesion exponent (``fieller``: with intervals)."""
    lines = []
    for r, v in (adhesion.by_radius if adhesion else {}).items():
        fit = ""
        if v.fitted is not None:
            fit = f", fitted b = {v.fitted:.2f}"
            if fieller:
                iv = v.interval
                fit += (
                    f" [{iv[0]:.2f}, {iv[1]:.2f}]"
                    if iv is not None
                    else " (no bounded interval: the data do not fix it)"
                )
                fit += f" against the {v.fitted_against}s"
        lines.append(f"adhesion exponent at R = {float(r) * 1e3:g} mm: closest b = {v.best:g}{fit}")
    return lines


def protocol_line(check: Verdict) -> str:
    """The report's line on the protocol check (docs/PHYSICS.md section 7.6)."""
    says = {
        "equivalent": "is quasi-static and its time step converged: halving the inertial "
        "number (or platen speed) and the time step changes no metric beyond its tolerance",
        "differs": "is NOT converged: halving the inertial number (or platen speed) and the "
        "time step changes a metric beyond its tolerance",
        "undecided": "is not shown converged: halving the inertial number (or platen speed) "
        "and the time step leaves a metric undecided",
    }
    return f"protocol check: the study's protocol {says[check.verdict]} ({check.reason})"


def build_report(
    spec, at, runs: dict, groups: list[dict], planned, adaptive: AdaptiveSummary | None = None
) -> StudyReport:
    """The study's report from its final look ``at`` (engine.study.look.judge_look, with
    the report's controls and protocol check judged), its compared ``runs`` (key ->
    engine.study.results.RunResult), its ``groups`` (mean and spread per radius and rule)
    and ``planned`` runs; ``adaptive``: its rounds, where it decides."""
    unconfined = getattr(spec.reference, "unconfined", False)
    refs, failed = at.refs, at.failed
    verdicts = []
    for d in at.verdicts:
        g = next(g for g in groups if g["radius"] == d["radius"] and g["rule"] == d["rule"])
        verdicts.append(
            replace(
                Verdict.from_dict(d),
                speedup=g["speedup"],
                thickness_diameters=g["thickness_diameters"],
                height_diameters=g["height_diameters"],
            )
        )
    if unconfined:
        verdicts = _note_failure_kinds(refs, runs, verdicts)
    verdicts = _note_missing(planned, failed, verdicts)
    strengths, ref_strength = None, None
    if unconfined:
        ref_strength = float(np.mean([r.scalars["unconfined_strength"] for r in refs.values()]))
        strengths = {"reference": [r.scalars["unconfined_strength"] for r in refs.values()]}
        strengths["variants"] = {}
        for r in runs.values():
            if not (r.is_reference or r.protocol or r.control):
                st = r.result.scalars["unconfined_strength"]
                strengths["variants"].setdefault((r.radius, r.rule.name), []).append(st)
    resolution = tuple(Verdict.from_dict(v) for v in at.resolution)
    rule_errors = tuple(Verdict.from_dict(v) for v in at.rule_errors)
    rules = rule_answers(spec, groups, verdicts)
    warnings = finite_size_warnings(groups, controlled=bool(resolution))
    control_lines = resolution_lines(resolution, rule_errors, spec)
    adhesion = adhesion_advice(spec, groups, ref_strength, strengths)
    lines = advice_lines(rules, verdicts) + control_lines
    lines += _adhesion_lines(adhesion, strengths is not None)
    message = "; ".join(lines + warnings)
    curve = None
    if at.controls:
        curve = _resolution_curve(spec, at, runs)
        more = curve_lines(curve.to_dict())
        control_lines += more
        if more:
            message = "; ".join([message, *more])
    protocol = None
    if at.half:
        protocol = Verdict.from_dict(at.protocol)
        line = protocol_line(protocol)
        control_lines.append(line)
        message = "; ".join([message, line])
    scalars = kind_of(spec.reference).summary_scalars
    return StudyReport(
        tolerances=dict(spec.tolerances),
        confidence=spec.confidence,
        rules=rules,
        verdicts=verdicts,
        warnings=tuple(warnings),
        resolution=resolution,
        rule_errors=rule_errors,
        control_lines=tuple(control_lines),
        adhesion_exponent=adhesion,
        message=message,
        resolution_curve=curve,
        protocol=protocol,
        noise_floor=dict(at.noise_floor),
        reference=_reference_summary(refs, scalars),
        adaptive=adaptive,
    )


def _resolution_curve(spec, at, runs: dict) -> ResolutionCurve:
    """The resolution curve of each metric from the references and the controls, with the
    fewest diameters across each property with a tolerance needs."""
    ctl_runs: dict[float, list] = {}
    for r in runs.values():
        if r.control:
            ctl_runs.setdefault(r.radius, []).append(
                (r.result.scalars["thickness_diameters"], metric_values(r.result))
            )
    ref_runs = [
        (x.scalars["thickness_diameters"], v) for x, v in zip(at.refs.values(), at.ref_values)
    ]
    curve = resolution_curves(ref_runs, ctl_runs, at.names, spec.confidence)
    for n, c in curve["metrics"].items():
        if n in spec.tolerances:
            c["needed"] = diameters_needed(c, spec.tolerances[n])
    return ResolutionCurve(curve["metrics"], curve["confidence"])


def _note_failure_kinds(refs: dict, runs: dict, verdicts: list[Verdict]) -> list[Verdict]:
    """Say what a strength verdict compared: only the runs that failed at a peak
    (engine.study.noise; engine.uniaxial.measures.failed_by_curve) where any run of the
    study failed, with how many references and runs of the variant hardened instead (their
    "strength" is the largest stress up to the strain limit, another quantity)."""
    ref_flags = [r.scalars["unconfined_failure"] == 1.0 for r in refs.values()]
    out = []
    for v in verdicts:
        flags = [
            r.result.scalars["unconfined_failure"] == 1.0
            for r in runs.values()
            if r.rule is not None and r.rule.name == v.rule and r.radius == v.radius
        ]
        reason = v.reason
        if flags and len(set(flags + ref_flags)) > 1:
            reason += (
                f"; strength compares failed runs only: {sum(ref_flags)} of "
                f"{len(ref_flags)} references and {sum(flags)} of {len(flags)} runs of this "
                "variant failed at a peak, the others hardened to the strain limit and are "
                "left out of it"
            )
        out.append(
            replace(v, reason=reason, failed_runs=sum(flags), reference_failed_runs=sum(ref_flags))
        )
    return out


def _note_missing(planned, failed: dict, verdicts: list[Verdict]) -> tuple[Verdict, ...]:
    """Each variant's runs that did not finish (``missing_runs``, and in its reason); a
    variant none of whose runs finished is ``undecided``, never judged."""
    keys_of: dict[tuple, list[str]] = {}
    for p in planned:
        if not p.is_reference and not p.control and not p.protocol:
            keys_of.setdefault((p.radius, p.rule.name), []).append(p.key)
    out = list(verdicts)
    for variant, keys in keys_of.items():
        lost = {k: failed[k] for k in keys if k in failed}
        i = next((i for i, v in enumerate(out) if (v.radius, v.rule) == variant), None)
        if i is None:
            out.append(Verdict(*variant, "undecided", "no run of this variant finished", 0))
            i = len(out) - 1
            out[i] = replace(out[i], judged=False)
        if lost:
            why = "; missing: " + "; ".join(f"{k} ({t})" for k, t in lost.items())
            out[i] = replace(out[i], missing_runs=lost, reason=out[i].reason + why)
    return tuple(out)


def _reference_summary(refs: dict, scalars) -> ReferenceSummary:
    """Mean and spread over reference seeds of the scalars a user quotes (``scalars``: the
    reference kind's, :mod:`engine.study.kinds`)."""
    out = {}
    for k in scalars:
        v = [r.scalars[k] for r in refs.values() if k in r.scalars]
        if v:
            out[k] = float(np.mean(v))
            out[k + "_std"] = float(np.std(v, ddof=1)) if len(v) > 1 else 0.0
    return ReferenceSummary(tuple(sorted(refs)), out)


# ---------------------------------------------------------------------- in words
def answer_lines(report: StudyReport, reference_radius: float | None) -> list[str]:
    """The study's answer in one line (per rule, the coarsest radius equivalent on every
    metric, as a factor over the reference radius ``reference_radius`` [m], and its
    speed-up), then one line that says how it relates to what was run: the next radius's
    verdict, and that this is the answer for the study's cell, not for a process's feature
    (``demscale plan``)."""
    parts, beyond = [], []
    for name, a in report.rules.items():
        r, stop = a.coarsest_radius, a.sequence_stopped_at
        if r is None:
            why = "" if stop is None else f" (R = {stop.radius * 1e3:g} mm {stop.verdict})"
            parts.append(f"{name}: no coarse radius shown equivalent{why}")
            continue
        factor = f", {r / reference_radius:.3g}x coarser" if reference_radius else ""
        speed = f", {a.speedup:.2g}x faster" if a.speedup else ""
        parts.append(f"{name}: equivalent on every metric up to R = {r * 1e3:g} mm{factor}{speed}")
        if stop is not None:
            beyond.append(f"R = {stop.radius * 1e3:g} mm is {stop.verdict} for {name}")
    if not parts:
        return ["Answer: no rule was judged"]
    lines = ["Answer: " + "; ".join(parts)]
    qualify = (
        "This is the answer for the study's own cell, each coarse run judged against the fine "
        "reference in it; how coarse a process's feature allows is `demscale plan`'s answer."
    )
    if beyond:
        qualify = f"Beyond it {'; '.join(beyond)} (next radius tested). " + qualify
    return [*lines, qualify]


def verdict_line(v: Verdict) -> str:
    """One short line per verdict: the radius, the rule, the verdict and the metrics that
    make it (those that differ, or those still undecided, with their errors)."""
    head = f"R = {v.radius * 1e3:g} mm, {v.rule}: {v.verdict.upper()}"
    if v.verdict == "equivalent":
        return f"{head}, every metric within its tolerance"
    which = [m for m in v.metrics if m.verdict == v.verdict] or list(v.metrics)
    words = []
    for m in which:
        err = m.level_error if m.level_error is not None else m.signed_error
        iv = m.differs_interval if v.verdict == "differs" else m.interval
        text = f"{m.metric} {_pct(err)}" if err is not None else m.metric
        if iv is not None:
            text += f" {interval_words(iv)}"
        if m.tolerance:
            text += f" against +-{100 * m.tolerance:g} %"
        words.append(text)
    return f"{head} on " + "; ".join(words)


def side_by_side(verdicts: dict[str, tuple[Verdict, ...]]) -> list[dict]:
    """One rule judged on several tests (docs/PHYSICS.md section 11.1): ``verdicts`` maps a
    test's name (``"uniaxial"``, ``"shear"``) to its study's verdicts
    (``StudyReport.verdicts``, studies with the same rules and radii:
    engine.study.spec.on_test). Returns per (radius, rule) its verdict on each test and the
    combined one: ``equivalent`` where every test's is (an intersection-union test, at each
    study's confidence with no correction), ``differs`` where any test's is (a wrong
    ``differs`` on some test has up to the sum of the studies' rates), else ``undecided``;
    a test without the variant counts as ``undecided`` ("not run")."""
    keys = sorted({(v.radius, v.rule) for vs in verdicts.values() for v in vs})
    out = []
    for radius, rule in keys:
        per = {}
        for test, vs in verdicts.items():
            v = next((v for v in vs if (v.radius, v.rule) == (radius, rule)), None)
            per[test] = "not run" if v is None else v.verdict
        if all(x == "equivalent" for x in per.values()):
            both = "equivalent"
        elif any(x == "differs" for x in per.values()):
            both = "differs"
        else:
            both = "undecided"
        out.append({"radius": radius, "rule": rule, "tests": per, "verdict": both})
    return out


__all__ = [
    "advice_lines",
    "answer_lines",
    "build_report",
    "finite_size_warnings",
    "protocol_line",
    "resolution_lines",
    "rule_answers",
    "side_by_side",
    "verdict_line",
]
