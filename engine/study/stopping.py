"""When a ``decide`` study stops adding runs, and the look its verdicts are judged at
(docs/PHYSICS.md section 7.2): the stopping rule of the adaptive loop (engine.study.loop),
in the role of Optuna's pruner beside the allocator (engine.study.allocate, its sampler).

The loop stops when a round adds no run (no undecided verdict can be decided within the
seed caps and the budget) or once every round has run; :func:`stop_reason` says which, and
whether every verdict was decided at the study's last look. :func:`final_look` is the look
the report judges at, :func:`most_added` the work the rounds still to come may add (the
study's progress is counted against it)."""

from __future__ import annotations

from .look import Look
from .plan import PlannedRun, to_seed_caps
from .spec import StudySpec

#: Why a study stops when a round adds no run.
NOTHING_TO_ADD = (
    "no undecided verdict can be decided within the seed caps and budget (each reason "
    "says how many seeds it would need)"
)


def all_rounds_run(spec: StudySpec) -> str:
    """Why a study stops once each of its rounds has run."""
    return f"all {spec.rounds} rounds run"


def stop_reason(look: Look, otherwise: str) -> str:
    """Why a study that stops adding runs stopped, from ``look`` (its runs judged at its
    last look, ``spec.looks``: no look follows, so it is judged there, :func:`final_look`;
    the loop's look, without the protocol check): ``"every verdict decided"`` where no
    variant is undecided, else ``otherwise`` (:data:`NOTHING_TO_ADD` or
    :func:`all_rounds_run`); ``"no reference run finished"`` where there is nothing to
    judge."""
    if not look.refs:
        return "no reference run finished"
    undecided = any(v["verdict"] == "undecided" for v in look.verdicts)
    return otherwise if undecided else "every verdict decided"


def final_look(spec: StudySpec, added: list[dict], stopped: str | None = None) -> int:
    """The look at which a study's verdicts are judged (engine.study.rates.look_alpha): 1
    for a study without ``decide``; else, while it may still add runs, 1 (the pilot: the
    planned runs) plus one per round that added runs (``added``: as
    :func:`engine.study.loop.plan_runs` returns them); once it has stopped (``stopped``: its
    reason), its last look, ``spec.looks``: no look follows, so the error rate of every look
    not taken is spent on the data it has (the looks' rates add up to alpha whatever data
    each sees: a union bound, docs/PHYSICS.md section 7.2). A study that stops after its
    pilot because no round could decide more is judged at its last look, not at the
    pilot's share."""
    if not spec.decide:
        return 1
    if stopped is not None:
        return spec.looks
    return 1 + len({a["round"] for a in added})


def most_added(
    spec: StudySpec, planned: list[PlannedRun], added: list[dict], stopped: str | None
) -> float:
    """The most particle-steps the rounds still to come of a ``decide`` study may add to
    its runs so far (``planned``, ``added`` and ``stopped`` as
    :func:`engine.study.loop.plan_runs` returns them): none without ``decide``, once it has
    stopped adding or once each of its ``rounds`` has added runs; else the budget not yet
    spent or every variant and the reference filled to their seed caps, whichever is less
    (for the plan's own runs the admitted worst case,
    :meth:`engine.study.plan.StudyPlan.estimated_particle_steps`). A round's runs come out
    of it, so the study's known runs plus this never grow: its progress, counted against
    that sum, never goes back when a round adds runs (engine.run_study)."""
    if not spec.decide or stopped is not None or len({a["round"] for a in added}) >= spec.rounds:
        return 0.0
    worst = to_seed_caps(spec, planned)
    if spec.budget is None:
        return worst
    keys = {a["run"] for a in added}
    spent = sum(p.particle_steps for p in planned if p.key in keys)
    return float(max(0.0, min(worst, spec.budget - spent)))


__all__ = ["NOTHING_TO_ADD", "all_rounds_run", "final_look", "most_added", "stop_reason"]
