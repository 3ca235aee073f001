r"""Seeds until decided: which runs a study adds where a verdict is undecided
(docs/PHYSICS.md section 7).

After the planned runs (look 1), a study with ``decide`` judges its verdicts and adds runs
in rounds; each round is judged again (one look per round, at most ``rounds`` + 1 looks, each
spending :math:`\alpha /` looks, so that peeking keeps the stated rates). The stopping rule:
stop when every verdict is decided, when no undecided variant can take another run (its
seeds at ``max_seeds``, the reference's at ``max_reference_seeds``), when the next run would
exceed the ``budget`` of particle-steps, or after ``rounds`` rounds.

Which runs a round adds (greedy, one run at a time, deterministic given the stored runs):

- a run is a coarse seed of an undecided variant, or a reference seed (which narrows the
  intervals of every variant);
- its worth is the relative shrinkage of the squared standard uncertainty it brings to the
  undecided metrics, :math:`\sum_m [v_m(n) - v_m(n+1)] / u_m^2` over the metrics it narrows
  (:math:`v_m(n) = s_m^2 / n`, coarse or reference term), per estimated particle-step of
  the run: coarse seeds are cheap; a reference seed wins when the reference term dominates;
- a variant that the caps could not decide even at ``max_seeds`` and
  ``max_reference_seeds`` (if its means and spreads stayed as observed) takes no run;
- a variant takes runs until, if its means and spreads stayed as observed, every undecided
  metric would be decided, and at most as many in one round as it has seeds (at least one):
  seed counts at most double per round, so a metric that sits at its tolerance (which no
  seed count decides) does not eat the budget in one round.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .advisor import _decides, _floored, _stack, error_rates
from .metrics import reference_scale


@dataclass(frozen=True)
class Addition:
    """One run to add: ``kind`` ``"coarse"`` (of ``variant``, a (radius, rule name)) or
    ``"reference"`` (``variant`` None), the ``round`` [1, rounds] and the ``reason``."""

    kind: str
    variant: tuple | None
    round: int
    reason: str


def _arrays(name, values, ref_values, cons):
    """A metric's coarse and reference values (seeds x levels) and its scale."""
    c, r = _stack(values, name), _stack(ref_values, name)
    return c, r, reference_scale(name, r.mean(0), cons)


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
    them), ``verdicts`` are their judgements, ``costs`` maps ``"reference"`` and each variant
    to the estimated particle-steps of one more run; ``budget_left``: particle-steps still
    allowed (None: unbounded); ``attempted``: runs planned so far per variant and
    ``"reference"``, failed ones included, which the seed caps count (default: the finished
    ones)."""
    cons = spec.reference.consolidation_stress
    names = [m["metric"] for m in verdicts[0]["metrics"]] if verdicts else []
    alpha_e, alpha_d = error_rates(spec.confidence, len(names), spec.looks)
    attempted = dict(attempted or {})
    n_ref0 = len(ref_values)
    tried_r = max(attempted.get("reference", n_ref0), n_ref0)
    left = np.inf if budget_left is None else float(budget_left)
    if n_ref0 < 2:  # no interval without a second reference seed
        k = min(2 - n_ref0, spec.max_reference_seeds - tried_r)
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
    undecided = {}
    for v in verdicts:
        key = (v["radius"], v["rule"])
        if v["verdict"] != "undecided" or key not in variants or not v["metrics"]:
            continue
        ms = [m["metric"] for m in v["metrics"] if m["verdict"] == "undecided"]
        if len(variants[key]) < 2:
            comps = {}
        else:
            comps = {n: _arrays(n, variants[key], ref_values, cons) for n in ms}
        undecided[key] = (ms, comps)
    if not undecided:
        return []
    n_c = {k: len(variants[k]) for k in undecided}
    tried_c = {k: max(attempted.get(k, n_c[k]), n_c[k]) for k in undecided}
    start = (dict(n_c), n_ref0)
    n_r = n_ref0
    limit_c = {k: min(spec.max_seeds - tried_c[k], max(1, n_c[k])) for k in undecided}
    limit_r = min(spec.max_reference_seeds - tried_r, max(1, n_ref0))
    added_c = dict.fromkeys(undecided, 0)
    added_r = 0
    out: list[Addition] = []

    def decided(k, nc=None, nr=None) -> bool:
        comps = undecided[k][1]
        nc = n_c[k] if nc is None else nc
        nr = n_r if nr is None else nr
        if not comps:  # one seed: a second one first
            return nc >= 2
        if nc == start[0][k] and nr == start[1]:
            return False  # as observed: its verdict is undecided
        return all(
            _decides(
                c,
                r,
                nc,
                nr,
                spec.tolerances[n],
                alpha_e,
                alpha_d,
                _floored(n, float(r.mean(0)[0]), cons) if r.shape[1] == 1 else None,
            )
            for n, (c, r, _) in comps.items()
        )

    # a variant that the caps cannot decide (if its means and spreads stayed as observed)
    # takes no run: seeds spent there would buy nothing
    for k in list(undecided):
        if not decided(
            k, n_c[k] + spec.max_seeds - tried_c[k], n_r + spec.max_reference_seeds - tried_r
        ):
            del undecided[k]
    if not undecided:
        return []

    def shrink(k, coarse: bool) -> float:
        comps = undecided[k][1]
        if not comps:
            return 1.0
        total = 0.0
        for c, r, sc in comps.values():
            cv, rv = c.var(0, ddof=1) / sc**2, r.var(0, ddof=1) / sc**2
            u2 = float(np.mean(cv / n_c[k] + rv / n_r))
            if u2 <= 0:
                continue
            if coarse:
                dv = float(np.mean(cv)) * (1 / n_c[k] - 1 / (n_c[k] + 1))
            else:
                dv = float(np.mean(rv)) * (1 / n_r - 1 / (n_r + 1))
            total += dv / u2
        return total

    while True:
        open_ = [k for k in undecided if not decided(k)]
        if not open_:
            break
        cands = []
        for k in open_:
            if added_c[k] < limit_c[k] and costs[k] <= left:
                cands.append((shrink(k, True) / costs[k], "coarse", k))
        if added_r < limit_r and costs["reference"] <= left:
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
                    f"round {round_no}: {', '.join(ms)} undecided for R = "
                    f"{k[0] * 1e3:g} mm, {k[1]}; a coarse seed shrinks its "
                    "intervals most per particle-step",
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
            added_r += 1
            left -= costs["reference"]
    return out


__all__ = ["Addition", "next_runs"]
