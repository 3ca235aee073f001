"""What a scaling study needs of the hopper (its entry in :mod:`engine.study.kinds`): verdict
metrics, the values a run gives them, a step estimate, its table's columns and summary."""

from __future__ import annotations

import math

import numpy as np

from .driver import run_hopper
from .spec import HopperTest

#: The hopper's verdict metrics, (name, unit, tolerance, reason) as
#: :class:`engine.study.metrics.Metric` takes them (the study layer, above this one, builds
#: them: engine/study/kinds.py). Their tolerances are chosen, not measured: the spread of a
#: discharge rate between seeds of one hopper has not been measured yet (docs/HOPPER.md).
HOPPER_METRICS = (
    (
        "discharge_number",
        "1",
        0.10,
        "the mass discharge rate, over rho sqrt(g) B^(3/2) per depth (slot) or B^(5/2) "
        "(cone) so that a resolution control's smaller hopper under stronger gravity compares "
        "(for runs of one hopper the same relative error as the rate's), is what a hopper is "
        "designed for (a feeder's throughput); a coarse model within ten per cent is taken as "
        "close enough (a chosen figure: the seed-to-seed spread of the simulated rate is not "
        "measured yet)",
    ),
    (
        "bulk_density",
        "kg/m^3",
        0.03,
        "the settled fill's bulk density enters the discharge rate linearly (Beverloo: "
        "W ~ rho_b sqrt(g) B^(3/2) or B^(5/2)); 3 % as the uniaxial test's density",
    ),
)

#: The hopper's scalars a study's table carries beside its errors.
HOPPER_TABLE_SCALARS = {
    "discharge_number": "1",
    "discharge_rate": "kg/s",
    "discharge_rate_se": "kg/s",
    "arched": "1",
    "mass_flow_index": "1",
    "bulk_density": "kg/m^3",
    "outlet_diameters": "1",
}

#: The hopper's scalars a study's reference summary quotes.
HOPPER_SUMMARY = (
    "discharge_number",
    "discharge_rate",
    "discharge_rate_se",
    "stopped",
    "arched",
    "arch_time",
    "arch_span",
    "arch_height",
    "mass_flow_index",
    "bulk_density",
    "fill_height",
    "outlet_diameters",
    "wall_time",
    "particles",
)


def hopper_metric_values(result) -> dict[str, np.ndarray]:
    """Values of the hopper's verdict metrics of one :class:`HopperResult`: the steady
    discharge number [-] (the rate over :attr:`HopperTest.rate_scale`; NaN where the flow
    stopped before its window) and the settled fill's bulk density [kg/m^3]."""
    s = result.scalars
    return {
        "discharge_number": np.array([s["discharge_number"]]),
        "bulk_density": np.array([s["bulk_density"]]),
    }


def hopper_steps(test: HopperTest) -> float:
    """Rough step count of a hopper run: the settling's two free-fall times from the fill's
    top (the fill's height taken at ``solid_fraction``, times 1.5 for the poured lattice),
    and the discharge bounded by ``max_discharge_time`` (an upper estimate: the rate is what
    the run measures). The time step of a hopper depends on its scene's fall height
    (:func:`engine.hopper.driver.resolved_dt`)."""
    from .driver import resolved_dt

    h = _height_of(test)
    t = 2.0 * math.sqrt(2.0 * 1.5 * h / test.gravity) + test.max_discharge_time
    return t / resolved_dt(test)


def _height_of(test: HopperTest) -> float:
    """Height of the settled fill of ``test`` [m] at its ``solid_fraction``."""
    if test.fill_height is not None:
        return test.fill_height
    return test.height_holding(test.n_particles * test.mean_particle_volume / test.solid_fraction)


def run_hopper_kind(
    test, progress=None, checkpoint=None, backend=None, max_wall_time=None, wall_time_setting=None
):
    """The kind's run: :func:`run_hopper` with its checkpoint, the wall-time limit and the
    backend."""
    return run_hopper(
        test,
        progress,
        max_wall_time=max_wall_time,
        wall_time_setting=wall_time_setting,
        checkpoint=checkpoint,
        backend=backend,
    )


def hopper_row(result) -> dict:
    """A study table row's hopper columns."""
    s = result.scalars
    return {"overburden_ratio": 0.0, **{k: s[k] for k in HOPPER_TABLE_SCALARS}}
