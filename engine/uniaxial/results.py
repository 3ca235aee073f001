"""What a uniaxial test gives back: the curves of each stage, the scalars, the progress reports
(SI units in :data:`CURVE_UNITS` and :data:`SCALAR_UNITS`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..simulation.snapshot import Snapshot
from .spec import UniaxialTest

#: Units of the curves of every stage.
CURVE_UNITS = {
    "time": "s",
    "strain": "1",
    "stress_top": "Pa",
    "stress_bottom": "Pa",
    "porosity": "1",
    "coordination": "1",
    "kinetic_energy": "J",
    "inertial_number": "1",
    "platen_gap": "m",
    "porosity_interior": "1",
    "coordination_interior": "1",
    "stress_lateral": "Pa",
    "stress_vertical": "Pa",
    "stress_interior": "Pa",
}


#: How the progress message of a run resumed from its checkpoint begins.
RESUMED = "resumed from its checkpoint"


@dataclass(frozen=True)
class Progress:
    """What a progress callback receives.

    Attributes: ``fraction`` of the whole test in [0, 1], ``stage`` name, ``stage_fraction``
    in [0, 1], simulated ``time`` [s], ``steps`` so far, ``message``.
    """

    fraction: float
    stage: str
    stage_fraction: float
    time: float
    steps: int
    message: str = ""


ProgressCallback = Callable[[Progress], object]


SnapshotCallback = Callable[[Snapshot], object]


@dataclass
class StageResult:
    """Curves of one stage (1-D arrays of equal length, units in :data:`CURVE_UNITS`), the
    particle positions [m] and radii [m] at its end, and the
    :class:`engine.simulation.snapshot.Snapshot` of its end (particles and contacts; None for a
    result read back from a curves-only file)."""

    name: str
    curves: dict[str, np.ndarray]
    positions: np.ndarray
    radii: np.ndarray
    steps: int
    snapshot: Snapshot | None = None


@dataclass
class UniaxialResult:
    """Result of :func:`run_uniaxial`.

    Attributes: ``test`` (the parameters), ``stages`` (name -> :class:`StageResult`, in order),
    ``scalars`` (name -> value; see :data:`SCALAR_UNITS`).
    """

    test: UniaxialTest
    stages: dict[str, StageResult]
    scalars: dict[str, float]

    def save_snapshots(self, directory, label: str = "") -> list:
        """Write the stage-end snapshots into ``directory`` (ParaView files and a PNG section
        per stage; see :func:`engine.io.vtkhdf.save`); returns the paths."""
        from ..io.vtkhdf import save

        return save(self, directory, label)


#: Units of the scalars of a :class:`UniaxialResult`.
SCALAR_UNITS = {
    "unconfined_strength": "Pa",
    "unconfined_failure": "1",
    "strain_at_peak": "1",
    "loading_stiffness": "Pa",
    "unloading_stiffness": "Pa",
    "consolidated_porosity": "1",
    "consolidated_porosity_interior": "1",
    "thickness_diameters": "1",
    "interior_margin": "m",
    "height_diameters": "1",
    "particles": "1",
    "steps": "1",
    "dt": "s",
    "wall_time": "s",
    "setup_time": "s",
    "particle_steps": "1",
    "threads": "1",
    "max_inertial_number": "1",
    "k0": "1",
    "unconfined_strength_platen": "Pa",
    "unconfined_strength_interior": "Pa",
    "self_weight_stress": "Pa",
    "strength_from_interior": "1",
    "dt_fraction": "1",
    "dt_critical": "s",
    "dt_limited_by_wall": "1",
    "impact_speed": "m/s",
    "inertial_number_held": "1",
    "inertial_number_held_max": "1",
}
