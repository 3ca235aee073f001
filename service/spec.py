"""The study spec as the API accepts it (``StudyCreate``, the "create" member of the study
model family), derived from the engine's parameter records.

Every field of :class:`engine.StudySpec`, :class:`engine.UniaxialTest` (the reference),
:class:`engine.ScalingRule` and the contact-law records is declared once, in the engine,
with :func:`engine.core.records.param` (unit, bounds, kind, default, description);
:func:`record_model` turns each record's :func:`engine.core.records.describe` into a pydantic
model, so that a new engine field appears in the API (and its OpenAPI document) without an
edit here. The engine stays the judge of what spans fields (``k2 >= k1``, a coarse radius
the cell can hold, ...): :mod:`service.admission` turns its ``ParameterError`` into a 422.

What the API adds to the records: the study's ``name`` (a label), the reference's
``preset`` (``engine.preset``), rules given by name (``engine.study.spec.NAMED_RULES``), the
``type`` tag of contact laws, and the constraints in :data:`SERVICE_LIMITS` that the engine
checks in code but does not declare. The rules of a request beyond its records (a study's
reference and a shear test's pair law required, a preset or a pair law for a uniaxial test,
a calibration design's minimum) are the engine's (:mod:`engine.core.inputs`), the same copy
the command line applies. Numbers, booleans and strings are strict: ``"1e-3"``
is not a number.
"""

from __future__ import annotations

import dataclasses
import typing
from types import NoneType, UnionType
from typing import Annotated, Any, Literal, Union

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    create_model,
    model_validator,
)
from pydantic_core import PydanticCustomError

import engine
from engine.calibration import CALIBRATED, LabTargets
from engine.calibration.calibrate import CORRECTED_BY
from engine.calibration.forward import SET_BY_CALIBRATION
from engine.calibration.targets import LOCUS_UNCERTAINTY_OF, UNCERTAINTY_OF, ShearLocus
from engine.core.errors import MissingField
from engine.core.inputs import DESIGN_MINIMUM, REQUIRED_GIVEN, check_test_json
from engine.core.records import ParamInfo, describe
from engine.study.spec import NAMED_RULES
from engine.uniaxial.spec import PRESETS, PROTOCOLS

from .cost import MIN_SETTLE_KE
from .models import NAME_MAX_LENGTH

