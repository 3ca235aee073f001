"""The CUDA backend (engine.cuda) against the CPU kernel, under numba-cuda's simulator.

The simulator must be switched on before numba.cuda is first imported, so the cases run in a
process of their own (``python -m tests.engine.cuda_cases CASE:LAUNCH:KERNELS ...`` with
``NUMBA_ENABLE_CUDASIM=1``), all of them in one, once a session (``cases``): this process,
and the CPU tests beside it under ``pytest -n``, never import numba.cuda. Tiny scenes, tens
of steps; see tests/engine/cuda_cases.py.
Skipped, with the reason, when numba-cuda (the ``gpu`` extra) is not installed.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.engine.helpers import computed_once

ROOT = Path(__file__).resolve().parents[2]
HAS_NUMBA_CUDA = importlib.util.find_spec("numba_cuda") is not None
needs_numba_cuda = pytest.mark.skipif(
    not HAS_NUMBA_CUDA, reason="numba-cuda is not installed (pip install 'demscale[gpu]')"
)
#: the tolerance of issue 21: float64, relative to each quantity's largest magnitude
REL = 1e-12


def _python(
    code_or_args: list[str], simulator: bool, timeout: float = 240.0
) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("NUMBA_ENABLE_CUDASIM", None)
    env.pop("DEMSCALE_BACKEND", None)
    if simulator:
        env["NUMBA_ENABLE_CUDASIM"] = "1"
    return subprocess.run(
        [sys.executable, *code_or_args],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


DIFFERENTIAL = {
    # case: features it must have exercised
    "bilinear-walls": ("adhesion", "plastic", "friction", "rolling", "walls", "wall_friction"),
    "periodic-rebuilds": ("periodic_x", "periodic_y", "periodic_z"),
    "eepa": ("pair_kernel=eepa", "adhesion", "walls", "periodic_x"),
    "eepa-normal-cap": ("pair_kernel=eepa", "normal_cap", "walls"),
    "hertz": ("pair_kernel=hertz", "friction", "rolling", "walls"),
}


#: every case in the one-launch-per-batch (cooperative) kernel; one also in the kernel per pass
CASES = [(name, "persistent") for name in DIFFERENTIAL] + [("bilinear-walls", "passes")]
#: The test suite runs general kernels (tests/conftest.py); one case runs the scene's own
#: kernels (DEMSCALE_KERNELS=scene), those of a production run on the device: the EEPA with
#: its normal cap, whose kernel no general one could stand for (the cap is kept), and whose
#: scene compiles one CPU kernel (the study's case, whose edits remove the periodic axes,
#: would compile two that no other test shares: about 15 s of CPU each, scene kernels
#: being smaller than general ones)
SCENE_KERNELS = {("eepa-normal-cap", "persistent")}


def _mode(name: str, launch: str) -> str:
    """The kernel mode a differential case runs in (:data:`SCENE_KERNELS`)."""
    return "scene" if (name, launch) in SCENE_KERNELS else "general"


#: Every case the tests below read (NAME:LAUNCH:KERNELS), run in one process.
SPECS = (
    *(f"{n}:{la}:{_mode(n, la)}" for n, la in CASES),
    "determinism:persistent:general",
    "instability:persistent:general",
)


def simulator_cases(tmp_path_factory, module: str, specs, timeout: float = 480.0) -> dict:
    """Every case of ``specs`` (NAME:LAUNCH:KERNELS) run by ``module`` (its ``__main__``:
    tests/engine/cuda_cases.py's ``main``) in one process under the simulator, once for the
    whole session however many workers ask (``computed_once``). A process that fails or
    outlives ``timeout`` [s] gives every case its error, stored like a result, so that no
    waiting worker starts it again; the timeout stays under pytest's 600 s a test, which
    counts a fixture's set-up (a worker waiting for another's run included)."""

    def run() -> dict:
        try:
            proc = _python(["-m", module, *specs], simulator=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            return {key: {"error": f"{module}: not done in {timeout:g} s"} for key in specs}
        if proc.returncode != 0:
            return {key: {"error": proc.stderr[-4000:]} for key in specs}
        return json.loads(proc.stdout.strip().splitlines()[-1])

    return computed_once(tmp_path_factory, module, run)


def case_result(cases: dict, spec: str) -> dict:
    """One case's result from :func:`simulator_cases`, its error raised as the test's."""
    r = cases[spec]
    assert "error" not in r, r["error"]
    return r


@pytest.fixture(scope="module")
def cases(tmp_path_factory) -> dict:
    """The results of :data:`SPECS`."""
    return simulator_cases(tmp_path_factory, "tests.engine.cuda_cases", SPECS)


def _case(cases: dict, name: str, launch: str = "persistent", kernels: str = "general") -> dict:
    return case_result(cases, f"{name}:{launch}:{kernels}")


@needs_numba_cuda
@pytest.mark.parametrize(("name", "launch"), CASES)
def test_cuda_kernels_follow_the_cpu_kernel(cases, name, launch):
    mode = _mode(name, launch)
    r = _case(cases, name, launch, mode)
    assert r["launch"] == launch and r["kernel_mode"] == mode
    for quantity, rel in r["rel"].items():
        assert rel <= REL, (quantity, rel, r)
    assert r["contacts"] > 20, r  # the contact law was exercised, not just free flight
    for f in DIFFERENTIAL[name]:
        assert f in r["features"] or name == "bilinear-walls", (f, r["features"])
    if name in ("bilinear-walls", "eepa", "eepa-normal-cap", "hertz"):
        assert r["wall_contacts"] > 0, r
    # the device builds the list as often as the CPU does, from the same positions
    assert r["rebuilds"][0] == r["rebuilds"][1] or name != "periodic-rebuilds", r
    if name in ("periodic-rebuilds", "hertz"):
        assert r["rebuilds"][1] >= 2, r
    if name == "bilinear-walls":  # lists built with every axis open, as often on both sides
        assert r["rebuilds_open"][0] == r["rebuilds_open"][1] >= 2, r
    if name == "periodic-rebuilds":
        assert r["n_entries"][0] == r["n_entries"][1] > 0


@needs_numba_cuda
def test_cuda_run_twice_is_bit_identical(cases):
    r = _case(cases, "determinism")
    assert r["bit_identical_twice"] and r["launch"] == "persistent", r
    assert r["rebuilds"][0] == r["rebuilds"][1] >= 2, r


@needs_numba_cuda
def test_cuda_reports_the_instability_the_cpu_reports(cases):
    r = _case(cases, "instability")
    assert r["errors"][0] is not None and r["errors"][0][0] == "speed", r
    assert r["errors"][1] == r["errors"][0], r


def test_backend_names_are_checked():
    import engine
    from engine.simulation.backend import check_backend, resolve_backend

    assert resolve_backend("cpu") == "cpu"
    assert check_backend(" CUDA ") == "cuda"
    with pytest.raises(engine.ParameterError, match="Simulation.backend"):
        resolve_backend("gpu")
    with pytest.raises(engine.ParameterError, match="DEMSCALE_BACKEND"):
        os.environ["DEMSCALE_BACKEND"] = "tpu"
        try:
            resolve_backend(None)
        finally:
            del os.environ["DEMSCALE_BACKEND"]


def test_backend_is_checked_where_it_is_given():
    import engine
    from demscale.cli import parser as build_parser

    test = engine.preset("quick")
    with pytest.raises(engine.ParameterError, match="run_uniaxial.backend"):
        engine.run_uniaxial(test, backend="gpu")
    spec = engine.default_study()
    with pytest.raises(engine.ParameterError, match="RunOptions.backend"):
        engine.run_study(spec, backend="tpu")  # refused before any run starts
    args = build_parser().parse_args(["study", "s.json", "--out", "o", "--backend", "cuda"])
    assert args.backend == "cuda"
    assert build_parser().parse_args(["run", "t.json", "--out", "o"]).backend is None
    with pytest.raises(SystemExit):
        build_parser().parse_args(["run", "t.json", "--out", "o", "--backend", "gpu"])


def test_service_setting_names_the_backend(monkeypatch):
    pydantic = pytest.importorskip("pydantic")
    from service.settings import Settings

    monkeypatch.setenv("DEMSCALE_BACKEND", "auto")
    assert Settings().backend == "auto"
    monkeypatch.setenv("DEMSCALE_BACKEND", "gpu")
    with pytest.raises(pydantic.ValidationError, match="backend"):
        Settings()


BLOCK_NUMBA_CUDA = """
import sys, importlib.abc
class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == 'numba.cuda' or name.startswith('numba.cuda.') or name == 'numba_cuda':
            raise ImportError('blocked: no numba-cuda here')
