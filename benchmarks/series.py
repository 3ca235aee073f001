"""What the benchmarks' run series (:mod:`benchmarks.size_series`,
:mod:`benchmarks.hopper_series`) share: listing their runs with the CPU time left, and
running those not stored yet. A run is named by its key, a tuple the series' functions take
as arguments (``stored(*key)``, ``estimate(*key)``, ...)."""

from __future__ import annotations

from collections.abc import Callable, Iterable


def list_runs(keys: Iterable[tuple], stored: Callable, estimate: Callable, line: Callable) -> float:
    """Print ``line(key, digest, seconds)`` for each run key of ``keys``, ``digest`` its
    stored digest (None: not run yet) and ``seconds`` its estimated CPU time [s]; return the
    estimated CPU time of the runs not stored [s]."""
    total = 0.0
    for k in keys:
        s, est = stored(*k), estimate(*k)
        if s is None:
            total += est
        print(line(k, s, est))
    return total


def run_missing(
    keys: Iterable[tuple],
    stored: Callable,
    key_name: Callable,
    test_of: Callable,
    run_one: Callable,
    report: str,
) -> int:
    """Run, in order, each run of ``keys`` that has no stored digest, printing what it runs
    and ``run_one``'s line; then the command of the series' report (``python -m report``).
    Returns 0 (the exit status)."""
    for k in keys:
        if stored(*k) is None:
            print(f"running {key_name(*k)} ({test_of(*k).n_particles} particles)", flush=True)
            print(run_one(*k), flush=True)
    print(f"the report: python -m {report}")
    return 0


def list_or_run(
    listing: bool,
    keys: list[tuple],
    stored: Callable,
    estimate: Callable,
    line: Callable,
    key_name: Callable,
    test_of: Callable,
    run_one: Callable,
    report: str,
) -> int:
    """A series' command: with ``listing`` its runs (:func:`list_runs`) and the CPU time left,
    else run those not stored (:func:`run_missing`). Returns the exit status."""
    if listing:
        total = list_runs(keys, stored, estimate, line)
        print(f"left to run: about {total / 3600:.1f} h CPU on one thread (wall: more, shared)")
        return 0
    return run_missing(keys, stored, key_name, test_of, run_one, report)
