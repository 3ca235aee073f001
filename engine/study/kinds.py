"""Test kinds as a registry (issue 51 item 2), as LAMMPS registers its granular sub-models:
each kind of test a study can take as its reference declares what the study, the service,
the command line and the page need of it, so that none of them tests which kind it is.

A kind declares: its spec and result records; its verdict metrics and how a run's values
of them are read; its shape measures; its run (the driver, with the options it honours:
checkpoints, a wall-time limit, backends); its resolution control and halved protocol; a
step estimate; its table's columns and units, its row's scalars and the reference scalars a
summary quotes; whether its runs keep snapshots; whether its stage-time bound grows with
the coarse-graining factor; the constants its study leaves in seconds (what a coarse run
against its control can see). :func:`kind_of` finds a record's kind, the one place where a
record's type is asked; :func:`register` adds one (a new kind: its own package and one
registration line).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

from ..core.errors import ParameterError
from ..core.records import from_dict
from ..hopper import spec as hopper_spec
from ..hopper import study as hopper_study
from ..hopper.results import HopperResult
from ..hopper.spec import HopperTest
from ..shear import spec as shear_spec
from ..shear.driver import run_shear
from ..shear.results import ShearResult
from ..shear.spec import ShearTest
from ..uniaxial.driver import run_uniaxial
from ..uniaxial.measures import overburden_ratio
from ..uniaxial.results import UniaxialResult
from ..uniaxial.spec import UniaxialTest, halved_protocol, uniaxial_from_json
from .metrics import (
    METRIC_COLUMNS,
    METRICS,
    SHAPE_NAMES,
    SHEAR_METRIC_COLUMNS,
    SHEAR_METRICS,
    Metric,
    metric_column,
    metric_names,
    shear_metric_values,
    uniaxial_metric_values,
    uniaxial_shape_errors,
)

#: Units of the columns of a uniaxial study's table (:attr:`engine.StudyResult.table`).
TABLE_UNITS = {
    "run": "",
    "radius": "m",
    "rule": "",
    "seed": "",
    "scale": "1",
    "particles": "1",
    "steps": "1",
    "dt": "s",
    "wall_time": "s",
    "particle_steps": "1",
    "speedup": "1",
    "speedup_steps": "1",
    "thickness_diameters": "1",
    "height_diameters": "1",
    "overburden_ratio": "1",
    "unconfined_failure": "1",
    "unconfined_strength": "Pa",
    **dict.fromkeys(METRIC_COLUMNS.values(), "1"),
    **dict.fromkeys(SHAPE_NAMES, "1"),
}

#: The shear test's scalars a shear study's table carries beside its errors.
SHEAR_TABLE_SCALARS = {
    "cohesion": "Pa",
    "friction_angle": "deg",
    "preshear_tau": "Pa",
    "sigma_1": "Pa",
    "sigma_c": "Pa",
    "ffc": "1",
    "bulk_density": "kg/m^3",
}

#: Units of the columns of a shear study's table.
SHEAR_TABLE_UNITS = {
    **{
        k: v
        for k, v in TABLE_UNITS.items()
        if k not in METRIC_COLUMNS.values()
        and k not in SHAPE_NAMES
        and not k.startswith("unconfined_")
    },
    **SHEAR_TABLE_SCALARS,
    **dict.fromkeys(SHEAR_METRIC_COLUMNS.values(), "1"),
}

#: The uniaxial test's scalars a study's reference summary quotes.
UNIAXIAL_SUMMARY = (
    "unconfined_strength",
    "unconfined_strength_platen",
    "unconfined_strength_interior",
    "self_weight_stress",
    "unconfined_failure",
    "loading_stiffness",
    "unloading_stiffness",
    "consolidated_porosity",
    "consolidated_porosity_interior",
    "wall_time",
    "particles",
)

#: The shear test's scalars a study's reference summary quotes.
SHEAR_SUMMARY = (
    "preshear_sigma",
    "preshear_tau",
    "cohesion",
    "cohesion_se",
    "friction_angle",
    "effective_friction_angle",
    "sigma_1",
    "sigma_c",
    "ffc",
    "bulk_density",
    "height_diameters",
    "wall_time",
    "particles",
)


@dataclass(frozen=True)
class TestKind:
    """What a study needs of one kind of test (module docstring).

    Attributes: ``name``; ``title`` (the test in words) and ``runner`` (the public function
    that runs one, as a refusal names them); ``spec``, ``result`` (record classes);
    ``json_type`` (the ``"type"`` a study's JSON gives its reference, None for the default
    kind);
    ``from_json(raw, owner)`` (its test from that JSON, the tag removed); ``metrics``
    (name -> :class:`engine.study.metrics.Metric`); ``metric_names(test)`` (those a study of
    ``test`` judges); ``headline`` (the metrics a user reads first, in order: the first a
    study judges is its headline, engine.study.allocate.headline);
    ``metric_values(result)``; ``shape_names``; ``shape_errors(run, ref)``;
    ``run(test, progress, checkpoint, backend, max_wall_time, wall_time_setting)``;
    ``checkpoints``, ``wall_time_limit`` (whether its run honours them), ``backends`` (the
    backends its run takes: None for any); ``control_test(reference, radius,
    reference_dt)``; ``halved_protocol(test)``; ``estimated_steps(test)``; ``table_units``;
    ``row_scalars(result)`` (its table row's own columns); ``hidden_columns`` (the table
    columns a study's page leaves out: they read 0 for every run of the kind);
    ``infinite_scalars`` (table scalars that may be infinite: a summary's JSON holds null
    there, so a page reads them from the runs' files); ``summary_scalars`` (the
    reference scalars a summary quotes); ``snapshots`` (whether its runs keep stage-end
    snapshots); ``stage_time_scales`` (whether a coarse run's ``max_stage_time`` grows by
    s); ``window`` (whether a study sets its interior window, ``interior_margin``);
    ``clock_constants`` (in words: what a rule that is the law's exact similarity leaves in
    seconds, the only thing a coarse run against its control can see); ``write_group(g,
    result, keep_particles)`` and ``read_group(g, test_json)`` (its run in an h5py group,
    engine.io.store's one run layout; ``test_json`` without the ``"type"`` tag).
    """

    name: str
    title: str
    runner: str
    spec: type
    result: type
    json_type: str | None
    from_json: Callable[[dict, str], Any]
    metrics: Mapping[str, Metric]
    metric_names: Callable[[Any], tuple[str, ...]]
    headline: tuple[str, ...]
    metric_values: Callable[[Any], dict]
    shape_names: tuple[str, ...]
    shape_errors: Callable[[Any, Any], dict]
    run: Callable[..., Any]
    checkpoints: bool
    wall_time_limit: bool
    backends: tuple[str, ...] | None
    control_test: Callable[[Any, float, float], Any]
    halved_protocol: Callable[[Any], Any]
    estimated_steps: Callable[[Any], float]
    table_units: Mapping[str, str]
    row_scalars: Callable[[Any], dict]
    hidden_columns: frozenset[str]
    infinite_scalars: tuple[str, ...]
    summary_scalars: tuple[str, ...]
    snapshots: bool
    stage_time_scales: bool
    window: bool
    clock_constants: str
    write_group: Callable[[Any, Any, bool], None]
    read_group: Callable[[Any, dict], Any]


def _stored(name: str) -> Callable[..., Any]:
    """engine.io.store's ``name``, imported when called (io sits below study in the layers:
    ARCHITECTURE.md)."""

    def call(*args: Any, **kwargs: Any) -> Any:
        from ..io import store

        return getattr(store, name)(*args, **kwargs)

    call.__name__ = name
    return call


KINDS: dict[str, TestKind] = {}


def register(kind: TestKind) -> TestKind:
    """Add ``kind`` to the registry (its name unique); returns it."""
    if kind.name in KINDS and KINDS[kind.name] is not kind:
        raise ValueError(f"a test kind named {kind.name!r} is registered already")
    KINDS[kind.name] = kind
    return kind


def kind_of(obj) -> TestKind:
    """The kind of a test or of its result (or of anything that carries its ``test``): the
    one place a record's type is asked. TypeError for anything else."""
    for kind in KINDS.values():
        if isinstance(obj, (kind.spec, kind.result)):
            return kind
    test = getattr(obj, "test", None)  # a run's outcome of another shape, by its test
    if test is not None and test is not obj:
        return kind_of(test)
    names = ", ".join(f"{k.spec.__name__}" for k in KINDS.values())
    raise TypeError(f"not a test of a registered kind ({names}): {type(obj).__name__}")


def kind_for_json(raw: Any) -> TestKind:
    """The kind a test's JSON object names by its ``"type"``: a kind's ``json_type``, or
    none or the default kind's class name for the default kind (the one whose
    ``json_type`` is None). KeyError for any other."""
    tag = raw.get("type") if isinstance(raw, dict) else None
    for kind in KINDS.values():
        if tag == kind.json_type or (kind.json_type is None and tag == kind.spec.__name__):
            return kind
    raise KeyError(tag)


def test_from_json(raw: dict, owner: str | None = None):
    """The test a JSON object holds: of the kind its ``"type"`` names (none, or the default
    kind's class name: the default kind, a uniaxial test's fields or a preset with overrides),
    from its other fields. ``owner`` names the fields in errors (None: the kind's class
    name); an unknown type is refused naming ``<owner>.type``."""
    raw = dict(raw)
    try:
        kind = kind_for_json(raw)
    except KeyError:
        names = sorted(k.json_type or k.spec.__name__ for k in KINDS.values())
        tag = raw.get("type")
        raise ParameterError(f"{owner or 'test'}.type", tag, f"one of {names}") from None
    raw.pop("type", None)
    return kind.from_json(raw, owner or kind.spec.__name__)


def kind_of_table(table: list[dict]) -> TestKind:
    """The kind of a study from its result table alone (a study read back without its
    spec): the one most of whose verdict metrics' error columns
    (engine.study.metrics.metric_column) its rows carry, the first registered at a tie; the
    default kind for a table with none."""
    present = {c for row in table for c in row}

    def carried(kind: TestKind) -> int:
        return len(present & {metric_column(n) for n in kind.metrics})

    best = max(KINDS.values(), key=carried)
    return best if carried(best) else kind_for_json(None)


# ------------------------------------------------------------------ the uniaxial test
def uniaxial_control_test(reference: UniaxialTest, radius: float, reference_dt: float):
    """The resolution control of coarse radius ``radius`` [m]: the ``reference`` law unscaled
    in the reference test scaled by s = R_ref / radius (docs/PHYSICS.md section 7.4): the
    cell, and so the pour column, and the interior margin times s (the control is as many of
    its diameters across as a coarse run is of its own), the platen speed times s (the strain
    rate kept) and gravity over s (the overburden rho g H kept); the law, the time step
    (``reference_dt`` [s]) and the stage times kept. For the linear law under K ~ R,
    f0 ~ R^2 with Hertz platens a coarse run is this test scaled up by 1/s in length and
    1/s^2 in force, all but its clock (docs/PHYSICS.md section 5.1)."""
    s = reference.radius / radius
    return replace(
        reference,
        cell=tuple(c * s for c in reference.cell),
        platen_speed=reference.platen_speed * s,
        gravity=reference.gravity / s,
        interior_margin=reference.margin * s,
        # the reference's step: the same law and radius have the same contact time
        dt=None if reference.dt is None else reference_dt,
    )


def uniaxial_steps(test: UniaxialTest) -> float:
    """Rough step count of a uniaxial test: fill (two free-fall times of the pour column),
    compression of the sample by 10 % there and back, release, unconfined strain. At a
    constant ``platen_speed`` the loading takes strain x height / speed; at an
    ``inertial_number`` I* the strain rate is I* sqrt(p / rho) / d (at most
    ``max_platen_speed`` / height), taken at a quarter of the consolidation stress as the
    stages' typical stress (engine.uniaxial.measures.loading_speed); a hold stage counted at
    twice its ``hold_time`` and ``hold_quiet``."""
    dt = test.resolved_dt()
    height = test.cell[2]
    if test.inertial_number is None:
        rate = test.platen_speed / height
    else:
        d = 2.0 * test.radius
        p = 0.25 * test.consolidation_stress
        rate = min(
            test.inertial_number * math.sqrt(p / test.density) / d,
            test.max_platen_speed / height,
        )
    t = 2 * test.fall_time + 0.2 / rate
    if test.hold_time is not None:  # at least hold_time, then until the bed is at rest
        t += 2 * (test.hold_time + (test.hold_quiet or 0.0))
    if test.unloading_inertial_number is not None:  # the unloading's share, about half
        t += 0.1 / rate * (test.inertial_number / test.unloading_inertial_number - 1.0)
    if test.unconfined:
        t += test.release_time + test.max_unconfined_strain / rate
    return t / dt


def _run_uniaxial(
    test, progress=None, checkpoint=None, backend=None, max_wall_time=None, wall_time_setting=None
):
    limit = {}
    if max_wall_time is not None:
        limit = {"max_wall_time": max_wall_time, "wall_time_setting": wall_time_setting}
    return run_uniaxial(test, progress=progress, checkpoint=checkpoint, backend=backend, **limit)


def _uniaxial_row(result) -> dict:
    s = result.scalars
    row = {"overburden_ratio": overburden_ratio(result)}
    if "unconfined_strength" in s:
        row["unconfined_failure"] = s["unconfined_failure"]
        row["unconfined_strength"] = s["unconfined_strength"]
    return row


UNIAXIAL = register(
    TestKind(
        name="uniaxial",
        title="uniaxial test",
        runner="engine.run_uniaxial",
        spec=UniaxialTest,
        result=UniaxialResult,
        json_type=None,
        from_json=uniaxial_from_json,
        metrics=METRICS,
        metric_names=lambda test: metric_names(test.unconfined),
        headline=("strength", "loading_stiffness"),
        metric_values=uniaxial_metric_values,
        shape_names=SHAPE_NAMES,
        shape_errors=uniaxial_shape_errors,
        run=_run_uniaxial,
        checkpoints=True,
        wall_time_limit=True,
        backends=None,
        control_test=uniaxial_control_test,
        halved_protocol=halved_protocol,
        estimated_steps=uniaxial_steps,
        table_units=TABLE_UNITS,
        row_scalars=_uniaxial_row,
        hidden_columns=frozenset(),
        infinite_scalars=(),
        summary_scalars=UNIAXIAL_SUMMARY,
        snapshots=True,
        stage_time_scales=False,
        window=True,
        clock_constants="the constants left in seconds (output_interval, release_time) and "
        "the runs' chaos",
        write_group=_stored("write_uniaxial_group"),
        read_group=_stored("read_uniaxial_group"),
    )
)


# ------------------------------------------------------------------ the shear test
#: Shear strain a shear point's stages take, as estimated: the reverse to zero shear stress
#: and the shear to its peak and 5 % past it (the stored points peak at a few hundredths of
#: strain, docs/SHEAR.md) [-].
POINT_STRAIN = 0.1


def shear_steps(test: ShearTest) -> float:
    """Rough step count of a shear test: its consolidation test's fill and lid descent
    (:func:`uniaxial_steps`), the pre-shear over ``preshear_min_strain`` and one
    ``steady_window`` more, and :data:`POINT_STRAIN` per shear point, each at the shear
    rate the inertial number gives at its normal stress, I sqrt(sigma / rho) / d (at most
    ``max_shear_speed`` over the gap, taken as the cell's height)."""
    cons = test.consolidation_test()
    d = 2.0 * test.radius

    def rate(sigma: float) -> float:
        return min(
            test.inertial_number * math.sqrt(sigma / test.density) / d,
            test.max_shear_speed / test.cell[2],
        )

    t = (test.preshear_min_strain + test.steady_window) / rate(test.preshear_stress)
    t += sum(POINT_STRAIN / rate(s) for s in test.normal_stresses)
    return uniaxial_steps(cons) + t / cons.resolved_dt()


def _run_shear(test, progress=None, checkpoint=None, **_options):
    # the kind declares what it does not honour (a wall-time limit, another backend):
    # run_study refuses those options before any run starts
    return run_shear(test, progress=progress, checkpoint=checkpoint)


def _shear_row(result) -> dict:
    s = result.scalars
    return {"overburden_ratio": 0.0, **{k: s[k] for k in SHEAR_TABLE_SCALARS}}


SHEAR = register(
    TestKind(
        name="shear",
        title="shear test",
        runner="engine.run_shear",
        spec=ShearTest,
        result=ShearResult,
        json_type="ShearTest",
        from_json=lambda raw, owner: from_dict(ShearTest, raw, owner),
        metrics=SHEAR_METRICS,
        metric_names=lambda test: tuple(SHEAR_METRICS),
        headline=("ffc",),
        metric_values=shear_metric_values,
        shape_names=(),
        shape_errors=lambda run, ref: {},
        run=_run_shear,
        checkpoints=True,
        wall_time_limit=False,
        backends=("cpu", "auto"),
        control_test=shear_spec.control_test,
        halved_protocol=shear_spec.halved_protocol,
        estimated_steps=shear_steps,
        table_units=SHEAR_TABLE_UNITS,
        row_scalars=_shear_row,
        hidden_columns=frozenset({"overburden_ratio"}),  # gravity off from the consolidation
        infinite_scalars=("ffc",),  # sigma_1 / sigma_c where sigma_c = 0
        summary_scalars=SHEAR_SUMMARY,
        snapshots=False,
        stage_time_scales=True,
        window=False,
        clock_constants="the curve samples' clock (output_interval, fixed in seconds) and "
        "the runs' chaos",
        write_group=_stored("write_shear_group"),
        read_group=_stored("read_shear_group"),
    )
)


# ------------------------------------------------------------------ the hopper (docs/HOPPER.md)
HOPPER_METRICS = {m[0]: Metric(*m) for m in hopper_study.HOPPER_METRICS}
HOPPER = register(
    TestKind(
        name="hopper",
        title="hopper",
        runner="engine.run_hopper",
        spec=HopperTest,
        result=HopperResult,
        json_type="HopperTest",
        from_json=lambda raw, owner: from_dict(HopperTest, raw, owner),
        metrics=HOPPER_METRICS,
        metric_names=lambda test: tuple(HOPPER_METRICS),
        headline=("discharge_number",),
        metric_values=hopper_study.hopper_metric_values,
        shape_names=(),
        shape_errors=lambda run, ref: {},
        run=hopper_study.run_hopper_kind,
        checkpoints=True,
        wall_time_limit=True,
        backends=None,
        control_test=hopper_spec.control_test,
        halved_protocol=hopper_spec.halved_protocol,
        estimated_steps=hopper_study.hopper_steps,
        table_units={
            **{
                k: v
                for k, v in TABLE_UNITS.items()
                if k not in METRIC_COLUMNS.values()
                and k not in SHAPE_NAMES
                and not k.startswith("unconfined_")
            },
            **hopper_study.HOPPER_TABLE_SCALARS,
            **{f"err_{k}": "1" for k in HOPPER_METRICS},
        },
        row_scalars=hopper_study.hopper_row,
        hidden_columns=frozenset({"overburden_ratio"}),  # engine.hopper.study.hopper_row's 0
        infinite_scalars=(),
        summary_scalars=hopper_study.HOPPER_SUMMARY,
        snapshots=False,
        stage_time_scales=False,
        window=False,
        clock_constants="the discharge samples' clock (output_interval, fixed in seconds), "
        "the gate's opening and the runs' chaos",
        write_group=_stored("write_hopper_group"),
        read_group=_stored("read_hopper_group"),
    )
)
