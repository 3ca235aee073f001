"""The API's request schema and the engine's parameter records agree: for every record a
study reaches (StudySpec, UniaxialTest, ScalingRule, the contact laws, the wall material),
the OpenAPI document has exactly the record's fields, with their units, bounds, choices,
defaults, nullability and required-ness as ``engine.core.records.describe`` declares them; named
rules are the engine's; the engine's own default study is a valid body."""

from __future__ import annotations

import dataclasses
import typing

import pytest
from fastapi.testclient import TestClient

import engine
from engine.core.records import describe
from engine.study.spec import NAMED_RULES
from service.app import create_app
from service.spec import SERVICE_LIMITS, SERVICE_REQUIRED, TAGGED, StudyCreate, jsonable

#: Fields the API adds to a record's own: the study's label, the reference's preset.
SERVICE_FIELDS = {"StudySpec": {"name"}, "UniaxialTest": {"preset", "protocol"}}


@pytest.fixture(scope="module")
def components(tmp_path_factory) -> dict:
    tmp = tmp_path_factory.mktemp("agreement")
    from service.settings import Settings

    settings = Settings(data_dir=tmp, api_token="agreement-token-0123456789", embedded_worker=False)
    with TestClient(create_app(settings)) as c:
        return c.get("/openapi.json").json()["components"]["schemas"]


def component_of(cls: type) -> str:
    return {"StudySpec": "StudyCreate", "UniaxialTest": "ReferenceIn"}.get(
        cls.__name__, f"{cls.__name__}In"
    )


def reachable_records() -> list[type]:
    """Every record class a study's fields lead to."""
    seen: list[type] = []
    todo = [engine.StudySpec]
    while todo:
        cls = todo.pop()
        if cls in seen:
            continue
        seen.append(cls)
        for hint in typing.get_type_hints(cls).values():
            for arg in (hint, *typing.get_args(hint)):
                for inner in (arg, *typing.get_args(arg)):
                    if dataclasses.is_dataclass(inner) and inner not in seen:
                        todo.append(inner)
    return seen


def branch(prop: dict) -> tuple[dict, bool]:
    """The non-null schema of a property, and whether null is allowed."""
    options = prop.get("anyOf")
    if options is None:
        return prop, False
    rest = [o for o in options if o.get("type") != "null"]
    return (rest[0] if len(rest) == 1 else {"anyOf": rest}), len(rest) < len(options)


def without_nulls(value):
    """``value`` with the null members of its objects left out, at any depth."""
    if isinstance(value, dict):
        return {k: without_nulls(v) for k, v in value.items() if v is not None}
    if isinstance(value, list):
        return [without_nulls(v) for v in value]
    return value


def test_every_record_a_study_reaches_is_in_the_document(components):
    records = reachable_records()
    assert {c.__name__ for c in records} >= {
        "StudySpec",
        "UniaxialTest",
        "ScalingRule",
        "BilinearAdhesive",
        "EEPA",
        "HertzMindlin",
        "WallMaterial",
    }
    for cls in records:
        assert component_of(cls) in components, cls.__name__


