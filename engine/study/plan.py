"""The runs of a scaling study: the planned ones (references per reference seed, then every
coarse radius x rule per seed) and, with ``decide``, those each round adds, replayed from the
outcomes so far (deterministic: a resumed study, or a report from stored runs, finds the same
runs)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..uniaxial.spec import GRAVITY, UniaxialTest
from .adaptive import Addition, next_runs
from .advisor import judge_groups
from .metrics import metric_names, metric_values, shape_errors
from .spec import ScalingRule, StudySpec


@dataclass(frozen=True)
class PlannedRun:
    """One run of a study: ``key``, ``radius`` [m], ``rule`` (None for a reference), ``seed``
    and its ``test`` (complete: a coarse run's time step is known before any run starts)."""

    key: str
    radius: float
    rule: ScalingRule | None
    seed: int
    test: UniaxialTest

    @property
    def is_reference(self) -> bool:
        return self.rule is None


def run_key(radius: float, rule: ScalingRule | None, seed: int) -> str:
    """Key of a run, e.g. ``ref-s1`` or ``r5mm-paper-s1``."""
    if rule is None:
        return f"ref-s{seed}"
    return f"r{radius * 1e3:g}mm-{rule.name}-s{seed}"


def estimated_steps(test: UniaxialTest) -> float:
    """Rough step count of a test: fill (two free-fall times of the pour column),
    compression of the sample by 10 % there and back, release, unconfined strain."""
    dt = test.resolved_dt()
    height = test.cell[2]
    t = 2 * math.sqrt(2 * test.pour_height / GRAVITY) + 0.2 * height / test.platen_speed
    if test.unconfined:
        t += test.release_time + test.max_unconfined_strain * height / test.platen_speed
    return t / dt


def cost_weights(planned: list[PlannedRun]) -> np.ndarray:
    cost = np.array([estimated_steps(p.test) * p.test.n_particles for p in planned])
    return cost / cost.sum()


def plan_runs(spec: StudySpec, outcomes: dict) -> tuple[list[PlannedRun], list[dict], str | None]:
    """Every run of ``spec`` given the ``outcomes`` so far: the planned runs, then, with
    ``decide``, the runs each round adds (engine.study.adaptive), replayed from the outcomes round
    by round (deterministic: a resumed study, or a report from stored runs, finds the same
    runs). Returns (runs, the added runs as {run, round, kind, reason}, why the study stopped
    adding: None while some run of the last round is still to run)."""
    planned = spec.planned_runs()
    added: list[dict] = []
    if not spec.decide:
        return planned, added, None
    spent = 0.0
    for round_no in range(1, spec.rounds + 1):
        if any(p.key not in outcomes for p in planned):
            return planned, added, None
        new = _added_runs(spec, planned, outcomes, round_no, spent)
        if not new:
            return (
                planned,
                added,
                _stop_reason(
                    spec,
                    planned,
                    outcomes,
                    "no undecided verdict can be decided within the seed "
                    "caps and budget (each reason says how many seeds it would need)",
                ),
            )
        for p, a in new:
            planned.append(p)
            spent += estimated_steps(p.test) * p.test.n_particles
            added.append({"run": p.key, "round": a.round, "kind": a.kind, "reason": a.reason})
    if any(p.key not in outcomes for p in planned):
        return planned, added, None
    return planned, added, _stop_reason(spec, planned, outcomes, f"all {spec.rounds} rounds run")


def _stop_reason(spec, planned, outcomes, otherwise: str) -> str:
    names, ref_values, variants = _judged_values(spec, planned, outcomes)
    if not ref_values:
        return "no reference run finished"
    _, verdicts = judge_groups(spec, ref_values, variants, names, looks=spec.looks)
    return (
        otherwise
        if any(v["verdict"] == "undecided" for v in verdicts)
        else ("every verdict decided")
    )


def adaptive_summary(
    spec: StudySpec, planned: list[PlannedRun], added: list[dict], stopped: str | None
) -> dict:
    keys = {a["run"] for a in added}
    return {
        "planned_runs": len(planned) - len(added),
        "added_runs": added,
        "looks": spec.looks,
        "stopped": stopped,
        "budget": spec.budget,
        "added_particle_steps": float(
            sum(estimated_steps(p.test) * p.test.n_particles for p in planned if p.key in keys)
        ),
    }


def _judged_values(spec: StudySpec, planned: list[PlannedRun], outcomes: dict):
    """Metric values of the finished references and of every variant's finished seeds that
    :func:`assemble` judges (a run whose curves cannot be compared is left out there too)."""
    names = metric_names(spec.reference.unconfined)
    ok = [p for p in planned if p.key in outcomes and not isinstance(outcomes[p.key], str)]
    refs = {p.seed: outcomes[p.key] for p in ok if p.is_reference}
    ref_values = [metric_values(r) for r in refs.values()]
    variants: dict[tuple, list[dict]] = {}
    for p in ok:
        if p.is_reference:
            continue
        res = outcomes[p.key]
        try:
            shape_errors(res, refs.get(p.seed, next(iter(refs.values()))))
        except (ValueError, StopIteration):
            continue
        variants.setdefault((p.radius, p.rule.name), []).append(metric_values(res))
    return names, ref_values, variants


def _added_runs(
    spec: StudySpec, planned: list[PlannedRun], outcomes: dict, round_no: int, spent: float
) -> list[tuple[PlannedRun, Addition]]:
    """The runs round ``round_no`` adds (engine.study.adaptive), as planned runs with new seeds."""
    names, ref_values, variants = _judged_values(spec, planned, outcomes)
    if not ref_values:
        return []
    _, verdicts = judge_groups(spec, ref_values, variants, names, looks=spec.looks)
    cost = {}
    for p in planned:
        k = "reference" if p.is_reference else (p.radius, p.rule.name)
        cost.setdefault(k, estimated_steps(p.test) * p.test.n_particles)
    budget_left = None if spec.budget is None else spec.budget - spent
    attempted: dict = {}
    for p in planned:
        k = "reference" if p.is_reference else (p.radius, p.rule.name)
        attempted[k] = attempted.get(k, 0) + 1
    adds = next_runs(spec, ref_values, variants, verdicts, cost, round_no, budget_left, attempted)
    dt_ref = spec.reference.resolved_dt()
    used: dict = {}
    for p in planned:
        used.setdefault(None if p.is_reference else (p.radius, p.rule.name), set()).add(p.seed)
    rules = {r.name: r for r in spec.rules}
    out = []
    for a in adds:
        seeds = used.setdefault(a.variant, set())
        seed = max(seeds | used.get(None, set())) + 1
        seeds.add(seed)
        ref = replace(spec.reference, seed=seed)
        if a.kind == "reference":
            out.append(
                (PlannedRun(run_key(ref.radius, None, seed), ref.radius, None, seed, ref), a)
            )
        else:
            radius, rule = a.variant[0], rules[a.variant[1]]
            out.append(
                (
                    PlannedRun(
                        run_key(radius, rule, seed),
                        radius,
                        rule,
                        seed,
                        rule.apply(ref, radius, dt_ref),
                    ),
                    a,
                )
            )
    return out
