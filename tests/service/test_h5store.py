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


def test_an_eepa_study_is_stored_with_its_law_and_resolved_exponents(tmp_path):
    import json

    spec = {k: v for k, v in TINIEST.items() if k != "name"}
    spec["reference"] = {
        **spec["reference"],
        "pair_law": {
            "type": "EEPA",
            "k1": 5e5,
            "k2": 2.5e6,
            "f0": -0.1,
            "n": 1.5,
            "chi": 1.25,
            # no adhesive branch (kadh 0): the switches of test_shear's EEPA bed, whose
            # kernel is compiled already; chi still resolves its exponent
        },
    }
    spec["rules"] = ["similarity"]
    res = engine.run_study(engine.StudySpec.from_dict(spec))
    path = tmp_path / "results.h5"
    write_results(path, "s1", res, still_ours=lambda: True)
    with h5py.File(path) as f:
        stored = json.loads(f.attrs["spec"])
        assert stored["reference"]["pair_law"]["type"] == "EEPA"
        assert stored["reference"]["pair_law"]["n"] == 1.5
        g = f["runs/r3.1mm-similarity-s1"]
        assert g.attrs["stiffness_exponent"] == pytest.approx(0.5)
        assert g.attrs["adhesive_exponent"] == pytest.approx(0.75)
        assert g.attrs["adhesion_exponent"] == 2.0