@pytest.mark.parametrize("cls", reachable_records(), ids=lambda c: c.__name__)
def test_fields_units_bounds_defaults_agree(components, cls):
    schema = components[component_of(cls)]
    props = schema["properties"]
    params = describe(cls)
    extra = SERVICE_FIELDS.get(cls.__name__, set()) | ({"type"} if cls in TAGGED else set())
    assert set(props) == {p.name for p in params} | extra, "field names differ"
    assert schema.get("additionalProperties") is False
    required = set(schema.get("required", ()))
    for p in params:
        prop = props[p.name]
        where = f"{cls.__name__}.{p.name}"
        body, nullable = branch(prop)
        assert nullable == p.nullable, where
        # the API may require what the engine defaults (service.spec.SERVICE_REQUIRED)
        assert (p.name in required) == (p.required or (cls.__name__, p.name) in SERVICE_REQUIRED), (
            where
        )
        if p.unit:
            assert prop.get("x-unit") == p.unit and f"[{p.unit}]" in prop["description"], where
        assert p.doc in prop["description"], where
        if not p.required and (cls.__name__, p.name) not in SERVICE_REQUIRED:
            if cls is engine.StudySpec and p.name == "reference":
                # the API shows the preset the engine's default reference is
                assert prop["default"] == {"preset": "quick"}, where
                assert p.default == engine.preset("quick"), where
            else:
                # null: left out (FastAPI writes the OpenAPI document without nulls)
                assert prop.get("default") == without_nulls(jsonable(p.default)), where
        if p.kind in ("float", "int"):
            expected_type = "number" if p.kind == "float" else "integer"
            assert body["type"] == expected_type, where
            # the engine's bounds, and those the service adds (service.spec.SERVICE_LIMITS)
            limits = SERVICE_LIMITS.get((cls.__name__, p.name), {})
            for key, bound in (
                ("exclusiveMinimum", limits.get("gt", p.gt)),
                ("minimum", limits.get("ge", p.ge)),
                ("exclusiveMaximum", limits.get("lt", p.lt)),
                ("maximum", limits.get("le", p.le)),
            ):
                assert body.get(key) == bound, (where, key)
        elif p.kind == "bool":
            assert body["type"] == "boolean", where
        elif p.kind == "str":
            if p.choices is not None:
                assert body["enum"] == list(p.choices), where
            limits = SERVICE_LIMITS.get((cls.__name__, p.name), {})
            if "pattern" in limits:
                assert body["pattern"] == limits["pattern"], where
        elif p.kind == "list":
            assert body["type"] == "array", where
            if p.max_items is not None:
                assert body["maxItems"] == p.max_items, where
        elif p.kind == "dict":
            assert body["type"] == "object", where


def test_named_rules_are_the_engines(components):
    items = components["StudyCreate"]["properties"]["rules"]["items"]
    (names,) = [o for o in items["anyOf"] if "enum" in o]
    assert names["enum"] == list(NAMED_RULES)
    for name in NAMED_RULES:
        body = StudyCreate.model_validate({"reference": {"preset": "quick"}, "rules": [name]})
        assert body.engine_dict()["rules"] == [engine.ScalingRule.named(name).to_dict()]


def test_the_engines_default_study_is_a_valid_body_and_comes_back_unchanged():
    spec = engine.default_study()
    body = StudyCreate.model_validate(spec.to_dict())
    assert engine.StudySpec.from_dict(body.engine_dict()).to_dict() == spec.to_dict()
    # and what the API documents as defaults is what the engine takes for left-out fields
    quick = {"reference": {"preset": "quick"}}
    assert engine.StudySpec.from_dict(
        StudyCreate.model_validate(quick).engine_dict()
    ) == engine.StudySpec(reference=engine.preset("quick"))


def test_a_study_and_a_calibration_need_their_test():
    # no silent default for the physics: the reference (or the calibration's test) is
    # required, and it names a preset or gives the pair law
    for body in ({}, {"reference": {"radius": 2.5e-3}}):
        with pytest.raises(ValueError, match="reference"):
            StudyCreate.model_validate(body)


def test_a_field_the_engine_does_not_declare_is_refused():
    with pytest.raises(ValueError, match="extra"):
        StudyCreate.model_validate({"reference": {"fill_fraction": 0.3}})


def test_cross_field_rules_are_stated_in_the_document(components):
    """Issue 42 item 6: a rule between fields is in the schema where JSON Schema can state
    it (a preset or a pair law; a target's sd with it) and in the field's description where
    it cannot; free text states no numeric limit."""
    assert components["ReferenceIn"]["anyOf"] == [
        {"required": ["preset"]},
        {"required": ["pair_law"]},
    ]
    dep = components["LabTargetsIn"]["dependentRequired"]
    assert dep["loading_stiffness"] == ["loading_stiffness_sd"]
    study = components["StudyCreate"]["properties"]
    assert "> reference.radius" in study["coarse_radii"]["description"]
    box = components["CalibrationCreate"]["properties"]["parameters"]["description"]
    assert "low < high" in box and "time step" in box and "parameters.<name>" in box
    assert "allowed" not in components["LabTargetsIn"]["properties"]["material"]["description"]
