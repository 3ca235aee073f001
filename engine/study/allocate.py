r"""Seeds where they decide: which runs a round of a ``decide`` study adds (docs/PHYSICS.md
section 7.2). Input: the study's groups on their compared scale with pooled spreads
(engine.study.noise) and their verdicts at the current look (engine.study.judge); output:
the runs to add, each with its reason. Deterministic given the stored runs.

- Every (radius, rule) not yet ``differs`` is a candidate (``equivalent`` is claimed at the
  final look only). Its **chance of being decided** at the next look with k more seeds is
  computed per metric from the pooled spreads, the projected counts and degrees of freedom
  and the observed differences (:meth:`engine.study.judge.Comparison.chance`), and combined
  over its metrics as (any metric differs) + (every metric equivalent), metrics taken as
  independent.
- A run is worth the rise it brings to the chances of the variants it touches per estimated
  particle-step: a coarse seed raises its variant's, a reference seed every variant's. Each
  candidate is valued at its best number of seeds (the chance of ``equivalent`` rises in a
  step, so one seed alone may show nothing), and one run of the best is added at a time,
  until no run raises a chance by :data:`MIN_GAIN` per run, or the seed caps and the
  ``budget`` stop it. At an equal worth the rule under test (the study's first rule) comes
  before the foils, and a coarse seed before a reference seed.
- A coarse seed at a radius with resolution controls costs its control too (the rule's own
  error is judged paired by seed): the control is reserved in the budget with it.
- A variant already decided on its headline metric (:func:`headline`: ``strength`` where
  the test has it) at the current look takes no run (it differs), and so does one the caps
  could not decide if its means and spreads stayed as observed (futility: stopping without
  a verdict never makes a wrong one).
- A variant or reference of one seed first gets seeds up to three (a spread of its own).

:func:`allocate_round` is the allocator the adaptive loop asks (engine.study.loop, in the
role of Optuna's sampler): from a look at the data (engine.study.look.judge_look) it
returns the runs of a round as planned runs of the study with new seeds, each with its
:class:`Addition` (round, kind, reason).
"""

from __future__ import annotations

from dataclasses import dataclass

from .intervals import WELCH_MIN_SEEDS
from .judge import compare
from .kinds import KINDS
from .noise import StudyNoise
from .plan import CONTROL
from .rates import error_rates

#: Least rise in a variant's chance of being decided, per added run, for which a run is
#: worth adding [-]: a run that adds under 2 % to the chance of a decision costs more than
#: 50 runs per decision.
MIN_GAIN = 0.02

#: Most seeds a candidate is looked ahead for in one valuation.
LOOKAHEAD = 8


@dataclass(frozen=True)
class Addition:
    """One run to add: ``kind`` ``"coarse"`` (of ``variant``, a (radius, rule name)) or
    ``"reference"`` (``variant`` None), the ``round`` [1, rounds] and the ``reason``."""

    kind: str
    variant: tuple | None
    round: int
    reason: str


def headline(names) -> str:
    """The metric a user reads first among a study's verdict metrics ``names``: the first
    its kind declares (:attr:`engine.study.kinds.TestKind.headline`: the unconfined strength
    where judged, else the loading stiffness; the flowability ffc in a shear study; the
    discharge number in a hopper's), the kind being the one whose metrics these are; the
    first name where no kind has them all."""
    kind = next((k for k in KINDS.values() if set(names) <= set(k.metrics)), None)
    return next((n for n in (kind.headline if kind else ()) if n in names), names[0])


def _combine(chances) -> float:
    """Chance a variant is decided from its metrics' (equivalent, differs) chances: any
    metric differs, or all are equivalent (metrics independent)."""
    none_differ, all_eq = 1.0, 1.0
    for p_eq, p_di in chances:
        none_differ *= 1.0 - p_di
        all_eq *= p_eq
    return min(1.0, 1.0 - none_differ + all_eq)


