"""Admission of a :class:`~service.spec.StudyCreate` into an :class:`engine.StudySpec`.

Pydantic has checked each field's range. Then, from the raw fields and before anything is
built (:mod:`service.cost`, microseconds): the number of runs, the particles of every run,
the bounds on the knobs that set work, and the worst-case particle-steps and curve samples
of the study against their caps. Only then does the engine build the spec and plan it, once
(:func:`engine.plan`: every run's test, checked runnable, e.g. the cell must hold the coarsest
particle; no packing is placed: the run that needs one places it); its errors are turned into
the same field-level 422 answers; the caps are checked once more on the built spec, and the
plan is stored with the job for the worker to run.
"""

from __future__ import annotations

import contextlib
import logging
import math
import re
from collections.abc import Callable, Iterator
from dataclasses import replace
from typing import NamedTuple

import numpy as np

import engine
from engine.study.kinds import TestKind, kind_for_json, kind_of
from engine.uniaxial.spec import particle_count

from . import cost
from .errors import UNION_TAGS, untagged
from .settings import Settings
from .spec import StudyCreate

log = logging.getLogger("demscale.api")


class SpecRejected(ValueError):
    """A spec the engine or the caps refuse; ``errors`` in FastAPI's 422 format."""

    def __init__(self, errors: list[dict]):
        self.errors = errors
        super().__init__("; ".join(e["msg"] for e in errors))


