"""Records are plain: their JSON form is derived from the declared fields (no record writes its
own), building one does no work (no packing, no coarse test), and a study is planned by one
pure function whose plan reads back unchanged."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import h5py
import pytest

import engine
from engine.contact.registry import LAWS
from engine.core.records import from_dict, to_dict
from engine.uniaxial.spec import uniaxial_from_json

from . import toy_law
from .test_uniaxial import tiny

#: Fields of UniaxialTest declared after runs were stored, with the value such a run had
#: (those of the protocol of issue 40 read at their seed values, engine.uniaxial.spec
#: SEED_PROTOCOL, by UniaxialTest.from_stored).
FIELDS_SINCE = {
    "gravity": 9.81,
    "gravity_off_after_fill": False,
    "pour_speed": None,
    "inertial_number": None,
    "max_platen_speed": 0.1,
    "dt_fraction": 0.2,
    "strength_from": "platen",
}

STORED = sorted((Path(__file__).resolve().parents[2] / "benchmarks" / "results").glob("*/*/*.h5"))


def test_every_stored_run_reads_back_and_writes_the_same_bytes():
    """The stored runs (docs/VALIDATION.md is computed from them) are matched to planned tests
    by their JSON form: the derived form must be the hand-written one they were stored with,
    key order included."""
    checked = 0
    for path in STORED:
        with h5py.File(path, "r") as f:
            text = f.attrs.get("test")  # a failed run stores its error only
        if text is None:
            continue
        stored = json.loads(text)
        test = engine.UniaxialTest.from_stored(stored)
        d = test.to_dict()
        # fields declared since a run was stored read back at the values such runs had; the
        # rest is
        # the stored text, key order included
        added = {k: v for k, v in d.items() if k not in stored}
        assert added == {k: FIELDS_SINCE[k] for k in added}, path.name
        assert json.dumps({k: v for k, v in d.items() if k in stored}) == text, path.name
        checked += 1
    assert checked > 100


@pytest.mark.parametrize(
    "record",
    [
        engine.preset("paper"),
        engine.preset("quick", pair_law=engine.EEPA(k1=5e5, k2=2e6, f0=-0.2, n=1.5)),
        engine.preset("quick", pair_law=engine.HertzMindlin(E=1e8), dt=None),
        engine.default_study(),
        engine.ScalingRule.named("similarity", dt="scaled"),
    ],
    ids=["paper", "eepa", "hertz-pairs", "default-study", "rule"],
)
def test_json_round_trip(record):
    data = json.loads(json.dumps(record.to_dict()))
    again = type(record).from_dict(data)
    assert again == record and again.to_dict() == data


def test_a_law_field_carries_its_type_and_a_record_field_does_not():
    d = engine.preset("quick").to_dict()
    assert d["pair_law"]["type"] == "BilinearAdhesive" and next(iter(d["pair_law"])) == "type"
    assert d["wall_law"]["type"] == "HertzMindlin"
    assert "type" not in d["wall_material"]
    assert d["cell"] == [0.05, 0.05, 0.3]  # tuples as lists
    # a law without its tag is the field's default kind
    del d["pair_law"]["type"]
    assert isinstance(engine.UniaxialTest.from_dict(d).pair_law, engine.BilinearAdhesive)


@pytest.mark.parametrize(
    "change,field",
    [
        ({"pair_law": {"type": "Nope", "k1": 1.0}}, "UniaxialTest.pair_law.type"),
        ({"pair_law": {"type": "EEPA", "k1": 1.0, "k2": 2.0, "stiff": 3}}, "EEPA"),
        ({"wall_law": {"type": "BilinearAdhesive", "k1": 1, "k2": 1}}, "UniaxialTest.wall_law"),
        ({"cell": "big"}, "UniaxialTest.cell"),
        ({"colour": "red"}, "UniaxialTest"),
        # a modulus whose shear modulus underflows to 0 (it was a ZeroDivisionError)
        ({"wall_material": {"E": 5e-324, "nu": 0.3}}, "WallMaterial.E"),
        ({"wall_law": {"type": "HertzMindlin", "E": 5e-324}}, "HertzMindlin.E"),
    ],
)
def test_bad_json_is_refused_naming_the_field(change, field):
    d = {**engine.preset("quick").to_dict(), **change}
    with pytest.raises(engine.ParameterError) as e:
        engine.UniaxialTest.from_dict(d)
    assert e.value.field.startswith(field), e.value


def test_study_json_takes_a_preset_and_rule_names_and_refuses_the_wrong_shapes():
    spec = engine.StudySpec.from_dict(
        {"reference": {"preset": "quick", "radius": 2e-3}, "rules": ["paper", "unscaled"]}
    )
    assert spec.reference == engine.preset("quick", radius=2e-3)
    assert [r.name for r in spec.rules] == ["paper", "unscaled"]
    seed = engine.StudySpec.from_dict({"reference": {"preset": "quick", "protocol": "seed"}})
    assert seed.reference == engine.preset("quick", protocol="seed")
    # a protocol without a preset: the record's defaults at that protocol, fields over both
    law = {"type": "BilinearAdhesive", "k1": 5e3, "k2": 2.5e4}
    t = uniaxial_from_json({"protocol": "seed", "pair_law": law, "dt": 2e-5})
    assert t.inertial_number is None and t.dt == 2e-5 and t.strength_from == "platen"
    with pytest.raises(engine.ParameterError) as e:
        engine.StudySpec.from_dict({"reference": {"preset": "quick", "protocol": "fast"}})
    assert e.value.field == "StudySpec.reference.protocol", e.value
    ref = {"reference": {"preset": "quick"}}
    for bad, field in (
        ({"rules": ["paper"]}, "StudySpec.reference"),  # no silent default for the physics
        ({**ref, "rules": "paper"}, "StudySpec.rules"),
        ({**ref, "rules": [{"name": "x", "slope": 1}]}, "StudySpec.rules[0]"),
        ({**ref, "coarse_radii": 0.005}, "StudySpec.coarse_radii"),
        ({**ref, "coarse_radii": [0.001]}, "StudySpec.coarse_radii[0]"),  # finer: not coarse
        ({**ref, "tolerances": [0.1]}, "StudySpec.tolerances"),
    ):
        with pytest.raises(engine.ParameterError) as e:
            engine.StudySpec.from_dict(bad)
        assert e.value.field == field, e.value


def test_a_registered_law_is_read_and_written_through_the_registry(monkeypatch):
    monkeypatch.setitem(LAWS, "PowerSpring", toy_law.PowerSpring)
    test = tiny(pair_law=toy_law.PowerSpring(k=5e5, p=1.5), dt=None)
    d = to_dict(test)
    assert d["pair_law"] == {"type": "PowerSpring", "k": 5e5, "p": 1.5}
    assert from_dict(engine.UniaxialTest, d) == test


def test_records_do_no_work_and_a_study_is_planned_by_one_pure_function(monkeypatch):
    placed = []
    monkeypatch.setattr(engine.uniaxial.spec, "_packing", lambda *a: placed.append(a))
    spec = engine.StudySpec(
        reference=tiny(), coarse_radii=(3e-3, 3.1e-3), seeds=(1, 2), reference_seeds=(1, 2, 3)
    )
    before = spec.to_dict()
    plan = engine.plan(spec)
    assert placed == []  # neither the records nor the plan place a packing
    assert spec.to_dict() == before  # the spec is not changed by planning
    assert engine.plan(spec) == plan  # and planning is deterministic
    # references, the protocol check (two reference seeds at half the rate and step),
    # variants, controls
    assert len(plan.runs) == 3 + 2 + 2 * 2 * 2 + 2 * 2
    assert [p.key for p in plan.runs if p.protocol] == ["half-s1", "half-s2"]
    again = engine.StudyPlan.from_dict(json.loads(json.dumps(plan.to_dict())))
    assert again == plan and sum(p.control for p in again.runs) == 4
    # the coarse tests carry the scaled law and the reference's time step
    coarse = next(p for p in plan.runs if p.key == "r3mm-paper-s2")
    assert coarse.test.seed == 2 and coarse.test.dt == spec.reference.dt
    assert coarse.test.pair_law.k1 == pytest.approx(spec.reference.pair_law.k1 * 3e-3 / 2.5e-3)
    assert dataclasses.replace(coarse.test, radius=2.5e-3) != spec.reference


def test_a_fill_the_packer_cannot_place_fails_its_run_naming_the_field():
    """Only the run places its fill; a cell too small for it is refused there, by name."""
    crowded = tiny(cell=(0.0121, 0.0121, 0.0101), pour_fraction=0.32, solid_fraction=0.74)
    with pytest.raises(engine.ParameterError, match="UniaxialTest.pour_fraction"):
        engine.run_uniaxial(crowded)
