"""The platen's material: the elastic properties a wall law reads."""

from __future__ import annotations

from dataclasses import dataclass

from ..core.records import check_fields, param
from .export import LiggghtsProperty, elastic_atom_type


@dataclass(frozen=True)
class WallMaterial:
    """Elastic properties of a wall (platen) for the Hertz-Mindlin wall law.

    Attributes:
        E: Young's modulus [Pa], >= 1 (steel: 2e11).
        nu: Poisson's ratio [-], in (-1, 0.5).
    """

    E: float = param(
        2e11, unit="Pa", doc="Young's modulus of the wall (>= 1 Pa, as a particle's)", ge=1.0
    )
    nu: float = param(0.3, unit="1", doc="Poisson's ratio of the wall", gt=-1, lt=0.5)

    def __post_init__(self) -> None:
        check_fields(self, "WallMaterial")

    @property
    def G(self) -> float:
        """Shear modulus [Pa]."""
        return self.E / (2.0 * (1.0 + self.nu))

    def liggghts_atom_type(self) -> tuple[LiggghtsProperty, ...]:
        """Its LIGGGHTS per-atom-type properties: ``youngsModulus`` E [Pa], ``poissonsRatio``
        nu [-] (a deck's platen atom type)."""
        return elastic_atom_type(self.E, self.nu)
