"""Numba flags and the numerical policy of the engine, in one place.

Every compiled kernel takes its options from here so that caching, the error model and the
parallel layout are the same everywhere. The policy constants are documented defaults; the
ones a user may want to change are also keyword arguments of :class:`engine.Simulation`.
"""

from __future__ import annotations

import os
from pathlib import Path

import numba

# The engine's thread budget is numba's thread count (``numba.get_num_threads()``, per calling
# thread: ``numba.set_num_threads`` limits it), and reading it starts numba's threading layer.
# OpenMP first: numba otherwise prefers TBB whenever a libtbb is installed (other packages
# pull one in), which can hang at interpreter exit. The step kernel itself runs its thread
# team on threads of its own (engine.simulation.simulation.run_team), not in numba's parallel
# regions. NUMBA_THREADING_LAYER, when set, wins.
if "NUMBA_THREADING_LAYER" not in os.environ and "NUMBA_THREADING_LAYER_PRIORITY" not in os.environ:
    numba.config.THREADING_LAYER_PRIORITY = ["omp", "workqueue", "tbb"]

#: Options of every serial kernel. ``error_model="numpy"`` makes a division by zero give inf
#: (caught by the instability checks) instead of raising inside compiled code, and removes
#: the exception checks from the hot loops. No fastmath: NaN checks must stay meaningful.
NJIT = {"cache": True, "nogil": True, "error_model": "numpy"}

#: Options of the contact-law kernels the step calls per contact: inlined at numba's IR level
#: into the pair and the particle pass. Left to LLVM, the composition was compiled as a call
#: with about 30 arguments spilled to the stack and its switches tested at run time; inlined,
#: the scene's compile-time flags fold its unused branches away.
NJIT_INLINE = {**NJIT, "inline": "always"}

#: Particles per parallel work item. Fixed (not derived from the thread count) so that every
#: reduction is summed over the same chunks in the same order whatever the thread count:
#: results are bit-identical with 1 and with N threads.
CHUNK = 64

#: Waiting in the step kernel's thread team (one team per call of the kernel; threads meet
#: at a barrier between the passes of a step instead of forking and joining twice per step).
#: A waiting thread spins for at most ``TEAM_SPIN_CYCLES`` time-stamp cycles (about 20 us at
#: 2.5 GHz: longer than the usual wait of a balanced team, about one chunk, shorter than
#: waking a sleeping thread, about 60 us on the 2-core VM of benchmarks/README.md), then
#: sleeps on a futex until the last thread arrives, so that it never holds a core another
#: process needs. The first thread of a call waits at most ``TEAM_JOIN_WAIT_US``
#: microseconds (polling every ``TEAM_POLL_US``) for the others to start and otherwise runs
#: that call alone.
TEAM_SPIN_CYCLES = 50_000
TEAM_POLL_US = 20
TEAM_JOIN_WAIT_US = 5000

#: ``Simulation(threads=None)`` runs one thread per this many particles [-]. Measured on 2
#: cores with the thread team (2026-11-26, settled beds, full law, 2 threads against 1): on an
#: otherwise idle machine 500 particles ran 1.77x faster, 1,000 1.82x, 2,025 1.5x to 2.3x;
#: with a second such process on the cores (both asking for 2 threads) 500 particles ran at
#: 0.55x to 0.62x, 1,000 at 0.89x to 0.93x, 2,025 at 0.81x to 1.15x. 1,000 per thread: a
#: second thread from 2,000 particles, where it gains alone and costs little when shared.
PARTICLES_PER_THREAD = 1000

#: ``Simulation(dt=None)`` takes this fraction of the smallest time-step limit of
#: :func:`engine.critical_time_step` (oscillation limits, Rayleigh time, Hertz contact time).
DT_FRACTION = 0.15

#: A contact whose overlap exceeds this fraction of the smaller radius stops the run with
#: :class:`engine.InstabilityError` (the contact laws are meaningless that deep).
MAX_OVERLAP_FRACTION = 0.5

#: A particle travelling more than this fraction of its radius in one step stops the run with
#: :class:`engine.InstabilityError` ("runaway kinetic energy": contacts are no longer resolved).
MAX_STEP_FRACTION = 0.2

#: Default Verlet skin as a fraction of the largest radius [-]. The list is rebuilt when some
#: particle has moved more than half the skin since the last build.
SKIN_FRACTION = 0.2

#: Angular speed below which the rolling-resistance torque is skipped [rad/s].
ROLLING_OMEGA_EPS = 1e-9

#: Largest accepted ratio of the largest to the smallest radius in a scene [-].
MAX_RADIUS_RATIO = 3.0


def cache_dir() -> Path:
    """Directory of the specialised kernel sources and their numba cache.

    ``DEMSCALE_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/demscale`` or ``~/.cache/demscale``.
    """
    env = os.environ.get("DEMSCALE_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "demscale"
