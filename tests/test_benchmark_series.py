"""benchmarks.series: the run series' listing and their runs of what is not stored; and
benchmarks.unloading_transient's reading of a run's full file."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

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


def test_the_unloading_transient_reads_a_velocity_jumps_stress_wave(tmp_path):
    """benchmarks/unloading_transient.run_row on a made-up full file: a platen moving down
    at 0.2 m/s then up at 0.02 m/s, the top stress dropping by rho_b c (0.22 m/s) with c =
    25 m/s and the interior's not at all, gives c_eff = 25 m/s and the shares left."""
    import h5py

    from benchmarks.unloading_transient import run_row

    path = tmp_path / "run.h5"
    with h5py.File(path, "w") as f:
        c = f.create_group("stages/consolidation")
        c["platen_gap"] = [0.1002, 0.1000]
        c["time"] = [0.999, 1.000]
        c["porosity_interior"] = [0.45, 0.44]
        u = f.create_group("stages/unloading")
        u["platen_gap"] = [0.1000, 0.10002]
        u["time"] = [1.000, 1.001]
        rho_b = 2000.0 * (1 - 0.44)
        u["stress_top"] = [2e4, 2e4 - rho_b * 25.0 * 0.22]
        u["stress_interior"] = [2.05e4, 2.05e4]
    r = run_row(path, 2000.0)
    assert r["v_load"] == pytest.approx(0.2) and r["v_unload"] == pytest.approx(0.02)
    assert r["c_eff"] == pytest.approx(25.0) and r["bulk_density"] == pytest.approx(rho_b)
    assert r["interior_share_left"] == 1.0 and r["top_share_left"] < 0.7