def next_runs(
    spec,
    noise: StudyNoise,
    verdicts: list[dict],
    costs: dict,
    round_no: int,
    budget_left: float | None,
    attempted: dict | None = None,
    control_costs: dict | None = None,
) -> list[Addition]:
    """The runs of round ``round_no`` (module docstring). ``verdicts``: the variants'
    judgements at look ``round_no``; ``costs``: estimated particle-steps of one more run of
    ``"reference"`` and of each variant; ``budget_left``: particle-steps still allowed (None:
    unbounded); ``attempted``: runs planned so far per variant and ``"reference"``, failed
    ones included, which the caps count; ``control_costs``: radius -> a control's cost where
    the study has controls (reserved with each coarse seed)."""
    names = noise.names
    head = headline(names)
    alpha_e, alpha_d = error_rates(spec.confidence, len(names), round_no + 1, spec.looks)
    attempted = dict(attempted or {})
    control_costs = control_costs or {}
    first_rule = spec.rules[0].name if spec.rules else None
    n_ref0 = max((noise.kept.get((n, "reference"), (0, 0))[0] for n in names), default=0)
    n_ref0 = max(n_ref0, len(noise.raw.get((names[0], "reference"), ())))
    tried_r = max(attempted.get("reference", n_ref0), n_ref0)
    left = float("inf") if budget_left is None else float(budget_left)
    if n_ref0 < 2:
        k = min(WELCH_MIN_SEEDS - n_ref0, spec.max_reference_seeds - tried_r)
        while k > 0 and k * costs["reference"] > left:
            k -= 1
        reason = (
            f"round {round_no}: one reference seed: its spread, which every interval needs, "
            "is unknown"
        )
        return [Addition("reference", None, round_no, reason)] * max(k, 0)

    comps: dict = {}
    for v in verdicts:
        key = (v["radius"], v["rule"])
        if v["verdict"] == "differs" or not v["metrics"] or key not in costs:
            continue
        comps[key] = {n: compare(noise, n, key, spec.tolerances[n]) for n in names}
    if not comps:
        return []
    seeds_of = {k: max(c.nc for c in cs.values()) for k, cs in comps.items()}
    tried_c = {k: max(attempted.get(k, seeds_of[k]), seeds_of[k]) for k in comps}

    def cost_of(k) -> float:
        return costs[k] + control_costs.get(k[0], 0.0)

    memo: dict = {}

    def chance(k, kc: int, kr: int) -> float:
        if (k, kc, kr) not in memo:
            memo[k, kc, kr] = _chance(k, kc, kr)
        return memo[k, kc, kr]

    def _chance(k, kc: int, kr: int) -> float:
        cs = comps[k]
        out = []
        for c in cs.values():
            if not c.known and c.nc + kc < 2:
                out.append((0.0, 0.0))
                continue
            if not c.known:
                return 0.0
            out.append(c.chance(c.nc + kc, c.nr + kr, alpha_e, alpha_d))
        return _combine(out)

    # futility, and variants whose next look decides them with the seeds they have
    for k in list(comps):
        cs = comps[k]
        if any(not c.known for c in cs.values()) or seeds_of[k] < WELCH_MIN_SEEDS:
            continue  # a spread of its own first: two seeds say too little to give up on
        most_c = spec.max_seeds - tried_c[k]
        most_r = spec.max_reference_seeds - tried_r
        proj = [c.projected(c.nc + most_c, c.nr + most_r, alpha_e, alpha_d) for c in cs.values()]
        if not (any(p == "differs" for p in proj) or all(p == "equivalent" for p in proj)):
            del comps[k]
            continue
        h = cs[head]
        if h.known and h.projected(h.nc, h.nr, alpha_e, alpha_d) == "differs":
            del comps[k]  # its headline metric already tells it apart at the next look
    if not comps:
        return []

    added_c = dict.fromkeys(comps, 0)
    added_r = 0
    out: list[Addition] = []
    while True:
        base = {k: chance(k, added_c[k], added_r) for k in comps}
        cands = []
        for k in comps:
            room = spec.max_seeds - tried_c[k] - added_c[k]
            if room <= 0 or cost_of(k) > left:
                continue
            if seeds_of[k] + added_c[k] < WELCH_MIN_SEEDS:  # a spread of its own first
                cands.append((float("inf"), 1.0, k[1] == first_rule, "coarse", k))
                continue
            best = 0.0
            for j in range(1, min(room, LOOKAHEAD) + 1):
                if j * cost_of(k) > left:
                    break
                gain = (chance(k, added_c[k] + j, added_r) - base[k]) / j
                best = max(best, gain)
            if best >= MIN_GAIN:
                cands.append((best / cost_of(k), best, k[1] == first_rule, "coarse", k))
        room_r = spec.max_reference_seeds - tried_r - added_r
        if room_r > 0 and costs["reference"] <= left:
            best = 0.0
            for j in range(1, min(room_r, LOOKAHEAD) + 1):
                if j * costs["reference"] > left:
                    break
                gain = sum(chance(k, added_c[k], added_r + j) - base[k] for k in comps) / j
                best = max(best, gain)
            if best >= MIN_GAIN:
                cands.append((best / costs["reference"], best, False, "reference", None))
        if not cands:
            break
        worth, gain, _, kind, k = max(cands, key=lambda c: (c[0], c[2], c[3] == "coarse"))
        if kind == "coarse":
            cs = comps[k]
            undecided = [
                n
                for n, c in cs.items()
                if not c.known or c.projected(c.nc, c.nr, alpha_e, alpha_d) is None
            ]
            why = (
                "a spread of its own first"
                if gain == 1.0 and worth == float("inf")
                else f"{100 * gain:.0f} % more chance of a verdict per run, the most per "
                "particle-step"
            )
            ctl = " with its resolution control" if k[0] in control_costs else ""
            out.append(
                Addition(
                    "coarse",
                    k,
                    round_no,
                    f"round {round_no}: R = {k[0] * 1e3:g} mm, {k[1]} not decided "
                    f"({', '.join(undecided) or 'equivalent so far'}): a coarse seed{ctl}, "
                    f"{why} (base chance {100 * base[k]:.0f} %)",
                )
            )
            added_c[k] += 1
            left -= cost_of(k)
        else:
            names_open = ", ".join(f"{x[0] * 1e3:g} mm {x[1]}" for x in comps)
            out.append(
                Addition(
                    "reference",
                    None,
                    round_no,
                    f"round {round_no}: a reference seed raises the chance of a verdict of "
                    f"the undecided variants ({names_open}) by {100 * gain:.0f} % per run, "
                    "the most per particle-step",
                )
            )
            added_r += 1
            left -= costs["reference"]
    return out