#: What the engine checks in code but does not declare with ``param``, keyed by
#: (record, field): pydantic ``Field`` constraints the API adds to the derived field.
SERVICE_LIMITS: dict[tuple[str, str], dict[str, Any]] = {
    # engine.ScalingRule.__post_init__: 1-40 letters, digits, '_', '-', '.'
    ("ScalingRule", "name"): {"pattern": r"^[A-Za-z0-9_.\-]{1,40}$"},
    # engine.StudySpec.__post_init__: the scaling rules act on the adhesive laws' K1, K2, f0
    ("UniaxialTest", "pair_law"): {"record": engine.contact.registry.adhesive_laws()},
    # service.cost: below this a fill never settles and runs to max_stage_time (the
    # bounds relative to dt and the stages, on output_interval and max_stage_time, are
    # checked at admission: a schema cannot state them)
    ("UniaxialTest", "settle_ke"): {"ge": MIN_SETTLE_KE},
    # the same for a shear study's reference (and the calibration's shear cell)
    ("ShearTest", "pair_law"): {"record": engine.contact.registry.adhesive_laws()},
    ("ShearTest", "settle_ke"): {"ge": MIN_SETTLE_KE},
    # and for a hopper study's (engine.HopperTest takes any pair law; a study, adhesive ones)
    ("HopperTest", "pair_law"): {"record": engine.contact.registry.adhesive_laws()},
}
#: Rules that span fields, which JSON Schema cannot state (it compares no two values): each
#: is written into the field's description in the OpenAPI document, and the request is
#: refused with a 422 naming the field when it breaks one (the engine's checks, or
#: :mod:`service.admission`'s where the engine is more lenient than the API).
CROSS_FIELD_RULES: dict[tuple[str, str], str] = {
    ("StudySpec", "coarse_radii"): "each > reference.radius (a coarse variant has larger "
    "particles than the reference) and <= 4 x reference.radius, all distinct; the cell must "
    "hold 2.4 coarsest diameters across and 2 in height",
    ("StudySpec", "seeds"): "distinct",
    ("StudySpec", "reference_seeds"): "distinct",
    ("StudySpec", "max_seeds"): "with decide: >= the number of seeds",
    ("StudySpec", "max_reference_seeds"): "with decide: >= the number of reference seeds",
    ("UniaxialTest", "consolidation_stress"): "> pre_stress",
    ("UniaxialTest", "pour_fraction"): "<= solid_fraction",
    ("UniaxialTest", "unloading_inertial_number"): "null where inertial_number is null",
    ("UniaxialTest", "hold_time"): "< max_stage_time",
    ("UniaxialTest", "hold_quiet"): "< max_stage_time; null where hold_time is null",
    ("UniaxialTest", "cell"): "x and y >= 4.8 largest radii, z >= 4 largest radii",
    ("UniaxialTest", "dt"): "<= the stable limit of the laws for the smallest particles "
    "(engine.UniaxialTest.time_step_limit; the 422 names the limit)",
    ("UniaxialTest", "output_interval"): ">= dt and <= 0.01 x cell height / platen_speed",
    ("UniaxialTest", "max_stage_time"): "<= 10 x max(2 free-fall times of the pour column, "
    "pour column / platen_speed)",
    ("UniaxialTest", "pair_law"): "|f0| / k1 within 0.5 of the smallest radius, and stiff "
    "enough to carry the consolidation stress within that overlap",
    ("BilinearAdhesive", "k2"): ">= k1",
    ("EEPA", "k2"): ">= k1",
    ("LabTargets", "shear"): "one locus per sigma_pre (all different)",
    ("LabTargets", "shear_tester"): "required with shear where tester is not a shear tester; "
    "given with shear only",
    ("ShearTest", "normal_stresses"): "2 to 8, each > 0 and < preshear_stress, at least two "
    "different (a yield locus is a line fitted through them)",
    ("ShearTest", "preshear_min_strain"): "<= preshear_strain",
    ("ShearTest", "steady_window"): "<= preshear_strain / 2 (the steady-state check compares "
    "two windows)",
    ("ShearTest", "cell"): "x and y >= 4.8 largest radii, z >= 4 largest radii and >= 8 x "
    "platen_layer x radius (two glued layers and a sheared bed between them)",
    ("ShearTest", "dt"): "<= the stable limit of the laws for the smallest particles (the "
    "422 names the limit)",
    ("ShearTest", "pair_law"): "|f0| / k1 within 0.5 of the smallest radius, and stiff "
    "enough to carry preshear_stress within that overlap",
    ("ShearLocus", "points"): "at least 2 (a yield locus is a line fitted through them), each "
    "sigma_n < sigma_pre, no two at one sigma_n, their fitted line rising (tan(phi) > 0)",
}
#: Fields the API requires where the engine has a default: the engine's request rules
#: (engine.core.inputs.REQUIRED_GIVEN, which the command line applies too): a study's
#: reference (the record requires it too; kept so that the two may differ, in the API's
#: favour, and the agreement test knows it) and a shear reference's pair law (no shear test
#: of the record's default law: nobody chose it, and there is no shear preset to name).
SERVICE_REQUIRED: frozenset[tuple[str, str]] = frozenset(REQUIRED_GIVEN)
#: Longest list or object the API takes where the engine declares no ``max_items``.
MAX_ITEMS = 32
#: Longest key of an object parameter (e.g. a metric name of ``tolerances``).
MAX_KEY_LENGTH = 64


def _is_union(hint: Any) -> bool:
    return typing.get_origin(hint) in (Union, UnionType)


