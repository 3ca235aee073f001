"""The adaptive loop of a scaling study, explicit: ask for the runs to run, tell their
outcomes (docs/PHYSICS.md section 7.2).

The pieces, in the roles Optuna gives its own: the static plan (engine.study.plan: every
planned run, its test complete), the allocator (engine.study.allocate.allocate_round, the
sampler: which runs a round adds, and why), the stopping rule (engine.study.stopping, the
pruner: when the study stops adding runs, and the look it is judged at), and one look at the
data (engine.study.look.judge_look) that both of them, and the report, read.

:class:`StudyLoop` holds a study's runs so far: :meth:`StudyLoop.ask` returns the runs still
to run, planning the next round (by the allocator) once the runs it is planned from have
their outcomes; :meth:`StudyLoop.tell` records an outcome. A round, once planned, is kept:
its runs are stored with their round and reason (engine.io.store), and a study loaded from
its store is given them back (``decided``) instead of judging its rounds again. A store
without them (written before they were stored) has its rounds replayed from its outcomes,
round by round, as they were decided: deterministic, so the same runs are found."""

from __future__ import annotations

from .allocate import allocate_round
from .look import judge_look
from .plan import PlannedRun, StudyPlan, as_plan, cost_weights
from .report import AdaptiveSummary
from .results import StudyResult, assemble
from .spec import StudySpec
from .stopping import NOTHING_TO_ADD, all_rounds_run, final_look, most_added, stop_reason


class StudyLoop:
    """The runs of one study (``study``: a :class:`engine.StudyPlan`, or a spec planned
    here) and their ``outcomes`` so far (key -> result or error text; the dict is kept and
    filled by :meth:`tell`). ``decided``: the added runs a store holds, each
    ``{run, round, kind, reason}`` (engine.io.store.stored_additions), taken as their
    rounds' decisions; rounds it lacks are planned by the allocator.

    Attributes: ``planned`` (the plan's runs, then each round's), ``added`` (each added
    run as ``{run, round, kind, reason}``), ``stopped`` (why the study stopped adding runs;
    None while it may add more, or has runs of its last round still to run)."""

    def __init__(
        self,
        study: StudyPlan | StudySpec,
        outcomes: dict | None = None,
        decided: list[dict] | None = None,
    ):
        self.plan = as_plan(study)
        self.spec = self.plan.spec
        self.planned: list[PlannedRun] = list(self.plan.runs)
        self.outcomes = {} if outcomes is None else outcomes
        self.added: list[dict] = []
        self.stopped: str | None = None
        self.rounds = 0  # rounds planned so far
        self.spent = 0.0  # particle-steps the rounds added
        self.decided = _decided_rounds(self.plan, decided or [])
        self._advance()

    # ------------------------------------------------------------------------ ask / tell
    def ask(self) -> list[PlannedRun]:
        """The runs still to run (planned order), the next round planned first where it
        can be; empty once the study is done."""
        self._advance()
        return [p for p in self.planned if p.key not in self.outcomes]

    def tell(self, key: str, outcome) -> None:
        """The outcome of run ``key``: its result, or the error text of a failed run."""
        self.outcomes[key] = outcome

    # ----------------------------------------------------------------------------- reads
    def round_of(self, key: str) -> list[dict] | None:
        """The additions of the round that added run ``key`` (the run's own among them):
        what its store keeps with it; None for a planned run."""
        mine = next((a for a in self.added if a["run"] == key), None)
        if mine is None:
            return None
        return [a for a in self.added if a["round"] == mine["round"]]

    def reserve(self) -> float:
        """The most particle-steps the rounds still to come may add
        (engine.study.stopping.most_added)."""
        return most_added(self.spec, self.planned, self.added, self.stopped)

    def weights(self):
        """Each run's share of the study's estimated work, the reserve counted in."""
        return cost_weights(self.planned, self.reserve())

    @property
    def look(self) -> int:
        """The look the study's verdicts are judged at now (engine.study.stopping)."""
        return final_look(self.spec, self.added, self.stopped)

    def summary(self) -> AdaptiveSummary:
        """The report's ``adaptive`` entry (:func:`adaptive_summary`)."""
        return adaptive_summary(self.spec, self.planned, self.added, self.stopped)

    def result(self) -> StudyResult:
        """The study's report from its outcomes, judged at :attr:`look`, with its
        ``adaptive`` entry where it decides."""
        adaptive = self.summary() if self.spec.decide else None
        return assemble(self.spec, self.planned, self.outcomes, self.look, adaptive)

    # --------------------------------------------------------------------------- rounds
    def _advance(self) -> None:
        """Plan the rounds that can be planned now: a round is planned from the finished
        references and variants (the controls and the protocol check take no part in it,
        so it need not wait for them), or taken from ``decided``. Once the rounds stop
        adding runs and every run is in, the stopping rule says why, from the runs judged
        at the study's last look (without the protocol check)."""
        spec = self.spec
        if not spec.decide or self.stopped is not None:
            return
        why = None  # NOTHING_TO_ADD where a round adds no run, else all its rounds ran
        while self.rounds < spec.rounds:
            round_no = self.rounds + 1
            new = self.decided.get(round_no)
            if new is None:
                pilot = (p for p in self.planned if not p.control and not p.protocol)
                if any(p.key not in self.outcomes for p in pilot):
                    return  # its references and variants still to run
                look = judge_look(spec, self.planned, self.outcomes, round_no, report=False)
                new = [
                    (p, {"run": p.key, "round": a.round, "kind": a.kind, "reason": a.reason})
                    for p, a in allocate_round(look, self.planned, round_no, self.spent)
                ]
                if not new:  # asked again while controls are still to run
                    why = NOTHING_TO_ADD
                    break
            self.rounds = round_no
            for p, a in new:
                self.planned.append(p)
                self.spent += p.particle_steps
                self.added.append(a)
        if all(p.key in self.outcomes for p in self.planned):
            last = judge_look(spec, self.planned, self.outcomes, spec.looks, report=False)
            self.stopped = stop_reason(last, why or all_rounds_run(spec))


