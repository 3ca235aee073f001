"""The import contract of the layers (ARCHITECTURE.md): the engine needs only numpy and
numba to import and never reaches up into the service or the command; within the engine, a
module imports at module level only from its own layer or the layers below it; the service
never imports the command."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: What engine modules may import at module level besides the standard library and engine.
ENGINE_TOP = {"numpy", "numba", "llvmlite"}
#: What they may import inside a function (files and figures, and scipy's statistics and
#: optimisers, on request).
ENGINE_LAZY = ENGINE_TOP | {"h5py", "matplotlib", "distributed", "scipy"}
#: Packages of the layers above the engine, or of the web and the database.
ABOVE = {
    "service",
    "demscale",
    "fastapi",
    "starlette",
    "sqlmodel",
    "sqlalchemy",
    "pydantic",
    "uvicorn",
    "httpx",
    "rich",
}


def imports(path: Path) -> list[tuple[str, bool]]:
    """(top-level package, at module level?) of every absolute import in a file."""
    tree = ast.parse(path.read_text())
    module_level = set()
    for node in tree.body:  # module body, and the bodies of its if/try blocks
        stack = [node]
        while stack:
            n = stack.pop()
            module_level.add(n)
            if isinstance(n, (ast.If, ast.Try)):
                stack += [
                    *n.body,
                    *n.orelse,
                    *getattr(n, "finalbody", []),
                    *[x for h in getattr(n, "handlers", []) for x in h.body],
                ]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            names = [node.module or ""]
        else:
            continue
        out += [(n.split(".")[0], node in module_level) for n in names]
    return out


def files(package: str) -> list[Path]:
    return sorted((ROOT / package).rglob("*.py"))


@pytest.mark.parametrize("path", files("engine"), ids=lambda p: str(p.relative_to(ROOT)))
def test_engine_modules_import_only_numpy_numba_and_the_standard_library(path):
    for name, top in imports(path):
        if name == "engine" or name in sys.stdlib_module_names or name == "__future__":
            continue
        allowed = ENGINE_TOP if top else ENGINE_LAZY
        assert name not in ABOVE, f"{path.name} imports {name}: the engine is below it"
        assert name in allowed, (
            f"{path.name} imports {name} {'at module level' if top else 'in a function'}"
        )


#: The engine's layers, lowest first (ARCHITECTURE.md): a module's path names its layer.
LAYERS = (
    "core",
    "contact",
    "kernel",
    "simulation",
    "cuda",
    "uniaxial",
    "shear",
    "hopper",
    "study",
    "io",
    "calibration",
    "process",
)


def engine_imports(path: Path) -> list[tuple[str, bool]]:
    """(imported engine module, at module level?) of every import of an engine file."""
    rel = path.relative_to(ROOT).with_suffix("")
    package = rel.parts[:-1]
    tree = ast.parse(path.read_text())
    top = {id(n) for n in tree.body}
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = list(package[: len(package) - (node.level - 1)])
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            names = [f"{module}.{a.name}" for a in node.names] if node.module is None else [module]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        out += [(n, id(node) in top) for n in names if n.split(".")[0] == "engine"]
    return out


def test_every_engine_module_is_in_a_layer():
    for path in files("engine"):
        parts = path.relative_to(ROOT / "engine").parts
        assert (len(parts) == 1 and parts[0] == "__init__.py") or parts[0] in LAYERS, path


@pytest.mark.parametrize("path", files("engine"), ids=lambda p: str(p.relative_to(ROOT)))
def test_engine_modules_import_only_their_own_layer_or_those_below(path):
    parts = path.relative_to(ROOT / "engine").parts
    if len(parts) == 1:
        return  # engine/__init__.py: the public API gathers every layer
    own = LAYERS.index(parts[0])
    for module, top in engine_imports(path):
        layer = module.split(".")[1] if "." in module else None
        if layer not in LAYERS or not top:
            continue  # the package itself (its version), or a function's import on request
        assert LAYERS.index(layer) <= own, (
            f"{path.relative_to(ROOT)} imports {module} at module level: "
            f"{layer} is above {parts[0]}"
        )


@pytest.mark.parametrize("path", files("service"), ids=lambda p: str(p.relative_to(ROOT)))
def test_the_service_never_imports_the_command(path):
    assert "demscale" not in {name for name, _ in imports(path)}, path.name


def _python_prints(code: str, *args: str) -> str:
    """What ``code`` prints, run with ``args`` in a fresh interpreter from the repository
    (a process of its own: what a module imports is seen from an empty ``sys.modules``)."""
    proc = subprocess.run(
        [sys.executable, "-c", code, *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    assert proc.returncode == 0, proc.stderr
    return proc.stdout.strip()


def test_import_engine_and_a_run_load_nothing_else():
    code = (
        "import sys, engine\n"
        "HEAVY = [['scipy', 'stats'], ['scipy', 'optimize'], ['scipy', 'special']]\n"
        "from tests.engine.test_uniaxial import tiny\n"
        "engine.run_uniaxial(tiny(unconfined=False))\n"
        "bad = sorted({m.split('.')[0] for m in sys.modules} & set(sys.argv[1:]))\n"
        "bad += sorted(m for m in sys.modules if m.split('.')[:2] in HEAVY)\n"
        "cuda = [m for m in sys.modules if m.startswith('numba.cuda')]\n"
        "print(bad, cuda)\n"
    )
    # numba itself imports scipy's top package where scipy is installed (for its LAPACK
    # bindings); the engine's statistics (scipy.stats, .special, .optimize) load on first use
    forbidden = sorted(ABOVE | {"h5py", "matplotlib", "distributed", "pandas"})
    out = _python_prints(code, *forbidden)
    assert out == "[] []", out


def test_the_worker_imports_no_web_stack_and_no_plots():
    """A worker process (started anew for each claim after a crash, and in the test suite
    dozens of times) needs neither the API's stack nor matplotlib: FastAPI alone was a tenth
    of its start (service/jsonsafe.py)."""
    code = (
        "import sys, service.worker\n"
        "print(sorted({m.split('.')[0] for m in sys.modules} & set(sys.argv[1:])))\n"
    )
    out = _python_prints(code, "fastapi", "starlette", "matplotlib", "uvicorn")
    assert out == "[]", out


#: A study flows one way (ARCHITECTURE.md, docs/PHYSICS.md section 7.1): each module of
#: engine/study imports at module level only the modules before it in this order.
STUDY_FLOW = (
    "channel",
    "intervals",
    "metrics",
    "kinds",
    "spec",
    "pooling",
    "reasons",
    "rates",
    "seeds",
    "comparison",
    "noise",
    "judge",
    "resolution",
    "plan",
    "look",
    "allocate",
    "stopping",
    "report",
    "adhesion",
    "advice",
    "results",
    "loop",
    "run",
)


def test_a_study_flows_one_way():
    study = ROOT / "engine" / "study"
    assert {p.stem for p in study.glob("*.py")} - {"__init__"} == set(STUDY_FLOW)
    for i, name in enumerate(STUDY_FLOW):
        tree = ast.parse((study / f"{name}.py").read_text())
        for node in tree.body:
            if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module:
                dep = node.module.split(".")[0]
                assert dep in STUDY_FLOW[:i], f"study/{name}.py imports .{dep}, not before it"
