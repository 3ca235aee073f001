#!/usr/bin/env bash
# The test suite: set up ./.venv, lint and check the formatting (ruff), hold the stored
# results to their size cap (scripts/check_results.py), then run every test (benchmarks
# excluded) on 3 workers: on 2 cores a third keeps them busy while a worker waits for a kernel
# another is compiling (the compile lock) or for a subprocess; measured 2026-12-07 on a
# fresh clone with cold caches: 1.85 cores busy on average with 3 workers, about 1.3 with 2
# (CHANGELOG). --dist worksteal: a worker left idle at the end takes queued tests from a busy one.
# The tests run in DEMSCALE_KERNELS=general (tests/conftest.py): one kernel per law family.
# Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/setup_env.sh
.venv/bin/ruff check engine service tests benchmarks demscale scripts
.venv/bin/ruff format --check engine service tests benchmarks demscale scripts
.venv/bin/python scripts/check_results.py
# The project's own sources compiled to bytecode once (about 2 s of CPU): where
# PYTHONDONTWRITEBYTECODE is set (as on the project's machines) no process writes them, and
# each of the suite's hundred-odd Python processes (workers, CLI runs, service workers, the
# simulator's cases) compiled engine/ and service/ again, about 0.15 s of CPU each.
.venv/bin/python -m compileall -q engine service demscale tests benchmarks
# Plugins named, not autoloaded: pytest rewrites the asserts of every module of an autoloaded
# plugin's distribution (schemathesis's, hypothesis's, anyio's: 263 modules), 3.5 s of CPU in
# each of the workers' collections (measured 2026-12-07); named, only the plugin module is.
export PYTEST_DISABLE_PLUGIN_AUTOLOAD=1
exec .venv/bin/python -m pytest -p xdist.plugin -p pytest_timeout -p schemathesis.pytest.plugin \
  -p _hypothesis_pytestplugin -n 3 --dist worksteal --timeout 600 "$@"
