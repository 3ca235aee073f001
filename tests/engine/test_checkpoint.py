"""Checkpoints of a run in flight: a run killed mid-stage and resumed from its checkpoint gives
curves byte for byte equal to those of a run that was never interrupted."""

from __future__ import annotations

import itertools
import os
import pickle
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

import engine
from engine.uniaxial.checkpoint import Checkpoint
from engine.uniaxial.driver import stages_of

from .test_uniaxial import COHESIVE, tiny

ROOT = Path(__file__).resolve().parents[2]
TIMINGS = ("wall_time", "setup_time")


class Killed(Exception):
    """Stands for the process dying: raised from the progress callback."""


def same_result(a: engine.UniaxialResult, b: engine.UniaxialResult) -> None:
    assert list(a.stages) == list(b.stages)
    for name, st in a.stages.items():
        other = b.stages[name]
        assert st.steps == other.steps, name
        for k, v in st.curves.items():
            assert v.tobytes() == other.curves[k].tobytes(), f"{name}.{k}"
        assert st.positions.tobytes() == other.positions.tobytes(), name
    for k, v in a.scalars.items():
        if k not in TIMINGS:
            assert v == b.scalars[k], k


@pytest.fixture(scope="module")
def cohesive_test():
    return tiny(pair_law=COHESIVE, unconfined=True)


@pytest.fixture(scope="module")
def uninterrupted(cohesive_test):
    return engine.run_uniaxial(cohesive_test)


def test_a_simulation_pickled_mid_run_goes_on_bit_identically(cohesive_test):
    """A cohesive bed falling onto its platen (pairs with plastic history, walls, periodic
    sides, rebuilds): pickled mid-run, unpickled, run on."""
    pos, radii = cohesive_test.initial_packing()
    scene = cohesive_test.scene(pos, radii)
    # the same two calls without the pickle: a run() ends with the closing half kick, so two
    # calls round differently from one of 6,000 steps (the driver always runs one curve
    # sample per call, and checkpoints between two of them)
    a = engine.Simulation(scene, dt=cohesive_test.dt)
    b = engine.Simulation(scene, dt=cohesive_test.dt)
    a.run(3500)
    a.run(2500)
    b.run(3500)
    c = pickle.loads(pickle.dumps(b))
    c.run(2500)
    assert a.n_contacts() > 0 and a.n_rebuilds > 1
    for attr in ("positions", "velocities", "angular_velocities", "forces", "wall_forces"):
        assert getattr(a, attr).tobytes() == getattr(c, attr).tobytes(), attr
    assert a.steps == c.steps == 6000
    ca, cc = a.contacts(), c.contacts()
    assert ca.max_overlaps.tobytes() == cc.max_overlaps.tobytes()
    assert ca.tangential_springs.tobytes() == cc.tangential_springs.tobytes()
    assert c.between_calls is None


@pytest.mark.parametrize("kills", [(3,), (40, 80, 130)])
def test_a_run_killed_and_resumed_gives_the_same_curves(
    tmp_path, cohesive_test, uninterrupted, kills
):
    """Killed after the k-th checkpoint of each attempt (every sample is checkpointed), in
    different stages, then resumed until it finishes."""
    path = tmp_path / "run.ckpt"
    seen_stages = []
    resumed = []
    for k in kills:
        ck = Checkpoint(path, interval=1e-12)

        def stop(p, ck=ck, k=k):
            if ck.writes >= k:
                seen_stages.append(p.stage)
                raise Killed()

        with pytest.raises(Killed):
            engine.run_uniaxial(cohesive_test, progress=stop, checkpoint=ck)
        assert path.exists()
    last = Checkpoint(path, interval=1e9)
    res = engine.run_uniaxial(cohesive_test, checkpoint=last)
    resumed.append(last.resumed_steps)
    assert last.resumed_steps is not None and last.resumed_steps > 0
    same_result(uninterrupted, res)
    assert path.exists()  # left for the caller, who stores the result first
    last.remove()
    assert not path.exists()
    if len(kills) > 1:  # the kills fell in more than one stage
        assert len(set(seen_stages)) > 1, seen_stages


