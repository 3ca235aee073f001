"""demscale's adhesive branch (kadh > 0) against LIGGGHTS 3.8's ``edinburgh/stiffness`` with
``fixKc on`` on one packing (issue 41 item 3: "the LIGGGHTS export carries it once it is
checked against LIGGGHTS on one packing").

    python -m benchmarks.liggghts_kadh.compare             # runs not yet stored, then the table
    python -m benchmarks.liggghts_kadh.compare --report    # the table of what is stored

The protocol, bed, sampling and metric are benchmarks/liggghts_eepa.py's (the 2,025-sphere
anchor bed, R = 2.5 mm; settle 0.05 s, then the top platen down at 10 mm/s for 0.5 s, dt
1e-5 s; relative RMS difference of the two platen-stress curves, its criterion 5 %), on its
case 5 (n = chi = 1, K1 = 5e3, K2 = 2.5e4 N/m, friction, LIGGGHTS' conventions: kt = K1,
Coulomb cap mu |F_n|) made cohesive:

- ``5f``: f0 = -0.2 N, kadh = 0 (LIGGGHTS ``fixKc`` off, ``surfaceEnergy`` 0): how far the
  two codes are apart with the constant adhesion alone (not compared before at n = 1);
- ``5k``: f0 = -0.2 N and kadh = 2.5e3 N/m = K1 / 2, in LIGGGHTS ``fixKc on`` with
  ``coefficientAdhesionStiffness`` = kadh / K1 = 0.5 (LIGGGHTS-PUBLIC
  src/normal_model_edinburgh_stiffness.h: ``k_adh = kn2kc * kn``, line 260).

**Criterion, stated before the runs**: kadh's mapping is checked on this packing when 5k's
relative RMS difference is within 5 % (docs/LIGGGHTS_EEPA.md's) and 5f's is too (else the
constant adhesion already separates the codes and 5k cannot single out kadh). Each code's
5k-against-5f difference is reported beside it: how much the adhesive branch moves this
loading curve at all (a confined compression loads most contacts; the branch acts on those
that unload in rearrangements). Results are stored in ``results/`` beside this file as
each run ends.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import benchmarks.liggghts_eepa as le

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
TARGET = le.TARGET


@dataclass(frozen=True)
class KCase(le.Case):
    """A case of benchmarks/liggghts_eepa.py with an adhesive branch kadh [N/m^chi]."""

    kadh: float = 0.0

    def eepa(self):
        return replace(super().eepa(), kadh=self.kadh)


CASES = {
    c.key: c
    for c in (
        KCase(
            "5f",
            "n = 1, friction, f0 = -0.2 N, kadh = 0",
            n=1.0,
            chi=1.0,
            k1=5e3,
            k2=2.5e4,
            f0=-0.2,
        ),
        KCase(
            "5k",
            "n = 1, friction, f0 = -0.2 N, kadh = 2.5e3 N/m (fixKc on)",
            n=1.0,
            chi=1.0,
            k1=5e3,
            k2=2.5e4,
            f0=-0.2,
            kadh=2.5e3,
        ),
    )
}

_deck = le.deck


def deck(case, top, side=0.05, data="pack2k.data") -> str:
    """benchmarks/liggghts_eepa.py's deck, with ``fixKc on`` and coefficientAdhesionStiffness
    = kadh / K1 where the case has kadh > 0."""
    text = _deck(case, top, side, data)
    kadh = getattr(case, "kadh", 0.0)
    if not kadh:
        return text
    old = "coefficientAdhesionStiffness peratomtypepair 1 0.0"
    assert old in text
    text = text.replace(old, f"coefficientAdhesionStiffness peratomtypepair 1 {kadh / case.k1!r}")
    text = text.replace("kadh = 0 (surfaceEnergy 0, fixKc off)", f"kadh = {kadh:g} N/m (fixKc on)")
    style = "pair_style      gran model edinburgh/stiffness tangential history rolling_friction cdt"
    assert style in text
    return text.replace(style, style + " fixKc on")


le.deck = deck  # run_liggghts and deck_id write their deck through it


def _path(code: str, key: str) -> Path:
    return RESULTS / f"{code}_{key}.json"


def run(keys) -> dict:
    out = {}
    for key in keys:
        case = CASES[key]
        for code, fn in (("demscale", le.run_demscale), ("liggghts", le.run_liggghts)):
            p = _path(code, key)
            if p.exists():
                out[(code, key)] = json.loads(p.read_text())
                continue
            print(f"{code} {key} ...", flush=True)
            r = fn(case)
            if r is None:
                print(f"{code} {key}: no result", flush=True)
                continue
            RESULTS.mkdir(parents=True, exist_ok=True)
            p.write_text(json.dumps({"case": asdict(case), **r}))
            out[(code, key)] = {"case": asdict(case), **r}
            print(f"{code} {key}: {r['seconds']:.0f} s", flush=True)
    return out


def table(results: dict) -> dict:
    rows = {}
    for key in CASES:
        d, g = results.get(("demscale", key)), results.get(("liggghts", key))
        if d is None or g is None:
            continue
        rows[key] = {
            "title": CASES[key].title,
            "rel_rms": le.rel_rms(d["strain"], d["stress"], g["strain"], g["stress"]),
            "stress_end_demscale": d["stress"][-1],
            "stress_end_liggghts": g["stress"][-1],
            "seconds": [d["seconds"], g["seconds"]],
            "liggghts_builds": g.get("builds"),
        }
    for code in ("demscale", "liggghts"):
        a, b = results.get((code, "5k")), results.get((code, "5f"))
        if a and b:
            rows[f"{code}: 5k against 5f"] = {
                "rel_rms": le.rel_rms(a["strain"], a["stress"], b["strain"], b["stress"])
            }
    if "5f" in rows and "5k" in rows:
        rows["checked"] = rows["5k"]["rel_rms"] <= TARGET and rows["5f"]["rel_rms"] <= TARGET
    (HERE / "table.json").write_text(json.dumps(rows, indent=1))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--cases", nargs="*", default=list(CASES))
    args = ap.parse_args()
    if args.report:
        results = {}
        for key in CASES:
            for code in ("demscale", "liggghts"):
                if _path(code, key).exists():
                    results[(code, key)] = json.loads(_path(code, key).read_text())
    else:
        results = run(args.cases)
    print(json.dumps(table(results), indent=1))


if __name__ == "__main__":
    main()
