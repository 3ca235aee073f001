"""Packaging without the package index: pyproject.toml declares an SPDX licence, the console
script and the extras; the engine (and the ``demscale`` command's help) import with none of
the optional packages present. ``scripts/check_install.sh`` checks real installs into fresh
virtual environments (it needs the index)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib")  # Python 3.11+

ROOT = Path(__file__).resolve().parent.parent
OPTIONAL = (
    "fastapi",
    "uvicorn",
    "sqlmodel",
    "pydantic",
    "pydantic_settings",
    "h5py",
    "matplotlib",
    "rich",
    "httpx",
)


def test_pyproject_declares_licence_script_and_extras():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    project = meta["project"]
    assert project["license"] == "MIT"  # an SPDX expression, not the deprecated table
    assert meta["build-system"]["requires"] == ["setuptools>=77"]  # PEP 639 support
    assert project["dependencies"] == ["numpy>=1.24", "numba>=0.59", "scipy>=1.11"]
    assert project["scripts"] == {"demscale": "demscale.cli:main"}
    extras = project["optional-dependencies"]
    assert {"service", "cli", "snapshots"} <= set(extras)
    assert any(d.startswith("rich") for d in extras["cli"])
    assert any(d.startswith("h5py") for d in extras["snapshots"])
    assert "demscale*" in meta["tool"]["setuptools"]["packages"]["find"]["include"]


# None in sys.modules: `import x` raises ImportError and importlib.util.find_spec("x") is
# None, as when x is not installed
BLOCK = f"""
import sys
OPTIONAL = {OPTIONAL!r}
sys.modules.update(dict.fromkeys(OPTIONAL))
"""


def _without_optional(code: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", BLOCK + code], cwd=ROOT, capture_output=True, text=True, timeout=300
    )


def test_engine_imports_with_numpy_and_numba_only():
    proc = _without_optional("""
import engine, engine.io.vtkhdf, demscale.cli
assert all(sys.modules[m] is None for m in OPTIONAL)
print(engine.UniaxialTest(cell=(0.015, 0.015, 0.015)).n_particles)
""")
    assert proc.returncode == 0, proc.stderr
    assert int(proc.stdout) > 10


def test_command_help_without_extras_and_study_names_its_extra():
    proc = _without_optional("""
from demscale.cli import main
try:
    main(["--help"])
except SystemExit as e:
    assert e.code == 0
sys.exit(main(["study", "examples/quick_study.json", "--out", "/nonexistent/never"]))
""")
    assert proc.returncode == 2, proc.stderr
    assert "usage: demscale" in proc.stdout
    assert 'pip install "demscale[cli]"' in proc.stderr
