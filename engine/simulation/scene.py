"""Scene description: particles, box, periodicity, walls, gravity and contact laws.

A :class:`Scene` is validated once on construction and not changed afterwards; a
:class:`engine.Simulation` copies what it needs. Units: m, kg, s, kg/m^3.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..contact.bilinear import BilinearAdhesive
from ..contact.eepa import EEPA
from ..contact.hertz import HertzMindlin
from ..contact.registry import law_names, pair_laws, wall_laws
from ..contact.wall import WallMaterial
from ..core.config import MAX_RADIUS_RATIO
from ..core.errors import ParameterError
from .mesh import Mesh, vec3


@dataclass(frozen=True)
class Plane:
    """An infinite planar wall (platen). Particles live on the side the normal points to.

    Attributes:
        point: a point of the plane at time 0 of the simulation [m].
        normal: normal pointing into the particle side (normalised on construction) [-].
        velocity: velocity of the plane [m/s]; changeable between runs with
            :meth:`engine.Simulation.set_wall_velocity`.
    """

    point: tuple[float, float, float]
    normal: tuple[float, float, float]
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "point", vec3("Plane", "point", self.point))
        n = vec3("Plane", "normal", self.normal)
        length = math.sqrt(sum(c * c for c in n))
        if length == 0.0:
            raise ParameterError("Plane.normal", self.normal, "a non-zero vector")
        object.__setattr__(self, "normal", tuple(c / length for c in n))
        object.__setattr__(self, "velocity", vec3("Plane", "velocity", self.velocity))


def _per_particle(name: str, value, n: int, positive: bool) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(f"Scene.{name}", value, "a real number or one per particle") from None
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,):
        raise ParameterError(
            f"Scene.{name}", f"array of shape {a.shape}", f"a scalar or shape ({n},)"
        )
    if not np.all(np.isfinite(a)):
        raise ParameterError(f"Scene.{name}", "non-finite entries", "finite")
    if positive and not np.all(a > 0):
        raise ParameterError(f"Scene.{name}", float(a.min()), "> 0 for every particle")
    return a


def _vectors(name: str, value, n: int) -> np.ndarray:
    if value is None:
        return np.zeros((n, 3))
    a = np.asarray(value, dtype=np.float64)
    if a.shape != (n, 3):
        raise ParameterError(f"Scene.{name}", f"array of shape {a.shape}", f"shape ({n}, 3)")
    if not np.all(np.isfinite(a)):
        raise ParameterError(f"Scene.{name}", "non-finite entries", "finite")
    return a.copy()


class Scene:
    """Particles, boundaries and contact laws of one simulation (SI units).

    Args:
        positions: (N, 3) particle centres [m].
        radii: (N,) radii or one radius [m], > 0; largest/smallest <= 3.
        density: particle density [kg/m^3], scalar or (N,).
        velocities: (N, 3) [m/s], default 0.
        angular_velocities: (N, 3) [rad/s], default 0.
        box: ((xlo, xhi), (ylo, yhi), (zlo, zhi)) [m]; required on periodic axes (the period
            is hi - lo), informative elsewhere.
        periodic: three booleans, minimum-image periodicity along x, y, z.
        walls: planar walls (:class:`Plane`).
        meshes: walls of finite extent (:class:`engine.Mesh`, triangle meshes; docs/MESH.md).
        gravity: acceleration [m/s^2].
        pair_law: :class:`BilinearAdhesive`, :class:`EEPA` or :class:`HertzMindlin` for
            particle pairs.
        wall_law: :class:`HertzMindlin` for particle-wall contacts, planes and meshes alike
            (required with walls or meshes);
            its E and nu are the particles' elastic properties.
        wall_material: :class:`WallMaterial` of the walls and meshes (required with either).
    """

    def __init__(
        self,
        positions,
        radii,
        density,
        velocities=None,
        angular_velocities=None,
        box=None,
        periodic: Sequence[bool] = (False, False, False),
        walls: Sequence[Plane] = (),
        gravity=(0.0, 0.0, -9.81),
        pair_law: BilinearAdhesive | EEPA | HertzMindlin | None = None,
        wall_law: HertzMindlin | None = None,
        wall_material: WallMaterial | None = None,
        meshes: Sequence[Mesh] = (),
    ) -> None:
        pos = np.asarray(positions, dtype=np.float64)
        if pos.ndim != 2 or pos.shape[1] != 3 or pos.shape[0] < 1:
            raise ParameterError(
                "Scene.positions", f"array of shape {pos.shape}", "shape (N, 3) with N >= 1"
            )
        if not np.all(np.isfinite(pos)):
            raise ParameterError("Scene.positions", "non-finite entries", "finite")
        n = pos.shape[0]
        self.positions = pos.copy()
        self.radii = _per_particle("radii", radii, n, positive=True)
        ratio = float(self.radii.max() / self.radii.min())
        if ratio > MAX_RADIUS_RATIO:
            raise ParameterError(
                "Scene.radii",
                f"max/min = {ratio:.3g}",
                f"a size ratio <= {MAX_RADIUS_RATIO:g}",
                "the cell list is sized by the largest particle",
            )
        self.density = _per_particle("density", density, n, positive=True)
        self.velocities = _vectors("velocities", velocities, n)
        self.angular_velocities = _vectors("angular_velocities", angular_velocities, n)

        per = tuple(bool(p) for p in periodic)
        if len(per) != 3:
            raise ParameterError("Scene.periodic", periodic, "three booleans (x, y, z)")
        self.periodic = per
        if box is None:
            if any(per):
                raise ParameterError("Scene.box", None, "given when an axis is periodic")
            lo = pos.min(axis=0) - self.radii.max()
            hi = pos.max(axis=0) + self.radii.max()
            box = tuple(zip(lo.tolist(), hi.tolist()))
        try:
            b = np.asarray(box, dtype=np.float64)
        except (TypeError, ValueError):
            raise ParameterError("Scene.box", box, "((xlo, xhi), (ylo, yhi), (zlo, zhi))") from None
        if b.shape != (3, 2) or not np.all(np.isfinite(b)) or not np.all(b[:, 1] > b[:, 0]):
            raise ParameterError(
                "Scene.box", box, "((xlo, xhi), (ylo, yhi), (zlo, zhi)) with hi > lo, finite"
            )
        self.box = b

        self.walls = tuple(walls)
        for k, w in enumerate(self.walls):
            if not isinstance(w, Plane):
                raise ParameterError(f"Scene.walls[{k}]", w, "an engine.Plane")
        self.meshes = tuple(meshes)
        for k, m in enumerate(self.meshes):
            if not isinstance(m, Mesh):
                raise ParameterError(f"Scene.meshes[{k}]", m, "an engine.Mesh")
        self.gravity = vec3("Scene", "gravity", gravity)

        if not isinstance(pair_law, pair_laws()):
            raise ParameterError("Scene.pair_law", pair_law, f"an {law_names(pair_laws())}")
        self.pair_law = pair_law
        if self.walls or self.meshes:
            if not isinstance(wall_law, wall_laws()):
                raise ParameterError(
                    "Scene.wall_law",
                    wall_law,
                    f"an {law_names(wall_laws())} when the scene has walls or meshes",
                )
            if not isinstance(wall_material, WallMaterial):
                raise ParameterError(
                    "Scene.wall_material",
                    wall_material,
                    "an engine.WallMaterial when the scene has walls or meshes",
                )
        self.wall_law = wall_law
        self.wall_material = wall_material

    @property
    def n(self) -> int:
        """Number of particles."""
        return self.positions.shape[0]

    @property
    def masses(self) -> np.ndarray:
        """Particle masses 4/3 pi R^3 rho [kg]."""
        return (4.0 / 3.0) * math.pi * self.radii**3 * self.density

    @property
    def inertia(self) -> np.ndarray:
        """Moments of inertia of solid spheres 2/5 m R^2 [kg m^2]."""
        return 0.4 * self.masses * self.radii**2

    @property
    def box_lengths(self) -> np.ndarray:
        """Box edge lengths [m]."""
        return self.box[:, 1] - self.box[:, 0]
