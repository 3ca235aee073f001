#!/usr/bin/env bash
# Issue 21's GPU figures in one call on a host with an NVIDIA GPU (about 9 minutes on an H200;
# measured 2026-12-04 in docs/GPU.md):
#   bash scripts/gpu_bench.sh            # targets 1-3 of benchmarks/gpu_speed.py
#   bash scripts/gpu_bench.sh --batch 15 # target 4 alone (experiment (b)'s 15 runs)
#   bash scripts/gpu_bench.sh --runs     # issue 54 (under 9 minutes): the reference at the
#                                        # default protocol alone, then experiment (b)'s runs
#                                        # side by side on streams (engine.cuda.batch),
#                                        # aggregate particle-steps/s; not measured yet
#   bash scripts/gpu_bench.sh --series   # issue 54's third point (under 9 minutes): one
#                                        # outlet-series hopper (64 d, 36,651 particles) and
#                                        # one 20-diameter column (55,004) on the GPU against
#                                        # their stored CPU seeds; not measured yet
# Wheels in wheels/ (git-ignored) are installed with --no-deps --no-index into .gpu-site and
# put first on the path, so a host without a package registry gets what it lacks:
# - numba-cuda 0.30.4 when the host has none: pip download numba-cuda==0.30.4
#   cuda-bindings==13.5.0 cuda-core==1.2.2 cuda-pathfinder==1.9.1 --no-deps -d wheels/
#   (with --python-version of the host's Python and --only-binary=:all:);
# - a numpy older than 2.5 where the host has 2.5 or newer: numba-cuda 0.30.4 registers
#   np.row_stack, which numpy 2.5 removed, and every kernel compile fails with
#   "module 'numpy' has no attribute 'row_stack'" (seen on the H200 image: Python 3.12,
#   numba 0.68.0, numba-cuda 0.30.4, numpy 2.5.2; a cp312 numpy 2.4.6 wheel, 16.6 MB, fixes it).
# The host needs an NVIDIA driver and the CUDA toolkit's NVVM, NVRTC and libcudadevrt (a
# CUDA 12 or 13 toolkit, or the nvidia-nvvm / nvidia-cuda-nvrtc wheels on LD_LIBRARY_PATH).
# Files read besides the code: benchmarks/liggghts/pack2k.data and the stored CPU references
# benchmarks/results/paper/b_cohesive/ref-s{1,2,3}.h5 and
# benchmarks/results/paper/protocol/ref-I5e-4-f0.4-s{1,2,3}.h5; the GPU runs are stored in
# benchmarks/results/gpu/.
set -u
cd "$(dirname "${BASH_SOURCE[0]}")/.."
PY=${PYTHON:-python3}
if [ -x .venv/bin/python ] && .venv/bin/python -c "import numba" 2>/dev/null; then
  PY=.venv/bin/python
fi
if compgen -G "wheels/*.whl" >/dev/null; then
  rm -rf .gpu-site
  "$PY" -m pip install --quiet --no-deps --no-index --no-compile --target .gpu-site wheels/*.whl || exit 2
  export PYTHONPATH="$PWD/.gpu-site:${PYTHONPATH:-}"
fi
if ! "$PY" -c "import numba_cuda" 2>/dev/null; then
  echo "numba-cuda is missing: put its wheels in wheels/ (see the header of this script)"
  exit 2
fi
if ! "$PY" -c "import sys, numpy; sys.exit(tuple(map(int, numpy.__version__.split('.')[:2])) >= (2, 5))"; then
  echo "numpy $("$PY" -c 'import numpy; print(numpy.__version__)') breaks numba-cuda 0.30.4: put a numpy 2.4 wheel in wheels/"
  exit 2
fi
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv 2>&1 || true
"$PY" -c "from numba import cuda; cuda.detect()" 2>&1 | tail -5
export DEMSCALE_CACHE_DIR="${DEMSCALE_CACHE_DIR:-$PWD/.cache/demscale}"
# the reductions' small grids are deliberate (one block sums the chunk sums)
export NUMBA_CUDA_LOW_OCCUPANCY_WARNINGS=0 PYTHONUNBUFFERED=1
exec timeout 585 "$PY" -m benchmarks.engine_speed --backend cuda --deadline 480 "$@"
