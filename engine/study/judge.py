r"""A group's verdict over its metrics (docs/PHYSICS.md section 7.1): every metric of a
coarse variant (or of the resolution controls, or of the protocol check) compared with the
references, or with the controls of its radius, and combined: a (radius, rule) differs when
any metric differs, is equivalent when all are, undecided otherwise.

What it puts together lives in its own modules: the statistics of one comparison
(:mod:`engine.study.comparison`: intervals, bias, pairing by seed, one metric's verdict),
the error-rate policy (:mod:`engine.study.rates`: alpha per test, metric and look), the
group's verdict record and its words (:mod:`engine.study.reasons`: :func:`judged`) and the
seeds (:mod:`engine.study.seeds`: seeds an undecided metric needs, whether pairing pays;
the runs a round adds are :mod:`engine.study.allocate`). Their names are importable from
here as before. Here each metric of a group makes one comparison (:func:`compare`, paired
where that pays) and one verdict, and the group's verdict is made of them. The functions
here are pure: arrays in, verdicts out.
"""

from __future__ import annotations

from .comparison import (
    Comparison,
    difference_interval,
    judge_metric,
    judge_samples,
    paired_where_it_pays,
)
from .metrics import noise_floor
from .noise import REFERENCE, StudyNoise
from .rates import (
    CONFIDENCE,
    EQUIVALENCE_LEVEL,
    PILOT_SHARE,
    VERDICTS,
    error_rates,
    look_alpha,
)
from .reasons import MAX_SEEDS_NEEDED, bias_words, describe, judged, verdict, what_decides
from .seeds import PAIRING_VARIANCE_RATIO, PLANNED_POWER, pairing_pays, seeds_needed


# ------------------------------------------------------------ one metric of a study's group
def compare(noise: StudyNoise, name: str, key, tolerance: float, against=REFERENCE) -> Comparison:
    """Group ``key`` against the references (``against`` = REFERENCE) or another group
    of its radius, unpaired, on the study's compared scale and spreads."""
    radius = key[0]
    c, sc = noise.group(name, key)
    if against == REFERENCE:
        r, sr = noise.reference(name, radius)
    else:
        r, sr = noise.group(name, against)
    return Comparison(noise.space[name, radius], c, r, sc, sr, tolerance)


def _judge(
    noise: StudyNoise,
    name: str,
    key,
    tolerance: float,
    alpha_e: float,
    alpha_d: float,
    cons: float,
    against=REFERENCE,
    pairs: tuple | None = None,
    what: str = "reference",
) -> dict:
    """:func:`judge_metric` of metric ``name`` of group ``key`` against the references
    (``against`` = REFERENCE) or the group ``against`` (:func:`compare`), with both raw
    values and the count of left-out values read from ``noise``; ``pairs``: both sides'
    values of the seeds they share, in one order, to be judged paired by seed where that
    pays (:func:`engine.study.comparison.paired_where_it_pays`); ``cons``: the
    consolidation stress [Pa]; ``what``: what the group is judged against, in words."""
    _, left = noise.kept.get((name, key), (0, 0))
    other = REFERENCE if against == REFERENCE or against[1] == REFERENCE else against
    comp = compare(noise, name, key, tolerance, against)
    if pairs is not None:
        comp = paired_where_it_pays(comp, name, *pairs, alpha_e)
    return judge_metric(
        name,
        comp,
        alpha_e,
        alpha_d,
        noise.raw[name, key],
        noise.raw[name, other],
        cons,
        against=what,
        counts={"left_out": left} if left else {},
    )


# --------------------------------------------------------------------------- a group
def judge_group(noise: StudyNoise, key, tolerances: dict, alpha_e: float, alpha_d: float) -> dict:
    """Every metric of group ``key`` against the references, and its overall verdict."""
    per_metric = [
        _judge(noise, n, key, tolerances[n], alpha_e, alpha_d, noise.cons) for n in noise.names
    ]
    seeds = max((m["seeds"] for m in per_metric), default=0)
    return judged(key[0], key[1], per_metric, seeds)


def judge_groups(
    spec,
    ref_values: list[dict],
    variants: dict[tuple, list[dict]],
    names,
    look: int = 1,
    looks: int = 1,
    controls: dict | None = None,
    pool: bool = True,
) -> tuple[dict, list[dict]]:
    """Noise floor and verdicts: ``ref_values`` per reference seed, ``variants`` maps
    (radius, rule name) to the metric values of its seeds, ``controls`` (radius -> the
    metric values of its controls) join their radius's pool; ``looks``: how many times a
    study may judge its data. Returns (noise floor per metric, verdicts)."""
    cons = spec.reference.consolidation_stress
    groups = dict(variants)
    for r, vals in (controls or {}).items():
        groups[r, "control"] = list(vals)
    noise = StudyNoise(ref_values, groups, names, cons, pool=pool)
    alpha_e, alpha_d = error_rates(getattr(spec, "confidence", CONFIDENCE), len(names), look, looks)
    out = [judge_group(noise, key, spec.tolerances, alpha_e, alpha_d) for key in variants]
    floor = noise_floor(ref_values, names, cons)
    return {n: floor[n]["noise"] for n in names}, out


