r"""Seeds until decided: which runs a study adds where a verdict is not yet decided
(docs/PHYSICS.md section 7.2).

A study with ``decide`` is a two-stage design (Stein 1945) with an early stop for gross
differences. The planned runs are its pilot (look 1; at least 3 + 3 seeds are advised, as
the default study runs). The pilot's verdicts may say ``differs`` (at a fifth of the rate,
:data:`engine.study.advisor.PILOT_SHARE`); every other variant, undecided or equivalent so
far, gets the seeds its pilot's spreads say it needs, and is judged again at the next look.
``equivalent`` is claimed at the final look only, so a study never stops on it: which seeds
a second stage gets depends on the spreads, not on how close the means came to the
tolerance. ``rounds`` > 1 repeats the sizing from all the seeds so far (each round a look
of the ``differs`` test, sharing the rest of its rate). The stopping rule: stop when no
variant needs another run, when the seed caps (``max_seeds``, ``max_reference_seeds``) or
the ``budget`` of particle-steps are reached, or after ``rounds`` rounds.

Which runs a round adds (greedy, one run at a time, deterministic given the stored runs):

- a variant needs runs until, with its spreads as observed and a true error of 0, its chance
  of ``equivalent`` at the next look would be at least
  :data:`engine.study.advisor.PLANNED_POWER` at every level of every metric
  (:func:`engine.study.advisor._decides` with ``planned``);
- a run is a coarse seed of such a variant, or a reference seed (which narrows the
  intervals of every variant); its worth is the relative shrinkage of the squared standard
  uncertainty it brings to the variant's metrics, :math:`\sum_m [v_m(n) - v_m(n+1)] / u_m^2`
  (:math:`v_m(n) = s_m^2 / n`, coarse or reference term, on the scale the verdict compares),
  per estimated particle-step of the run: coarse seeds are cheap; a reference seed wins
  when the reference term dominates;
- futility: a variant that the caps could not decide even at ``max_seeds`` and
  ``max_reference_seeds`` if its means and spreads stayed as observed (an error that sits at
  the tolerance) takes no run; stopping without a verdict never makes a wrong one;
- a variant of one seed first gets seeds up to three, a reference of one seed likewise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .advisor import (
    PLANNED_POWER,
    _decides,
    _projected,
    _Space,
    _stack,
    error_rates,
    variant_decided,
)
from .intervals import WELCH_MIN_SEEDS


@dataclass(frozen=True)
class Addition:
    """One run to add: ``kind`` ``"coarse"`` (of ``variant``, a (radius, rule name)) or
    ``"reference"`` (``variant`` None), the ``round`` [1, rounds] and the ``reason``."""

    kind: str
    variant: tuple | None
    round: int
    reason: str


def next_runs(
    spec,
    ref_values: list[dict],
    variants: dict[tuple, list[dict]],
    verdicts: list[dict],
    costs: dict,
    round_no: int,
    budget_left: float | None,
    attempted: dict | None = None,
) -> list[Addition]:
    """The runs of round ``round_no`` (module docstring). ``ref_values`` and ``variants``
    hold metric values per finished seed (as :func:`engine.study.advisor.judge_groups` takes
    them), ``verdicts`` are their judgements at look ``round_no``, ``costs`` maps
    ``"reference"`` and each variant to the estimated particle-steps of one more run;
    ``budget_left``: particle-steps still allowed (None: unbounded); ``attempted``: runs
    planned so far per variant and ``"reference"``, failed ones included, which the seed caps
    count (default: the finished ones)."""
    cons = spec.reference.consolidation_stress
    names = [m["metric"] for m in verdicts[0]["metrics"]] if verdicts else []
    # the look these runs are sized for
    alpha_e, alpha_d = error_rates(spec.confidence, len(names), round_no + 1, spec.looks)
    attempted = dict(attempted or {})
    n_ref0 = len(ref_values)
    tried_r = max(attempted.get("reference", n_ref0), n_ref0)
    left = np.inf if budget_left is None else float(budget_left)
    if n_ref0 < 2:  # no interval without a second reference seed
        k = min(WELCH_MIN_SEEDS - n_ref0, spec.max_reference_seeds - tried_r)
        while k > 0 and k * costs["reference"] > left:  # within the budget
            k -= 1
        return [
            Addition(
                "reference",
                None,
                round_no,
                f"round {round_no}: one reference "
                "seed: its spread, which every interval needs, is unknown",
            )
        ] * max(k, 0)
    # every variant not told apart (undecided, or equivalent so far: equivalence is claimed
    # at the final look only, on seeds sized from the spreads, never by stopping on it)
    undecided = {}
    for v in verdicts:
        key = (v["radius"], v["rule"])
        if v["verdict"] == "differs" or key not in variants or not v["metrics"]:
            continue
        ms = [m["metric"] for m in v["metrics"] if m["verdict"] == "undecided"]
        if len(variants[key]) < 2:
            comps = {}
        else:
            comps = {
                m["metric"]: _Space(
                    m["metric"],
                    _stack(variants[key], m["metric"]),
                    _stack(ref_values, m["metric"]),
                    spec.tolerances[m["metric"]],
                    cons,
                )
                for m in v["metrics"]
            }
        undecided[key] = (ms, comps)
    if not undecided:
        return []
    n_c = {k: len(variants[k]) for k in undecided}
    tried_c = {k: max(attempted.get(k, n_c[k]), n_c[k]) for k in undecided}
    n_r = n_ref0

    def decided(k) -> bool:
        """Whether variant ``k`` has the seeds its spreads say it needs (planned)."""
        comps = undecided[k][1]
        if not comps:  # one seed: its spread first
            return n_c[k] >= WELCH_MIN_SEEDS
        return all(_decides(sp, n_c[k], n_r, alpha_e, alpha_d, True) for sp in comps.values())

    # futility: a variant that the caps could not decide if its means and spreads stayed as
    # observed (no metric would differ, not every one would be equivalent) takes no run:
    # stopping without a verdict never makes a wrong one
    for k in list(undecided):
        most_c = n_c[k] + spec.max_seeds - tried_c[k]
        most_r = n_r + spec.max_reference_seeds - tried_r
        comps = undecided[k][1]
        if comps and not variant_decided(
            _projected(sp, most_c, most_r, alpha_e, alpha_d) for sp in comps.values()
        ):
            del undecided[k]
    if not undecided:
        return []

    def shrink(k, coarse: bool) -> float:
        comps = undecided[k][1]
        if not comps:
            return 1.0
        total = 0.0
        for sp in comps.values():
            cv, rv = sp.stats[2], sp.stats[3]
            u2 = float(np.mean(cv / n_c[k] + rv / n_r))
            if u2 <= 0:
                continue
            if coarse:
                dv = float(np.mean(cv)) * (1 / n_c[k] - 1 / (n_c[k] + 1))
            else:
                dv = float(np.mean(rv)) * (1 / n_r - 1 / (n_r + 1))
            total += dv / u2
        return total

    added_c = dict.fromkeys(undecided, 0)
    out: list[Addition] = []
    while True:
        open_ = [k for k in undecided if not decided(k)]
        if not open_:
            break
        cands = []
        for k in open_:
            if tried_c[k] + added_c[k] < spec.max_seeds and costs[k] <= left:
                cands.append((shrink(k, True) / costs[k], "coarse", k))
        if n_r - n_ref0 + tried_r < spec.max_reference_seeds and costs["reference"] <= left:
            worth = sum(shrink(k, False) for k in open_ if undecided[k][1])
            if worth > 0:
                cands.append((worth / costs["reference"], "reference", None))
        if not cands:
            break
        _, kind, k = max(cands, key=lambda c: (c[0], c[1] == "coarse"))
        if kind == "coarse":
            ms = undecided[k][0]
            out.append(
                Addition(
                    "coarse",
                    k,
                    round_no,
                    f"round {round_no}: R = {k[0] * 1e3:g} mm, {k[1]} not decided "
                    f"({', '.join(ms) or 'equivalent so far'}); its pilot's spreads call "
                    f"for more seeds ({PLANNED_POWER:.0%} power for equivalent at error 0); "
                    "a coarse seed narrows its intervals most per particle-step",
                )
            )
            n_c[k] += 1
            added_c[k] += 1
            left -= costs[k]
        else:
            names_open = ", ".join(f"{x[0] * 1e3:g} mm {x[1]}" for x in open_)
            out.append(
                Addition(
                    "reference",
                    None,
                    round_no,
                    f"round {round_no}: the reference term dominates the "
                    f"intervals of the undecided variants ({names_open}); a "
                    "reference seed shrinks them most per particle-step",
                )
            )
            n_r += 1
            left -= costs["reference"]
    return out


__all__ = ["Addition", "next_runs"]
