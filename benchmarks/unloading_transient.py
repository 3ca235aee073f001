"""The top platen's stress at the start of the unloading, read from the stored full files of
the size series' slow-unloading runs (kinds ``unload``, ``unload_check``, ``unload_rest``
and ``unload_quiet``, benchmarks/size_series.py): how much of the consolidation stress the
top platen loses in the first curve sample, against the interior's, and whether that drop is
the stress wave a velocity jump launches into an elastic medium, Delta sigma = rho_b c Delta
v.

    python -m benchmarks.unloading_transient      # the table, and its JSON stored

At the end of the consolidation the top platen moves down at the loading speed, which at a
held inertial number grows with the sample's height (v = I (h / d) sqrt(sigma / rho)); the
unloading reverses it (``unload_rest``: a hold stops it first, so the unloading starts from
rest and Delta v is v_unload alone). A reversal by Delta v = v_load + v_unload unloads the
layer at the platen at once, by rho_b c Delta v (rho_b the bulk density, c the sample's wave
speed), while the interior learns of it only after the wave's transit. The unloading
stiffness is a secant over the samples between half and all of the peak stress of the top
platen's curve (``engine.uniaxial.measures.secant_slope``), so such a drop, where it is a
sizeable share of the consolidation stress, sits inside the secant's window. This module
measures, per run: v_load (the platen's speed over the last sample of the stage before the
unloading, the consolidation's or the hold's, 0) and v_unload (over the unloading's first)
[m/s], the top stress's drop over that first sample [Pa] and as a share of its start, the
interior virial stress's share, the bulk density rho_b = rho (1 - porosity, interior)
[kg/m^3], and c_eff = drop / (rho_b Delta v) [m/s]: a constant c_eff across sizes says the
drop is the wave's. For a run with a hold stage it also stores the hold's length [s] and the
top and interior stresses left at its end, as shares of their values at its start (the
relaxation once the platen stops), and how much the top and interior stresses still swing
over the hold's last fifth (peak to peak, as a share of their start) with the kinetic energy
at its end as a share of that fifth's largest: a bed whose lowest axial mode still rings has
a large top swing, a small interior one (the mode's stress is antisymmetric about the
middle, which the interior window straddles) and its energy ending near a turning point. The
full files live outside git (``var/size_series/``, regenerable from the digests' tests); a
file whose sha256 is not its digest's is skipped. Stored:
benchmarks/results/unloading_transient/summary.json.
"""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np

from benchmarks import size_series as S
from engine.io.digest import sha256_of

STORE = S.ROOT / "benchmarks" / "results" / "unloading_transient"
KINDS = ("unload", "unload_check", "unload_rest", "unload_quiet")