def _non_null(hint: Any) -> Any:
    """``hint`` without ``None`` (``X | None`` -> ``X``)."""
    if _is_union(hint):
        args = [a for a in typing.get_args(hint) if a is not NoneType]
        return args[0] if len(args) == 1 else Union[tuple(args)]  # noqa: UP007
    return hint


def _record_classes(hint: Any) -> tuple[type, ...]:
    hint = _non_null(hint)
    return typing.get_args(hint) if _is_union(hint) else (hint,)


def _tagged_records() -> frozenset[type]:
    """Records that can stand in a union (the contact laws): their JSON form carries a
    ``type`` tag naming the class (``UniaxialTest.to_dict``)."""
    out: set[type] = set()
    for cls in (engine.UniaxialTest, engine.StudySpec):
        for hint in typing.get_type_hints(cls).values():
            classes = _record_classes(hint)
            if len(classes) > 1 and all(dataclasses.is_dataclass(c) for c in classes):
                out |= set(classes)
    return frozenset(out)


TAGGED = _tagged_records()


def jsonable(value: Any) -> Any:
    """An engine default as JSON shows it (records as objects, tagged where they are)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        out = {f.name: jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
        return {"type": type(value).__name__, **out} if type(value) in TAGGED else out
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, dict):
        return {k: jsonable(v) for k, v in value.items()}
    return value


def _bounds(info: ParamInfo) -> dict[str, Any]:
    return {k: getattr(info, k) for k in ("gt", "ge", "lt", "le") if getattr(info, k) is not None}


def _scalar(kind: str, info: ParamInfo, extra: dict[str, Any]) -> Any:
    """The annotated type of a float, int, bool or str value."""
    if kind == "float":
        return Annotated[float, Field(strict=True, allow_inf_nan=False, **_bounds(info), **extra)]
    if kind == "int":
        return Annotated[int, Field(strict=True, **_bounds(info), **extra)]
    if kind == "bool":
        return Annotated[bool, Field(strict=True)]
    if info.choices is not None:
        return Literal[tuple(info.choices)]
    return Annotated[str, Field(strict=True, **extra)]


def _item_kind(item_hint: Any) -> str:
    item_hint = _non_null(item_hint)
    if dataclasses.is_dataclass(item_hint):
        return "record"
    return {float: "float", int: "int", bool: "bool", str: "str"}.get(item_hint, "float")


def _named_rule(value: Any) -> Any:
    """A rule given by name becomes that rule of ``engine.study.spec.NAMED_RULES``
    (:meth:`engine.ScalingRule.named` judges the name, as for the command line)."""
    if not isinstance(value, str):
        return value
    try:
        return engine.ScalingRule.named(value).to_dict()
    except engine.ParameterError as e:
        raise ValueError(f"unknown rule {value!r}: give a rule object or {e.limit}") from None


def _named_or_rule() -> Any:
    rule = record_model(engine.ScalingRule)
    named = Literal[tuple(NAMED_RULES)]
    return Annotated[
        rule,
        BeforeValidator(_named_rule, json_schema_input_type=Union[named, rule]),  # noqa: UP007
        Field(description=f"a rule object, or the name of one of {list(NAMED_RULES)}"),
    ]


def _field_type(owner: type, info: ParamInfo, hint: Any) -> Any:
    """The pydantic type of one declared field of ``owner``."""
    extra = dict(SERVICE_LIMITS.get((owner.__name__, info.name), {}))
    narrowed = extra.pop("record", None)
    if owner is engine.StudySpec and info.name == "reference":
        return Any  # the reference models below (ReferenceIn, ShearTestIn) stand here
    if info.kind == "record":
        classes = tuple(narrowed) if narrowed else _record_classes(hint)
        models = [record_model(c) for c in classes]
        if len(models) == 1:
            return models[0]
        default = classes[0].__name__

        def tag(value: Any) -> str:  # an untagged law is the first record (BilinearAdhesive)
            return (
                value.get("type", default)
                if isinstance(value, dict)
                else getattr(value, "type", default)
            )

        tagged = tuple(Annotated[m, Tag(c.__name__)] for m, c in zip(models, classes))
        return Annotated[Union[tagged], Discriminator(tag)]  # noqa: UP007
    if info.kind == "list":
        args = typing.get_args(_non_null(hint))
        fixed = len(args) if args and args[-1] is not Ellipsis else None
        item_hint = args[0] if args else float
        if owner is engine.StudySpec and info.name == "rules":
            item: Any = NamedOrRule
        elif _item_kind(item_hint) == "record":
            item = record_model(_non_null(item_hint))
        else:
            item = _scalar(_item_kind(item_hint), info, extra)
        longest = fixed or info.max_items or MAX_ITEMS
        return Annotated[list[item], Field(min_length=fixed or 1, max_length=longest)]
    if info.kind == "dict":
        key = Annotated[str, Field(max_length=MAX_KEY_LENGTH)]
        value = _scalar("float", info, extra)
        return Annotated[dict[key, value], Field(max_length=info.max_items or MAX_ITEMS)]
    return _scalar(info.kind, info, extra)


def _description(owner: type, info: ParamInfo) -> str:
    unit = f" [{info.unit}]" if info.unit else ""
    text = f"{info.doc}{unit}"
    # free text (a str without choices) has no limit to state
    if info.kind in ("float", "int", "bool") or info.choices or _bounds(info):
        text += f"; allowed: {info.limit_text()}"
    rule = CROSS_FIELD_RULES.get((owner.__name__, info.name))
    return f"{text}; also: {rule}" if rule else text


def fields_of(cls: type) -> dict[str, tuple[Any, Any]]:
    """``create_model`` field definitions of every declared field of the record ``cls``."""
    hints = typing.get_type_hints(cls)
    out: dict[str, tuple[Any, Any]] = {}
    for info in describe(cls):
        kind = _field_type(cls, info, hints[info.name])
        if info.nullable:
            kind = kind | None
        field_kwargs: dict[str, Any] = {
            "description": _description(cls, info),
            "json_schema_extra": {"x-unit": info.unit} if info.unit else None,
        }
        if info.required or (cls.__name__, info.name) in SERVICE_REQUIRED:
            out[info.name] = (kind, Field(..., **field_kwargs))
        else:
            out[info.name] = (kind, Field(jsonable(info.default), **field_kwargs))
    return out


_forbid = ConfigDict(extra="forbid")
_MODELS: dict[type, type[BaseModel]] = {}


def record_model(cls: type) -> type[BaseModel]:
    """The request model of an engine record: its declared fields, unknown fields refused;
    contact laws also take their ``type`` tag."""
    if cls in _MODELS:
        return _MODELS[cls]
    fields = fields_of(cls)
    if cls in TAGGED:
        name = cls.__name__
        fields = {"type": (Literal[name], Field(name, description="the record's kind")), **fields}
    doc = (cls.__doc__ or cls.__name__).strip().split("\n\n")[0]
    config = _forbid
    # a target needs its uncertainty: JSON Schema states that much
    uncertainty = {LabTargets: UNCERTAINTY_OF, ShearLocus: LOCUS_UNCERTAINTY_OF}.get(cls)
    if uncertainty is not None:
        depends = {v: [sd] for v, sd in uncertainty.items()}
        config = ConfigDict(extra="forbid", json_schema_extra={"dependentRequired": depends})
    model = create_model(f"{cls.__name__}In", __config__=config, __doc__=doc, **fields)
    _MODELS[cls] = model
    return model


NamedOrRule = _named_or_rule()
_reference_fields = fields_of(engine.UniaxialTest)


class _ReferenceBase(BaseModel):
    """A test as a request gives it: a named preset, or the pair law (the physics) with any
    other fields; never the record's defaults alone, which would run a law nobody chose."""

    model_config = ConfigDict(
        extra="forbid",
        # JSON Schema states it: at least one of the two
        json_schema_extra={"anyOf": [{"required": ["preset"]}, {"required": ["pair_law"]}]},
    )

    @model_validator(mode="after")
    def _named_or_given(self):
        # the engine's request rule (engine.core.inputs), as the command line applies it
        try:
            check_test_json(self.model_dump(exclude_unset=True), "")
        except MissingField as e:
            raise PydanticCustomError("preset_or_pair_law", f"{e.limit}: {e.why}") from None
        return self


