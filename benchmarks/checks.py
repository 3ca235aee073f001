"""Target checks shared by the benchmarks."""

from __future__ import annotations


def report(checks: list[tuple[str, bool]]) -> int:
    """Print PASS/FAIL per target; the exit status is 0 when every target is met."""
    print()
    for what, ok in checks:
        print(f"{'PASS' if ok else 'FAIL'}  {what}")
    return 0 if all(ok for _, ok in checks) else 1
