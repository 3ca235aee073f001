"""Shared test set-up: kernel cache in the user cache dir unless DEMSCALE_CACHE_DIR is set.

``DEMSCALE_TEST_CPU_LOG=FILE`` appends a line per test to FILE: its node id, "all" (setup,
call and teardown together),
wall seconds, CPU seconds of the test's process (all its threads) and of the child
processes it waited for. The suite's cost is CPU on two cores, not the wall time of a test
beside others (a test that sleeps on a subprocess costs its wall time, not its CPU):
``sort -t$'\\t' -k4 -rn FILE`` ranks what to trim."""

from __future__ import annotations

import os
import resource
import time

import pytest

_CPU_LOG = os.environ.get("DEMSCALE_TEST_CPU_LOG")


def _cpu() -> tuple[float, float]:
    s = resource.getrusage(resource.RUSAGE_SELF)
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime, c.ru_utime + c.ru_stime


if _CPU_LOG:

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_protocol(item, nextitem):
        w0, (s0, c0) = time.monotonic(), _cpu()
        yield
        w1, (s1, c1) = time.monotonic(), _cpu()
        with open(_CPU_LOG, "a") as f:
            f.write(f"{item.nodeid}\tall\t{w1 - w0:.2f}\t{s1 - s0:.2f}\t{c1 - c0:.2f}\n")


# One kernel per family (and friction cap and periodic axes) for every test scene, not one
# per scene's set of switches: the same bits (tests/engine/test_kernels.py, which holds the
# scene mode to it), far fewer kernels compiled on a cold run (each 10-40 s of CPU; counts in
# docs/GUIDE.md, Development). Test scenes keep to a few sets of periodic axes for the same
# reason (tests/engine/helpers.py::pair_scene). Tests of the specialisation itself set
# DEMSCALE_KERNELS=scene; subprocesses (workers, the CLI) inherit the mode.
os.environ.setdefault("DEMSCALE_KERNELS", "general")