ReferenceIn = create_model(
    "ReferenceIn",
    __base__=_ReferenceBase,
    __doc__="The fine reference test: a preset, and/or the pair law and any other fields of "
    "engine.UniaxialTest; the preset's values (or the record's defaults) fill in what is "
    "left out. A preset or a pair_law is required.",
    type=(
        Literal["UniaxialTest"],
        Field(
            "UniaxialTest",
            description="the reference's kind: the uniaxial test (the default); a shear test "
            'is given with "type": "ShearTest" (ShearTestIn)',
        ),
    ),
    preset=(
        Literal[tuple(PRESETS)] | None,
        Field(None, description="a named test (engine.preset) whose fields the others override"),
    ),
    protocol=(
        Literal[tuple(PROTOCOLS)],
        Field(
            "default",
            description="the protocol of the preset (or of the record's defaults): 'default' "
            "(dt from the contact time, loading at an inertial number) or 'seed' (the seed's "
            "dt = 1e-5 s and 10 mm/s platen); given fields override it",
        ),
    ),
    **{
        name: (
            kind,
            Field(
                spec.default, description=spec.description, json_schema_extra=spec.json_schema_extra
            ),
        )
        for name, (kind, spec) in _reference_fields.items()
    },
)
#: A shear study's reference (``"type": "ShearTest"``): engine.ShearTest's declared fields,
#: from its records as the calibration's shear cell's (:data:`ShearCellIn`); the pair law
#: required (:data:`SERVICE_REQUIRED`).
ShearTestIn = record_model(engine.ShearTest)
#: A hopper study's reference (``"type": "HopperTest"``, docs/HOPPER.md): engine.HopperTest's
#: declared fields; the pair law required (:data:`SERVICE_REQUIRED`), as a shear test's.
HopperTestIn = record_model(engine.HopperTest)
#: The reference kinds a study takes, by their ``type`` (engine.study.spec.TEST_TYPES).
REFERENCE_MODELS = {
    "UniaxialTest": ReferenceIn,
    "ShearTest": ShearTestIn,
    "HopperTest": HopperTestIn,
}


