#!/usr/bin/env bash
# Create ./.venv (once) and install demscale with the service, test and cli extras into it.
# Run by main_job.sh and test.sh; re-running only reinstalls when pyproject.toml changed.
# Installs with uv (itself pip-installed into .venv), or with pip when that fails.
# Quiet unless something fails: the installer's output (and setuptools' notes on editable installs)
# goes to .venv/setup.log, printed whole if the install fails. The `demscale` command lives
# in ./.venv/bin: `source .venv/bin/activate` puts it on a shell's PATH (said once, when
# installed).
# DEMSCALE_BYTECODE=lazy (scripts/test.sh) installs without compiling every installed module
# to bytecode (about 28 s of CPU on 2 cores, most of the install): the test run writes the
# bytecode of the modules it imports instead. By default (all) every module is compiled, so
# that on a machine where PYTHONDONTWRITEBYTECODE is set no process compiles them again; a
# venv installed lazily is compiled then (the stamp keeps the mode). Any other value is
# refused, installed or not.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
mode=${DEMSCALE_BYTECODE:-all}
case "$mode" in
  all) bytecode=(--compile-bytecode) pip_bytecode=() ;;
  lazy) bytecode=() pip_bytecode=(--no-compile) ;;
  *)
    echo "setup: DEMSCALE_BYTECODE must be 'all' or 'lazy', not '$mode'" >&2
    exit 2
    ;;
esac
# The stamp holds the mode of the install (empty in stamps written before the modes: all).
stamp=.venv/.demscale-installed
log=.venv/setup.log
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  echo "setup: installing demscale and its service, test and cli extras into ./.venv ..."
  # uv resolves and installs the same releases as pip in about a quarter of the time (its
  # downloads in parallel; measured on a fresh clone: CHANGELOG); pip when uv cannot be had
  # uv reads no pip configuration: a package mirror given to pip in the environment is
  # passed on (one in pip.conf is not; uv then fails or reaches pypi.org, and pip follows)
  if [ -n "${PIP_INDEX_URL:-}" ]; then export UV_INDEX_URL="${UV_INDEX_URL:-$PIP_INDEX_URL}"; fi
  if [ -n "${PIP_EXTRA_INDEX_URL:-}" ]; then
    export UV_EXTRA_INDEX_URL="${UV_EXTRA_INDEX_URL:-$PIP_EXTRA_INDEX_URL}"
  fi
  install_uv() {
    .venv/bin/python -m pip install --quiet uv &&
      .venv/bin/python -m uv pip install --quiet ${bytecode[@]+"${bytecode[@]}"} --python .venv/bin/python -e '.[service,test,cli]'
  }
  install_pip() {
    .venv/bin/python -m pip install --quiet --upgrade pip &&
      .venv/bin/python -m pip install --quiet ${pip_bytecode[@]+"${pip_bytecode[@]}"} -e '.[service,test,cli]'
  }
  rm -f "$log.uv"
  if ! install_uv >"$log" 2>&1; then
    echo "setup: uv could not install (its output in $log.uv); installing with pip" >&2
    mv "$log" "$log.uv"
    if ! install_pip >"$log" 2>&1; then
      cat "$log" >&2
      echo "setup: the install into ./.venv failed (pip's output above, kept in $log)" >&2
      exit 1
    fi
  fi
  echo "$mode" >"$stamp"
  echo "setup: done. The demscale command is in ./.venv/bin: run 'source .venv/bin/activate'"
  echo "       in each new shell (or call .venv/bin/demscale), then e.g. 'demscale --help'."
elif [ "$mode" = all ] && [ "$(cat "$stamp")" = lazy ]; then
  # installed lazily (by scripts/test.sh): every module compiled now, as an install would
  echo "setup: compiling the installed modules to bytecode (installed without) ..."
  .venv/bin/python -m compileall -q -j 0 .venv/lib >>"$log" 2>&1 || true
  echo all >"$stamp"
fi