def run_row(path: Path, density: float) -> dict:
    """One run's first unloading sample against the last of the stage before it (the
    consolidation, or the hold where the run has one: module docstring), from its full
    file; ``density`` the particles' [kg/m^3]."""
    with h5py.File(path) as f:
        c, u = f["stages/consolidation"], f["stages/unloading"]
        before = f["stages/hold"] if "hold" in f["stages"] else c
        gap, t = before["platen_gap"][-2:], before["time"][-2:]
        ug, ut = u["platen_gap"][:2], u["time"][:2]
        top, inner = u["stress_top"][:2], u["stress_interior"][:2]
        porosity = float(c["porosity_interior"][-1])
        hold = {}
        if "hold" in f["stages"]:
            h = f["stages/hold"]
            top_h, ke = h["stress_top"][:], h["kinetic_energy"][:]
            tail = slice(len(top_h) - max(2, len(top_h) // 5), None)  # the last fifth
            hold = {
                "hold_time": float(h["time"][-1] - h["time"][0]),
                "hold_top_left": float(top_h[-1] / top_h[0]),
                "hold_interior_left": float(h["stress_interior"][-1] / h["stress_interior"][0]),
                "hold_top_swing": float(np.ptp(top_h[tail]) / top_h[0]),
                "hold_interior_swing": float(
                    np.ptp(h["stress_interior"][tail]) / h["stress_interior"][0]
                ),
                "hold_end_ke_share": float(ke[-1] / ke[tail].max()),
            }
    v_load = float((gap[0] - gap[1]) / (t[1] - t[0]))
    v_unload = float((ug[1] - ug[0]) / (ut[1] - ut[0]))
    rho_b = density * (1.0 - porosity)
    drop = float(top[0] - top[1])
    return {
        "v_load": v_load,
        "v_unload": v_unload,
        "top_drop": drop,
        "top_share_left": float(top[1] / top[0]),
        "interior_share_left": float(inner[1] / inner[0]),
        "bulk_density": rho_b,
        "c_eff": drop / (rho_b * (v_load + v_unload)),
        **hold,
    }


def rows(law_name: str = "bond1") -> dict:
    """Per kind and size, the stored runs' rows (:func:`run_row`) whose full file is here
    and is the one the digest names."""
    out: dict = {}
    for kind in KINDS:
        for size, n in sorted(S.TABLES[kind].get(law_name, {}).items()):
            got = []
            for seed in range(1, n + 1):
                d, full = (
                    S.stored(kind, law_name, size, seed),
                    S.full_path_of(kind, law_name, size, seed),
                )
                if d is None or not full.exists() or sha256_of(full) != d.full_sha256:
                    continue
                got.append({"seed": seed, **run_row(full, d.test["density"])})
            if got:
                out.setdefault(kind, {})[f"{size:.3g}"] = got
    return out


def _means_table(data: dict, header: str, columns: tuple) -> list[str]:
    """Per kind and size, the runs' means of ``columns`` ((key, format) pairs) as rows under
    the markdown ``header``; runs without the first key left out, a size without any such
    run too; no table where no size has one."""
    lines = [header, "|---|---:|---:|" + "---:|" * len(columns)]
    for kind, sizes in data.items():
        for size, rs in sizes.items():
            rs = [r for r in rs if columns[0][0] in r]
            if rs:
                cells = " | ".join(
                    f"{float(np.mean([r[k] for r in rs])):{fmt}}" for k, fmt in columns
                )
                lines.append(f"| {kind} | {size} | {len(rs)} | {cells} |")
    return lines if len(lines) > 2 else []


def table(data: dict) -> list[str]:
    """The size means as a markdown table."""
    return _means_table(
        data,
        "| kind | size [d] | runs | v_load [m/s] | v_unload [m/s] | top drop [Pa] | top left "
        "| interior left | c_eff [m/s] |",
        (
            ("v_load", ".4f"),
            ("v_unload", ".4f"),
            ("top_drop", ".0f"),
            ("top_share_left", ".3f"),
            ("interior_share_left", ".3f"),
            ("c_eff", ".1f"),
        ),
    )


def hold_table(data: dict) -> list[str]:
    """The hold's size means (runs with a hold stage) as a markdown table: its length, the
    top and interior stresses left at its end and their swings over its last fifth, as
    shares of their values at its start, and the end energy's share of that fifth's
    largest."""
    return _means_table(
        data,
        "| kind | size [d] | runs | hold [s] | top stress left | interior stress left | "
        "top swing, last fifth | interior swing, last fifth | end KE / max KE, last fifth |",
        (
            ("hold_time", ".4f"),
            ("hold_top_left", ".3f"),
            ("hold_interior_left", ".3f"),
            ("hold_top_swing", ".3f"),
            ("hold_interior_swing", ".4f"),
            ("hold_end_ke_share", ".3f"),
        ),
    )


def main() -> int:
    data = rows()
    if not data:
        print("no full files here (var/size_series/): run benchmarks.size_series first")
        return 1
    c = [r["c_eff"] for sizes in data.values() for rs in sizes.values() for r in rs]
    by_kind = {
        kind: [r["c_eff"] for rs in sizes.values() for r in rs] for kind, sizes in data.items()
    }
    summary = {
        "what": __doc__.splitlines()[0],
        "runs": data,
        "c_eff_range": [min(c), max(c)],
        "c_eff_mean": float(np.mean(c)),
        "c_eff_by_kind": {
            k: {"runs": len(v), "range": [min(v), max(v)], "mean": float(np.mean(v))}
            for k, v in by_kind.items()
        },
    }
    STORE.mkdir(parents=True, exist_ok=True)
    (STORE / "summary.json").write_text(json.dumps(summary, indent=1, allow_nan=False) + "\n")
    print("\n".join(table(data)))
    held = hold_table(data)
    if held:
        print("\nThe hold (runs with a hold stage):")
        print("\n".join(held))
    lo, hi = summary["c_eff_range"]
    print(f"c_eff over {len(c)} runs: {lo:.1f} to {hi:.1f} m/s (mean {np.mean(c):.1f})")
    for k, v in summary["c_eff_by_kind"].items():
        print(
            f"  {k}: {v['runs']} runs, {v['range'][0]:.1f} to {v['range'][1]:.1f} m/s "
            f"(mean {v['mean']:.1f})"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
