"""benchmarks.series: the run series' listing and their runs of what is not stored."""

from __future__ import annotations

from types import SimpleNamespace

from benchmarks.series import list_runs, run_missing

#: The run keys of a series of two runs, (1,) and (2,): the first stored, the second not.
KEYS = [(1,), (2,)]


def stored(k):
    return SimpleNamespace(ok=True) if k == 1 else None


def test_only_the_runs_not_stored_run_in_order(capsys):
    ran = []
    rc = run_missing(
        [*KEYS, (3,)],
        stored,
        lambda k: f"k{k}",
        lambda k: SimpleNamespace(n_particles=10 * k),
        lambda k: ran.append(k) or f"ran {k}",
        "benchmarks.some_report",
    )
    assert rc == 0 and ran == [2, 3]
    out = capsys.readouterr().out.splitlines()
    assert out == [
        "running k2 (20 particles)",
        "ran 2",
        "running k3 (30 particles)",
        "ran 3",
        "the report: python -m benchmarks.some_report",
    ]


def test_the_list_counts_only_what_is_left(capsys):
    total = list_runs(KEYS, stored, lambda k: 60.0 * k, lambda k, s, est: f"{k[0]} {s is None}")
    assert total == 120.0
    assert capsys.readouterr().out.splitlines() == ["1 False", "2 True"]
