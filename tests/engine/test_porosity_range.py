"""The porosity range LabTargets accepts is the measured one (benchmarks/porosity_range.py):
the constant agrees with the stored measurement, the stored range is the benchmark's rule
applied to the stored readings, and a porosity outside it is refused by field and limit."""

from __future__ import annotations

import json

import pytest

import engine
from benchmarks import porosity_range as bench
from engine.calibration import LabTargets
from engine.calibration.targets import POROSITY_RANGE


@pytest.fixture(scope="module")
def stored():
    return json.loads(bench.SUMMARY.read_text())


def test_every_grid_run_is_stored_read_or_reported_failed(stored):
    keys = {bench.key(p, s) for p, s in bench.jobs()}
    assert not stored["missing"]
    assert set(stored["runs"]) | set(stored["failed"]) == keys
    assert not set(stored["runs"]) & set(stored["failed"])
    # every grid point is measured by at least one seed
    for p in bench.points():
        assert any(bench.key(p, s) in stored["runs"] for s in bench.SEEDS), p


def test_the_stored_range_is_the_rule_applied_to_the_stored_readings(stored):
    assert bench.decide_range(stored["runs"]) == stored["range"]


def test_porosity_range_is_the_stored_measurement(stored):
    # python -m benchmarks.porosity_range --report rewrites the summary from the stored runs
    assert tuple(stored["range"]["range"]) == POROSITY_RANGE


def test_the_range_holds_every_reading_of_every_run(stored):
    lo, hi = POROSITY_RANGE
    for run in stored["runs"].values():
        for reading in bench.READINGS:
            for branch in ("loading", "unloading"):
                for v in run[reading][branch].values():
                    assert lo < v < hi


def _targets(porosity: float) -> LabTargets:
    return LabTargets.from_dict(
        {
            "tester": "uniaxial",
            "compression": [{"stress": 1e4, "porosity": porosity, "sd": 0.01}],
        }
    )


@pytest.mark.parametrize("side", [0, 1])
def test_a_porosity_outside_the_range_is_refused_naming_the_field_and_the_limit(side):
    lo, hi = POROSITY_RANGE
    outside = lo - 0.01 if side == 0 else hi + 0.01
    with pytest.raises(engine.ParameterError) as e:
        _targets(outside)
    assert e.value.field == "LabTargets.compression[0].porosity"
    assert f"[{lo:g}, {hi:g}]" in e.value.limit
    assert "benchmarks.porosity_range" in str(e.value)


def test_the_range_edges_are_accepted():
    lo, hi = POROSITY_RANGE
    for p in (lo, hi):
        assert _targets(p).compression[0].porosity == p
