"""Compile every CUDA kernel of the CUDA backend to PTX for a GPU architecture, without a
GPU: the real numba-cuda target (typing, lowering, NVVM), which the simulator does not
exercise. Needs NVVM and NVRTC (pip wheels nvidia-nvvm and nvidia-cuda-nvrtc, found through
LD_LIBRARY_PATH or the CUDA toolkit).

    python scripts/cuda_ptx_check.py [--cc 9.0]

The scenes of tests/engine/cuda_cases.py are set up and one call and one rebuild are made
(then a curve sample's measures, the pour's speed cap and a platen speed on the device) with
every kernel launch replaced by a PTX compile for the argument types of that launch.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from numba.cuda import compile_ptx
from numba.cuda.typing.typeof import typeof


class HostArray(np.ndarray):
    """A numpy array standing in for a device array (copy_to_host, slicing)."""

    def copy_to_host(self, out=None, stream=0):
        if out is None:
            return np.array(self)
        out[...] = self
        return out

    def copy_to_device(self, ary, stream=0):
        self[...] = ary


class HostStream:
    """A stream standing in for a CUDA stream (nothing is queued)."""

    def synchronize(self):
        pass


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cc", default="9.0")
    args = ap.parse_args()
    cc = tuple(int(v) for v in args.cc.split("."))
    import numba.cuda.dispatcher as nd

    class _Device:  # device functions compile for the current device's architecture
        compute_capability = cc

    nd.get_current_device = lambda: _Device()
    import engine.cuda.kernels as ck
    import engine.cuda.simulation as cs

    compiled: dict = {}

    class Fake:
        def __init__(self, fn):
            self.py_func = fn
            self.overloads = {0: self}

        def specialize(self, *a):
            return self

        def max_cooperative_grid_blocks(self, *a):
            return 1

        def __getitem__(self, config):
            def launch(*a):
                sig = tuple(typeof(v) for v in a)
                key = (id(self.py_func), sig)
                if key not in compiled:
                    t0 = time.perf_counter()
                    ptx, _ = compile_ptx(self.py_func, sig, cc=cc)
                    compiled[key] = len(ptx)
                    print(
                        f"  {self.py_func.__name__}: {len(ptx)} bytes of PTX "
                        f"({time.perf_counter() - t0:.1f} s)",
                        flush=True,
                    )

            return launch

    real_kernel = ck.kernel
    ck.kernel = lambda fn, bindings, memo: Fake(real_kernel(fn, bindings, memo).py_func)
    cs.cuda.to_device = lambda a, stream=0: np.array(a).view(HostArray)
    cs.cuda.default_stream = HostStream
    import engine.cuda.measures as cm

    cm.kernel = ck.kernel  # the measure kernels too (engine.cuda.measures)

    def read_ctl(self):
        return np.array([1, 0, 1, 0])  # stopped after one step: OK

    cs.CudaSimulation._read_ctl = read_ctl
    from tests.engine import cuda_cases as cc_

    scenes = {
        "bilinear-walls": cc_.scene(cc_.FULL),
        "eepa": cc_.scene(cc_.EEPA),
        "eepa-normal-cap": cc_.scene(cc_.EEPA_NORMAL_CAP, periodic=(True, False, False)),
        "hertz-open-box": cc_.scene(cc_.HERTZ, periodic=(False, False, False)),
        "periodic": cc_.scene(cc_.ELASTIC, periodic=(True, True, True), walls=False, gravity=False),
    }
    for launch in ("persistent", "passes"):
        os.environ["DEMSCALE_CUDA_LAUNCH"] = launch
        for name, sc in scenes.items():
            print(f"{name} ({launch}):", flush=True)
            sim = cs.CudaSimulation(sc)
            sim.run(2)
            # a curve sample's measures, the pour's cap and a platen speed on the device
            sim.sample_sums(0.0, float(np.inf) if len(sc.walls) < 2 else 0.02, 0.003, 0.012)
            sim.cap_speed(0.01)
            if sc.walls:
                sim.set_wall_velocity(0, (0.0, 0.0, 0.0))
            if any(sc.periodic):  # new kernels for the new features, launched again
                sim.set_periodic((False, False, False))
                sim.run(2)
    print(f"PTX for compute capability {args.cc}: {len(compiled)} kernel signatures compiled")
    return 0


if __name__ == "__main__":
    sys.exit(main())
