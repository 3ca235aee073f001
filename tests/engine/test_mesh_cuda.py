"""Mesh walls on the CUDA backend against the CPU kernel, under numba-cuda's simulator.

The cases run in one process of their own, once a session (``python -m
tests.engine.test_mesh_cuda CASE:LAUNCH:KERNELS ...`` with ``NUMBA_ENABLE_CUDASIM=1``, as
tests/engine/test_cuda.py runs tests/engine/cuda_cases.py): a dozen particles in a V-shaped
trough of triangles (concave edges: two contacts at once) with a plane at each end and a
gate mesh moving under them, stepped side by side on both backends in short runs;
positions, velocities, spins, the forces on the planes and the meshes, and every mesh
contact are compared after each run. Small on purpose: the simulator runs every GPU thread
as a Python thread.
"""

from __future__ import annotations

import numpy as np
import pytest

import engine
from tests.engine.helpers import rel_diff
from tests.engine.test_cuda import case_result, needs_numba_cuda, simulator_cases

#: the tolerance of tests/engine/test_cuda.py (issue 21): relative to each quantity's largest
REL = 1e-12
R = 2.5e-3


def trough(width=0.012, depth=0.004, length=0.02, n=3):
    """A V-shaped trough along x (two inclined strips of ``n`` x 1 quads) [m]."""
    xs = np.linspace(0.0, length, n + 1)
    ys = (-width / 2, 0.0, width / 2)
    zs = (depth, 0.0, depth)
    v = np.array([[x, y, z] for x in xs for y, z in zip(ys, zs)])
    tri = []
    for i in range(n):
        for j in range(2):
            a = 3 * i + j
            b, c, d = a + 3, a + 4, a + 1
            tri += [[a, b, c], [a, c, d]]
    return engine.Mesh(v, tri)


def gate(x0=0.004, size=0.004, z=0.00186, speed=-3.0):
    """A small square plate (two triangles) over the trough's floor, sliding along -x."""
    h = size / 2
    v = [[x0 - h, -h, z], [x0 + h, -h, z], [x0 + h, h, z], [x0 - h, h, z]]
    return engine.Mesh(v, [[0, 1, 2], [0, 2, 3]], velocity=(speed, 0.0, 0.0))


