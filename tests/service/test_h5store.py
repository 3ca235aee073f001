"""The HDF5 writer leaves nothing behind when the study is no longer the worker's."""

from __future__ import annotations

import h5py
import pytest

import engine
from service.h5store import NotOurs, write_results
from tests.service.conftest import TINIEST


@pytest.fixture(scope="module")
def result():
    spec = {k: v for k, v in TINIEST.items() if k != "name"}
    return engine.run_study(engine.StudySpec.from_dict(spec))


def test_results_written_only_while_ours(result, tmp_path):
    path = tmp_path / "study" / "results.h5"
    with pytest.raises(NotOurs):
        write_results(path, "s1", result, still_ours=lambda: False)
    assert not path.exists() and list(path.parent.iterdir()) == []  # no temporary left
    write_results(path, "s1", result, still_ours=lambda: True)
    with h5py.File(path) as f:
        assert set(f["runs"]) == set(result.runs)
    assert [p.name for p in path.parent.iterdir()] == ["results.h5"]