def _reference_kind(value: Any) -> str:
    """The reference's ``type``: "UniaxialTest" where none is given (existing requests)."""
    if isinstance(value, dict):
        return value.get("type", "UniaxialTest")
    return getattr(value, "type", "UniaxialTest")


Reference = Annotated[
    Union[tuple(Annotated[m, Tag(k)] for k, m in REFERENCE_MODELS.items())],  # noqa: UP007
    Discriminator(
        _reference_kind,
        custom_error_type="reference_type",
        custom_error_message=f"the reference's type must be one of {list(REFERENCE_MODELS)}",
    ),
]
_study_fields = fields_of(engine.StudySpec)
_reference_doc = next(i.doc for i in describe(engine.StudySpec) if i.name == "reference")
_study_fields["reference"] = (
    Reference,
    Field(
        ...,
        description=f"{_reference_doc}: a uniaxial test, a preset named, e.g. "
        '{"preset": "quick"}, or the pair law with the other fields of the test; or a shear '
        'test, "type": "ShearTest" with its pair law and any other fields of '
        'engine.ShearTest (docs/SHEAR.md); or a hopper, "type": "HopperTest" with its pair '
        "law and any other fields of engine.HopperTest (docs/HOPPER.md)",
    ),
)

#: A study that fits the default caps: the quick preset against two coarse radii.
EXAMPLE = {
    "name": "quick",
    "reference": {"preset": "quick", "radius": 2.5e-3},
    "coarse_radii": [3.75e-3, 5e-3],
    "rules": ["paper", "unscaled"],
    "seeds": [1],
    "reference_seeds": [1, 2],
    "tolerances": {"density": 0.03, "strength": 0.15},
}
#: A shear study (docs/SERVICE.md): the tests' smallest shear cell (about 120 grains, 6 x 3 x
#: 6 diameters) against one coarse radius.
SHEAR_EXAMPLE = {
    "name": "shear",
    "reference": {
        "type": "ShearTest",
        "cell": [0.03, 0.015, 0.03],
        "pair_law": {"k1": 5e3, "k2": 2.5e4, "f0": -0.4, "mu_s": 0.5, "mu_r": 0.001},
        "normal_stresses": [3e3, 7e3],
        "inertial_number": 2e-3,
        "max_stage_time": 2.0,
    },
    "coarse_radii": [3.1e-3],
    "rules": ["paper"],
    "reference_seeds": [1, 2],
    "protocol_check": False,
}


