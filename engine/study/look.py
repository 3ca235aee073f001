"""A look at a study's data: its runs' outcomes measured and judged once
(docs/PHYSICS.md sections 5, 7.1 and 7.2).

:func:`judge_look` is the one place where a set of outcomes becomes metric values, errors
against the reference, the groups on their compared scale with their pooled spreads
(:class:`engine.study.noise.StudyNoise`) and the variants' verdicts at a look. The
adaptive loop asks it at each round (:mod:`engine.study.loop`: the allocator and the
stopping rule read its verdicts) and the report asks it once more, at the study's final
look (:func:`engine.study.results.assemble`), so that what decided the runs and what is
reported are the same arithmetic on the same values.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .judge import judge_group, judge_protocol, judge_rule_error
from .kinds import kind_of
from .metrics import metric_column, noise_floor, relative_error
from .noise import StudyNoise
from .plan import CONTROL, PROTOCOL, PlannedRun
from .rates import error_rates
from .spec import StudySpec


@dataclass
class Look:
    """The runs of a study measured and judged at look ``look`` of ``spec.looks``.

    Attributes:
        names: the verdict metrics of the study's kind; shapes: its shape measures.
        refs: packing seed -> outcome of each finished reference (planned order).
        ref_values: metric values of those references, in that order.
        values: run key -> metric values of every finished run that is compared.
        errors: run key -> its errors (metric columns against the mean reference, shape
            measures against the reference of its seed; zeros for a reference) [-].
        failed: run key -> why it is not compared: its error text, ``"not run"``, or
            ``"not comparable: ..."`` (curves that cannot be compared with a reference).
        variants: (radius [m], rule name) -> metric values of its seeds (planned order).
        seeds_of: (radius [m], rule name) -> the packing seed of each of those values.
        controls: radius [m] -> packing seed -> metric values of its resolution controls.
        half: packing seed -> metric values of the protocol check.
        noise: the groups on their compared scale with pooled spreads (None: no
            reference finished).
        noise_floor: metric -> the references' relative noise floor [-] (None with one
            reference seed; :func:`engine.study.metrics.noise_floor`).
        alpha_e, alpha_d: the one-sided rates of the equivalence and differs tests.
        verdicts: each variant's verdict at this look (:func:`engine.study.judge.judge_group`).
        resolution, rule_errors: the report's look only: the two errors the resolution
            controls separate (:func:`judge_controls`).
        protocol: the report's look only: the protocol check's verdict
            (:func:`engine.study.judge.judge_protocol`; None without one).
    """

    spec: StudySpec
    look: int
    names: tuple
    shapes: tuple
    refs: dict
    ref_values: list
    values: dict = field(default_factory=dict)
    errors: dict = field(default_factory=dict)
    failed: dict = field(default_factory=dict)
    variants: dict = field(default_factory=dict)
    seeds_of: dict = field(default_factory=dict)
    controls: dict = field(default_factory=dict)
    half: dict = field(default_factory=dict)
    noise: StudyNoise | None = None
    noise_floor: dict = field(default_factory=dict)
    alpha_e: float = 0.0
    alpha_d: float = 0.0
    verdicts: list = field(default_factory=list)
    resolution: list = field(default_factory=list)
    rule_errors: list = field(default_factory=list)
    protocol: dict | None = None


def judge_look(
    spec: StudySpec,
    planned: list[PlannedRun],
    outcomes: dict,
    look: int = 1,
    report: bool = True,
) -> Look:
    """Measure every finished run of ``planned`` (``outcomes``: key -> result, or an error
    text for a failed run) and judge every variant at look ``look`` of ``spec.looks``.

    A run whose curves cannot be compared with a reference is left out (listed in
    ``failed``). The groups pooled with the variants are the resolution controls and, for
    the ``report``, the protocol check; the report's look also judges the controls'
    resolution and rule errors and the protocol check. The adaptive loop looks with
    ``report=False``: a round is planned from the references and variants (and the
    controls' spreads), the protocol check takes no part in it. With no finished
    reference, the returned look has no ``noise`` and no verdicts."""
    failed = {p.key: outcomes[p.key] for p in planned if isinstance(outcomes.get(p.key), str)}
    for p in planned:
        if p.key not in outcomes:
            failed[p.key] = "not run"
    ok = [p for p in planned if p.key in outcomes and not isinstance(outcomes[p.key], str)]
    refs = {p.seed: outcomes[p.key] for p in ok if p.is_reference}
    kind = kind_of(spec.reference)  # what the study's kind measures, asked once
    names = tuple(kind.metric_names(spec.reference))
    shapes = tuple(kind.shape_names)
    ref_values = [kind.metric_values(r) for r in refs.values()]
    out = Look(spec, look, names, shapes, refs, ref_values, failed=failed)
    if not refs:
        return out
    cons = spec.reference.consolidation_stress
    floor_mean = {n: np.mean([v[n] for v in out.ref_values], axis=0) for n in names}
    first_ref = next(iter(refs.values()))
    for p in ok:
        res = outcomes[p.key]
        values = kind.metric_values(res)
        errors = {
            metric_column(n): (
                0.0 if p.is_reference else relative_error(n, values[n], floor_mean[n], cons)
            )
            for n in names
        }
        if p.is_reference:
            errors.update(dict.fromkeys(shapes, 0.0))
        else:
            try:
                errors.update(kind.shape_errors(res, refs.get(p.seed, first_ref)))
            except ValueError as e:
                failed[p.key] = f"not comparable: {e}"
                continue
        out.values[p.key], out.errors[p.key] = values, errors
        if p.is_reference:
            continue
        if p.protocol:
            out.half[p.seed] = values
        elif p.control:
            out.controls.setdefault(p.radius, {})[p.seed] = values
        else:
            out.variants.setdefault((p.radius, p.rule.name), []).append(values)
            out.seeds_of.setdefault((p.radius, p.rule.name), []).append(p.seed)
    groups = {
        **out.variants,
        **{(r, CONTROL): list(c.values()) for r, c in out.controls.items()},
        **(
            {(spec.reference.radius, PROTOCOL): list(out.half.values())}
            if report and out.half
            else {}
        ),
    }
    out.noise = StudyNoise(out.ref_values, groups, names, cons)
    floor = noise_floor(out.ref_values, names, cons)
    out.noise_floor = {n: floor[n]["noise"] for n in names}
    out.alpha_e, out.alpha_d = error_rates(spec.confidence, len(names), look, spec.looks)
    out.verdicts = [
        judge_group(out.noise, k, spec.tolerances, out.alpha_e, out.alpha_d) for k in out.variants
    ]
    if report:
        out.resolution, out.rule_errors = judge_controls(out, planned, outcomes)
        if out.half:
            ref_by_seed = dict(zip(refs, out.ref_values))
            r_ref = spec.reference.radius
            out.protocol = judge_protocol(spec, out.noise, r_ref, out.half, ref_by_seed, names)
    return out


def judge_controls(look: Look, planned: list[PlannedRun], outcomes: dict):
    """The two errors the resolution controls separate (docs/PHYSICS.md section 7.4): per
    radius with controls, the controls against the reference (the resolution error: what a
    sample that many diameters across loses; judged once, at the study's confidence), and
    per coarse variant at that radius, the variant against the controls (the rule's own
    error, at the variant's look; ``look.seeds_of`` gives the packing seed of each of its
    values): paired by seed where that pays (:func:`engine.study.judge.judge_rule_error`),
    since a control and a coarse run of one seed start from the same scaled cloud; the
    study's groups with their spreads pooled by radius (``look.noise``). Returns
    (resolution errors, rule errors)."""
    spec, noise, names, controls = look.spec, look.noise, look.names, look.controls
    if not controls:
        return [], []
    alpha_e, alpha_d = error_rates(spec.confidence, len(names), 1, 1)
    resolution = [
        judge_group(noise, (r, CONTROL), spec.tolerances, alpha_e, alpha_d) for r in controls
    ]
    for v in resolution:
        ctl = [
            p.key for p in planned if p.control and p.radius == v["radius"] and p.key in look.values
        ]
        v["diameters_across"] = outcomes[ctl[0]].scalars["thickness_diameters"] if ctl else None
        v["what"] = "resolution"
    rule_errors = []
    for (r, rule), vals in look.variants.items():
        if r not in controls:
            continue
        mine = dict(zip(look.seeds_of[(r, rule)], vals))
        v = judge_rule_error(spec, r, rule, mine, controls[r], names, look.look, spec.looks, noise)
        v["what"] = "rule"
        rule_errors.append(v)
    return resolution, rule_errors


__all__ = ["Look", "judge_controls", "judge_look"]
