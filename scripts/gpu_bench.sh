#!/usr/bin/env bash
# Issue 21's GPU figures in one call on a host with an NVIDIA GPU (about 8 minutes on an H200):
#   bash scripts/gpu_bench.sh            # the targets 1-3 of benchmarks/gpu_speed.py
#   bash scripts/gpu_bench.sh --batch 15 # target 4 alone (experiment (b)'s 15 runs)
# numba-cuda and its CUDA Python packages come from wheels/ when they are not installed
# (no package registry needed): pip download numba-cuda==0.30.4 cuda-bindings==13.5.0 \
#   cuda-core==1.2.2 cuda-pathfinder==1.9.1 --no-deps -d wheels/   (cp311 wheels, 16 MB)
# The host needs an NVIDIA driver and the CUDA toolkit's NVVM, NVRTC and libcudadevrt (a
# CUDA 12 or 13 toolkit, or the nvidia-nvvm / nvidia-cuda-nvrtc wheels on LD_LIBRARY_PATH).
set -u
cd "$(dirname "${BASH_SOURCE[0]}")/.."
PY=${PYTHON:-python3}
if [ -x .venv/bin/python ] && .venv/bin/python -c "import numba" 2>/dev/null; then
  PY=.venv/bin/python
fi
if ! "$PY" -c "import numba_cuda" 2>/dev/null; then
  "$PY" -m pip install --quiet --no-deps --no-index --target .gpu-site wheels/*.whl || exit 2
  export PYTHONPATH="$PWD/.gpu-site:${PYTHONPATH:-}"
fi
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv 2>&1 || true
"$PY" -c "from numba import cuda; cuda.detect()" 2>&1 | tail -5
export DEMSCALE_CACHE_DIR="${DEMSCALE_CACHE_DIR:-$PWD/.cache/demscale}"
exec timeout 570 "$PY" -m benchmarks.engine_speed --backend cuda --deadline 400 "$@"