sys.meta_path.insert(0, Block())
"""

WITHOUT_GPU = (
    BLOCK_NUMBA_CUDA
    + """
import numpy as np, engine
sc = engine.Scene(np.array([[0.01, 0.01, 0.01], [0.02, 0.01, 0.01]]), np.full(2, 2.5e-3),
                  2000.0, box=[(0, 0.03)] * 3, gravity=(0, 0, 0),
                  pair_law=engine.BilinearAdhesive(k1=5e3, k2=2.5e4))
sim = engine.Simulation(sc, dt=1e-5, backend="auto")
sim.run(3)
print("auto:", sim.backend, type(sim).__name__)
try:
    engine.Simulation(sc, dt=1e-5, backend="cuda")
except engine.ParameterError as e:
    print("cuda:", e.field, "|", e)
print("imported:", sorted(m for m in sys.modules if m.startswith('numba.cuda')))
"""
)


def test_without_numba_cuda_auto_takes_the_cpu_and_cuda_names_the_field():
    proc = _python(["-c", WITHOUT_GPU], simulator=False, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = proc.stdout
    assert "auto: cpu Simulation" in out
    assert "cuda: Simulation.backend |" in out and "numba-cuda is not installed" in out
    assert "imported: []" in out


@needs_numba_cuda
def test_import_engine_does_not_import_numba_cuda():
    code = (
        "import sys, engine, engine.study, engine.uniaxial; "
        "print(sorted(m for m in sys.modules if m.startswith('numba.cuda')))"
    )
    proc = _python(["-c", code], simulator=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip() == "[]"
