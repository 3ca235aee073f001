"""Cases of the device measures (engine.cuda.measures) and of simulations stepped side by side
on one device (engine.cuda.batch), run under numba-cuda's simulator in a process of their own
(tests/engine/test_cuda_measures.py starts it, once a session):

    NUMBA_ENABLE_CUDASIM=1 python -m tests.engine.cuda_measure_cases NAME:LAUNCH:KERNELS ...

(tests/engine/cuda_cases.py's ``run_cases``: one JSON object, each case's result under its
spec.) Tiny scenes of tests/engine/cuda_cases.py (a few dozen particles between two platens,
periodic in x and y), a few steps each.
"""

from __future__ import annotations

import numpy as np

import engine
from engine.uniaxial.driver import cap_speed, sample_measures
from tests.engine.cuda_cases import FULL, R, _rel, scene

KEYS = ("coordination", "por_in", "coord_in", "s_lat", "s_ver", "s_in", "ke")


def host_measures(sim, f, gap, area, margin) -> dict:
    """The host's measures of the CUDA simulation's state: the state pulled, then the CPU
    class's methods (which read only the host arrays) on it."""
    from engine.cuda.simulation import CudaSimulation

    sim._pull_all()
    sim.__class__ = engine.Simulation
    try:
        return sample_measures(sim, f, gap, area, margin, 2, device=False)
    finally:
        sim.__class__ = CudaSimulation


def measures_case() -> dict:
    """The device's measures and the host's on the same state, after a few steps of a
    compressed bed (contacts across the interior window's edges and with both platens)."""
    sc = scene(FULL, speed=0.3)
    sim = engine.Simulation(sc, backend="cuda", skin=0.05 * R)
    twin = engine.Simulation(sc, backend="cuda", skin=0.05 * R)  # the same steps and edits
    out: dict = {"rel": {}, "abs": {}, "samples": 0}
    area = float(sc.box[0][1] - sc.box[0][0]) * float(sc.box[1][1] - sc.box[1][0])
    for _ in range(2):
        sim.run(4)
        twin.run(4)
        f = sim.wall_forces
        w = sim.wall_positions
        gap = float(w[1, 2] - w[0, 2])
        margin = 0.3 * gap
        before = sim.pull_counts
        for s in (sim, twin):  # as drive() does before a sample
            s.set_wall_velocity(1, (0.0, 0.0, -0.01 * (out["samples"] + 1)))
        dev = sample_measures(sim, f, gap, area, margin, 2, device=True)
        again = sample_measures(sim, f, gap, area, margin, 2, device=True)
        out["pulls_by_device_sample"] = {
            k: v - before.get(k, 0) for k, v in sim.pull_counts.items() if v != before.get(k, 0)
        }
        host = host_measures(sim, f, gap, area, margin)
        out["pulls_by_host_sample"] = {
            k: v - before.get(k, 0) for k, v in sim.pull_counts.items() if v != before.get(k, 0)
        }
        out["device_twice_identical"] = dev == again
        for k in KEYS:
            scale = max(abs(host[k]), 1e-300)
            out["rel"][k] = max(out["rel"].get(k, 0.0), abs(dev[k] - host[k]) / scale)
            out["abs"][k] = host[k]
        out["samples"] += 1
    # the state's sums on the device against the CPU class's on the pulled state
    before = sim.pull_counts
    dev_sums = (sim.kinetic_energy(), sim.pair_stress(1e-6), sim.n_contacts())
    out["pulls_by_device_sums"] = {
        k: v - before.get(k, 0) for k, v in sim.pull_counts.items() if v != before.get(k, 0)
    }
    sim._pull_all()
    host_sums = (
        engine.Simulation.kinetic_energy(sim),
        engine.Simulation.pair_stress(sim, 1e-6),
        engine.Simulation.n_contacts(sim),
    )
    out["sums_rel"] = [_rel(h, d) for h, d in zip(host_sums, dev_sums)]
    out["n_contacts"] = [host_sums[2], dev_sums[2]]
    top = sim.wall_positions[1, 2]
    sim.run(3)
    twin.run(3)
    out["platen_moved"] = float((sim.wall_positions[1, 2] - top) / (-0.02 * 3 * sim.dt))
    # a capped pour's cap on the device and on the host, on two copies of the same state
    v = sim.velocities
    cap = float(np.median(np.sqrt(np.einsum("ij,ij->i", v, v))))
    before = sim.pull_counts
    out["capped"] = [cap_speed(sim, cap, device=True), cap_speed(twin, cap, device=False)]
    out["pulls_by_device_cap"] = {
        k: v - before.get(k, 0) for k, v in sim.pull_counts.items() if v != before.get(k, 0)
    }
    out["cap_rel"] = {q: _rel(getattr(twin, q), getattr(sim, q)) for q in ("velocities", "forces")}
    speeds = np.sqrt(np.einsum("ij,ij->i", sim.velocities, sim.velocities))
    out["fastest_over_cap"] = float(speeds.max() / cap)
    counts = sim.contact_counts()
    z = sim.positions[:, 2] - float(sim.wall_positions[0, 2])
    inside = (z >= margin) & (z <= gap - margin)
    out["contacts"] = int(counts.sum()) // 2
    out["interior_particles"] = int(inside.sum())
    out["interior_contacts"] = int(counts[inside].sum())
    out["wall_contacts"] = len(sim.contacts().wall_particles)
    return out


def batch_case() -> dict:
    """Three scenes (different sizes and seeds) stepped side by side on their own streams,
    against the same three run one after the other on the default stream."""
    from engine.cuda.batch import step_together

    scenes = [
        scene(FULL, n=24, seed=3, speed=0.3),
        scene(FULL, n=36, seed=5, speed=0.3),
        scene(FULL, n=30, seed=7, speed=0.3, periodic=(True, False, False)),
    ]
    steps = 8
    skin = 0.03 * R  # thin: each list rebuilt once within the steps, on the threads' streams
    # (0.01 R rebuilt them 3-5 times: 19 s in the simulator against 7 s)
    alone = []
    for sc in scenes:
        s = engine.Simulation(sc, backend="cuda", skin=skin)
        s.run(steps)
        alone.append(s)
    together = [engine.Simulation(sc, backend="cuda", skin=skin) for sc in scenes]
    step_together(together, steps)
    step_together(together, 0)  # a force evaluation only: the same as run(0)
    for s in alone:
        s.run(0)
    q = ("positions", "velocities", "angular_velocities", "wall_forces", "wall_positions")
    out = {
        "n": [s.n for s in together],
        "steps": [s.steps for s in together],
        "streams_distinct": len({id(s.stream) for s in together}) == len(together),
        "bit_identical": all(
            np.array_equal(getattr(a, k), getattr(b, k)) for a, b in zip(alone, together) for k in q
        ),
        "rel": max(_rel(getattr(a, k), getattr(b, k)) for a, b in zip(alone, together) for k in q),
        "contacts": [len(s.contacts().pairs) for s in together],
        "rebuilds": [s.n_rebuilds for s in together],
    }
    try:
        step_together([together[0], together[0]], 1)
        out["twice_refused"] = False
    except engine.ParameterError:
        out["twice_refused"] = True
    return out


CASES = {"measures": measures_case, "batch": batch_case}

if __name__ == "__main__":
    from tests.engine.cuda_cases import main

    main(lambda name: CASES[name]())
