"""The shear side of a calibration's forward model (docs/CALIBRATION.md, "Shear data").

A parameter set whose targets hold a shear tester's yield loci (``LabTargets.shear``) runs,
besides the uniaxial test of its uniaxial targets (if any), one shear test per locus
(:func:`engine.run_shear`): the calibration's shear cell (:func:`shear_cell`, or the one
given) with the locus's pre-shear stress as ``preshear_stress`` and its points' normal
stresses as ``normal_stresses``, in the data's order, and the parameter set's law. Each run
is compared with the data per target, with the data's sd, like every other target:

- ``tau@<sigma_n>Pa:<sigma_pre>Pa``: the shear stress at failure at the laboratory's sigma_n
  [Pa], the run's point read at the lab's normal stress along the run's own locus,
  tau + tan(phi) (sigma_n - sigma) (the servo holds a point's normal stress within a few
  per cent of its target, docs/SHEAR.md; the slope carries the point to the target); the
  sd: the lab's tau_sd with its sigma_n_sd carried along the lab's locus
  (:meth:`ShearLocus.tau_sd`);
- ``tau_pre@<sigma_pre>Pa`` (where the lab gives tau_pre): the pre-shear's steady shear
  stress [Pa], read at sigma_pre as tau_pre sigma_pre / sigma (steady flow holds the stress
  ratio; the servo holds sigma within 2 % of sigma_pre);
- ``bulk_density@<sigma_pre>Pa`` (where the lab gives it): the run's bulk density over the
  pre-shear's last window [kg/m^3].

ffc, sigma_1 and sigma_c are not targets: they are functions of the same points (the
locus's line and Mohr circles), so counting them too would weigh those points twice.

A run's shear results are kept in its outcome under :data:`SHEAR` as their JSON form
(:meth:`engine.ShearResult.to_dict`: the test, scalars, points and locus), stored per
locus as ``<key>-shear-<sigma_pre>Pa.json`` and found again on a rerun when the stored test
is the same test.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, replace
from pathlib import Path

from ..core.errors import ParameterError
from ..shear.spec import ShearTest
from ..uniaxial.spec import UniaxialTest
from .targets import LabTargets

#: The key of a run outcome's shear results (sigma_pre [Pa] -> the result's JSON form).
SHEAR = "shear"
#: The default shear cell in mean diameters (Lx, Ly, H): docs/SHEAR.md's default, 10 x 5 x
#: 15 (no difference from 20 diameters tall seen with six seeds, no rate effect at half the
#: rate; the cross-section not varied).
CELL_DIAMETERS = (10.0, 5.0, 15.0)
#: The uniaxial test's fields a derived shear cell takes as they are (the material and the
#: numerics; the cell and the shear procedure are the shear test's defaults).
FROM_UNIAXIAL = (
    "radius",
    "polydispersity",
    "density",
    "seed",
    "dt",
    "dt_fraction",
    "output_interval",
)
#: The shear test's fields a calibration sets itself: the law (each parameter set's) and the
#: stresses (each locus's sigma_pre and sigma_n). A shear cell is the other fields.
SET_BY_CALIBRATION = ("pair_law", "preshear_stress", "normal_stresses")
#: Units of the shear targets (a quantity's name up to its "@").
SHEAR_UNITS = {"tau": "Pa", "tau_pre": "Pa", "bulk_density": "kg/m^3"}


@dataclass(frozen=True)
class Forward:
    """The tests one parameter set runs: ``uniaxial`` (None where the targets have no
    uniaxial target) and ``shear``, one :class:`engine.ShearTest` per yield locus, in the
    order of ``LabTargets.shear``."""

    uniaxial: UniaxialTest | None
    shear: tuple[ShearTest, ...] = ()

    def to_dict(self) -> dict:
        """JSON form (a failed run's file names its tests by a digest of it)."""
        return {
            "uniaxial": None if self.uniaxial is None else self.uniaxial.to_dict(),
            "shear": [t.to_dict() for t in self.shear],
        }


def shear_cell(base: UniaxialTest) -> dict:
    """The shear cell of a calibration whose base test is ``base``, as the fields of an
    :class:`engine.ShearTest` but :data:`SET_BY_CALIBRATION`: ``base``'s material and
    numerics (:data:`FROM_UNIAXIAL`) in docs/SHEAR.md's default cell, :data:`CELL_DIAMETERS`
    mean diameters 2R; the shear test's defaults for the rest."""
    d = 2.0 * base.radius
    return {
        "cell": [n * d for n in CELL_DIAMETERS],
        **{name: getattr(base, name) for name in FROM_UNIAXIAL},
    }


def check_shear_cell(base: UniaxialTest, cell: ShearTest | dict | None) -> dict:
    """The shear cell of a calibration (the fields of an :class:`engine.ShearTest` but
    :data:`SET_BY_CALIBRATION`): ``cell`` (a ShearTest, whose law and stresses are left
    out, or those fields as a dict: its JSON form), or :func:`shear_cell` of ``base``. No
    shear test is built here: a cell is judged with each locus's stresses and a law
    (:func:`shear_tests`), not with the shear test's default stresses and law. Raises
    :class:`engine.ParameterError` at ``calibrate.shear_test...``: a field the calibration
    sets, a particle radius not the base test's (the law is calibrated for one radius:
    the result's ``reference_radius``)."""
    if cell is None:
        return shear_cell(base)
    if isinstance(cell, ShearTest):
        fields = {k: v for k, v in cell.to_dict().items() if k not in SET_BY_CALIBRATION}
    elif isinstance(cell, dict):
        fields = dict(cell)
        for k in SET_BY_CALIBRATION:
            if k in fields:
                raise ParameterError(
                    f"calibrate.shear_test.{k}",
                    fields[k],
                    "left out (the calibration sets it: the calibrated law, each locus's stresses)",
                )
    else:
        raise ParameterError(
            "calibrate.shear_test", type(cell).__name__, "an engine ShearTest or its fields"
        )
    radius = fields.get("radius", _RADIUS_DEFAULT)
    if radius != base.radius:
        raise ParameterError(
            "calibrate.shear_test.radius",
            radius,
            f"the test's radius = {base.radius:g} m",
            "the law is calibrated for one particle radius",
        )
    return fields


_RADIUS_DEFAULT = next(f.default for f in dataclasses.fields(ShearTest) if f.name == "radius")


def _renamed(e: ParameterError, i: int, sigma_pre: float) -> ParameterError:
    """An error of locus ``i``'s shear test named where the request holds it: its pre-shear
    and normal stresses are the data's (``LabTargets.shear[i]...``), the rest the shear
    cell's (``calibrate.shear_test.<field>``); a law the test refuses at this locus (too
    soft to carry its consolidation within the overlap limit) names its sigma_pre [Pa]."""
    field = e.field.split(".", 1)[1] if "." in e.field else ""
    if field.startswith("pair_law"):  # e.g. too soft for this locus's consolidation
        return ParameterError(
            f"LabTargets.shear[{i}].sigma_pre",
            sigma_pre,
            "a pre-shear stress the test's law can be consolidated to",
            f"{e}",
        )
    if field == "preshear_stress":
        where = f"LabTargets.shear[{i}].sigma_pre"
    elif field.startswith("normal_stresses["):
        k = field[len("normal_stresses[") : field.index("]")]
        where = f"LabTargets.shear[{i}].points[{k}].sigma_n"
    else:
        where = "calibrate.shear_test" + (f".{field}" if field else "")
    return ParameterError(where, e.value, e.limit, e.why)


def shear_tests(cell: dict, targets: LabTargets, law) -> tuple[ShearTest, ...]:
    """One shear test per yield locus of ``targets``: the shear cell ``cell``
    (:func:`check_shear_cell`) at the locus's sigma_pre and its points' sigma_n, with
    ``law``. Raises :class:`engine.ParameterError` named where the request holds the value
    (:func:`_renamed`): e.g. a law too soft to carry a locus's sigma_pre within the overlap
    limit names ``LabTargets.shear[i].sigma_pre``."""
    out = []
    for i, locus in enumerate(targets.shear):
        fields = {
            **cell,
            "pair_law": law,
            "preshear_stress": locus.sigma_pre,
            "normal_stresses": [p.sigma_n for p in locus.points],
        }
        try:
            out.append(ShearTest.from_dict(fields))
        except ParameterError as e:
            raise _renamed(e, i, locus.sigma_pre) from None
    return tuple(out)


def cell_summary(test: ShearTest) -> dict:
    """A shear cell as a result states it: the fields of a locus's test but those the
    calibration sets (:data:`SET_BY_CALIBRATION`)."""
    return {k: v for k, v in test.to_dict().items() if k not in SET_BY_CALIBRATION}


def run_shear_tests(tests: tuple[ShearTest, ...], progress=None) -> dict[float, dict]:
    """Run each test (:func:`engine.run_shear`); sigma_pre [Pa] -> the result's JSON form.
    ``progress`` hears each as a share of the whole (its stage named with the locus's
    sigma_pre); its errors (a stage that misses its criterion, ...) are raised."""
    from ..shear.driver import run_shear

    out = {}
    n = len(tests)
    for i, t in enumerate(tests):
        here = None
        if progress is not None:

            def here(p, i=i, s=t.preshear_stress):
                return progress(
                    replace(p, fraction=(i + p.fraction) / n, stage=f"shear@{s:g}Pa {p.stage}")
                )

        out[t.preshear_stress] = run_shear(t, progress=here).to_dict()
    return out


def measure_shear(shear: dict[float, dict], targets: LabTargets) -> list[dict]:
    """Each shear target of ``targets`` read from a run's shear results (sigma_pre -> the
    result's JSON form): name, lab value, lab sd, the run's value and unit (module
    docstring)."""
    out = []
    for locus in targets.shear:
        s = locus.sigma_pre
        res = shear[s]
        slope = float(res["locus"]["slope"])
        failures = {p["target"]: p for p in res["points"] if p["kind"] == "failure"}
        for k, p in enumerate(locus.points):
            run = failures[p.sigma_n]
            value = float(run["tau"]) + slope * (p.sigma_n - float(run["sigma"]))
            out.append(
                {
                    "name": f"tau@{p.sigma_n:g}Pa:{s:g}Pa",
                    "lab": p.tau,
                    "sd": locus.tau_sd(k),
                    "value": value,
                    "unit": "Pa",
                }
            )
        sc = res["scalars"]
        if locus.tau_pre is not None:
            sigma = float(sc["preshear_sigma"])
            value = float(sc["preshear_tau"]) * s / sigma if sigma > 0 else math.nan
            out.append(
                {
                    "name": f"tau_pre@{s:g}Pa",
                    "lab": locus.tau_pre,
                    "sd": locus.tau_pre_sd,
                    "value": value,
                    "unit": "Pa",
                }
            )
        if locus.bulk_density is not None:
            out.append(
                {
                    "name": f"bulk_density@{s:g}Pa",
                    "lab": locus.bulk_density,
                    "sd": locus.bulk_density_sd,
                    "value": float(sc["bulk_density"]),
                    "unit": "kg/m^3",
                }
            )
    return out


def shear_curves(shear: dict[float, dict]) -> list[dict]:
    """The check run's yield loci as the result shows them: per sigma_pre [Pa] the
    pre-shear point and the points of failure (sigma, tau [Pa]), the fitted locus (c [Pa],
    tan(phi)), sigma_1, sigma_c [Pa], ffc and the bulk density [kg/m^3]."""
    out = []
    for s in sorted(shear):
        res = shear[s]
        loc = res["locus"]
        pts = res["points"]
        out.append(
            {
                "sigma_pre": float(s),
                "preshear": {"sigma": pts[0]["sigma"], "tau": pts[0]["tau"]},
                "points": [
                    {"target": p["target"], "sigma": p["sigma"], "tau": p["tau"]} for p in pts[1:]
                ],
                "cohesion": loc["cohesion"],
                "slope": loc["slope"],
                "sigma_1": loc["sigma_1"],
                "sigma_c": loc["sigma_c"],
                # inf (no unconfined strength) as null: JSON has no infinity
                "ffc": loc["ffc"] if math.isfinite(loc["ffc"]) else None,
                "bulk_density": res["scalars"]["bulk_density"],
            }
        )
    return out


def _shear_file(folder: Path, key: str, sigma_pre: float) -> Path:
    return folder / f"{key}-shear-{sigma_pre:g}Pa.json"


def store_loci(folder: Path, key: str, shear: dict[float, dict]) -> None:
    """Store each locus's result of run ``key`` (written to a temporary file and renamed:
    a file found is whole): the JSON form alone, no curves (a calibration reads only the
    points, locus and scalars; :func:`engine.shear.results.save_shear` keeps the curves
    too)."""
    for s, res in shear.items():
        path = _shear_file(folder, key, s)
        tmp = path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(res))
        tmp.replace(path)


def stored_loci(folder: Path, key: str, tests: tuple[ShearTest, ...]) -> dict[float, dict] | None:
    """The stored results of run ``key`` for ``tests``, or None where one is missing or was
    stored for another test."""
    out = {}
    for t in tests:
        path = _shear_file(folder, key, t.preshear_stress)
        if not path.exists():
            return None
        res = json.loads(path.read_text())
        if res.get("test") != json.loads(json.dumps(t.to_dict())):
            return None
        out[t.preshear_stress] = res
    return out


__all__ = [
    "CELL_DIAMETERS",
    "SET_BY_CALIBRATION",
    "SHEAR",
    "SHEAR_UNITS",
    "Forward",
    "cell_summary",
    "check_shear_cell",
    "measure_shear",
    "run_shear_tests",
    "shear_cell",
    "shear_curves",
    "shear_tests",
    "store_loci",
    "stored_loci",
]
