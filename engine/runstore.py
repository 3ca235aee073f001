"""One HDF5 file per finished run, written atomically, read back as a
:class:`engine.UniaxialResult` (curves and scalars; particle positions are not kept).

Long runs are stored once and every metric, verdict and report is recomputed from the stored
curves (``engine.study.assemble``); a study resumes with the runs not yet stored
(``run_study(completed=...)``). A failed run is stored as a file holding only its error.
h5py is imported only here, when a run is stored or read (the engine itself needs only numpy
and numba).

Layout of ``<key>.h5``: attrs ``test`` (JSON of :meth:`engine.UniaxialTest.to_dict`),
``error`` (only for a failed run), ``versions``, ``machine`` (JSON: the processor and the
number of logical CPUs of the machine that stored the run, which for a process pool or
``benchmarks/run_batch.py`` is the one that ran it; absent in runs stored before it was
recorded); group ``scalars`` (attrs, with
``<name>_units``); one group per stage (attr ``steps``) with one dataset per curve (attr
``units``) and, when kept, a group ``particles`` (``positions`` (N, 3), ``radii`` (N,) at the
stage's end [m]).
"""

from __future__ import annotations

import json
import os
import platform
import socket
from pathlib import Path

import numpy as np

from .uniaxial import (
    CURVE_UNITS,
    SCALAR_UNITS,
    StageResult,
    UniaxialResult,
    UniaxialTest,
    failed_by_curve,
)


def this_machine() -> dict:
    """The processor (model name from /proc/cpuinfo where there is one) and the number of
    logical CPUs of this machine: where a stored run's wall time was measured."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((line.split(":", 1)[1].strip() for line in f
                        if line.startswith("model name")), cpu)
    except OSError:
        pass
    return {"cpu": cpu, "logical_cpus": os.cpu_count()}


def stored_machine(path: Path) -> dict | None:
    """The ``machine`` attribute of a stored run, or None where it was not recorded."""
    import h5py

    with h5py.File(path, "r") as f:
        text = f.attrs.get("machine")
    return None if text is None else json.loads(text)


def save_run(path: Path, outcome, keep_particles: bool = True) -> Path:
    """Write ``outcome`` (a UniaxialResult or an error text) to ``path`` atomically; with
    ``keep_particles`` also the particle positions and radii at each stage's end."""
    import h5py
    import numba

    from . import __version__

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{socket.gethostname()}.{os.getpid()}.tmp")
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs["versions"] = json.dumps({"demscale": __version__,
                                              "numba": numba.__version__,
                                              "numpy": np.__version__})
            f.attrs["machine"] = json.dumps(this_machine())
            if isinstance(outcome, str):
                f.attrs["error"] = outcome
            else:
                f.attrs["test"] = json.dumps(outcome.test.to_dict())
                sc = f.create_group("scalars")
                for k, v in outcome.scalars.items():
                    sc.attrs[k] = float(v)
                    sc.attrs[f"{k}_units"] = SCALAR_UNITS.get(k, "")
                for i, (name, st) in enumerate(outcome.stages.items()):
                    g = f.create_group(f"stages/{name}")
                    g.attrs.update({"steps": int(st.steps), "position": i})
                    for c, v in st.curves.items():
                        ds = g.create_dataset(c, data=np.asarray(v), compression="gzip",
                                              shuffle=True)
                        ds.attrs["units"] = CURVE_UNITS.get(c, "")
                    if keep_particles and st.positions is not None:
                        p = g.create_group("particles")
                        for name, v in (("positions", st.positions), ("radii", st.radii)):
                            ds = p.create_dataset(name, data=np.asarray(v), compression="gzip")
                            ds.attrs["units"] = "m"
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def load_run(path: Path):
    """The stored outcome: a :class:`engine.UniaxialResult` or the error text."""
    import h5py

    with h5py.File(path, "r") as f:
        if "error" in f.attrs:
            return str(f.attrs["error"])
        test = UniaxialTest.from_dict(json.loads(f.attrs["test"]))
        scalars = {k: float(v) for k, v in f["scalars"].attrs.items()
                   if not k.endswith("_units")}
        stages = {}
        for name in sorted(f["stages"], key=lambda n: int(f["stages"][n].attrs["position"])):
            g = f["stages"][name]
            p = g.get("particles")
            stages[name] = StageResult(
                name, {c: g[c][()] for c in g if c != "particles"},
                None if p is None else p["positions"][()], None if p is None else p["radii"][()],
                int(g.attrs["steps"]))
    if "unconfined_failure" in scalars and "unconfined" in stages:
        # one criterion for every run, stored before or after it was written: failure is
        # derived from the stored curve (engine.uniaxial.failed_by_curve)
        u = stages["unconfined"].curves
        failed = scalars["unconfined_failure"] == 1.0 or failed_by_curve(
            u["strain"], u["stress_top"], test.failure_strain)
        scalars["unconfined_failure"] = 1.0 if failed else 0.0
    return UniaxialResult(test, stages, scalars)


def completed_runs(spec, directory: Path) -> tuple[dict, list[str]]:
    """The runs of the :class:`engine.StudySpec` ``spec`` stored in ``directory`` whose test is
    exactly the planned one (what ``run_study(completed=...)`` resumes from), and the keys of
    stored runs made with other parameters (to be run again). With ``spec.decide`` the runs
    its rounds added are found too, round by round (:func:`engine.study.plan_runs`)."""
    from .study import plan_runs

    done, stale, seen = {}, [], set()
    while True:
        planned = {p.key: p.test for p in plan_runs(spec, done)[0]}
        fresh = [k for k in planned if k not in seen]
        if not fresh:
            return done, stale
        seen.update(fresh)
        for key, outcome in load_all(directory, fresh).items():
            if isinstance(outcome, str) or outcome.test == planned[key]:
                done[key] = outcome
            else:
                stale.append(key)


def load_all(directory: Path, keys) -> dict:
    """Stored outcomes of the given run keys found in ``directory``."""
    out = {}
    for k in keys:
        p = Path(directory) / f"{k}.h5"
        if p.exists():
            out[k] = load_run(p)
    return out
