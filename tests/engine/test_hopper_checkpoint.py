"""Checkpoints of a hopper run: a run killed while its fill settles and again while it
discharges, resumed each time from its checkpoint, gives a discharge record byte for byte equal
to that of a run never interrupted. The tiny slot hopper of tests/engine/test_hopper_run.py
(100 particles, outlet 6 diameters), settled to 1e-2 N m g R and discharged for 40 ms (a
sixth of it flows out); one thread."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

import engine
from engine.hopper.driver import HOPPER_TRAJECTORY
from engine.hopper.scene import build_hopper
from engine.hopper.spec import HopperTest
from engine.uniaxial import checkpoint as ck_module
from engine.uniaxial.checkpoint import Checkpoint

D = 5e-3  # particle diameter [m]


class Killed(Exception):
    """Stands for the process dying: raised from the progress callback."""


def _killer(stage: str, after: int):
    """A progress callback that raises :class:`Killed` at the ``after``-th report of
    ``stage``; ``seen`` keeps the reports' messages."""
    count = {"n": 0, "seen": []}

    def progress(p):
        count["seen"].append((p.stage, p.message))
        if p.stage == stage:
            count["n"] += 1
            if count["n"] == after:
                raise Killed(stage)

    return progress, count


def test_a_killed_hopper_run_resumes_bit_identically(tmp_path):
    t = HopperTest(outlet_width=6 * D, particles=100, settle_ke=1e-2, max_discharge_time=0.04)
    whole = engine.run_hopper(t, threads=1)
    path = tmp_path / "run.ckpt"

    # killed while settling: checkpoints every sample (interval ~ 0), the settled fill's not yet
    progress, c = _killer("settle", 5)
    with pytest.raises(Killed):
        engine.run_hopper(t, progress, threads=1, checkpoint=Checkpoint(path, 1e-9))
    assert path.exists()

    # resumed, then killed while discharging
    ck = Checkpoint(path, 1e-9)
    progress, c = _killer("discharge", 20)
    with pytest.raises(Killed):
        engine.run_hopper(t, progress, threads=1, checkpoint=ck)
    assert ck.resumed_steps is not None and ck.resumed_steps > 0
    assert c["seen"][0][0] == "settle" and c["seen"][0][1].startswith(engine.RESUMED)
    settled_at = ck.resumed_steps

    # resumed mid-discharge, run to the end
    ck = Checkpoint(path, 1e-9)
    progress, c = _killer("none", 0)
    res = engine.run_hopper(t, progress, threads=1, checkpoint=ck)
    assert ck.resumed_steps > settled_at
    assert c["seen"][0] == ("discharge", f"{engine.RESUMED} at step {ck.resumed_steps}")

    # grains flowed out after the second resumption, and the whole record came through it
    d = res.curves["discharged_mass"]
    assert d[19] == 0.0 < d[-1] and len(d) > 30
    for k, v in whole.curves.items():
        assert v.tobytes() == res.curves[k].tobytes(), k
    for a in ("wall_edges", "wall_stress_fill", "wall_stress_flow"):
        assert getattr(whole, a).tobytes() == getattr(res, a).tobytes(), a
    for k, v in whole.scalars.items():
        if k != "wall_time":
            assert v == res.scalars[k] or (math.isnan(v) and math.isnan(res.scalars[k])), k


