"""Checkpoints of a uniaxial run in flight: its full state, written atomically every few
minutes of wall time, so that a run whose process was killed resumes where it was.

A checkpoint is a pickle of the stage driver between two curve samples: the
:class:`engine.Simulation` (particles, neighbour list with the contact history, walls, step
count and the phase of the next kernel call), the finished stages with their snapshots, the
current stage's rows, step count, start height and time, the failure detector, the progress
fraction and the snapshot clock. Nothing is random after the packing is placed (the packing's
generator is used once, before the first step), so a resumed run is bit-identical to one that
was never interrupted (tests/engine/test_checkpoint.py kills a run mid-stage and compares the
stored curves byte for byte).

A checkpoint is only used for the very test it was written for, by the very code that makes
a run's trajectory: the file carries the test's parameters and a digest of the engine's
packages a run steps through (:data:`TRAJECTORY_PACKAGES`) and the numba and Python
versions, and one that does not match is ignored (and replaced). Code a run does not step
through (studies, calibration, storage and figures) is left out, so that a long run cut off by
a session's end still resumes after an edit there. Pickles run code when they
are read: a checkpoint file is trusted like the program itself, and lives in a folder only
its owner can write (the service keeps it beside the study's runs, mode 0600).
"""

from __future__ import annotations

import functools
import hashlib
import math
import os
import pickle
import subprocess
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numba

from ..core.errors import ParameterError

__all__ = [
    "CHECKPOINT_INTERVAL",
    "TRAJECTORY_PACKAGES",
    "Checkpoint",
    "check_interval",
    "code_digest",
    "trajectory_digest",
]

#: Default wall time between two checkpoints of a run [s]: a killed run loses at most this
#: much work; one write of a paper-scale run's state (about 20 MB) takes a fraction of a second.
CHECKPOINT_INTERVAL = 60.0
_FORMAT = "demscale-checkpoint/1"
_ENGINE = Path(__file__).resolve().parents[1]
#: The engine's packages a uniaxial run steps through (its records and errors, the contact
#: laws, the kernels, the simulation, the stage driver, the CUDA backend): nothing else in
#: the engine (studies, calibration, storage, figures) is imported by them, so an edit
#: elsewhere cannot change a trajectory.
TRAJECTORY_PACKAGES = ("core", "contact", "kernel", "simulation", "uniaxial", "cuda")


def _source_digest(root: Path, packages: tuple[str, ...] | None) -> str:
    """Digest of the Python sources under ``root`` (only those of ``packages``, or all) and
    the numba and Python versions."""
    h = hashlib.sha256(f"{numba.__version__} {sys.version_info[:2]}".encode())
    dirs = [root] if packages is None else [root / p for p in packages]
    for f in sorted(f for d in dirs for f in d.rglob("*.py")):
        h.update(f.relative_to(root).as_posix().encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:20]


@functools.cache
def code_digest() -> str:
    """Digest of all the engine's Python sources and the numba and Python versions: the code
    a stored run records it was made by (:func:`this_code`)."""
    return _source_digest(_ENGINE, None)


@functools.cache
def trajectory_digest(packages: tuple[str, ...] = TRAJECTORY_PACKAGES) -> str:
    """Digest of the sources of ``packages`` (the engine's packages a run steps through: a
    uniaxial run's :data:`TRAJECTORY_PACKAGES`; a hopper's adds its own) and the numba and
    Python versions: a checkpoint written by other such code is not resumed (its trajectory
    could differ)."""
    return _source_digest(_ENGINE, packages)


_code: dict | None = None


def this_code() -> dict:
    """The code that makes this process's runs: the engine's source digest
    (:func:`code_digest`) and, where the engine is a git checkout, its commit and whether the
    work tree's engine/ differed from it (None where not a checkout). Taken once per process,
    at the first run's start (:func:`engine.run_uniaxial` asks for it), so that a source file
    edited while a long run goes on does not relabel the run: the process runs the code it
    imported."""
    global _code
    if _code is None:
        root = _ENGINE.parent
        commit, dirty = None, None
        try:
            out = subprocess.run(
                ["git", "-C", str(root), "rev-parse", "HEAD"],
                capture_output=True,
                text=True,
                timeout=5,
            )
            if out.returncode == 0:
                commit = out.stdout.strip()
                st = subprocess.run(
                    ["git", "-C", str(root), "status", "--porcelain", "--", "engine"],
                    capture_output=True,
                    text=True,
                    timeout=5,
                )
                dirty = bool(st.stdout.strip()) if st.returncode == 0 else None
        except (OSError, subprocess.SubprocessError):
            pass
        _code = {"engine_digest": code_digest(), "git_commit": commit, "engine_modified": dirty}
    return _code


def check_interval(interval: float, field: str) -> None:
    """Raise :class:`engine.ParameterError` naming ``field`` unless ``interval`` is a finite
    wall time > 0 s."""
    if not (
        isinstance(interval, (int, float))
        and not isinstance(interval, bool)
        and math.isfinite(interval)
        and interval > 0
    ):
        raise ParameterError(field, interval, "a wall time > 0 s")


