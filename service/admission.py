"""Admission of a :class:`~service.spec.StudyCreate` into an :class:`engine.StudySpec`.

Pydantic has checked each field's range; the engine then checks what spans fields (e.g. the
cell must hold the coarsest particle) and its errors are turned into the same field-level 422
answers; last the size caps (particles per run, runs, particle-steps per study) apply.
"""

from __future__ import annotations

import re

import engine

from .settings import Settings
from .spec import StudyCreate


class SpecRejected(ValueError):
    """A spec the engine or the caps refuse; ``errors`` in FastAPI's 422 format."""

    def __init__(self, errors: list[dict]):
        self.errors = errors
        super().__init__("; ".join(e["msg"] for e in errors))


def _error(loc: tuple, msg: str, value: object) -> dict:
    return {"type": "value_error", "loc": ("body", *loc), "msg": msg, "input": value}


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
        "BilinearAdhesive": ("reference", "pair_law"),
        "WallMaterial": ("reference", "wall_material"),
        "ScalingRule": ("rules",),
        "HertzMindlin": ("reference", "wall_law"),
    }.get(head, ())
    if head == "ScalingRule":
        rest = []
    return (*prefix, *rest)


def admit(body: StudyCreate, settings: Settings) -> engine.StudySpec:
    """The engine spec of ``body`` if the engine accepts it and it is within the caps;
    raises :class:`SpecRejected` otherwise."""
    data = body.engine_dict()
    try:
        spec = engine.StudySpec.from_dict(data)
    except engine.ParameterError as e:
        raise SpecRejected([_error(engine_loc(e.field), str(e), e.value)]) from e
    except (TypeError, ValueError) as e:  # e.g. an explicit null where a value is needed
        raise SpecRejected([_error((), f"the spec is not valid: {e}", None)]) from e
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
        raise SpecRejected(
            [
                _error(
                    loc,
                    f"run {biggest.key} would have {n} particles; the limit "
                    f"is {settings.max_particles_per_run} per run "
                    "(DEMSCALE_MAX_PARTICLES_PER_RUN): use a smaller cell, "
                    "larger particles or a lower fill_fraction",
                    n,
                )
            ]
        )
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
