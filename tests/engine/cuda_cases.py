"""Differential cases of the CUDA backend against the CPU kernel, run under numba-cuda's
simulator in a process of their own (tests/engine/test_cuda.py starts it, once a session):

    NUMBA_ENABLE_CUDASIM=1 python -m tests.engine.cuda_cases NAME:LAUNCH:KERNELS ...

The cases named run one after the other, each with its launch and kernel mode
(:func:`run_cases`), and the process prints one JSON object: each case's result, or its
error, under its spec.

Each case builds a tiny scene (a few dozen particles), steps a CPU and a CUDA simulation side
by side in short runs and compares them after every run: positions, velocities, angular
velocities, wall forces and positions, the contacts with their history (largest overlap,
tangential spring). Its result: the largest difference of each quantity relative to its
largest magnitude, the counts that show the case exercised what it names (contacts, wall
contacts, rebuilds), and for some cases a second CUDA run (bit-identical?) or the
instability both raised.
"""

from __future__ import annotations

import json
import os
import sys
import traceback

import numpy as np

import engine
from engine.kernel import specialise
from tests import naive
from tests.engine.helpers import rel_diff as _rel  # also cuda_measure_cases'

R = 2.5e-3

FULL = engine.BilinearAdhesive(
    k1=5e3, k2=2.5e4, f0=-0.2, kadh=1e3, mu_s=0.5, mu_r=0.002, restitution=0.4
)
ELASTIC = engine.BilinearAdhesive(k1=5e3, k2=5e3, mu_s=0.3, restitution=0.7)
EEPA = engine.EEPA(
    k1=2e5, k2=1e6, f0=-0.05, kadh=5e4, n=1.5, chi=1.5, mu_s=0.4, mu_r=0.002, restitution=0.5
)
EEPA_NORMAL_CAP = engine.EEPA(
    k1=2e5,
    k2=1e6,
    f0=-0.05,
    kadh=5e4,
    n=1.5,
    chi=1.5,
    mu_s=0.4,
    restitution=0.5,
    friction_cap="normal",
)
HERTZ = engine.HertzMindlin(E=5e7, nu=0.25, restitution=0.5, mu=0.3, mu_r=0.002)
WALL_LAW = engine.HertzMindlin(E=1e8, nu=0.25, restitution=0.5, mu=0.3, mu_r=0.002)


def scene(
    law,
    n=36,
    side=0.016,
    periodic=(True, True, False),
    walls=True,
    gravity=True,
    speed=0.05,
    spin=20.0,
    seed=3,
):
    lengths = np.array([side, side, side])
    pos, rad = naive.rsa_packing(n, lengths, 0.8 * R, R, seed, max_overlap=0.1, periodic=periodic)
    rng = np.random.default_rng(seed)
    planes = []
    if walls:
        # each wall touches the outermost particles (overlap 0.02 R): wall contacts at once
        lo = (pos - rad[:, None]).min(axis=0) + 0.02 * R
        hi = (pos + rad[:, None]).max(axis=0) - 0.02 * R
        planes = [
            engine.Plane((0, 0, lo[2]), (0, 0, 1)),
            engine.Plane((0, 0, hi[2]), (0, 0, -1), velocity=(0, 0, -0.05)),
        ]
        if not periodic[0]:
            planes += [
                engine.Plane((lo[0], 0, 0), (1, 0, 0)),
                engine.Plane((hi[0], 0, 0), (-1, 0, 0), velocity=(-0.02, 0, 0)),
            ]
    return engine.Scene(
        pos,
        rad,
        2000.0,
        velocities=rng.normal(0, speed, pos.shape),
        angular_velocities=rng.normal(0, spin, pos.shape),
        box=[(0, L) for L in lengths],
        periodic=periodic,
        walls=planes,
        gravity=(0, 0, -9.81) if gravity else (0, 0, 0),
        pair_law=law,
        wall_law=WALL_LAW,
        wall_material=engine.WallMaterial(),
    )