def resume(checkpoint, test, refuse, *packages) -> tuple[Checkpoint | None, Any, float]:
    """What a run needs of its ``checkpoint`` argument (a :class:`Checkpoint`, a path or
    None): it as a Checkpoint (or None), the driver state it holds for ``test``
    (:meth:`Checkpoint.load`, with ``packages`` where given) or None, and the wall time the
    load took [s] (set-up time, as a new Simulation's kernel). A state ``refuse(state)``
    gives a reason against (words that follow the path) is warned about and not resumed.
    The warnings name the run's caller."""
    if checkpoint is None:
        return None, None, 0.0
    if not isinstance(checkpoint, Checkpoint):
        checkpoint = Checkpoint(checkpoint)
    t0 = time.perf_counter()
    state = checkpoint.load(test, *packages, stacklevel=4)
    why = None if state is None else refuse(state)
    if why:
        warnings.warn(
            f"checkpoint {checkpoint.path} {why}; the run starts from the beginning",
            RuntimeWarning,
            stacklevel=3,
        )
        state = None
        checkpoint.resumed_steps = None  # not resumed: the run starts from the beginning
    return checkpoint, state, time.perf_counter() - t0


class Checkpoint:
    """Where a run's checkpoint lives and how often it is written.

    Args:
        path: the checkpoint file (its folder is created on the first write).
        interval: wall time between two writes [s] (> 0); the first write comes ``interval``
            after the run (or its resumption) starts, at the next curve sample.
        after_fill: also write it when the fill ends (default True), whatever the interval:
            the poured and settled bed, a run's one random and often longest stage, is
            never poured again after a crash.

    :func:`engine.run_uniaxial` (and :func:`engine.run_hopper`) resumes from ``path`` when it
    holds a checkpoint of the same test and engine, writes it while it runs, and leaves it
    in place: the caller removes it (:meth:`remove`) once the run's result is stored, so a
    crash between the end of the run and the store loses nothing. Attributes: ``writes``
    (checkpoints written by this object), ``resumed_steps`` (the step the run resumed from,
    or None).
    """

    def __init__(
        self, path, interval: float = CHECKPOINT_INTERVAL, after_fill: bool = True
    ) -> None:
        check_interval(interval, "Checkpoint.interval")
        self.path = Path(path)
        self.interval = float(interval)
        self.after_fill = bool(after_fill)
        self.writes = 0
        self.resumed_steps: int | None = None
        self._last = time.monotonic()

    # ------------------------------------------------------------------ reading
    def load(self, test, packages: tuple[str, ...] = TRAJECTORY_PACKAGES, stacklevel: int = 3):
        """The driver state stored for ``test``, or None (no file, another test, other code
        of the engine's ``packages`` its run steps through, or an unreadable file: each is
        warned about, at ``stacklevel``, and ignored)."""
        try:
            with open(self.path, "rb") as fh:
                stored = pickle.load(fh)
        except FileNotFoundError:
            return None
        except Exception as e:  # a torn or foreign file is not fatal
            warnings.warn(
                f"checkpoint {self.path} is unreadable ({type(e).__name__}: {e}); "
                "the run starts from the beginning",
                RuntimeWarning,
                stacklevel=stacklevel,
            )
            return None
        why = None
        if not isinstance(stored, dict) or stored.get("format") != _FORMAT:
            why = "not a demscale checkpoint of this format"
        elif stored.get("code") != trajectory_digest(tuple(packages)):
            why = "written by other engine code"
        elif stored.get("test") != test.to_dict():
            why = "written for another test"
        if why:
            warnings.warn(
                f"checkpoint {self.path} is {why}; the run starts from the beginning",
                RuntimeWarning,
                stacklevel=stacklevel,
            )
            return None
        driver = stored["driver"]
        self.resumed_steps = int(driver.sim.steps)
        self._last = time.monotonic()
        return driver

    # ------------------------------------------------------------------ writing
    def start(self) -> None:
        """Start the interval's clock (the run begins or resumes here)."""
        self._last = time.monotonic()

    def due(self, driver) -> bool:
        """Write the checkpoint if ``interval`` has passed since the last one."""
        if time.monotonic() - self._last < self.interval:
            return False
        self.save(driver)
        return True

    def save(self, driver) -> None:
        """Write the driver's state atomically (a temporary file in the same folder, flushed
        to disk, then renamed over the old one): a kill at any moment leaves either the old
        checkpoint or the new one, never a torn file."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        blob = pickle.dumps(
            {
                "format": _FORMAT,
                "code": trajectory_digest(
                    getattr(driver, "trajectory_packages", TRAJECTORY_PACKAGES)
                ),
                "test": driver.test.to_dict(),
                "driver": driver,
            },
            protocol=pickle.HIGHEST_PROTOCOL,
        )
        tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(blob)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, self.path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
        self.writes += 1
        self._last = time.monotonic()

    def remove(self) -> None:
        """Delete the checkpoint (and a temporary file a killed writer left)."""
        self.path.unlink(missing_ok=True)
        for tmp in self.path.parent.glob(f".{self.path.name}.*.tmp"):
            tmp.unlink(missing_ok=True)

    def __repr__(self) -> str:
        return (
            f"Checkpoint({str(self.path)!r}, interval={self.interval:g}, "
            f"after_fill={self.after_fill})"
        )