def test_a_hopper_checkpoint_is_tied_to_the_hopper_sources(tmp_path, monkeypatch):
    """A hopper checkpoint carries the digest of the hopper's packages as well as the
    uniaxial run's: an edit to engine/hopper invalidates it, and a uniaxial checkpoint's
    digest is not it."""
    assert HOPPER_TRAJECTORY[-1] == "hopper" and set(ck_module.TRAJECTORY_PACKAGES) < set(
        HOPPER_TRAJECTORY
    )
    assert ck_module.trajectory_digest(HOPPER_TRAJECTORY) != ck_module.trajectory_digest()
    t = HopperTest(outlet_width=6 * D, particles=100)
    path = tmp_path / "run.ckpt"
    progress, _ = _killer("settle", 2)
    with pytest.raises(Killed):
        engine.run_hopper(t, progress, threads=1, checkpoint=Checkpoint(path, 1e-9))
    # the same file read as if written by other hopper sources: ignored, with a warning
    monkeypatch.setattr(ck_module, "trajectory_digest", lambda packages=(): "other")
    with pytest.warns(RuntimeWarning, match="other engine code"):
        assert Checkpoint(path).load(t, HOPPER_TRAJECTORY) is None


def test_a_discharge_streams_its_snapshots_without_changing_the_run(tmp_path):
    """ParaView snapshots of a discharge (engine.io.vtkhdf.SnapshotWriter): one at the gate's
    opening, one every snapshot_interval of the discharge, one at its end; the run's record
    is the one it has without them."""
    from engine.io.vtkhdf import SnapshotWriter

    t = HopperTest(outlet_width=6 * D, particles=100, settle_ke=1e-2, max_discharge_time=0.04)
    plain = engine.run_hopper(t, threads=1)
    taken = []
    with SnapshotWriter(tmp_path / "snaps") as writer:

        def add(snap):
            taken.append((snap.stage, snap.time, len(snap.radii)))
            writer.add(snap)

        res = engine.run_hopper(t, threads=1, on_snapshot=add, snapshot_interval=0.01)
    for k, v in plain.curves.items():
        assert v.tobytes() == res.curves[k].tobytes(), k
    stages = [s for s, _, _ in taken]
    assert stages[0] == "discharge" and stages[-1] == "discharged", stages
    opened = taken[0][1]
    gaps = [b - a for (_, a, _), (_, b, _) in itertools.pairwise(taken[:-1])]
    assert len(taken) >= 5 and all(g >= 0.01 - 1e-12 for g in gaps), taken
    # the last sample may fall a sample past max_discharge_time (0.04 s)
    assert taken[-2][1] - opened < 0.05 and all(n == 100 for _, _, n in taken)
    # the end's snapshot falls on the last interval's step here: the writer keeps one
    assert writer.labels[-1] in ("discharged", "discharge+discharged"), writer.labels
    assert (tmp_path / "snaps" / "particles.vtkhdf").exists()
    # the walls and the gate, where they are at each step: the gate moves down, walls do not
    import h5py

    geo = build_hopper(t)
    n_tri = sum(len(m.triangles) for m in geo.scene.meshes)
    with h5py.File(tmp_path / "snaps" / "walls.vtkhdf", "r") as f:
        v = f["VTKHDF"]
        steps = int(v["Steps"].attrs["NSteps"])
        assert steps == len(writer.labels)
        assert list(v["Polygons/NumberOfCells"][:]) == [n_tri] * steps
        mesh = v["CellData/mesh"][:].reshape(steps, n_tri)
        gate = mesh[0] == geo.gate_mesh
        assert gate.any() and np.array_equal(mesh[0], mesh[-1])
        pts = v["Points"][:].reshape(steps, -1, 3)
        tri = v["Polygons/Connectivity"][: n_tri * 3].reshape(n_tri, 3)
        on_gate = np.unique(tri[gate])
        assert pts[-1, on_gate, 2].max() < pts[0, on_gate, 2].max() - 1e-3  # opened downwards
        walls = np.setdiff1d(np.arange(pts.shape[1]), on_gate)
        assert np.array_equal(pts[0, walls], pts[-1, walls])
    assert (tmp_path / "snaps" / "walls.pvd").exists()
    assert (tmp_path / "snaps" / "walls-0000.vtu").exists()
    with pytest.raises(engine.ParameterError, match="run_hopper.snapshot_interval"):
        engine.run_hopper(t, threads=1, snapshot_interval=-1.0)
