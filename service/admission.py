"""Admission of a :class:`~service.spec.StudyCreate` into an :class:`engine.StudySpec`.

Pydantic has checked each field's range; the engine then checks what spans fields (e.g. the
cell must hold the coarsest particle) and its errors are turned into the same field-level 422
answers; last the size caps (particles per run, runs, particle-steps per study) apply.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import re

import numpy as np

import engine

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


def _reference_fields(data: dict) -> dict:
    """The reference test's fields as the engine will build them: the preset (``quick``
    when no reference is given) or the record's defaults, overridden by the request."""
    given = dict(data.get("reference", {"preset": "quick"}))
    name = given.pop("preset", None)
    if name is not None:
        base = engine.preset(name).to_dict()
    else:
        base = {
            f.name: f.default if f.default_factory is dataclasses.MISSING else f.default_factory()
            for f in dataclasses.fields(engine.UniaxialTest)
        }
    return {**base, **given}


def particles_before_packing(fields: dict, radius: float) -> float:
    """Particles of the test ``fields`` with particles of ``radius``, by the engine's own
    count (``UniaxialTest.n_particles``) but without building the test: building it places
    the packing, which for a request with millions of particles would take the server's
    memory and time before any cap could refuse it. inf when the count overflows."""
    probe = object.__new__(engine.UniaxialTest)  # no __post_init__: nothing is placed
    for name, value in {**fields, "radius": radius}.items():
        object.__setattr__(probe, name, tuple(value) if isinstance(value, list) else value)
    try:
        with np.errstate(all="ignore"):  # a zero radius counts as inf, not as a warning
            return float(probe.n_particles)
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


def _check_size_first(data: dict, settings: Settings) -> None:
    """Refuse a study whose largest run is over the particle cap before the engine places
    any packing (the exact check follows on the built spec)."""
    fields = _reference_fields(data)
    if not isinstance(fields.get("radius"), (int, float)):
        return  # the engine names the bad field
    radii = [("reference", (("reference",)), fields["radius"])]
    radii += [(f"r{r * 1e3:g}mm", ("coarse_radii", i), r)
              for i, r in enumerate(data.get("coarse_radii", ()))]
    for key, loc, radius in radii:
        n = particles_before_packing(fields, radius)
        if n > settings.max_particles_per_run:
            raise _too_many_particles(loc, key, n, settings)


def admit(body: StudyCreate, settings: Settings) -> engine.StudySpec:
    """The engine spec of ``body`` if the engine accepts it and it is within the caps;
    raises :class:`SpecRejected` otherwise."""
    data = body.engine_dict()
    try:
        _check_size_first(data, settings)
        spec = engine.StudySpec.from_dict(data)
    except SpecRejected:
        raise
    except engine.ParameterError as e:
        raise SpecRejected([_error(engine_loc(e.field), str(e), e.value)]) from e
    except (TypeError, ValueError) as e:  # e.g. an explicit null where a value is needed
        raise SpecRejected([_error((), f"the spec is not valid: {e}", None)]) from e
    except Exception as e:  # an input the engine's checks did not foresee: logged, refused
        log.exception("the engine failed on a submitted spec: %s", data)
        raise SpecRejected(
            [_error((), f"the engine cannot build this study: {type(e).__name__}: {e}", None)]
        ) from e
    runs = spec.planned_runs()
    if len(runs) > settings.max_runs:
        raise SpecRejected(
            [
                _error(
                    (),
                    f"the study has {len(runs)} runs (seeds x (1 + radii x "
                    f"rules)); the limit is {settings.max_runs} "
                    "(DEMSCALE_MAX_RUNS)",
                    len(runs),
                )
            ]
        )
    biggest = max(runs, key=lambda p: p.test.n_particles)
    n = biggest.test.n_particles
    if n > settings.max_particles_per_run:
        loc = (
            ("reference",)
            if biggest.rule is None
            else ("coarse_radii", spec.coarse_radii.index(biggest.radius))
        )
        raise _too_many_particles(loc, biggest.key, n, settings)
    cost = spec.estimated_particle_steps()
    if cost > settings.max_particle_steps:
        raise SpecRejected(
            [
                _error(
                    (),
                    f"the study would take about {cost:.3g} particle-steps; "
                    f"the limit is {settings.max_particle_steps:.3g} "
                    "(DEMSCALE_MAX_PARTICLE_STEPS): use fewer or coarser runs, "
                    "a smaller cell or fewer seeds",
                    cost,
                )
            ]
        )
    return spec
