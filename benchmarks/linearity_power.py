"""How large a departure from the line the size series' linearity check sees, in the designs
the free surface's strength was fitted on (issue 50; docs/PHYSICS.md section 7.5).

The check (``engine.study.resolution.linearity``) holds each size's standardised residual
to Student's t at 1 - 0.05 / (2 G) on the degrees of freedom of ``sources_df``, which is
the smallest source's wherever a source has fewer than two (a size of two seeds outside
the pool). In ``bond1``'s strength series the 25-diameter size has two failed seeds and
sits outside the pool, so every residual is held to t on one degree of freedom (89 at
seven sizes), and the 5-diameter column, whose strength is a quarter of the next size's,
stays in the fit. This simulation says what that check can see there; it changes no rule
and no stored answer.

Simulated (``python -m benchmarks.linearity_power``, about a minute a law): the truth is the
line fitted without the 5-diameter column (the sizes with a core), each size's seeds drawn
around it with the spread the rule gives each stored size (``size_noise``, pooled: the
larger of the pool's, scaled as (d / L)^2, and the size's own), at the stored sizes and
seed counts
(the stored design) and with three seeds at every size of fewer (the design a third seed
would give). The 5-diameter mean is then moved off the line by a fraction of its stored
departure (0: the false alarms; 1: as far as the stored column lies), the same draws at
every fraction. Per design and departure: how often the sizes are called not linear (the
check's power), and how often ``asymptotic_curve`` then leaves the 5-diameter size out;
per design, how often a size's spread is a source of fewer than two degrees of freedom (the
floor, the power's ceiling). Stored in benchmarks/results/linearity_power/;
docs/RESOLUTION.md prints it.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from benchmarks import size_report as R
from engine.study.resolution import asymptotic_curve, fit_curve, size_noise

OUT = Path(__file__).resolve().parent / "results" / "linearity_power"
#: Fractions of the stored 5-diameter departure simulated.
FRACTIONS = (0.0, 0.1, 0.25, 0.5, 1.0)
#: Simulated series per design and fraction.
REPLICATES = 2000
COARSEST = 5.0


def stored_sizes(law_name: str) -> tuple[list[dict], float]:
    """The strength series as the report fits it (``size_report.strength_runs``): per size
    the seeds' log strengths and its d / L, finest first; and the reference size."""
    ref_size = R.FEATURES["free_surface"][3]
    out = [
        {
            "size": size,
            "x": 1.0 / float(np.mean([z for z, _ in rs])),
            "logs": np.log([float(np.mean(v["strength"])) for _, v in rs]),
            "reference": size == ref_size,
        }
        for size, rs in sorted(R.strength_runs(law_name).items(), reverse=True)
    ]
    return out, ref_size


def truth(sizes: list[dict]) -> dict:
    """The line through the sizes with a core, and each size's spread as the rule models
    the stored sizes (``size_noise``, pooled: the larger of the pool's, scaled as
    (d / L)^2, and the size's own)."""
    c = fit_curve([s for s in sizes if s["size"] != COARSEST], 0.95, pooled=True)
    a, b = math.log(c["bulk"]), c["slope"]
    counts = np.array([len(s["logs"]) for s in sizes])
    var_of_mean = size_noise(sizes, True).var_of_mean
    k = next(i for i, s in enumerate(sizes) if s["size"] == COARSEST)
    departure = float(np.mean(sizes[k]["logs"]) - (a + b * sizes[k]["x"]))
    return {
        "a": a,
        "b": b,
        "sd": {f"{s['size']:.4g}": math.sqrt(v * n) for s, v, n in zip(sizes, var_of_mean, counts)},
        "departure": departure,
        # in the standard errors the rule gives the coarsest size's mean
        "departure_in_standard_errors": departure / math.sqrt(float(var_of_mean[k])),
    }


def simulate(sizes: list[dict], t: dict, counts: list[int], seed: int) -> dict:
    """Per fraction of the departure: how often the sizes are called not linear, and how
    often the coarsest is left out; and how often a size's spread is a source of fewer than
    two degrees of freedom (a two-seed size out of the pool: the floor every residual then
    gets, the ceiling of the power). The same draws at every fraction (common random
    numbers), so that the rates differ by the departure alone."""
    rng = np.random.default_rng(seed)
    called = dict.fromkeys(FRACTIONS, 0)
    left_out = dict.fromkeys(FRACTIONS, 0)
    floored = 0
    sd = [t["sd"][f"{s['size']:.4g}"] for s in sizes]
    for _ in range(REPLICATES):
        noise = [rng.normal(0.0, q, n) for q, n in zip(sd, counts)]
        for f in FRACTIONS:
            sim = []
            for s, e in zip(sizes, noise):
                mean = t["a"] + t["b"] * s["x"]
                if s["size"] == COARSEST:
                    mean += f * t["departure"]
                sim.append({"x": s["x"], "logs": mean + e, "reference": s["reference"]})
            if f == 0.0:
                floored += min(d for d, _ in size_noise(sim, True).sources) < 2
            called[f] += fit_curve(sim, 0.95, pooled=True)["linear"] is False
            c = asymptotic_curve(sim, 0.95, pooled=True)
            left_out[f] += any(abs(z - COARSEST) < 0.5 for z in c["left_out"])
    return {
        "floored": floored / REPLICATES,
        "rows": [
            {
                "fraction": f,
                "called_not_linear": called[f] / REPLICATES,
                "coarsest_left_out": left_out[f] / REPLICATES,
            }
            for f in FRACTIONS
        ],
    }


def run(law_name: str) -> dict:
    sizes, ref_size = stored_sizes(law_name)
    t = truth(sizes)
    stored = [len(s["logs"]) for s in sizes]
    designs = {"stored": stored, "three_seeds_at_least": [max(3, n) for n in stored]}
    out = {
        "law": law_name,
        "property": "strength",
        "sizes": [s["size"] for s in sizes],
        "reference_size": ref_size,
        "truth": t,
        "replicates": REPLICATES,
        "designs": {},
    }
    for k, (name, counts) in enumerate(designs.items()):
        out["designs"][name] = {"seeds": counts, **simulate(sizes, t, counts, 1000 * (k + 1))}
    return out


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("laws", nargs="*", default=["bond1"])
    args = p.parse_args(argv)
    OUT.mkdir(parents=True, exist_ok=True)
    for law in args.laws:
        got = run(law)
        (OUT / f"{law}_strength.json").write_text(json.dumps(got, indent=1) + "\n")
        print(json.dumps(got, indent=1))


if __name__ == "__main__":
    main()