def _decided_rounds(plan: StudyPlan, decided: list[dict]) -> dict[int, list[tuple]]:
    """Stored additions as rounds: round -> [(planned run, addition)], for the rounds 1, 2,
    ... the store holds each run of (a run is the plan's with another seed, its key named
    by :func:`engine.study.plan.run_key`); nothing where the study does not decide, a key
    is no run of the plan or a round is missing in between (its rounds are then planned
    again)."""
    spec = plan.spec
    if not spec.decide or not decided:
        return {}
    templates: dict[str, PlannedRun] = {}
    for p in plan.runs:
        templates.setdefault(p.key.rpartition("-s")[0], p)
    keys = {p.key for p in plan.runs}
    rounds: dict[int, list[tuple]] = {}
    for a in decided:
        prefix, _, seed = str(a["run"]).rpartition("-s")
        if a["run"] in keys or not seed.isdigit() or prefix not in templates:
            return {}
        run = templates[prefix].with_seed(int(seed))
        if run.key != a["run"]:
            return {}
        entry = {k: a[k] for k in ("run", "round", "kind", "reason")}
        entry["round"] = int(entry["round"])
        rounds.setdefault(entry["round"], []).append((run, entry))
        keys.add(run.key)
    if sorted(rounds) != list(range(1, len(rounds) + 1)) or len(rounds) > spec.rounds:
        return {}
    return rounds


def plan_runs(
    study: StudyPlan | StudySpec, outcomes: dict, decided: list[dict] | None = None
) -> tuple[list[PlannedRun], list[dict], str | None]:
    """Every run of ``study`` given the ``outcomes`` so far (and the ``decided`` additions a
    store holds): the planned runs, then, with ``decide``, the runs each round adds.
    Returns (runs, the added runs as {run, round, kind, reason}, why the study stopped
    adding: None while some run of the last round is still to run). The outcomes are not
    changed."""
    loop = StudyLoop(study, dict(outcomes), decided)
    return loop.planned, loop.added, loop.stopped


def adaptive_summary(
    spec: StudySpec, planned: list[PlannedRun], added: list[dict], stopped: str | None
) -> AdaptiveSummary:
    """The report's ``adaptive`` entry: planned and added runs, the looks, the look judged
    at, why it stopped, the budget and the particle-steps the rounds added."""
    keys = {a["run"] for a in added}
    return AdaptiveSummary(
        planned_runs=len(planned) - len(added),
        added_runs=tuple(dict(a) for a in added),
        looks=spec.looks,
        look=final_look(spec, added, stopped),
        stopped=stopped,
        budget=spec.budget,
        added_particle_steps=float(sum(p.particle_steps for p in planned if p.key in keys)),
    )


__all__ = ["StudyLoop", "adaptive_summary", "plan_runs"]