class _StudyBase(BaseModel):
    model_config = ConfigDict(
        extra="forbid", json_schema_extra={"examples": [EXAMPLE, SHEAR_EXAMPLE]}
    )

    def engine_dict(self) -> dict:
        """The spec as :meth:`engine.StudySpec.from_dict` takes it (what the client set;
        the engine fills in its defaults)."""
        return self.model_dump(exclude_unset=True, exclude={"name"})


StudyCreate = create_model(
    "StudyCreate",
    __base__=_StudyBase,
    __doc__="A scaling study to run (the body of ``POST /studies``): engine.StudySpec's "
    "fields, and a name.",
    name=(
        str | None,
        Field(None, max_length=NAME_MAX_LENGTH, strict=True, description="A label."),
    ),
    **_study_fields,
)


# ------------------------------------------------------------------------------ calibration
#: Most design runs, waves and runs per wave a calibration takes (60 runs in all by default
#: make the issue's "within 60 runs" plan: 25 + 2 x 15 + the check run).
MAX_CALIBRATION_RUNS = 60
MAX_WAVES = 4
MAX_WAVE_RUNS = 30

#: A parameter's box: (low, high) in the law's units.
Box = Annotated[
    list[Annotated[float, Field(strict=True, allow_inf_nan=False)]],
    Field(min_length=2, max_length=2, description="(low, high) in the law's units"),
]
CalibratedName = Literal[tuple(CALIBRATED)]

_then_fields = {k: v for k, v in _study_fields.items() if k != "reference"}
ThenStudyIn = create_model(
    "ThenStudyIn",
    __config__=_forbid,
    __doc__="The scaling study of the calibrated law (engine.StudySpec's fields but the "
    "reference, which is the calibration's test with the calibrated law).",
    **_then_fields,
)

ShearCellIn = create_model(
    "ShearCellIn",
    __config__=_forbid,
    __doc__="The shear cell a calibration's yield loci run in: engine.ShearTest's fields but "
    "the pair law (the calibrated one) and the stresses (each locus's sigma_pre and sigma_n); "
    "its radius must be the test's.",
    **{k: v for k, v in fields_of(engine.ShearTest).items() if k not in SET_BY_CALIBRATION},
)

CALIBRATION_EXAMPLE = {
    "name": "my powder",
    "test": {"preset": "quick"},
    "targets": {
        "tester": "uniaxial",
        "loading_stiffness": 1.2e6,
        "loading_stiffness_sd": 1.0e5,
        "strength": [{"consolidation_stress": 2e4, "strength": 3.0e3, "sd": 400.0}],
    },
    "parameters": {"k1": [3e3, 2e4], "f0": [-1e-3, -1e-5]},
    "runs": 12,
    "waves": 1,
    "wave_runs": 8,
}


