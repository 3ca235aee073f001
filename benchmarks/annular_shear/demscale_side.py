"""demscale's side of the ring-shear benchmark: the default shear test with the LIGGGHTS-
convention law (docs/SHEAR.md, "Against a ring shear cell (LIGGGHTS)")."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import engine
from engine.shear.results import load_shear, save_shear

#: results of the benchmark (both codes)
STORE = Path(__file__).resolve().parents[1] / "results" / "annular_shear"
SEEDS = (1, 2, 3, 4, 5, 6)
#: the normal stresses of the comparison [Pa]: three of the default test's four
NORMAL_STRESSES = (2e3, 4e3, 8e3)


def law() -> engine.EEPA:
    """The default shear test's cohesionless law in LIGGGHTS' conventions: EEPA with n = chi
    = 1 (the bilinear law's force), tangential stiffness K1 (kt_ratio 1) and the Coulomb cap
    mu |F_n| (``friction_cap="normal"``); K1, K2 [N/m], f0 [N]."""
    b = engine.ShearTest().pair_law
    return engine.EEPA(
        k1=b.k1,
        k2=b.k2,
        f0=0.0,
        kadh=0.0,
        n=1.0,
        chi=1.0,
        kt_ratio=1.0,
        mu_s=b.mu_s,
        mu_r=b.mu_r,
        restitution=b.restitution,
        friction_cap="normal",
    )


def test_for(seed: int) -> engine.ShearTest:
    """The default shear test (10 x 5 x 15 diameters, I = 1e-3, sigma_pre = 10 kPa) with
    :func:`law`, at ``NORMAL_STRESSES`` and packing ``seed``."""
    return replace(engine.ShearTest(), pair_law=law(), normal_stresses=NORMAL_STRESSES, seed=seed)


def path_for(seed: int) -> Path:
    return STORE / "demscale" / f"s{seed}.json"


def run(seeds=SEEDS) -> None:
    """Run every seed not yet stored (one at a time), each stored the moment it ends."""
    for seed in seeds:
        p = path_for(seed)
        if p.exists() or p.with_suffix(".failed").exists():
            continue
        t0 = time.time()
        print(f"demscale s{seed}: running", flush=True)
        try:
            res = engine.run_shear(test_for(seed))
        except (engine.StageError, FloatingPointError, engine.InstabilityError) as e:
            p.parent.mkdir(parents=True, exist_ok=True)
            p.with_suffix(".failed").write_text(f"{type(e).__name__}: {e}\n")
            print(f"demscale s{seed}: FAILED {type(e).__name__}: {e}", flush=True)
            continue
        save_shear(p, res, wall_seconds=time.time() - t0)
        s = res.scalars
        print(
            f"demscale s{seed}: {time.time() - t0:.0f} s, tau_pre {s['preshear_tau']:.0f} Pa, "
            f"phi {s['friction_angle']:.1f} deg, dt {s['dt']:.4g} s",
            flush=True,
        )


def load_all() -> list:
    """The stored demscale runs (``engine.ShearResult`` without curves), by seed."""
    return [load_shear(path_for(s)) for s in SEEDS if path_for(s).exists()]
