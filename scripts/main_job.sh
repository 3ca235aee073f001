#!/usr/bin/env bash
# The main job: set up ./.venv, start the API with its embedded worker on 127.0.0.1, submit the
# default scaling study, show its progress and print where its summary and plots are served.
# Extra arguments go to `demscale job` (e.g. --port 8001, --exit).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bash scripts/setup_env.sh
exec .venv/bin/python -m demscale job "$@"