def _plain(value: object) -> object:
    """``value`` as strict JSON can carry it: non-finite numbers and engine objects as text."""
    if isinstance(value, bool) or value is None or isinstance(value, (int, str)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else str(value)
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    return repr(value)


def _error(loc: tuple, msg: str, value: object) -> dict:
    return {"type": "value_error", "loc": ("body", *loc), "msg": msg, "input": _plain(value)}


def engine_loc(field: str) -> tuple:
    """Where in the request body the engine's dotted field name points."""
    parts: list = []
    for name, index in re.findall(r"(\w+)(?:\[(\d+)\])?", field):
        parts.append(name)
        if index:
            parts.append(int(index))
    head, rest = (parts[0], parts[1:]) if parts else ("StudySpec", [])
    prefix = {
        "StudySpec": (),
        "UniaxialTest": ("reference",),
        "ShearTest": ("reference",),
        "HopperTest": ("reference",),
        "preset": ("reference", "preset"),
        # a contact law's errors name its type, as pydantic's tagged-union errors do
        "BilinearAdhesive": ("reference", "pair_law", "BilinearAdhesive"),
        "EEPA": ("reference", "pair_law", "EEPA"),
        "WallMaterial": ("reference", "wall_material"),
        "ScalingRule": ("rules",),
        "HertzMindlin": ("reference", "wall_law"),
    }.get(head, ())
    if head == "ScalingRule":
        rest = []
    return (*prefix, *rest)


#: A rule that spans fields is broken by the field the engine names or by one it compares it
#: with: when the request set only the other one, that one is named (the field the user
#: gave), with the engine's words. Keyed by the field the engine names; the others as paths
#: from the same test (or law), most likely first.
RELATED: dict[str, tuple[tuple[str, ...], ...]] = {
    "k2": (("k1",),),
    "consolidation_stress": (("pre_stress",),),
    "pour_fraction": (("solid_fraction",),),
    "output_interval": (("dt",), ("platen_speed",), ("cell",)),
    "max_stage_time": (
        ("platen_speed",),
        ("cell",),
        ("pour_fraction",),
        ("solid_fraction",),
        ("pour_speed",),
        ("gravity",),
    ),
    # the stable time step: set by the stiffest law and the lightest particle
    "dt": (
        ("pair_law", "k2"),
        ("pair_law", "k1"),
        ("pair_law", "kadh"),
        ("pair_law", "restitution"),
        ("radius",),
        ("polydispersity",),
        ("density",),
        ("wall_law",),
        ("wall_material",),
    ),
    "f0": (("k1",),),
    "cell": (("radius",), ("polydispersity",)),
    # a shear reference's (engine.ShearTest.__post_init__)
    "normal_stresses": (("preshear_stress",),),
    "preshear_min_strain": (("preshear_strain",),),
    "steady_window": (("preshear_strain",),),
    "preshear_stress": (("pair_law", "f0"), ("pair_law", "k1")),
}


def given_paths(value, prefix: tuple = ()) -> set[tuple]:
    """Every path into a request body (objects and lists, and each one's prefixes): what
    the client set."""
    out = {prefix} if prefix else set()
    if isinstance(value, dict):
        for k, v in value.items():
            out |= given_paths(v, (*prefix, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            out |= given_paths(v, (*prefix, i))
    return out


def value_at(body, path: tuple):
    for key in path:
        body = body[key]
    return body


def _blamed(loc: tuple, given: set[tuple], data: dict) -> tuple[tuple, str] | None:
    """The field the client set that breaks the rule the engine reported at ``loc`` (a
    field the client did not set), and its value in words; None to keep ``loc``."""
    plain = untagged(loc)
    if not plain or plain in given:
        return None
    if isinstance(plain[-1], int) and plain[:-1] not in given:  # an item of a list left out
        plain = plain[:-1]
    name = plain[-1]
    # the test (or law) the field belongs to: "dt" and "cell" at the test, law fields at it
    if name in ("dt", "cell", "output_interval", "max_stage_time") or plain[-2:-1] != ("pair_law",):
        test = plain[:-1]
    else:
        test = plain[:-2]
    for other in RELATED.get(name, ()):
        where = (*plain[:-1], *other) if name in ("k2", "f0") else (*test, *other)
        if where in given:
            value = value_at(data, where)
            return where, f"{'.'.join(map(str, where))} = {value!r}"
    return None


def engine_error(loc: tuple, msg: str, value, data: dict) -> dict:
    """A 422 error of the engine's at ``loc`` in the request ``data``: at the field the
    client set that breaks the rule when the engine named one it left to a default."""
    blamed = _blamed(loc, given_paths(data), data)
    if blamed is None:
        return _error(loc, msg, value)
    where, given = blamed
    return _error(
        tagged(where, data),
        f"{given}: with it, {msg} ({loc[-1]} was not given: the preset's or the default)",
        value_at(data, where),
    )


#: The law fields of a test, and the law a body means where it names none (``type``).
_LAW_FIELDS = {"pair_law": "BilinearAdhesive", "wall_law": "HertzMindlin"}


def tagged(path: tuple, data: dict) -> tuple:
    """``path`` (into the body ``data``) as pydantic writes the loc of a field inside a
    tagged union: the law's type after ``pair_law`` (``("reference", "pair_law", "EEPA",
    "k1")``)."""
    for i, part in enumerate(path[:-1]):
        if part in _LAW_FIELDS and path[i + 1] not in UNION_TAGS:
            try:
                law = value_at(data, path[: i + 1])
            except (KeyError, IndexError, TypeError):
                law = {}
            kind = law.get("type", _LAW_FIELDS[part]) if isinstance(law, dict) else None
            return (*path[: i + 1], kind, *path[i + 1 :]) if kind else tuple(path)
    return tuple(path)


def _unstable_alone(fields: dict, loc: tuple) -> str | None:
    """Where the engine refused k2 >= k1 and the client set both: whether k1 alone is beyond
    the test's time step (with the softest k2 it admits, k2 = k1); the engine's words if so.
    Then k1 is the field to name, not k2 (a k1 of 1e300 N/m is wrong whatever k2 is)."""
    law = fields.get("pair_law")
    if untagged(loc)[-1:] != ("k2",) or not isinstance(law, dict) or "k1" not in law:
        return None
    try:
        engine.UniaxialTest.from_dict({**fields, "pair_law": {**law, "k2": law["k1"]}})
    except engine.ParameterError as e:
        return str(e) if e.field.endswith(".dt") else None
    except Exception:  # anything else: the engine's own error (k2) stands
        return None
    return None


def particles_from_fields(fields: dict, radius: float) -> float:
    """Particles of the test ``fields`` with particles of ``radius``, by the engine's own
    count (:func:`engine.uniaxial.spec.particle_count`, what ``UniaxialTest.n_particles``
    returns) from the raw fields, before any record is built: a request with millions of
    particles is refused by the cap in microseconds. inf when the count overflows."""
    try:
        with np.errstate(all="ignore"):  # a zero radius counts as inf, not as a warning
            return float(
                particle_count(
                    tuple(fields["cell"]),
                    radius,
                    fields["solid_fraction"],
                    fields["polydispersity"],
                )
            )
    except (OverflowError, ValueError, ZeroDivisionError):
        return math.inf


def _too_many_particles(loc: tuple, key: str, n: float, settings: Settings) -> SpecRejected:
    return SpecRejected(
        [
            _error(
                loc,
                f"run {key} would have {n:.0f} particles; the limit "
                f"is {settings.max_particles_per_run} per run "
                "(DEMSCALE_MAX_PARTICLES_PER_RUN): use a smaller cell, "
                "larger particles or a lower solid fraction",
                n,
            )
        ]
    )


def _too_many_runs(n: int, settings: Settings) -> SpecRejected:
    return SpecRejected(
        [
            _error(
                (),
                f"the study has {n} runs (seeds x (1 + radii x rules), + seeds x radii "
                "resolution controls); "
                f"the limit is {settings.max_runs} (DEMSCALE_MAX_RUNS)",
                n,
            )
        ]
    )


#: What the particle-steps cap is, and how to come under it, per kind of job.
_STEPS_CAP = {
    "study": (
        "max_particle_steps",
        "DEMSCALE_MAX_PARTICLE_STEPS",
        "use fewer or coarser runs, a smaller cell, fewer seeds or a lower max_stage_time",
    ),
    "calibration": (
        "max_calibration_particle_steps",
        "DEMSCALE_MAX_CALIBRATION_PARTICLE_STEPS",
        "use fewer runs, waves or wave_runs, a smaller cell or a lower max_stage_time",
    ),
}


#: What bounds each stage of a test in the worst case (the refusal names them).
UNIAXIAL_BOUNDS = "max_stage_time, the platen travel, release_time, max_unconfined_strain"
SHEAR_BOUNDS = (
    "the fill and consolidation's max_stage_time and platen travel, preshear_strain, "
    "failure_strain, and max_stage_time for each reversal and normal-stress stage"
)
HOPPER_BOUNDS = "max_settle_time and max_discharge_time"


def check_costs(
    costs: list[cost.RunCost],
    settings: Settings,
    kind: str = "study",
    bounds: str = UNIAXIAL_BOUNDS,
) -> None:
    """The job's worst-case particle-steps and curve samples against their caps (``kind``:
    a ``study`` or a ``calibration``, each with its particle-steps cap; ``bounds``: what
    bounds its stages, :data:`UNIAXIAL_BOUNDS` or a shear study's :data:`SHEAR_BOUNDS`)."""
    attr, env, advice = _STEPS_CAP[kind]
    cap = getattr(settings, attr)
    where = "reference" if kind == "study" else "test"
    steps = sum(c.particle_steps for c in costs)
    if steps > cap:
        worst = max(costs, key=lambda c: c.particle_steps)
        raise SpecRejected(
            [
                _error(
                    (),
                    f"the {kind} could take {steps:.3g} particle-steps at worst (every stage "
                    f"to its bound: {bounds}; the largest run {worst.key}: "
                    f"{worst.particle_steps:.3g}); the limit is {cap:.3g} ({env}): {advice}",
                    steps,
                )
            ]
        )
    samples = sum(c.samples for c in costs)
    if samples > settings.max_curve_samples:
        raise SpecRejected(
            [
                _error(
                    (where, "output_interval"),
                    f"the {kind} could store {samples:.3g} curve samples at worst; the limit "
                    f"is {settings.max_curve_samples} (DEMSCALE_MAX_CURVE_SAMPLES): use a "
                    "longer output_interval, a lower max_stage_time or fewer runs",
                    samples,
                )
            ]
        )


def _check_bounds(fields: dict, where: str = "reference", data: dict | None = None) -> None:
    bad = cost.work_bounds(fields, cost.reference_dt(fields))
    if bad:
        errors: dict[tuple, dict] = {}
        for name, value, bound in bad:  # one error per field named
            e = engine_error(
                (where, name),
                f"UniaxialTest.{name} = {value!r} is not allowed: must be {bound}",
                value,
                data if data is not None else {},
            )
            if e["loc"] in errors:
                errors[e["loc"]]["msg"] += f"; and {e['msg']}"
            else:
                errors[e["loc"]] = e
        raise SpecRejected(list(errors.values()))


@contextlib.contextmanager
def engine_refusals(
    data: dict, loc_of: Callable[[str], tuple], fields: Callable[[], dict], noun: str, built: str
) -> Iterator[None]:
    """Turn what the engine raises while building the request ``data`` into its 422
    (:class:`SpecRejected`): a ParameterError at ``loc_of(field)`` (:func:`refused`, with
    the test's ``fields()`` as built), a TypeError or ValueError as "the ``noun`` is not
    valid" (e.g. an explicit null where a value is needed), anything else, an input the
    engine's checks did not foresee, logged and refused as "the engine cannot build this
    ``built``". A SpecRejected passes through."""
    try:
        yield
    except SpecRejected:
        raise
    except engine.ParameterError as e:
        raise refused(e, loc_of(e.field), data, fields()) from e
    except (TypeError, ValueError) as e:
        raise SpecRejected([_error((), f"the {noun} is not valid: {e}", None)]) from e
    except Exception as e:  # an input the engine's checks did not foresee: logged, refused
        log.exception("the engine failed on a submitted %s: %s", noun, data)
        raise SpecRejected(
            [_error((), f"the engine cannot build this {built}: {type(e).__name__}: {e}", None)]
        ) from e


def refused(e: engine.ParameterError, loc: tuple, data: dict, fields: dict) -> SpecRejected:
    """The 422 of an engine refusal ``e`` at ``loc`` of the request ``data`` (its test's
    ``fields`` as built): at the field the client set (:func:`engine_error`), and at k1 where
    k1 alone is beyond the time step (:func:`_unstable_alone`)."""
    alone = _unstable_alone(fields, loc)
    where = (*untagged(loc)[:-1], "k1")
    if alone is not None and where in given_paths(data):
        value = value_at(data, where)
        msg = f"{'.'.join(map(str, where))} = {value!r} is beyond the time step: {alone}"
        return SpecRejected([_error(tagged(where, data), msg, value)])
    return SpecRejected([engine_error(loc, str(e), e.value, data)])


def check_coarse_radii(data: dict, fields: dict) -> None:
    """Each coarse radius above the reference's: a coarse variant has larger particles (a
    finer one is not coarse-graining, and costs more than the reference)."""
    r_ref = fields.get("radius")
    if not isinstance(r_ref, (int, float)):
        return
    for i, r in enumerate(data.get("coarse_radii") or ()):
        if isinstance(r, (int, float)) and not r > r_ref:
            raise SpecRejected(
                [
                    _error(
                        ("coarse_radii", i),
                        f"coarse_radii[{i}] = {r:g} m is not allowed: must be > the reference "
                        f"radius {r_ref:g} m (a coarse variant has larger particles than the "
                        "reference)",
                        r,
                    )
                ]
            )


def reference_kind(data: dict) -> TestKind | None:
    """The test kind the study's fields name by their reference's ``"type"``
    (:func:`engine.study.kinds.kind_for_json`; none: the default kind); None for a type no
    kind has (the engine's building of the spec names it)."""
    try:
        return kind_for_json(data.get("reference"))
    except KeyError:
        return None


def _check_backend(settings: Settings, kind: TestKind) -> None:
    """A study whose kind runs on the CPU only (its ``backends`` lack ``"cuda"``: the shear
    test's engine.run_shear) on a service whose runs go to the GPU (DEMSCALE_BACKEND=cuda):
    refused rather than run elsewhere."""
    if settings.backend != "cuda" or kind.backends is None or "cuda" in kind.backends:
        return
    raise SpecRejected(
        [
            _error(
                ("reference", "type"),
                "this service runs its studies on the GPU (DEMSCALE_BACKEND=cuda) and the "
                f"{kind.title} runs on the CPU only ({kind.runner}): a {kind.name} study "
                "needs a service with DEMSCALE_BACKEND=cpu or auto",
                kind.json_type,
            )
        ]
    )


def _check_hopper_particles(data: dict, fields: dict, settings: Settings) -> None:
    """The particles of a hopper reference against the cap, from its fields (its count
    from ``particles`` or ``fill_height``, engine.HopperTest.n_particles: arithmetic, no
    fill placed), before the plan places the hopper's fill to find its time step; the
    coarse variants have larger particles, so fewer. A test the engine refuses is left to
    the engine's building of the spec, which names the field."""
    try:
        n = float(engine.HopperTest.from_dict(fields).n_particles)
    except (engine.ParameterError, TypeError, ValueError, KeyError, AttributeError):
        return
    if n > settings.max_particles_per_run:
        given = given_paths(data)
        # the field that set the count: particles, or fill_height where particles is null
        count = "particles" if fields.get("particles") is not None else "fill_height"
        loc = next(
            (
                ("reference", f)
                for f in (count, "radius", "outlet_width", "depth")
                if ("reference", f) in given
            ),
            ("reference",),
        )
        raise _too_many_particles(loc, "reference", n, settings)


def _check_size_first(data: dict, settings: Settings) -> None:
    """Refuse, from the raw fields before the engine builds anything, a study with too many
    runs, a run over the particle cap, a knob out of its work bounds, or a worst case over
    the caps (the engine's own checks, and the caps once more, follow on the built spec).
    A kind whose costs have their own model (:data:`KIND_COSTS`: the shear test, the
    hopper): the runs and the particles here (:data:`KIND_PARTICLES`), its worst case on
    the built plan."""
    n_runs = cost.plan_counts(data)
    if n_runs > settings.max_runs:
        raise _too_many_runs(n_runs, settings)
    fields = cost.reference_fields(data)
    if not isinstance(fields.get("radius"), (int, float)):
        return  # the engine names the bad field
    check_coarse_radii(data, fields)
    kind = reference_kind(data)
    name = None if kind is None else kind.name
    if kind is not None:
        _check_backend(settings, kind)
    KIND_PARTICLES.get(name, _check_particles)(data, fields, settings)
    if name in KIND_COSTS:  # its worst case on the built plan
        return
    try:  # the reference's own checks first (the time step, k2 >= k1, ...), then the
        # bounds that compare its fields, then the worst case
        engine.UniaxialTest.from_dict(fields)
    except engine.ParameterError as e:
        raise refused(e, engine_loc(e.field), data, fields) from e
    except (TypeError, ValueError, KeyError, AttributeError):
        return  # the engine's building of the spec names it
    try:  # a field the engine will refuse may make the arithmetic fail: the engine names it
        _check_bounds(fields, data=data)
        costs = cost.worst_case(data)
    except (SpecRejected, engine.ParameterError):
        raise
    except (ArithmeticError, TypeError, ValueError, KeyError, AttributeError):
        return
    check_costs(costs, settings)


def _check_particles(data: dict, fields: dict, settings: Settings) -> None:
    """The particles of the reference and of each coarse radius against the cap, from the
    raw fields (:func:`particles_from_fields`)."""
    radii = [("reference", (("reference",)), fields["radius"])]
    radii += [
        (f"r{r * 1e3:g}mm", ("coarse_radii", i), r)
        for i, r in enumerate(data.get("coarse_radii", ()))
    ]
    given = given_paths(data)
    for key, loc, radius in radii:
        n = particles_from_fields(fields, radius)
        if n > settings.max_particles_per_run:
            if loc == ("reference",):  # the field the client set that makes them many
                loc = next(
                    (
                        ("reference", f)
                        for f in ("radius", "cell", "solid_fraction", "polydispersity")
                        if ("reference", f) in given
                    ),
                    loc,
                )
            raise _too_many_particles(loc, key, n, settings)


class Admitted(NamedTuple):
    """An admitted study: the engine's ``plan`` and the worst-case ``costs`` of its runs
    (:func:`service.cost.worst_case` of the built spec, as checked against the caps)."""

    plan: engine.StudyPlan
    costs: list[cost.RunCost]


def admit(body: StudyCreate, settings: Settings) -> Admitted:
    """The engine's plan of ``body`` (:func:`engine.plan`, once) and its worst-case costs if
    the engine accepts it and it is within the caps; raises :class:`SpecRejected`
    otherwise. (The checks on the built spec repeat those on the raw fields, which give up
    where a field the engine will refuse makes their arithmetic fail.)"""
    return admit_spec(body.engine_dict(), settings)


def admit_spec(data: dict, settings: Settings) -> Admitted:
    """:func:`admit` of a study's fields as :meth:`engine.StudySpec.from_dict` takes them."""
    with engine_refusals(data, engine_loc, lambda: cost.reference_fields(data), "spec", "study"):
        _check_size_first(data, settings)
        study = engine.plan(engine.StudySpec.from_dict(data))
    spec, runs = study.spec, study.runs
    if len(runs) > settings.max_runs:
        raise _too_many_runs(len(runs), settings)
    biggest = max(runs, key=lambda p: p.test.n_particles)
    n = biggest.test.n_particles
    if n > settings.max_particles_per_run:
        loc = (
            ("reference",)
            if biggest.is_reference
            else ("coarse_radii", spec.coarse_radii.index(biggest.radius))
        )
        raise _too_many_particles(loc, biggest.key, n, settings)
    own = KIND_COSTS.get(kind_of(spec.reference).name)
    if own is not None:  # a kind whose costs have their own model and bounds (shear)
        costs_of, bounds = own
        costs = costs_of(study)
        check_costs(costs, settings, bounds=bounds)
        return Admitted(study, costs)
    _check_bounds(spec.reference.to_dict(), data=data)
    costs = cost.worst_case(spec.to_dict())
    check_costs(costs, settings)
    return Admitted(study, costs)


def shear_study_costs(study: engine.StudyPlan) -> list[cost.RunCost]:
    """The worst case of every run of a shear study (:func:`study_costs` with
    :func:`shear_cost`)."""
    return study_costs(study, shear_cost)


def hopper_study_costs(study: engine.StudyPlan) -> list[cost.RunCost]:
    """The worst case of every run of a hopper study (:func:`study_costs` with
    :func:`hopper_cost`)."""
    return study_costs(study, hopper_cost)


def hopper_cost(test) -> cost.RunCost:
    """The worst case of one hopper run (an :class:`engine.HopperTest`, docs/HOPPER.md) at
    its time step (engine.hopper.driver.resolved_dt): the settling to ``max_settle_time``
    and the discharge to ``max_discharge_time``, each checked every ``output_interval`` (so
    one sample's steps past its bound at most); a curve sample every ``output_interval`` of
    the discharge and one at the gate's opening (the settling records no curve)."""
    from engine.hopper.driver import resolved_dt

    dt = resolved_dt(test)
    per_sample = max(1.0, float(round(test.output_interval / dt)))
    settle = math.ceil(test.max_settle_time / dt) + per_sample
    discharge = math.ceil(test.max_discharge_time / dt) + per_sample
    samples = 1 + math.ceil(discharge / per_sample)
    return cost.RunCost(
        f"hopper@{test.radius * 1e3:g}mm", float(test.n_particles), settle + discharge, samples
    )


def study_costs(study: engine.StudyPlan, cost_of) -> list[cost.RunCost]:
    """The worst case of every run of a study whose kind has its own cost model
    (``cost_of(test)``, e.g. :func:`shear_cost`, of each planned
    run's test: references, coarse variants, controls and protocol checks) and, with
    ``decide``, of the runs it may add: each reference and coarse variant up to its seed cap
    (``max_reference_seeds``, ``max_seeds``), or, with a ``budget`` of estimated
    particle-steps, that budget times the largest ratio of worst-case to estimated
    particle-steps (and of curve samples to estimated particle-steps) of the runs they copy,
    whichever is less (as :func:`service.cost.worst_case` does for a uniaxial study)."""
    from engine.study.plan import estimated_steps

    spec = study.spec
    out = []
    first: dict[object, tuple[cost.RunCost, object]] = {}
    for p in study.runs:
        c = cost_of(p.test)
        out.append(cost.RunCost(p.key, c.particles, c.steps, c.samples))
        if p.is_reference or (p.rule is not None and not p.control and not p.protocol):
            first.setdefault(p.variant, (c, p.test))
    if not spec.decide:
        return out
    n_ref, n_seeds = len(spec.reference_seeds), len(spec.seeds)
    extra = []
    for variant, (c, test) in first.items():
        cap = spec.max_reference_seeds - n_ref if variant is None else spec.max_seeds - n_seeds
        extra += [(c, test)] * max(0, cap)
    if not extra:
        return out
    particle_steps = sum(c.particle_steps for c, _ in extra)
    samples = sum(c.samples for c, _ in extra)
    if spec.budget is not None:
        typical = [(c, estimated_steps(t) * t.n_particles) for c, t in first.values()]
        ps_ratio = max(c.particle_steps / e for c, e in typical if e > 0)
        sample_ratio = max(c.samples / e for c, e in typical if e > 0)
        particle_steps = min(particle_steps, ps_ratio * spec.budget)
        samples = min(samples, sample_ratio * spec.budget)
    particles = max(c.particles for c, _ in extra)
    out.append(
        cost.RunCost(
            "runs added until decided (worst case)", particles, particle_steps / particles, samples
        )
    )
    return out


# ------------------------------------------------------------------------------ calibration
class AdmittedCalibration(NamedTuple):
    """An admitted calibration: its normalised ``request`` (what the worker runs: the
    test's, the targets' and the then-study's JSON forms, the boxes and the design's size),
    the worst-case ``costs`` of its runs, and the then-study's (empty without one)."""

    request: dict
    costs: list[cost.RunCost]
    then_costs: list[cost.RunCost]


def calibration_loc(field: str) -> tuple:
    """Where in a calibration's body the engine's dotted field name points."""
    head, _, rest = field.partition(".")
    if head == "calibrate":
        parts = rest.split(".")
        return tuple(parts) if parts != [""] else ()
    if head in ("LabTargets", "CompressionPoint", "StrengthPoint", "ShearLocus", "LocusPoint"):
        loc = engine_loc(field.replace(head, "StudySpec", 1))
        return ("targets", *loc) if head == "LabTargets" else ("targets",)
    loc = engine_loc(field)
    return ("test", *loc[1:]) if loc[:1] == ("reference",) else ("test", *loc)


def calibration_costs(test, stresses, total: int, shear=()) -> list[cost.RunCost]:
    """Worst case of every run: each of ``total`` parameter sets runs a branch per
    consolidation stress, each counted as a whole run (the fill they share included), and a
    shear test per yield locus (``shear``: :func:`shear_cost`)."""
    dt = test.dt if test.dt is not None else test.time_step_limit().recommended
    branches = [
        cost.run_cost(f"{s:g}Pa", replace(test, consolidation_stress=s), dt) for s in stresses
    ]
    branches += [shear_cost(t) for t in shear]
    one = cost.RunCost(
        "calibration run",
        max(b.particles for b in branches),
        sum(b.steps for b in branches),
        sum(b.samples for b in branches),
    )
    return [one] * total


def shear_cost(test) -> cost.RunCost:
    """The worst case of one shear test (an :class:`engine.ShearTest`, docs/SHEAR.md): its
    fill and consolidation as the uniaxial test's stages (:func:`service.cost.run_cost` of
    its consolidation test, those two stages), the pre-shear and each shear to failure at
    their strain bounds (``preshear_strain``, ``failure_strain`` of the gap at the shear
    speed of the stage's stress, at most ``max_shear_speed``: t = strain x max(d / (I
    sqrt(sigma / rho)), H / v_max)) or ``max_stage_time`` where that is shorter, and each
    point's reversal and normal-stress stage at ``max_stage_time`` (they end on a reading,
    not a distance); a curve sample every ``output_interval`` and one at each stage's start."""
    ct = test.consolidation_test()
    dt = ct.dt if ct.dt is not None else ct.time_step_limit().recommended
    cap = test.max_stage_time
    consol = cost.worst_stage_times(ct)
    times = [consol["fill"], consol["pre_compression"]]
    d, h = 2.0 * test.radius, test.cell[2]

    def strain_time(strain: float, sigma: float) -> float:
        rate = test.inertial_number * math.sqrt(sigma / test.density)
        if not rate > 0:  # a stress so small its rate underflows: the stage's time bound
            return cap
        return min(cap, strain * max(d / rate, h / test.max_shear_speed))

    times.append(strain_time(test.preshear_strain, test.preshear_stress))
    for s in test.normal_stresses:
        times += [cap, cap, strain_time(test.failure_strain, s)]
    steps = [max(1.0, float(math.ceil(t / dt))) for t in times]
    per_sample = max(1.0, float(round(test.output_interval / dt)))
    samples = sum(1 + math.ceil(n / per_sample) for n in steps)
    return cost.RunCost(
        f"shear@{test.preshear_stress:g}Pa", float(ct.n_particles), sum(steps), float(samples)
    )


def calibration_shear_tests(test, targets, shear_test: dict | None = None) -> tuple:
    """The shear tests a calibration's parameter set runs, one per yield locus of
    ``targets``, with the test's law: in the cell ``shear_test`` (the request's fields of
    an :class:`engine.ShearTest` but the law and stresses), else the default cell
    (:func:`engine.calibration.forward.shear_cell` of the test, the docs/SHEAR.md default
    in diameters); none without shear targets."""
    from engine.calibration.forward import check_shear_cell, shear_tests

    if not targets.shear:
        return ()
    return shear_tests(check_shear_cell(test, shear_test), targets, test.pair_law)


def admit_calibration(body, settings: Settings) -> AdmittedCalibration:
    """The normalised request of ``body`` (a :class:`service.spec.CalibrationCreate`) and
    its worst-case costs if the engine accepts it and it is within the caps (the particles of
    its test, the number of runs, the particle-steps and curve samples of all its runs at
    worst; a then-study is admitted as a study would be, with the uncalibrated law); raises
    :class:`SpecRejected` with the field otherwise."""
    from engine.calibration import LabTargets
    from engine.calibration.calibrate import (
        calibration_runs,
        check_corrections,
        check_request,
    )
    from engine.calibration.forward import cell_summary

    data = body.engine_dict()
    total = calibration_runs(data["runs"], data["waves"], data["wave_runs"])
    if total > settings.max_runs:
        raise SpecRejected(
            [
                _error(
                    ("runs",),
                    f"the calibration runs up to {total} parameter sets (runs + waves x "
                    f"wave_runs + the check run); the limit is {settings.max_runs} "
                    "(DEMSCALE_MAX_RUNS)",
                    total,
                )
            ]
        )
    fields = cost.reference_fields({"reference": data["test"]})
    if isinstance(fields.get("radius"), (int, float)):
        n = particles_from_fields(fields, fields["radius"])
        if n > settings.max_particles_per_run:
            raise _too_many_particles(("test",), "calibration run", n, settings)
    with engine_refusals(data, calibration_loc, lambda: fields, "calibration", "calibration"):
        test = engine.UniaxialTest.from_dict(fields)  # its own checks first (the time step)
        _check_bounds(fields, "test", data)
        targets = LabTargets.from_dict(data["targets"])
        params = {k: tuple(v) for k, v in data["parameters"].items()}
        shear_test = data.get("shear_test")
        stresses = check_request(test, targets, params, data["runs"], shear_test)
        corrections = check_corrections(data.get("resolution"))
        for sv in stresses:  # each branch a test the engine can run
            replace(test, consolidation_stress=sv)
        shear = calibration_shear_tests(test, targets, shear_test)
        costs = calibration_costs(test, stresses, total, shear)
    check_costs(costs, settings, "calibration")
    request = {
        "test": test.to_dict(),
        "targets": targets.to_dict(),
        "parameters": {k: list(v) for k, v in params.items()},
        **{k: data[k] for k in ("runs", "waves", "wave_runs", "seed")},
        "resolution": {k: list(v) for k, v in corrections.items()} or None,
        "then_study": None,
        # the shear cell with every field (the defaults filled in), as the result states it
        "shear_test": cell_summary(shear[0]) if shear else None,
        "vary_seed": bool(data.get("vary_seed", False)),
    }
    then_costs: list[cost.RunCost] = []
    then = data.get("then_study")
    if then is not None:
        try:
            admitted = admit_spec({**then, "reference": data["test"]}, settings)
        except SpecRejected as e:
            raise SpecRejected(
                [{**err, "loc": ("body", "then_study", *tuple(err["loc"])[1:])} for err in e.errors]
            ) from e
        spec = admitted.plan.spec.to_dict()
        spec.pop("reference")
        request["then_study"] = spec
        then_costs = admitted.costs
    return AdmittedCalibration(request, costs, then_costs)


#: The test kinds (engine.study.kinds) whose study costs have their own model and bounds:
#: kind name -> (costs of a plan, bounds); the rest take cost.worst_case on the raw spec.
KIND_COSTS = {
    "shear": (shear_study_costs, SHEAR_BOUNDS),
    "hopper": (hopper_study_costs, HOPPER_BOUNDS),
}

#: The test kinds whose particles are counted from their own fields before the engine
#: builds anything: kind name -> check; the rest count theirs from the cell, the solid
#: fraction and each radius (:func:`_check_particles`).
KIND_PARTICLES = {"hopper": _check_hopper_particles}