def mesh_scene(n=6, seed=4):
    """``n`` particles in two rows touching the trough's sides (the first two also the
    gate), the third in the trough's groove touching both sides."""
    rng = np.random.default_rng(seed)
    k = np.arange(n)
    pos = np.stack([0.003 + 0.0045 * (k // 2), 0.0022 * (2 * (k % 2) - 1), 0.00385 + 0 * k], 1)
    pos[2] = (0.0172, 0.0, 0.0023)
    pos += rng.uniform(-2e-5, 2e-5, pos.shape)
    pos[0, 0] = 0.00199  # on the plane x = 0 and on the gate's edge
    law = engine.HertzMindlin(E=1e8, nu=0.25, restitution=0.5, mu=0.3, mu_r=0.01)
    return engine.Scene(
        pos,
        0.8 * R,
        2000.0,
        velocities=rng.normal(0, 0.05, (n, 3)),
        angular_velocities=rng.normal(0, 30.0, (n, 3)),
        gravity=(0.0, 0.0, -9.81),
        # a bilinear pair law (Hertz pairs on the device are tests/engine/cuda_cases.py's):
        # the CPU kernel of the CPU mesh tests and the conical hopper's, none of its own
        pair_law=engine.BilinearAdhesive(k1=5e3, k2=5e3, mu_s=0.3, restitution=0.5),
        walls=[engine.Plane((0, 0, 0), (1, 0, 0)), engine.Plane((0.02, 0, 0), (-1, 0, 0))],
        meshes=[trough(), gate()],
        wall_law=law,
        wall_material=engine.WallMaterial(),
    )


QUANTITIES = (
    "positions",
    "velocities",
    "angular_velocities",
    "wall_forces",
    "mesh_forces",
    "mesh_displacements",
)


#: The module's cases (NAME:LAUNCH:KERNELS), run in one process (tests/engine/cuda_cases.py's
#: ``run_cases``), once for the whole session.
SPECS = ("trough:persistent:general", "trough:passes:general", "hopper:persistent:general")


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> dict:
    """Every case of :data:`SPECS`, in a process of their own under the simulator (it must be
    on before numba.cuda is first imported; this process never imports it)."""
    return simulator_cases(tmp_path_factory, "tests.engine.test_mesh_cuda", SPECS)


def _run_case(results: dict, name: str, launch: str) -> dict:
    return case_result(results, f"{name}:{launch}:general")


@needs_numba_cuda
@pytest.mark.parametrize("launch", ["persistent", "passes"])
def test_cuda_meshes_follow_the_cpu(results, launch):
    r = _run_case(results, "trough", launch)
    assert r["launch"] == launch
    for quantity, rel in r["rel"].items():
        assert rel <= REL, (quantity, rel, r)
    assert {"walls", "meshes", "wall_friction", "wall_rolling"} <= set(r["features"]), r
    assert min(r["mesh_contacts"]) > 0 and r["most_contacts"] == 2, r  # the groove's two
    assert r["wall_contacts"] > 0, r  # planes and meshes side by side
    # the device finds the candidates as often as the CPU, the gate's drift among the causes
    assert r["rebuilds"][0] == r["rebuilds"][1] >= 3, r


@needs_numba_cuda
def test_a_settled_hopper_discharges_on_the_device_as_on_the_cpu(results):
    """The hopper's driver on the CUDA backend: a fill settled on the CPU, carried to the
    device (the state of a checkpoint), opened and discharged for a few samples on each
    backend side by side; the sink (``park_below``, a kernel on the device) on the fill's
    lowest grains."""
    r = _run_case(results, "hopper", "persistent")
    for quantity, rel in r["rel"].items():
        assert rel <= REL, (quantity, rel, r)
    assert r["parked"] == [12, 12] and r["wall_contacts"] > 10, r  # the sink and the walls
    assert r["on_gate"] > 0 and r["still_on_gate"] == [0, 0], r  # their contacts deleted
    assert r["samples"] >= 3 and r["same_regions"], r
    assert r["backends"] == ["cpu", "cuda"], r


def hopper_case() -> dict:
    """:func:`test_a_settled_hopper_discharges_on_the_device_as_on_the_cpu`'s case."""
    import copy
    import math
    from dataclasses import replace

    from engine.cuda import CudaSimulation
    from engine.hopper.driver import HopperRun

    d = 2 * R
    t = engine.HopperTest(outlet_width=6 * d, particles=100)
    cpu = HopperRun(t, backend="cpu")
    cpu.settle()
    gpu = copy.copy(cpu)
    gpu.sim = CudaSimulation.__new__(CudaSimulation)
    gpu.sim.__setstate__(copy.deepcopy(cpu.sim.__getstate__()))
    gpu.masses = cpu.masses.copy()
    rel = {"velocities": 0.0, "positions": 0.0, "kinetic_energy": 0.0, "wall_stress": 0.0}

    def compare():
        for q in ("positions", "velocities"):
            rel[q] = max(rel[q], rel_diff(getattr(cpu.sim, q), getattr(gpu.sim, q)))
        ke = (cpu.sim.kinetic_energy(), gpu.sim.kinetic_energy())
        rel["kinetic_energy"] = max(rel["kinetic_energy"], abs(ke[0] - ke[1]) / max(ke))
        ws = (cpu.wall_stress(cpu.edges), gpu.wall_stress(gpu.edges))
        rel["wall_stress"] = max(rel["wall_stress"], rel_diff(*ws))

    compare()
    walls = int(np.isin(cpu.sim.mesh_contacts().meshes, cpu.geo.wall_meshes).sum())
    # the sink on the fill's 12 lowest grains (the lattice's sites, far below), the rest
    # thrown at 1 m/s (no grain reaches the sink in this short a discharge)
    rng = np.random.default_rng(3)
    v = rng.normal(0.0, 1.0, (cpu.sim.n, 3))
    low = float(np.sort(cpu.sim.positions[:, 2])[12])
    lowest = np.nonzero(cpu.sim.positions[:, 2] < low)[0]
    for run in (cpu, gpu):
        run.sim.set_velocities(v)
    # they lie on the gate: their mesh contacts go with them
    on_gate = int(np.isin(cpu.sim.mesh_contacts().particles, lowest).sum())
    for run in (cpu, gpu):
        run.sim.park_below(low, run.geo.parking)
    compare()
    rel["radii"] = rel_diff(cpu.sim.radii, gpu.sim.radii)
    parked = [int((run.sim.radii == 0.0).sum()) for run in (cpu, gpu)]
    still = [int(np.isin(run.sim.mesh_contacts().particles, lowest).sum()) for run in (cpu, gpu)]
    # the gate opened and a few samples of the discharge (four steps apart), on each backend
    few = replace(t, output_interval=4 * cpu.dt, max_discharge_time=10 * cpu.dt)
    results = []
    for run in (cpu, gpu):
        run.test = few
        run.sample_steps = 4
        run.sink_steps = 3  # the sink's kernel between the samples too
        results.append(run.discharge())
    compare()
    a, b = (r.curves for r in results)
    for k in ("discharged_mass", "remaining_mass", "wall_speed", "kinetic_energy"):
        x, y = np.nan_to_num(a[k]), np.nan_to_num(b[k])
        rel[f"curve {k}"] = rel_diff(x, y)
    regions = [run.regions() for run in (cpu, gpu)]
    same = all(np.array_equal(p, q) for p, q in zip(*regions))
    assert math.isfinite(rel["positions"])
    return {
        "rel": rel,
        "parked": parked,
        "on_gate": on_gate,
        "still_on_gate": still,
        "wall_contacts": walls,
        "samples": len(a["time"]),
        "same_regions": same,
        "backends": [cpu.sim.backend, gpu.sim.backend],
    }


def case(name: str) -> dict:
    if name == "hopper":
        return hopper_case()
    if name != "trough":
        raise SystemExit(f"unknown case {name}")
    sc = mesh_scene()
    kw = {"dt": 2e-6, "skin": 0.05 * R}
    cpu = engine.Simulation(sc, backend="cpu", **kw)
    gpu = engine.Simulation(sc, backend="cuda", **kw)
    rel = dict.fromkeys((*QUANTITIES, "mesh_overlaps", "mesh_points"), 0.0)
    contacts = []
    most = walls = 0
    for block in range(8):
        if block == 4:  # a host edit: the gate turns back
            for sim in (cpu, gpu):
                sim.set_mesh_velocity(1, (2.0, 0.0, 0.0))
        if block:
            cpu.run(8)
            gpu.run(8)
        for q in QUANTITIES:
            rel[q] = max(rel[q], rel_diff(getattr(cpu, q), getattr(gpu, q)))
        a, b = cpu.mesh_contacts(), gpu.mesh_contacts()
        if not (np.array_equal(a.particles, b.particles) and np.array_equal(a.meshes, b.meshes)):
            rel["mesh_points"] = float("inf")
        else:
            rel["mesh_overlaps"] = max(rel["mesh_overlaps"], rel_diff(a.overlaps, b.overlaps))
            rel["mesh_points"] = max(rel["mesh_points"], rel_diff(a.points, b.points))
        contacts.append(len(a.particles))
        most = max(most, int(np.max(np.bincount(a.particles))) if a.particles.size else 0)
        walls += len(cpu.contacts().wall_particles)
        assert cpu.steps == gpu.steps
    return {
        "rel": rel,
        "mesh_contacts": contacts,
        "most_contacts": most,
        "wall_contacts": walls,
        "rebuilds": [cpu.n_rebuilds, gpu.n_rebuilds],
        "launch": "persistent" if gpu._dev.persistent else "passes",
        "features": [k for k, v in gpu.features.items() if v is True],
    }


if __name__ == "__main__":
    from tests.engine.cuda_cases import main

    main(case)
