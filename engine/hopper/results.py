"""What a hopper discharge gives back: its sampled curves, the wall normal stress by height and
the scalars (SI units in :data:`HOPPER_CURVE_UNITS` and :data:`HOPPER_SCALAR_UNITS`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .spec import HopperTest

#: Units of the discharge's curves (one sample every ``output_interval``, from the gate's
#: opening).
HOPPER_CURVE_UNITS = {
    "time": "s",  # since the gate began to open
    "discharged_mass": "kg",  # centres more than one largest diameter below the outlet
    "remaining_mass": "kg",  # inside the hopper's walls, above that level
    "escaped_mass": "kg",  # anywhere else (none, unless a grain leaked through a wall)
    "wall_speed": "m/s",  # mean downward speed of the grains next to the wall (a band)
    "wall_count": "1",
    "centre_speed": "m/s",  # ... and of the grains on the centre line
    "centre_count": "1",
    "kinetic_energy": "J",
}

#: Units of the scalars of a :class:`HopperResult`.
HOPPER_SCALAR_UNITS = {
    "particles": "1",
    "total_mass": "kg",
    "discharged_mass": "kg",
    "remaining_mass": "kg",
    "escaped_mass": "kg",
    "discharge_rate": "kg/s",
    "discharge_rate_se": "kg/s",
    "discharge_rate_per_depth": "kg/(s m)",
    "discharge_number": "1",  # the rate over HopperTest.rate_scale
    "discharge_number_se": "1",
    "window_start": "s",
    "window_end": "s",
    "window_samples": "1",
    "stopped": "1",
    "arched": "1",
    "arch_time": "s",
    "arch_span": "m",  # the walls' distance apart at the arch's feet
    "arch_height": "m",  # its crown over its feet
    "mass_flow_index": "1",
    "mass_flow": "1",
    "fill_height": "m",  # the height the fill holds at its bulk density, level
    "bulk_density": "kg/m^3",
    "outlet_diameters": "1",
    "thickness_diameters": "1",  # B over the largest diameter: the smallest feature
    "height_diameters": "1",  # fill_height over the mean diameter
    "free_fall_time": "s",
    "settle_time": "s",
    "discharge_time": "s",
    "steps": "1",
    "particle_steps": "1",
    "dt": "s",
    "wall_time": "s",
}


@dataclass
class HopperResult:
    """Result of :func:`engine.hopper.driver.run_hopper`.

    Attributes: ``test``; ``curves`` (:data:`HOPPER_CURVE_UNITS`, 1-D arrays of one length);
    ``wall_edges`` (the height bins' edges above the outlet, from 0 to the settled fill
    height [m]); ``wall_stress_fill`` (the wall normal stress in each bin with the fill
    settled behind the closed gate [Pa]); ``wall_stress_flow`` (its mean over the samples of
    the steady window [Pa]; NaN where there is no window); ``scalars``
    (:data:`HOPPER_SCALAR_UNITS`: ``stopped``, ``arched``, ``mass_flow`` are 0 or 1;
    ``arch_time``, ``arch_span`` and ``arch_height`` are NaN unless arched,
    ``discharge_rate*`` NaN without a steady window, ``discharge_rate_per_depth`` NaN for a
    cone)."""

    test: HopperTest
    curves: dict[str, np.ndarray]
    wall_edges: np.ndarray
    wall_stress_fill: np.ndarray
    wall_stress_flow: np.ndarray
    scalars: dict[str, float]

    @property
    def arched(self) -> bool:
        """Whether the flow stopped in an arch over the outlet."""
        return bool(self.scalars["arched"])

    @property
    def flow_mode(self) -> str:
        """``"mass"``, ``"funnel"`` or ``"unknown"`` (no steady window, or no grain on the
        centre line)."""
        k = self.scalars["mass_flow_index"]
        if math.isnan(k):
            return "unknown"
        return "mass" if self.scalars["mass_flow"] else "funnel"

    def to_dict(self) -> dict:
        """The test, scalars, flow mode and wall stress profiles as plain JSON-friendly values
        (NaN where not measured); the curves are left out."""
        return {
            "test": self.test.to_dict(),
            "scalars": {k: float(v) for k, v in self.scalars.items()},
            "flow_mode": self.flow_mode,
            "wall_edges": [float(x) for x in self.wall_edges],
            "wall_stress_fill": [float(x) for x in self.wall_stress_fill],
            "wall_stress_flow": [float(x) for x in self.wall_stress_flow],
        }


def save_hopper(path, res: HopperResult, **extra) -> None:
    """Store ``res`` as ``path`` (.json: its test, scalars, flow mode, wall stress profiles and
    the ``extra`` keys; NaN written as NaN) and its curves beside it (.npz), each written whole
    (a temporary file, then a rename), the curves first: a .json present means a complete
    run (as :func:`engine.shear.results.save_shear`)."""
    import json
    from pathlib import Path

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".npz.tmp")
    with open(tmp, "wb") as f:
        np.savez_compressed(f, **res.curves)
    tmp.replace(path.with_suffix(".npz"))
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps({**res.to_dict(), **extra}, indent=1, default=float))
    tmp.replace(path)


def load_hopper(path, curves: bool = False) -> HopperResult:
    """A run stored by :func:`save_hopper`: its test, scalars and wall stress profiles; with
    ``curves`` its curves from the .npz beside it (else none)."""
    import json
    from pathlib import Path

    path = Path(path)
    d = json.loads(path.read_text())
    c: dict[str, np.ndarray] = {}
    if curves:
        with np.load(path.with_suffix(".npz")) as z:
            c = {k: z[k] for k in z.files}
    return HopperResult(
        HopperTest.from_dict(d["test"]),
        c,
        np.array(d["wall_edges"], dtype=float),
        np.array(d["wall_stress_fill"], dtype=float),
        np.array(d["wall_stress_flow"], dtype=float),
        {k: float(v) for k, v in d["scalars"].items()},
    )