class Compare:
    """Running record of the largest relative differences between two simulations."""

    QUANTITIES = ("positions", "velocities", "angular_velocities", "wall_forces", "wall_positions")

    def __init__(self):
        self.rel = dict.fromkeys(
            (*self.QUANTITIES, "max_overlaps", "tangential_springs", "pairs"), 0.0
        )
        self.bit_identical = True
        self.contacts = 0
        self.wall_contacts = 0

    def __call__(self, cpu, gpu):
        for q in self.QUANTITIES:
            a, b = getattr(cpu, q), getattr(gpu, q)
            self.rel[q] = max(self.rel[q], _rel(a, b))
            self.bit_identical &= bool(np.array_equal(a, b))
        ca, cb = cpu.contacts(), gpu.contacts()
        same = ca.pairs.shape == cb.pairs.shape and np.array_equal(ca.pairs, cb.pairs)
        self.rel["pairs"] = max(self.rel["pairs"], 0.0 if same else float("inf"))
        if same:
            for q in ("max_overlaps", "tangential_springs"):
                self.rel[q] = max(self.rel[q], _rel(getattr(ca, q), getattr(cb, q)))
        if not np.array_equal(cpu.contact_counts(), gpu.contact_counts()):
            self.rel["pairs"] = float("inf")
        self.contacts += len(ca.pairs)
        self.wall_contacts += len(ca.wall_particles)
        assert cpu.steps == gpu.steps


def run_pair(sc, blocks, steps, compare, edits=None, **kw):
    cpu = engine.Simulation(sc, backend="cpu", **kw)
    gpu = engine.Simulation(sc, backend="cuda", **kw)
    assert gpu.backend == "cuda" and type(gpu).__name__ == "CudaSimulation"
    r0 = (cpu.n_rebuilds, gpu.n_rebuilds)
    compare(cpu, gpu)
    for b in range(blocks):
        if edits and b in edits:
            for sim in (cpu, gpu):
                edits[b](sim)
            compare(cpu, gpu)
        cpu.run(steps)
        gpu.run(steps)
        compare(cpu, gpu)
    return cpu, gpu, (cpu.n_rebuilds - r0[0], gpu.n_rebuilds - r0[1])


def case(name: str) -> dict:
    cmp = Compare()
    out: dict = {"case": name}
    if name == "bilinear-walls":
        # the full bilinear law, periodic x and y, a moving platen, gravity; the periodicity
        # is then removed (x and y open: the grid spans the particles by the device's
        # bounds reduction) and a wall re-aimed between runs (set_* on the device state); a
        # skin of 0.1 R rebuilds the lists 4 times in 24 steps (0.05 R: 8 times, 8 s against 3 s
        # in the simulator)
        at_edit = {}

        def open_axes(sim):
            at_edit[sim.backend] = sim.n_rebuilds
            sim.set_periodic((False, False, False))

        edits = {
            3: open_axes,
            4: lambda s: s.set_wall_velocity(1, (0.0, 0.0, -0.2)),
            5: lambda s: s.set_velocities(angular_velocities=np.zeros((s.n, 3))),
            2: lambda s: s.set_wall_position(1, s.wall_positions[1] + (0, 0, -0.1 * R)),
        }
        cpu, gpu, rb = run_pair(scene(FULL, speed=0.3), 6, 4, cmp, edits=edits, skin=0.1 * R)
        # the lists built with every axis open (the device's bounds reduction), on each side
        out["rebuilds_open"] = [sim.n_rebuilds - at_edit[sim.backend] for sim in (cpu, gpu)]
    elif name == "periodic-rebuilds":
        # fully periodic, no walls, no gravity, fast particles and a thin skin: rebuilds (4
        # in 30 steps; a skin of 0.02 R made 14, each a hundred-odd launches in the
        # simulator), pairs across every face
        cpu, gpu, rb = run_pair(
            scene(ELASTIC, periodic=(True, True, True), walls=False, gravity=False, speed=0.05),
            5,
            6,
            cmp,
            skin=0.1 * R,
        )
        out["n_entries"] = [cpu.n_neighbour_entries, gpu.n_neighbour_entries]
    elif name == "eepa":
        cpu, gpu, rb = run_pair(scene(EEPA), 5, 5, cmp)
    elif name == "eepa-normal-cap":
        cpu, gpu, rb = run_pair(scene(EEPA_NORMAL_CAP, periodic=(True, False, False)), 5, 5, cmp)
    elif name == "hertz":
        # Hertz-Mindlin pairs, periodic x and y, walls on z (the kernel of the CPU tests'
        # Hertz cells: no kernel of its own to compile); fast particles, a thin skin:
        # rebuilds. (Open axes, where the grid spans the particles by the device's bounds
        # reduction, are bilinear-walls' once its periodicity is removed.)
        cpu, gpu, rb = run_pair(scene(HERTZ, speed=0.5), 5, 5, cmp, skin=0.05 * R)
    elif name == "determinism":
        sc = scene(FULL, speed=0.5)  # a skin of 0.1 R: two builds in 20 steps
        a = engine.Simulation(sc, backend="cuda", skin=0.1 * R)
        b = engine.Simulation(sc, backend="cuda", skin=0.1 * R)
        for sim in (a, b):
            sim.run(20)
        out["launch"] = "persistent" if a._dev.persistent else "passes"
        out["bit_identical_twice"] = all(
            np.array_equal(getattr(a, q), getattr(b, q)) for q in Compare.QUANTITIES
        )
        out["rebuilds"] = [a.n_rebuilds, b.n_rebuilds]
        return out
    elif name == "instability":
        sc = scene(ELASTIC, walls=False, gravity=False, speed=0.05)
        v = sc.velocities.copy()
        v[5] = (1e3, 0.0, 0.0)  # far beyond max_step_fraction per step
        sc = engine.Scene(
            sc.positions,
            sc.radii,
            2000.0,
            velocities=v,
            box=sc.box,
            periodic=sc.periodic,
            pair_law=ELASTIC,
        )
        errors = []
        for backend in ("cpu", "cuda"):
            sim = engine.Simulation(sc, backend=backend, dt=1e-5)
            try:
                sim.run(10)
                errors.append(None)
            except engine.InstabilityError as e:
                errors.append([e.reason, e.step, list(e.particles)])
        out["errors"] = errors
        return out
    else:
        raise SystemExit(f"unknown case {name}")
    out.update(launch="persistent" if gpu._dev.persistent else "passes")
    out.update(
        rel=cmp.rel,
        bit_identical=cmp.bit_identical,
        contacts=cmp.contacts,
        wall_contacts=cmp.wall_contacts,
        rebuilds=list(rb),
        steps=cpu.steps,
        # what the scene exercised (its own switches, whatever DEMSCALE_KERNELS compiled)
        features=[
            k if v is True else f"{k}={v}"
            for k, v in specialise.scene_features(gpu.scene).items()
            if v
        ],
        kernel_mode=specialise.kernel_mode(),
    )
    return out