def allocate_round(look, planned: list, round_no: int, spent: float) -> list[tuple]:
    """The runs round ``round_no`` adds, judged from ``look`` (a
    :class:`engine.study.look.Look` of ``planned`` at look ``round_no``, without the
    protocol check): planned runs of the study (``planned``, the stored plan's first) with
    new seeds, nothing planned again, each with its :class:`Addition`; ``spent``: the
    particle-steps the earlier rounds added. A control follows each added coarse seed at a
    radius with controls (its cost reserved by :func:`next_runs`). Returns (run, addition)
    pairs, the round's order."""
    spec = look.spec
    if not look.refs:
        return []
    cost: dict = {}
    attempted: dict = {}
    template: dict = {}  # the first planned run of each variant (None: the reference)
    used: dict = {}
    for p in planned:
        k = "reference" if p.is_reference else p.variant
        cost.setdefault(k, p.particle_steps)
        attempted[k] = attempted.get(k, 0) + 1
        template.setdefault(p.variant, p)
        used.setdefault(p.variant, set()).add(p.seed)
    budget_left = None if spec.budget is None else spec.budget - spent
    control_costs = {
        k[0]: c for k, c in cost.items() if k is not None and k != "reference" and k[1] == CONTROL
    }
    adds = next_runs(
        spec, look.noise, look.verdicts, cost, round_no, budget_left, attempted, control_costs
    )
    out = []
    for a in adds:
        seeds = used.setdefault(a.variant, set())
        seed = max(seeds | used.get(None, set())) + 1
        seeds.add(seed)
        # the planned run with a new seed: the same test (a coarse test's time step is the
        # reference's, whatever its seed), so an added run is what the stored plan holds
        out.append((template[None if a.kind == "reference" else a.variant].with_seed(seed), a))
    for p, a in list(out):
        # a control follows each added coarse seed at its radius (one control per radius
        # and seed serves every rule there), so that the rule's own error keeps its pairs
        # (engine.study.judge.judge_rule_error); the allocation reserved its cost
        ck = (p.radius, CONTROL)
        if a.kind != "coarse" or ck not in template or p.seed in used.get(ck, set()):
            continue
        ctl = template[ck].with_seed(p.seed)
        used[ck].add(p.seed)
        reason = (
            f"round {a.round}: the resolution control of seed {p.seed} at "
            f"R = {p.radius * 1e3:g} mm, which {p.key} is paired with for the rule's own error"
        )
        out.append((ctl, Addition("control", ck, a.round, reason)))
    return out


__all__ = ["LOOKAHEAD", "MIN_GAIN", "Addition", "allocate_round", "headline", "next_runs"]
