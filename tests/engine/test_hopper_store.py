"""A hopper run in the one run layout (engine/io/store.py, docs/HOPPER.md): written and read
back bit for bit through its kind, NaN profiles and scalars included, with an added run's
round; a stored test of a type no kind has is refused naming it. No simulation."""

from __future__ import annotations

import json
import math

import h5py
import numpy as np
import pytest

import engine
from engine.hopper.results import HOPPER_CURVE_UNITS
from engine.io.store import load_run, read_addition, read_run_group, save_run, stage_names


def _result() -> engine.HopperResult:
    t = engine.HopperTest(shape="cone", outlet_width=0.035, particles=300, seed=4)
    curves = {k: np.linspace(0.0, 1.0, 7) * (i + 1) for i, k in enumerate(HOPPER_CURVE_UNITS)}
    curves["wall_speed"][3] = math.nan  # no grain in the band at that sample
    return engine.HopperResult(
        t,
        curves,
        np.array([0.0, 0.01, 0.02, 0.03]),
        np.array([300.0, 150.0, 50.0]),
        np.array([math.nan, math.nan, math.nan]),
        {"discharge_rate": 0.25, "arch_time": math.nan, "steps": 1234.0, "wall_time": 2.5},
    )


def test_a_hopper_run_is_stored_and_read_back(tmp_path):
    res = _result()
    added = [{"run": "r3.1mm-paper-s3", "round": 2, "kind": "coarse", "reason": "undecided"}]
    path = save_run(tmp_path / "r3.1mm-paper-s3.h5", res, added=added)
    back = load_run(path)
    assert isinstance(back, engine.HopperResult) and back.test == res.test
    assert back.scalars["discharge_rate"] == 0.25 and math.isnan(back.scalars["arch_time"])
    assert set(back.curves) == set(res.curves)
    for k, v in res.curves.items():
        np.testing.assert_array_equal(back.curves[k], v)
    np.testing.assert_array_equal(back.wall_edges, res.wall_edges)
    np.testing.assert_array_equal(back.wall_stress_fill, res.wall_stress_fill)
    assert np.isnan(back.wall_stress_flow).all() and back.wall_stress_flow.shape == (3,)
    with h5py.File(path) as f:
        assert json.loads(f.attrs["test"])["type"] == "HopperTest"
        assert stage_names(f) == ["discharge"] and f["stages/discharge"].attrs["steps"] == 1234
        assert f["stages/discharge/discharged_mass"].attrs["units"] == "kg"
        assert f["scalars"].attrs["discharge_rate_units"] == "kg/s"
        assert read_addition(f) == added


def test_a_stored_test_of_an_unknown_type_is_refused(tmp_path):
    path = save_run(tmp_path / "run.h5", _result())
    with h5py.File(path, "r+") as f:
        f.attrs["test"] = json.dumps({"type": "RingShear"})
    with h5py.File(path) as f, pytest.raises(ValueError, match="'RingShear'"):
        read_run_group(f)
