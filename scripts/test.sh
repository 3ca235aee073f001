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
# Installed without compiling every module to bytecode (DEMSCALE_BYTECODE=lazy: most of the
# install's CPU); the run below writes the bytecode of what it imports instead.
DEMSCALE_BYTECODE=lazy bash scripts/setup_env.sh
.venv/bin/ruff check engine service tests benchmarks demscale scripts
.venv/bin/ruff format --check engine service tests benchmarks demscale scripts
.venv/bin/python scripts/check_results.py
# Bytecode written, whatever the machine's PYTHONDONTWRITEBYTECODE says (it is set on the
# project's machines): each module the suite imports is compiled once and read by every
# later process (the suite starts a hundred-odd: workers, CLI runs, service workers, the
# simulator's cases), and pytest keeps its assert-rewritten test modules likewise.
unset PYTHONDONTWRITEBYTECODE
# Plugins named, not autoloaded: pytest rewrites the asserts of every module of an autoloaded
# plugin's distribution (schemathesis's, hypothesis's, anyio's: 263 modules), 3.5 s of CPU in
# each of the workers' collections (measured 2026-12-07); named, only the plugin module is.
export PYTEST_DISABLE_PLUGIN_AUTOLOAD=1
plugins=(-p xdist.plugin -p pytest_timeout -p schemathesis.pytest.plugin -p _hypothesis_pytestplugin)
# One collection first, in two halves side by side, writes that bytecode and the rewritten
# test modules, so that the three workers, which collect together, do not each compile the
# same modules (measured 2026-12-07 under load: set-up and the workers' collections 81 s of
# wall time and 79 s of CPU against 101 s and 107 s with every module compiled at install).
# Its output goes to .venv/warmup-{1,2}.log, and neither its failure nor its time limit
# (300 s) stops the suite: the run below reports any collection error. The schemathesis
# module's cases, built at collection, are left to the workers (nothing to compile). Only
# for the whole suite (no arguments, as CI runs it): a run of a few tests skips it.
if [ "$#" -eq 0 ]; then
  warm=(timeout 300 .venv/bin/python -m pytest "${plugins[@]}" --collect-only -q -p no:cacheprovider)
  "${warm[@]}" tests/engine >.venv/warmup-1.log 2>&1 &
  "${warm[@]}" tests --ignore=tests/engine --ignore=tests/service/test_schemathesis.py \
    >.venv/warmup-2.log 2>&1 &
  wait
fi
exec .venv/bin/python -m pytest "${plugins[@]}" -n 3 --dist worksteal --timeout 600 "$@"