def judge_values(
    name: str,
    values: list[dict],
    ref_values: list[dict],
    tolerance: float,
    consolidation_stress: float,
    alpha_equivalent: float = EQUIVALENCE_LEVEL * (1 - CONFIDENCE),
    alpha_differs: float = (1 - CONFIDENCE) / 2,
    others: dict | None = None,
) -> dict:
    """One metric of one group of seeds (``values``: metric values per seed) against
    reference seeds (``ref_values``), with the spreads pooled with ``others`` (key -> metric
    values per seed of the other groups at its radius; None: its own spread): the study's
    arithmetic for a group outside a study (benchmarks, tests)."""
    key = (0.0, "group")
    groups = {key: list(values)}
    for k, v in (others or {}).items():
        groups[0.0, str(k)] = list(v)
    noise = StudyNoise(ref_values, groups, [name], consolidation_stress)
    return _judge(
        noise, name, key, tolerance, alpha_equivalent, alpha_differs, consolidation_stress
    )


def _judge_by_seed(
    spec,
    noise: StudyNoise,
    key,
    other,
    values: dict[int, dict],
    others: dict[int, dict],
    names,
    look: int,
    looks: int,
    against: str,
) -> tuple[list[dict], int]:
    """Every metric of group ``key`` against group ``other`` of the same radius (its
    ``REFERENCE`` entry: the references), whose runs share packing seeds (``values`` and
    ``others``: seed -> metric values): paired by seed where :func:`pairing_pays`, else
    unpaired with the study's spreads. Returns (per-metric judgements, pairs)."""
    cons = spec.reference.consolidation_stress
    alpha_e, alpha_d = error_rates(getattr(spec, "confidence", CONFIDENCE), len(names), look, looks)
    both = sorted(set(values) & set(others))
    per_metric = [
        _judge(
            noise,
            n,
            key,
            spec.tolerances[n],
            alpha_e,
            alpha_d,
            cons,
            other,
            ([values[s][n] for s in both], [others[s][n] for s in both]),
            against,
        )
        for n in names
    ]
    return per_metric, len(both)


def judge_rule_error(
    spec,
    radius: float,
    rule: str,
    values: dict[int, dict],
    controls: dict[int, dict],
    names,
    look: int = 1,
    looks: int = 1,
    noise: StudyNoise | None = None,
) -> dict:
    """A coarse variant against the resolution controls of its radius: the rule's own error
    (docs/PHYSICS.md section 7.4). ``values`` and ``controls`` map packing seed to metric
    values; ``noise``: the study's (pooled spreads), else built from these two groups. A
    metric is judged on the per-seed differences of the seeds both have where
    :func:`pairing_pays`, else unpaired with the pooled spreads."""
    key, ck = (radius, rule), (radius, "control")
    if noise is None:
        noise = StudyNoise(
            [],
            {key: list(values.values()), ck: list(controls.values())},
            names,
            spec.reference.consolidation_stress,
        )
    per_metric, pairs = _judge_by_seed(
        spec, noise, key, ck, values, controls, names, look, looks, "control"
    )
    out = judged(radius, rule, per_metric, len(values))
    out["control_seeds"] = len(controls)
    out["paired_seeds"] = pairs
    return out


def judge_protocol(
    spec, noise: StudyNoise, radius: float, half: dict[int, dict], refs: dict[int, dict], names
) -> dict:
    """The protocol check (docs/PHYSICS.md section 7.6): the reference seeds run at half the
    rate and step (``half``: seed -> metric values, the group (radius, "protocol") of
    ``noise``) against the references (``refs``: seed -> metric values), paired by seed
    where that pays; judged once, at the study's confidence. ``equivalent`` states that
    halving the rate and the step moves no metric beyond its tolerance (not that the
    protocol has converged: a finer one could move a metric again by less than that)."""
    key = (radius, "protocol")
    per_metric, pairs = _judge_by_seed(
        spec, noise, key, (radius, REFERENCE), half, refs, names, 1, 1, "reference"
    )
    out = judged(radius, "protocol", per_metric, len(half))
    out["paired_seeds"] = pairs
    out["what"] = "protocol"
    return out


__all__ = [
    "CONFIDENCE",
    "EQUIVALENCE_LEVEL",
    "MAX_SEEDS_NEEDED",
    "PAIRING_VARIANCE_RATIO",
    "PILOT_SHARE",
    "PLANNED_POWER",
    "VERDICTS",
    "Comparison",
    "bias_words",
    "compare",
    "describe",
    "difference_interval",
    "error_rates",
    "judge_group",
    "judge_groups",
    "judge_metric",
    "judge_protocol",
    "judge_rule_error",
    "judge_samples",
    "judge_values",
    "judged",
    "look_alpha",
    "pairing_pays",
    "seeds_needed",
    "verdict",
    "what_decides",
]