def test_progress_never_goes_back_across_a_resume(tmp_path, cohesive_test):
    path = tmp_path / "run.ckpt"
    ck = Checkpoint(path, interval=1e-12)
    before = []

    def stop(p):
        before.append(p.fraction)
        if ck.writes >= 60:
            raise Killed()

    with pytest.raises(Killed):
        engine.run_uniaxial(cohesive_test, progress=stop, checkpoint=ck)
    after = []
    engine.run_uniaxial(
        cohesive_test, progress=lambda p: after.append(p.fraction), checkpoint=Checkpoint(path)
    )
    assert after[0] >= before[-2]  # resumed where the last checkpoint was
    assert all(b >= a for a, b in itertools.pairwise(after))
    assert after[-1] == 1.0


def _cut_off(path: Path, test, writes: int) -> None:
    """Run ``test`` with a checkpoint at ``path`` written at every curve sample, and kill it
    after ``writes`` writes."""
    ck = Checkpoint(path, interval=1e-12)

    def stop(p):
        if ck.writes >= writes:
            raise Killed()

    with pytest.raises(Killed):
        engine.run_uniaxial(test, progress=stop, checkpoint=ck)


def test_a_checkpoint_of_another_test_or_a_torn_file_is_ignored(tmp_path, cohesive_test):
    path = tmp_path / "run.ckpt"
    _cut_off(path, cohesive_test, 5)
    other = tiny(pair_law=COHESIVE, unconfined=True, seed=cohesive_test.seed + 1)
    with pytest.warns(RuntimeWarning, match="another test"):
        assert Checkpoint(path).load(other) is None
    path.write_bytes(path.read_bytes()[:100])
    with pytest.warns(RuntimeWarning, match="unreadable"):
        assert Checkpoint(path).load(cohesive_test) is None
    path.write_bytes(pickle.dumps({"format": "something else"}))
    with pytest.warns(RuntimeWarning, match="not a demscale checkpoint"):
        assert Checkpoint(path).load(cohesive_test) is None


def test_a_refused_checkpoint_is_not_reported_as_resumed(tmp_path, cohesive_test):
    # e.g. one written on the other backend: the run starts over and says nothing of a resume
    from engine.uniaxial.checkpoint import resume

    path = tmp_path / "run.ckpt"
    _cut_off(path, cohesive_test, 2)
    ck, state, _ = resume(Checkpoint(path), cohesive_test, lambda s: None)
    assert state is not None and ck.resumed_steps is not None
    with pytest.warns(RuntimeWarning, match="another backend"):
        ck, state, _ = resume(Checkpoint(path), cohesive_test, lambda s: "was of another backend")
    assert state is None and ck.resumed_steps is None


def test_a_checkpoint_of_other_trajectory_code_is_ignored(tmp_path, cohesive_test):
    from engine.uniaxial import checkpoint as ck_module

    path = tmp_path / "run.ckpt"
    _cut_off(path, cohesive_test, 2)
    assert Checkpoint(path).load(cohesive_test) is not None
    stored = pickle.loads(path.read_bytes())
    path.write_bytes(pickle.dumps({**stored, "code": "0" * 20}))
    with pytest.warns(RuntimeWarning, match="other engine code"):
        assert Checkpoint(path).load(cohesive_test) is None
    assert stored["code"] == ck_module.trajectory_digest() != ck_module.code_digest()


def test_the_resume_digest_follows_only_the_code_a_run_steps_through(tmp_path):
    """An edit in a package a run steps through changes the digest a checkpoint is resumed
    by; an edit in the studies, calibration or storage does not (a long run cut off by a
    session's end resumes after it). Every engine import of those packages stays inside
    them."""
    import ast
    import shutil

    from engine.uniaxial import checkpoint as ck_module

    engine_dir = ROOT / "engine"
    root = tmp_path / "engine"
    shutil.copytree(engine_dir, root, ignore=shutil.ignore_patterns("__pycache__"))
    keys = ck_module.TRAJECTORY_PACKAGES

    def digests():
        return ck_module._source_digest(root, keys), ck_module._source_digest(root, None)

    run0, all0 = digests()
    assert run0 == ck_module.trajectory_digest() and all0 == ck_module.code_digest()
    with open(root / "study" / "advice.py", "a") as fh:
        fh.write("\n# an edit outside the trajectory\n")
    run1, all1 = digests()
    assert run1 == run0 and all1 != all0
    with open(root / "kernel" / "step_template.py", "a") as fh:
        fh.write("\n# an edit in the kernel\n")
    assert digests()[0] != run0
    outside = {p.name for p in engine_dir.iterdir() if p.is_dir()} - set(keys) - {"__pycache__"}
    assert outside >= {"study", "calibration", "io"}
    for f in (f for pkg in keys for f in (engine_dir / pkg).rglob("*.py")):
        for node in ast.walk(ast.parse(f.read_text())):
            if not isinstance(node, ast.ImportFrom) or not node.module:
                continue
            parts = node.module.split(".")
            # the engine package imported: ``from ..x`` or ``from engine.x``
            top = parts[0] if node.level >= 2 else parts[1] if parts[0] == "engine" else None
            allowed = (f.name, top) == ("results.py", "io")  # its snapshot writer
            assert top not in outside or allowed, f"{f.relative_to(engine_dir)} imports {top}"


