#!/usr/bin/env bash
# The test suite: set up ./.venv, lint and check the formatting (ruff), hold the stored
# results to their size cap (scripts/check_results.py), then run every test (benchmarks
# excluded) on 2 workers.
# Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/setup_env.sh
.venv/bin/ruff check engine service tests benchmarks demscale scripts
.venv/bin/ruff format --check engine service tests benchmarks demscale scripts
.venv/bin/python scripts/check_results.py
exec .venv/bin/python -m pytest -n 2 --timeout 600 "$@"