class CalibrationCreate(BaseModel):
    """A calibration to run (the body of ``POST /calibrations``): the test whose pair law is
    calibrated, the laboratory targets, the parameters and their boxes, the design's size
    and, optionally, the scaling study of the calibrated law that follows."""

    model_config = ConfigDict(extra="forbid", json_schema_extra={"examples": [CALIBRATION_EXAMPLE]})

    name: str | None = Field(None, max_length=NAME_MAX_LENGTH, strict=True, description="A label.")
    test: ReferenceIn = Field(  # type: ignore[valid-type]
        ...,
        description="the uniaxial test whose pair law is calibrated (required: a preset "
        "named, or the pair law with the other fields of the test); its time step must be "
        "stable for every law in the parameters' boxes",
    )
    targets: record_model(LabTargets) = Field(  # type: ignore[valid-type]
        ..., description="the laboratory data (engine.calibration.LabTargets)"
    )
    parameters: dict[CalibratedName, Box] = Field(
        ...,
        min_length=1,
        max_length=len(CALIBRATED),
        description="law parameters to calibrate and their (low, high) boxes; also: each a "
        "parameter of the test's pair law, low < high, each end a value some law of the box "
        "takes within the law's own bounds (e.g. k2 >= k1), and, where the test fixes dt, "
        "each end runnable at that time step (a 422 at parameters.<name> names the limit)",
    )
    runs: int = Field(
        25,
        strict=True,
        ge=DESIGN_MINIMUM["runs"],
        le=MAX_CALIBRATION_RUNS,
        description="runs of the space-filling design (at least parameters + 2)",
    )
    waves: int = Field(
        2,
        strict=True,
        ge=DESIGN_MINIMUM["waves"],
        le=MAX_WAVES,
        description="history-matching waves after the design",
    )
    wave_runs: int = Field(
        15,
        strict=True,
        ge=DESIGN_MINIMUM["wave_runs"],
        le=MAX_WAVE_RUNS,
        description="runs per wave (at most)",
    )
    seed: int = Field(0, strict=True, ge=0, le=2**31 - 1, description="the design's random seed")
    resolution: (
        dict[
            Literal[tuple(CORRECTED_BY)],
            Annotated[
                list[Annotated[float, Field(strict=True, allow_inf_nan=False, ge=0)]],
                Field(min_length=2, max_length=2),
            ],
        ]
        | None
    ) = Field(
        None,
        description="the test's cell is not the bulk: per kind of target, [factor, sd of its "
        "log] taking the cell's value to the bulk's (e.g. from the resolution curve of a "
        "study whose reference is this test; docs/CALIBRATION.md)",
    )
    then_study: ThenStudyIn | None = Field(  # type: ignore[valid-type]
        None,
        description="a scaling study of the calibrated law, submitted when the calibration "
        "succeeds (its reference: the test with the calibrated law)",
    )
    vary_seed: bool = Field(
        False,
        strict=True,
        description="each run packs its own sample (the test's packing seed plus the run's "
        "index), so that the emulators' noise holds the packing scatter; false: every run on "
        "the test's one packing, whose own offset the calibration then absorbs into the "
        "parameters (docs/CALIBRATION.md)",
    )
    shear_test: ShearCellIn | None = Field(  # type: ignore[valid-type]
        None,
        description="with shear targets (targets.shear): the shear cell each yield locus runs "
        "in (engine.ShearTest's fields; its particle radius the test's); null: the default "
        "cell, 10 x 5 x 15 diameters of the test's particles with the test's material and "
        "time step (docs/CALIBRATION.md, Shear data)",
    )

    def engine_dict(self) -> dict:
        """The request as :func:`service.admission.admit_calibration` takes it (what the
        client set; defaults filled in for the design's size)."""
        out = self.model_dump(exclude_unset=True, exclude={"name"})
        for k in ("runs", "waves", "wave_runs", "seed"):
            out.setdefault(k, getattr(self, k))
        return out
