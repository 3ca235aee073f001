"""The flow function a uniaxial tester measures: one sample's fill, then consolidation,
unloading, release and unconfined compression at each of several consolidation stresses
(docs/PHYSICS.md section 4).

The fill is the slow, seed-dependent part of a test and the same for every consolidation
stress, so it is run once and the stage driver is branched after it (a copy of its state,
as a checkpoint is: :mod:`engine.uniaxial.checkpoint`): each branch is exactly the run
:func:`engine.run_uniaxial` makes of the test at that consolidation stress, bit for bit,
at the cost of its later stages alone. The result gives the flow function, unconfined
strength sigma_c against consolidation stress sigma_1, its flowability ffc = sigma_1 /
sigma_c, and per branch the whole :class:`engine.UniaxialResult` (K0, stiffness, porosity).
"""

from __future__ import annotations

import math
import pickle
from dataclasses import dataclass, replace

from ..core.errors import ParameterError
from ..simulation.backend import check_backend
from .checkpoint import check_interval
from .driver import ProgressCallback, _Driver
from .results import UniaxialResult
from .spec import UniaxialTest

#: Most consolidation stresses a flow function takes.
MAX_STRESSES = 12


@dataclass(frozen=True)
class FlowFunction:
    """Unconfined strength against consolidation stress from one fill.

    Attributes: ``test`` (the base test; each branch is it at one consolidation stress),
    ``consolidation_stresses`` [Pa] (ascending), ``results`` (one
    :class:`engine.UniaxialResult` per stress)."""

    test: UniaxialTest
    consolidation_stresses: tuple[float, ...]
    results: tuple[UniaxialResult, ...]

    @property
    def strengths(self) -> tuple[float, ...]:
        """Unconfined strength sigma_c of each branch [Pa]."""
        return tuple(r.scalars["unconfined_strength"] for r in self.results)

    @property
    def ffc(self) -> tuple[float, ...]:
        """Flowability sigma_1 / sigma_c of each branch [-] (inf for a zero strength)."""
        return tuple(
            s1 / sc if sc > 0 else math.inf
            for s1, sc in zip(self.consolidation_stresses, self.strengths)
        )

    def points(self) -> list[dict]:
        """One row per branch: consolidation stress, strength, ffc, failed at a peak, K0,
        consolidated porosity (JSON-friendly)."""
        return [
            {
                "consolidation_stress": s1,
                "strength": r.scalars["unconfined_strength"],
                "ffc": f,
                "failed": bool(r.scalars["unconfined_failure"]),
                "k0": r.scalars.get("k0"),
                "consolidated_porosity": r.scalars["consolidated_porosity"],
            }
            for s1, r, f in zip(self.consolidation_stresses, self.results, self.ffc)
        ]


def flow_function(
    test: UniaxialTest,
    consolidation_stresses,
    progress: ProgressCallback | None = None,
    backend: str | None = None,
    max_wall_time: float | None = None,
    wall_time_setting: str = "max_wall_time",
) -> FlowFunction:
    """The flow function of ``test``'s sample: its fill once, then each of
    ``consolidation_stresses`` [Pa] (module docstring). ``test`` must have the unconfined
    stage; each stress must exceed its ``pre_stress``. ``progress`` hears the whole: branch
    k of n reports a ``fraction`` of (k + its own fraction) / n (the fill is branch 0's);
    ``max_wall_time`` [s] bounds the whole (fill and branches) as
    :func:`engine.run_uniaxial` bounds a run. Raises :class:`engine.ParameterError` naming
    the offending stress, or what :func:`engine.run_uniaxial` raises."""
    stresses = tuple(sorted(float(s) for s in consolidation_stresses))
    if not 1 <= len(stresses) <= MAX_STRESSES:
        raise ParameterError(
            "flow_function.consolidation_stresses",
            len(stresses),
            f"1 to {MAX_STRESSES} stresses",
        )
    if not test.unconfined:
        raise ParameterError(
            "flow_function.test.unconfined", False, "True (a flow function needs strengths)"
        )
    tests = []
    for k, s in enumerate(stresses):
        if not (math.isfinite(s) and s > test.pre_stress):
            raise ParameterError(
                f"flow_function.consolidation_stresses[{k}]",
                s,
                f"> pre_stress = {test.pre_stress:g} Pa",
            )
        tests.append(replace(test, consolidation_stress=s))
    backend = check_backend(backend, "flow_function.backend")
    if max_wall_time is not None:
        check_interval(max_wall_time, "flow_function.max_wall_time")
    n = len(tests)

    def branch_progress(k: int) -> ProgressCallback | None:
        if progress is None:
            return None
        return lambda p: progress(replace(p, fraction=(k + p.fraction) / n))

    d = _Driver(tests[0], branch_progress(0), None, None, backend)
    d.max_wall_time, d.wall_time_setting = max_wall_time, wall_time_setting
    d.begin("fill")
    d.loop()
    d.end("fill")
    filled = pickle.dumps(d, protocol=pickle.HIGHEST_PROTOCOL)
    results = []
    for k, t in enumerate(tests):
        branch = pickle.loads(filled)
        branch.test = t
        branch.progress = branch_progress(k)
        results.append(branch.run())
    return FlowFunction(test, stresses, tuple(results))


__all__ = ["MAX_STRESSES", "FlowFunction", "flow_function"]
