"""The study spec as the API accepts it (``StudyCreate``, the "create" member of the study
model family), with a range for every field. Fields left out take the engine's defaults (the
``quick`` preset). What spans fields, and the size caps, are checked in
:mod:`service.admission`.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field

import engine

_forbid = ConfigDict(extra="forbid")
Stress = Annotated[float, Field(gt=0, le=1e8, description="[Pa]")]
Fraction = Annotated[float, Field(gt=0, lt=1, description="[-]")]
Friction = Annotated[float, Field(ge=0, le=10, description="[-]")]
Restitution = Annotated[float, Field(gt=0, le=1, description="[-]")]
Radius = Annotated[float, Field(ge=1e-5, le=0.05, description="particle radius [m]")]
Seed = Annotated[int, Field(ge=0, lt=2**31)]
Length = Annotated[float, Field(gt=0, le=2.0, description="[m]")]


class BilinearAdhesiveIn(BaseModel):
    """Bilinear adhesive elasto-plastic pair law (see engine.BilinearAdhesive)."""

    model_config = _forbid
    type: Literal["BilinearAdhesive"] = "BilinearAdhesive"
    k1: float = Field(gt=0, le=1e10, description="loading stiffness [N/m]")
    k2: float = Field(gt=0, le=1e11, description="unloading stiffness [N/m], >= k1")
    f0: float = Field(0.0, ge=-1e4, le=0, description="pull-off force [N]")
    kadh: float = Field(0.0, ge=0, le=1e11, description="adhesive branch slope [N/m]")
    kt_ratio: float = Field(2 / 7, ge=0, le=10, description="Kt / K1 [-]")
    mu_s: Friction = 0.5
    mu_r: Friction = 0.001
    restitution: Restitution = 0.4


class HertzMindlinIn(BaseModel):
    """Hertz-Mindlin law (see engine.HertzMindlin)."""

    model_config = _forbid
    type: Literal["HertzMindlin"] = "HertzMindlin"
    E: float = Field(gt=0, le=1e13, description="Young's modulus [Pa]")
    nu: float = Field(0.25, gt=-1, lt=0.5, description="Poisson's ratio [-]")
    restitution: Restitution = 0.4
    mu: Friction = 0.3
    mu_r: Friction = 0.0


class WallMaterialIn(BaseModel):
    """Platen material."""

    model_config = _forbid
    E: float = Field(2e11, gt=0, le=1e13, description="Young's modulus [Pa]")
    nu: float = Field(0.3, gt=-1, lt=0.5, description="Poisson's ratio [-]")


class ReferenceIn(BaseModel):
    """The fine reference test: a preset and/or fields of engine.UniaxialTest."""

    model_config = _forbid
    preset: Literal["quick", "paper"] | None = None
    cell: tuple[Length, Length, Length] | None = Field(None, description="(Lx, Ly, Lz) [m]")
    radius: Radius | None = None
    polydispersity: float | None = Field(None, ge=0, lt=0.5)
    density: float | None = Field(None, ge=100, le=25_000, description="[kg/m^3]")
    solid_fraction: float | None = Field(None, gt=0, le=0.74)
    pour_fraction: float | None = Field(None, gt=0, le=0.32)
    interior_margin: float | None = Field(None, ge=0, le=2.0, description="[m]")
    pair_law: BilinearAdhesiveIn | None = Field(
        None, description="the scaling rules act on K1, K2, kadh and f0 of this law"
    )
    wall_law: HertzMindlinIn | None = None
    wall_material: WallMaterialIn | None = None
    pre_stress: Stress | None = None
    consolidation_stress: Stress | None = None
    platen_speed: float | None = Field(None, gt=0, le=1.0, description="[m/s]")
    unloaded_stress: Fraction | None = None
    unconfined: bool | None = None
    failure_drop: Fraction | None = None
    failure_strain: float | None = Field(None, ge=0, lt=0.5)
    max_unconfined_strain: float | None = Field(None, gt=0, lt=0.8)
    settle_ke: float | None = Field(None, gt=0, le=1.0)
    release_time: float | None = Field(None, gt=0, le=10.0, description="[s]")
    seed: Seed | None = None
    output_interval: float | None = Field(None, gt=0, le=1.0, description="[s]")
    dt: float | None = Field(None, gt=0, le=1e-3, description="[s]; null: automatic")
    max_stage_time: float | None = Field(None, gt=0, le=60.0, description="[s]")


class ScalingRuleIn(BaseModel):
    """A scaling rule: K ~ s^stiffness_exponent, f0 ~ s^adhesion_exponent, s = R / R_ref."""

    model_config = _forbid
    name: str = Field(pattern=r"^[A-Za-z0-9_.\-]{1,40}$")
    stiffness_exponent: float = Field(1.0, ge=-1, le=4)
    adhesion_exponent: float = Field(2.0, ge=-1, le=5)
    dt: Literal["fixed", "scaled"] = "fixed"


NAMED_RULES = ("paper", "unscaled", "linear_adhesion", "cubic_adhesion")


def _named_rule(value: object) -> object:
    """A rule given by name becomes the engine's named rule."""
    if not isinstance(value, str):
        return value
    if value not in NAMED_RULES:
        raise ValueError(f"unknown rule {value!r}: give a rule object or one of {NAMED_RULES}")
    r = engine.ScalingRule.named(value)
    return {
        "name": r.name,
        "stiffness_exponent": r.stiffness_exponent,
        "adhesion_exponent": r.adhesion_exponent,
        "dt": r.dt,
    }


RuleIn = Annotated[
    ScalingRuleIn,
    BeforeValidator(_named_rule),
    Field(description=f"a rule object, or a name among {NAMED_RULES}"),
]


class StudyCreate(BaseModel):
    """A scaling study to run (the body of ``POST /studies``)."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            "example": {
                "name": "quick",
                "reference": {"preset": "quick", "radius": 2.5e-3},
                "coarse_radii": [3.75e-3, 5e-3],
                "rules": ["paper", "unscaled"],
                "seeds": [1],
                "reference_seeds": [1, 2],
                "tolerances": {"density": 0.03, "strength": 0.15},
            }
        },
    )
    name: str | None = Field(None, max_length=100, description="A label.")
    reference: ReferenceIn | None = None
    coarse_radii: list[Radius] | None = Field(None, min_length=1, max_length=8)
    rules: list[RuleIn] | None = Field(None, min_length=1, max_length=8)
    seeds: list[Seed] | None = Field(None, min_length=1, max_length=10)
    reference_seeds: list[Seed] | None = Field(None, min_length=1, max_length=10)
    tolerances: dict[str, float] | None = Field(None, description="metric -> tolerance [-]")
    interior_diameters: float | None = Field(None, ge=2, le=10)

    def engine_dict(self) -> dict:
        """The spec as :meth:`engine.StudySpec.from_dict` takes it (unset fields left out)."""
        return self.model_dump(exclude_unset=True, exclude={"name"})
