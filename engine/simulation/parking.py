"""Parking: particles taken out of a run for good (:meth:`engine.Simulation.park_below`), the
hopper's sink for its discharged grains (docs/HOPPER.md, "The sink").

A parked particle is moved to its own site of a :class:`ParkingLattice` (the site of scene id
k is the k-th of the lattice, so no two particles ever share one, whatever the backend, the
threads or the renumbering), at rest, with radius 0 and zero inverse mass and inverse moment
of inertia. What keeps it out of the run:

- a pair touches when its centres are closer than the sum of the radii: a parked particle
  touches no other parked one (0 + 0) and no live one whose centre stays farther than that
  particle's radius from the lattice (the caller's choice of sites: below the live grains'
  reach, above every wall);
- the neighbour list lists a pair closer than the radii plus the skin: sites farther apart
  than the skin add no entry (:meth:`ParkingLattice.check` asks for more);
- a zero inverse mass leaves its velocity at zero whatever the forces (gravity included), so
  it never moves again, and the step's guards (overlap, step length) never see it;
- its position at the last list build is set to its site, so parking triggers no rebuild;
  its pair contacts are deleted with their history when it is parked (the list's entries
  of its old neighbours then find it out of reach, as a contact that has opened).

It still costs its share of the per-particle passes (a few multiplications), no contact
work. Its mass still counts in :attr:`engine.Simulation.masses` (what the hopper weighs as
discharged); :attr:`engine.Simulation.radii` reads 0 for it (a snapshot shows it as a point).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.errors import ParameterError


@dataclass(frozen=True)
class ParkingLattice:
    """A lattice of parking sites [m]: site s (a scene id) at ``origin + (ix ax, iy ay,
    -iz az)`` with ix = s mod nx, iy = (s div nx) mod ny, iz = s div (nx ny): rows along x,
    then y, then layers going down from ``origin``.

    Attributes: ``origin`` (3 numbers [m], the first site), ``spacing`` (ax, ay, az [m], each
    > 0), ``nx``, ``ny`` (sites per row and rows per layer, >= 1)."""

    origin: tuple[float, float, float]
    spacing: tuple[float, float, float]
    nx: int
    ny: int

    def __post_init__(self) -> None:
        o = np.asarray(self.origin, dtype=float)
        a = np.asarray(self.spacing, dtype=float)
        if o.shape != (3,) or not np.all(np.isfinite(o)):
            raise ParameterError("ParkingLattice.origin", self.origin, "3 finite numbers [m]")
        if a.shape != (3,) or not np.all(np.isfinite(a)) or not np.all(a > 0):
            raise ParameterError("ParkingLattice.spacing", self.spacing, "3 numbers > 0 [m]")
        for name in ("nx", "ny"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ParameterError(f"ParkingLattice.{name}", v, "an integer >= 1")
        object.__setattr__(self, "origin", tuple(float(x) for x in o))
        object.__setattr__(self, "spacing", tuple(float(x) for x in a))
        object.__setattr__(self, "nx", int(self.nx))
        object.__setattr__(self, "ny", int(self.ny))

    def sites(self, ids) -> np.ndarray:
        """The sites of scene ids ``ids`` [m], (len(ids), 3)."""
        s = np.asarray(ids, dtype=np.int64)
        ix = s % self.nx
        iy = (s // self.nx) % self.ny
        iz = s // (self.nx * self.ny)
        ax, ay, az = self.spacing
        ox, oy, oz = self.origin
        return np.stack([ox + ix * ax, oy + iy * ay, oz - iz * az], axis=1)

    def lowest(self, n: int) -> float:
        """z of the lowest site of ``n`` particles [m]."""
        layers = math.ceil(n / (self.nx * self.ny))
        return self.origin[2] - (layers - 1) * self.spacing[2]

    def check(self, skin: float) -> None:
        """Sites farther apart than ``skin`` [m] along each axis (no neighbour entry between
        two parked particles): else a ParameterError naming the spacing."""
        if min(self.spacing) <= skin:
            raise ParameterError(
                "ParkingLattice.spacing",
                f"{min(self.spacing):.4g} m",
                f"> the neighbour skin {skin:.4g} m",
            )


def park_args(height, lattice) -> float:
    """:meth:`engine.Simulation.park_below`'s arguments checked once for both backends."""
    h = float(height)
    if math.isnan(h):
        raise ParameterError("Simulation.park_below.height", height, "a number [m]")
    if not isinstance(lattice, ParkingLattice):
        raise ParameterError(
            "Simulation.park_below.lattice", type(lattice).__name__, "an engine ParkingLattice"
        )
    return h
