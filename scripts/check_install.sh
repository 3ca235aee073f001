#!/usr/bin/env bash
# Install demscale into fresh virtual environments the way a user would, from this checkout,
# and check what each install brings (needs the package index: not part of the test run).
#
#   1. `pip install .`            the engine alone: numpy + numba, no fastapi, h5py,
#                                 matplotlib or rich; `import engine` works and the
#                                 `demscale` command prints its help
#   2. `pip install ".[cli]"`     adds rich, h5py and matplotlib: `demscale study` can run
#   3. `pip install ".[service]"` (with --service) the API imports
# The wheel is built once, verbosely, and the build log must not mention a deprecation.
# Usage: bash scripts/check_install.sh [--service]    (PYTHON=python3.12 to pick the Python)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
PY=${PYTHON:-python3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

echo "== building the wheel (isolated build, setuptools from the index)"
"$PY" -m venv "$work/build"
"$work/build/bin/python" -m pip install --quiet --upgrade pip
"$work/build/bin/python" -m pip wheel --no-deps -v -w "$work/dist" . >"$work/build.log" 2>&1 \
  || { cat "$work/build.log"; exit 1; }
if grep -i "deprecat" "$work/build.log"; then
  echo "FAIL: the build warns of a deprecation (above)"; exit 1
fi
wheel=$(ls "$work"/dist/demscale-*.whl)
echo "   $(basename "$wheel"): no deprecation warning"

echo "== engine only: pip install demscale"
"$PY" -m venv "$work/engine"
"$work/engine/bin/python" -m pip install --quiet "$wheel"
# from outside the checkout, so that `import engine` finds the installed package
(cd "$work" && "$work/engine/bin/python" - <<'EOF'
import importlib.util
import sys

import engine

extra = [m for m in ("fastapi", "h5py", "matplotlib", "rich", "sqlmodel", "uvicorn")
         if importlib.util.find_spec(m) is not None]
assert not extra, f"the engine-only install brought {extra}"
assert "site-packages" in engine.__file__, engine.__file__
test = engine.UniaxialTest(cell=(0.015, 0.015, 0.015))
print(f"   engine {engine.__version__} from {engine.__file__}: {test.n_particles} particles "
      f"in the tiny test; installed: numpy, numba only ({sys.version.split()[0]})")
EOF
)
"$work/engine/bin/demscale" --help >/dev/null
if "$work/engine/bin/demscale" study examples/quick_study.json --out "$work/o" 2>"$work/err"; then
  echo "FAIL: demscale study ran without its extra"; exit 1
fi
grep -q 'demscale\[cli\]' "$work/err" || { cat "$work/err"; exit 1; }
echo "   demscale --help works; demscale study asks for demscale[cli]"

echo "== with the cli extra: pip install \"demscale[cli]\""
"$work/engine/bin/python" -m pip install --quiet "$wheel[cli]"
(cd "$work" && "$work/engine/bin/python" -c "import h5py, matplotlib, rich, engine.io.vtkhdf, demscale.cli")
echo "   rich, h5py, matplotlib import"

if [ "${1:-}" = "--service" ]; then
  echo "== with the service extra: pip install \"demscale[service]\""
  "$work/engine/bin/python" -m pip install --quiet "$wheel[service]"
  (cd "$work" && "$work/engine/bin/python" -c "
from pathlib import Path
import service.web
from service.app import create_app
assert (Path(service.web.__file__).parent / 'templates' / 'studies.html').is_file()")
  "$work/engine/bin/demscale" serve --help >/dev/null
  echo "   service.app imports, the page templates are installed; demscale serve --help works"
fi
echo "OK"
