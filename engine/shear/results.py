"""What a shear test gives back: the curves of each stage, the shear points, the yield locus
and the scalars (SI units in :data:`SHEAR_CURVE_UNITS` and :data:`SHEAR_SCALAR_UNITS`)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..uniaxial.results import StageResult
from .locus import YieldLocus
from .spec import ShearTest

#: Units of the curves of every shear stage (the fill and the consolidation are the uniaxial
#: test's stages, with its curves: engine.uniaxial.results.CURVE_UNITS).
SHEAR_CURVE_UNITS = {
    "time": "s",
    "displacement": "m",
    "shear_strain": "1",
    "shear_stress": "Pa",
    "shear_stress_base": "Pa",
    "normal_stress": "Pa",
    "normal_stress_base": "Pa",
    "lid_height": "m",
    "bulk_density": "kg/m^3",
    "kinetic_energy": "J",
    "inertial_number": "1",
}


@dataclass(frozen=True)
class ShearPoint:
    """One point of incipient failure.

    Attributes: ``target`` (the normal stress asked for) [Pa]; ``sigma`` (the lid's normal
    stress, smoothed, where the smoothed shear stress peaks) [Pa]; ``tau`` (that peak) [Pa];
    ``strain`` (shear strain at the peak) [-]; ``peaked`` (True when the shear stress fell
    ``failure_drop`` below the peak afterwards; False: the shear reached
    ``failure_strain`` first and ``tau`` is its largest value, a lower bound)."""

    target: float
    sigma: float
    tau: float
    strain: float
    peaked: bool


@dataclass
class ShearStage:
    """Curves of one shear stage (1-D arrays of equal length, units in
    :data:`SHEAR_CURVE_UNITS`) and its steps."""

    name: str
    curves: dict[str, np.ndarray]
    steps: int


@dataclass
class ShearResult:
    """Result of :func:`engine.run_shear`.

    Attributes: ``test``; ``consolidation`` (the fill and the consolidation under a flat
    lid: :class:`engine.StageResult` by name); ``stages`` (the shear stages by name, in
    order: ``preshear``, then per point k ``point{k}_reverse``, ``point{k}_normal``,
    ``point{k}_shear``); ``points`` (:class:`ShearPoint`, in the order of
    ``test.normal_stresses``); ``locus`` (:class:`engine.shear.locus.YieldLocus`);
    ``scalars`` (:data:`SHEAR_SCALAR_UNITS`)."""

    test: ShearTest
    consolidation: dict[str, StageResult]
    stages: dict[str, ShearStage]
    points: tuple[ShearPoint, ...]
    locus: YieldLocus
    scalars: dict[str, float]

    def to_dict(self) -> dict:
        """The test, scalars, shear points (the pre-shear point first) and locus as plain
        JSON-friendly values (ffc may be ``inf``); the curves are left out."""
        return {
            "test": self.test.to_dict(),
            "scalars": {k: float(v) for k, v in self.scalars.items()},
            "points": self.yield_points(),
            "locus": self.locus.to_dict(),
        }

    def yield_points(self) -> list[dict]:
        """The yield locus's points with the pre-shear point first (JSON-friendly)."""
        s = self.scalars
        pre = {
            "kind": "preshear",
            "target": self.test.preshear_stress,
            "sigma": float(s["preshear_sigma"]),
            "tau": float(s["preshear_tau"]),
            "strain": float(s["preshear_strain"]),
            "peaked": False,
        }
        return [pre] + [{"kind": "failure", **asdict(p)} for p in self.points]


#: Units of the scalars of a :class:`ShearResult`.
SHEAR_SCALAR_UNITS = {
    "preshear_sigma": "Pa",
    "preshear_tau": "Pa",
    "preshear_strain": "1",
    "preshear_drift": "1",
    "preshear_height_drift": "1",
    "cohesion": "Pa",
    "cohesion_se": "Pa",
    "friction_angle": "deg",
    "effective_friction_angle": "deg",
    "sigma_c": "Pa",
    "sigma_1": "Pa",
    "sigma_2": "Pa",
    "ffc": "1",
    "preshear_above": "Pa",
    "bulk_density": "kg/m^3",
    "bulk_density_consolidated": "kg/m^3",
    "height_diameters": "1",
    "glued_base": "1",
    "glued_lid": "1",
    "particles": "1",
    "servo_time": "s",
    "servo_gain": "m/(s Pa)",
    "servo_halvings": "1",
    "steps": "1",
    "particle_steps": "1",
    "thickness_diameters": "1",
    "dt": "s",
    "wall_time": "s",
}


def save_shear(path, res: ShearResult, **extra) -> None:
    """Store ``res`` as ``path`` (.json: its test, scalars, shear points, locus and the
    ``extra`` keys) and its shear stages' curves beside it (.npz, ``<stage>/<curve>``),
    each written whole (a temporary file, then a rename), the curves first: a .json
    present means a complete run. The consolidation's stages are not stored."""
    import json
    from pathlib import Path

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    curves = {f"{name}/{k}": v for name, st in res.stages.items() for k, v in st.curves.items()}
    tmp = path.with_suffix(".npz.tmp")
    with open(tmp, "wb") as f:
        np.savez_compressed(f, **curves)
    tmp.replace(path.with_suffix(".npz"))
    data = {**res.to_dict(), **extra}
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=1, default=float))
    tmp.replace(path)


def load_shear(path, curves: bool = False) -> ShearResult:
    """A run stored by :func:`save_shear` (or ``benchmarks/shear_cell.py``'s store, the same
    layout): its test, scalars, points and locus; with ``curves`` its shear stages' curves
    from the .npz beside it (else no stages). The consolidation's stages are not stored
    (``consolidation`` is empty). Scalars that a run stored before they existed lacks
    (``particle_steps``, ``thickness_diameters``) are computed from its test and scalars."""
    import json
    from pathlib import Path

    from .locus import YieldLocus

    path = Path(path)
    d = json.loads(path.read_text())
    test = ShearTest.from_dict(d["test"])
    s = {k: float(v) for k, v in d["scalars"].items()}
    s.setdefault("particle_steps", s["particles"] * s["steps"])
    s.setdefault("thickness_diameters", test.thickness_diameters)
    points = tuple(
        ShearPoint(p["target"], p["sigma"], p["tau"], p["strain"], bool(p["peaked"]))
        for p in d["points"]
        if p["kind"] == "failure"
    )
    stages: dict[str, ShearStage] = {}
    if curves:
        with np.load(path.with_suffix(".npz")) as z:
            for key in z.files:
                name, _, curve = key.partition("/")
                stages.setdefault(name, ShearStage(name, {}, 0)).curves[curve] = z[key]
    return ShearResult(test, {}, stages, points, YieldLocus(**d["locus"]), s)