CASES = (
    "bilinear-walls",
    "periodic-rebuilds",
    "eepa",
    "eepa-normal-cap",
    "hertz",
    "determinism",
    "instability",
)


def _shared_arrays_once_per_block() -> None:
    """Mend a race in numba-cuda's simulator (0.x, ``FakeCUDAShared.array``): it looks a
    shared array up by call site and creates it when absent, without a lock, so two of a
    block's threads arriving together may each get an array of their own. A reduction in
    shared memory then reads only its own thread's part: the largest displacement of a step
    came out too small now and then, and one of two identical runs rebuilt its list once
    more (CI, stop 31: rebuilds [4, 5] with bit-identical states). On a device the block has
    one shared array; here the first thread's array is made the block's, under a lock."""
    import threading
    import traceback

    from numba.core import types
    from numba.cuda.simulator import kernelapi
    from numba.np import numpy_support

    cls = kernelapi.FakeCUDAShared
    if getattr(cls, "_demscale_locked", False):
        return
    unlocked = cls.array
    lock = threading.Lock()

    def array(self, shape, dtype, alignment=None):
        if shape == 0 or alignment is not None:  # dynamic shared memory; refusals
            return unlocked(self, shape, dtype, alignment)
        if isinstance(dtype, types.Type):
            dtype = numpy_support.as_dtype(dtype)
        caller = traceback.extract_stack(sys._getframe())[-2][0:2]  # the kernel's line
        with lock:
            res = self._allocations.get(caller)
            if res is None:
                res = self._allocations[caller] = np.empty(shape, dtype)
        return res

    cls.array = array
    cls._demscale_locked = True


def run_cases(case_fn, specs: list[str]) -> dict:
    """Each ``NAME:LAUNCH:KERNELS`` of ``specs`` run by ``case_fn(NAME)`` in this process in
    turn, with ``DEMSCALE_CUDA_LAUNCH`` and ``DEMSCALE_KERNELS`` set for it (read where a
    simulation is made or its device launch chosen, within the case): {spec: its result, or
    {"error": its traceback}}, so that one case's exception hides no other's (a hang or a
    crash of the process loses them all: tests/engine/test_cuda.py's ``simulator_cases``
    then gives each the process's error)."""
    out = {}
    for spec in specs:
        name, launch, kernels = spec.split(":")
        os.environ["DEMSCALE_CUDA_LAUNCH"] = launch
        os.environ["DEMSCALE_KERNELS"] = kernels
        try:
            out[spec] = case_fn(name)
        except Exception:
            out[spec] = {"error": traceback.format_exc()[-4000:]}
    return out


def main(case_fn) -> None:
    """The cases named on the command line, under the simulator, as one JSON line."""
    sys.setswitchinterval(5e-5)  # the simulator's threads hand the GIL over faster
    _shared_arrays_once_per_block()
    print(json.dumps(run_cases(case_fn, sys.argv[1:])))


if __name__ == "__main__":
    main(case)