def test_the_interval_is_checked():
    for bad in (0, -1.0, float("nan"), float("inf"), True, "60"):
        with pytest.raises(engine.ParameterError, match="Checkpoint.interval"):
            Checkpoint("x.ckpt", interval=bad)


def test_writes_are_spaced_by_the_interval(tmp_path, cohesive_test, uninterrupted):
    """With an interval longer than the run, the one checkpoint is the settled bed's, at the
    fill's end (after_fill); without it none is written: the cost of checkpointing a short
    run is one write, or nil."""
    ck = Checkpoint(tmp_path / "run.ckpt", interval=3600.0, after_fill=False)
    res = engine.run_uniaxial(cohesive_test, checkpoint=ck)
    assert ck.writes == 0 and not ck.path.exists()
    same_result(uninterrupted, res)
    ck = Checkpoint(tmp_path / "fill.ckpt", interval=3600.0)
    res = engine.run_uniaxial(cohesive_test, checkpoint=ck)
    assert ck.writes == 1 and ck.path.exists()
    same_result(uninterrupted, res)
    # it holds the bed after the fill: a run resumed from it pours nothing and ends the same
    resumed = Checkpoint(ck.path, interval=3600.0)
    d = resumed.load(cohesive_test)
    assert d is not None and set(d.stages) == {"fill"} and d.current is None
    same_result(uninterrupted, engine.run_uniaxial(cohesive_test, checkpoint=resumed))
    assert resumed.resumed_steps is not None


_CHILD = textwrap.dedent("""
    import sys, time
    import engine
    from tests.engine.test_uniaxial import COHESIVE, tiny
    test = tiny(pair_law=COHESIVE, unconfined=True)
    ck = engine.Checkpoint(sys.argv[1], interval=0.05)
    def slow(p):
        time.sleep(0.002)  # stretches the run in wall time only
        print(p.stage, ck.writes, flush=True)
    engine.run_uniaxial(test, progress=slow, checkpoint=ck)
    print("finished", flush=True)
""")


def test_a_process_killed_with_sigkill_resumes_bit_identically(
    tmp_path, cohesive_test, uninterrupted
):
    """The real thing: a process SIGKILLed mid-stage after some checkpoints, resumed here."""
    path = tmp_path / "run.ckpt"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    child = subprocess.Popen(
        [sys.executable, "-c", _CHILD, str(path)],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        text=True,
    )
    stage = None
    deadline = time.monotonic() + 240
    try:
        for line in child.stdout:
            stage, writes = line.split()[0], line.split()[-1]
            if stage == "consolidation" and int(writes) >= 3:
                break
            assert time.monotonic() < deadline, "the child did not reach consolidation"
        else:
            pytest.fail(f"the child ended before it was killed (last: {stage})")
        child.send_signal(signal.SIGKILL)
    finally:
        child.kill()
        child.wait(30)
    assert child.returncode == -signal.SIGKILL
    ck = Checkpoint(path)
    res = engine.run_uniaxial(cohesive_test, checkpoint=ck)
    assert ck.resumed_steps > 0
    same_result(uninterrupted, res)
    assert res.stages["fill"].snapshot is not None  # stage-end snapshots survive the resume
    np.testing.assert_array_equal(
        res.stages["fill"].snapshot.positions, uninterrupted.stages["fill"].snapshot.positions
    )
    assert set(res.stages) == set(stages_of(res.test))
