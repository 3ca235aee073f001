"""The hopper's scene (docs/HOPPER.md): its walls and gate as triangle meshes
(:class:`engine.Mesh`), a catch floor far below the outlet, the sink's parking lattice above
it, and the fill on a loose lattice inside the walls above the closed gate.

Frame: z up, the outlet in the plane z = 0 centred on the z axis; a slot's walls run along y
(its periodic depth, the box [0, depth]), its outlet across x in [-B/2, B/2]; a cone's axis is
the z axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.config import SKIN_FRACTION
from ..simulation.mesh import Mesh
from ..simulation.parking import ParkingLattice
from ..simulation.scene import Plane, Scene
from .spec import CONE_SIDES, HopperTest

#: Lattice spacing of the poured fill in diameters of the largest particle [-] ...
LATTICE_SPACING = 1.1
#: ... each site moved at random by up to this fraction of the spacing along each axis [-]
#: (no two particles overlap: 1.1 - 2 x 0.02 x 1.1 > 1), breaking the lattice's symmetry.
LATTICE_JITTER = 0.02
#: The gate reaches this many diameters beyond the outlet's edges [-].
GATE_OVERHANG = 2.0
#: The walls rise this many diameters above the top of the poured lattice [-].
WALL_HEADROOM = 2.0
#: The catch floor lies this many largest diameters below the outlet, plus 2 B, plus the
#: height of the heap the whole fill would make on it (:func:`heap_height`) [-].
CATCH_DIAMETERS = 20.0
#: The sink, below which the discharged grains are parked (:class:`engine.hopper.driver.
#: HopperRun`), lies this many largest diameters above the highest the heap could reach
#: (:func:`heap_height`): CATCH_DIAMETERS - SINK_DIAMETERS diameters plus 2 B below the
#: outlet [-]. (Until 2026-12-06 a drag slowed the grains below it: the catch zone.)
SINK_DIAMETERS = 10.0
#: The parking lattice's spacing [largest diameters] (> the skin, 0.1 d: no neighbour entry
#: between parked grains) and its first layer's depth below the sink [largest diameters]
#: (a grain is parked within a quarter diameter below the sink: it stays clear of the sites).
PARK_SPACING = 0.5
PARK_BELOW = 2.0
#: The heap's slope [deg] and solid fraction [-] in :func:`heap_height`: steeper and looser
#: than a cohesionless heap of spheres, so that the estimate is high.
HEAP_ANGLE = 35.0
HEAP_FRACTION = 0.5


@dataclass
class HopperGeometry:
    """The built hopper: its scene and what the driver and the measures read of it.

    Attributes: ``scene``; ``wall_top`` (the walls' top, z [m]); ``catch_depth`` (the catch
    floor at z = -catch_depth [m]); ``gate_stop`` (z at which the opened gate stops, below the
    catch floor out of the particles' reach [m]); ``sink`` (z below which a grain is parked
    [m]: :data:`SINK_DIAMETERS`); ``parking`` (its sites, :func:`parking_lattice`);
    ``wall_meshes`` and ``gate_mesh`` (indices in
    ``scene.meshes``: a slot's two walls, -x then +x, are two meshes, so that the engine's
    force on each can be read); ``half_width`` (B / 2 [m]); ``tan`` (tan of the half-angle);
    ``depth`` (the slot's period [m], None for a cone)."""

    scene: Scene
    wall_top: float
    catch_depth: float
    gate_stop: float
    sink: float
    parking: ParkingLattice
    wall_meshes: tuple[int, ...]
    gate_mesh: int
    half_width: float
    tan: float
    depth: float | None


def wall_radius(test: HopperTest, z) -> np.ndarray:
    """Distance from the axis (cone: to a corner of its polygon) or from the mid-plane
    (slot) to the wall at height ``z`` above the outlet [m]: B / 2 + z tan(theta)."""
    t = math.tan(math.radians(test.half_angle))
    return 0.5 * test.outlet_width + t * np.maximum(np.asarray(z, dtype=float), 0.0)


def _slot_meshes(test: HopperTest, top: float) -> tuple[list[Mesh], Mesh]:
    d = test.max_diameter
    b = 0.5 * test.outlet_width
    t = math.tan(math.radians(test.half_angle))
    # along the periodic y the walls reach beyond both faces of the box (docs/MESH.md)
    m = 2.0 * d
    y0, y1 = -m, test.depth + m
    xt = b + t * top
    left = Mesh(
        [[-b, y0, 0.0], [-b, y1, 0.0], [-xt, y1, top], [-xt, y0, top]],
        [[0, 2, 1], [0, 3, 2]],
        name="hopper wall -x",
    )
    right = Mesh(
        [[b, y0, 0.0], [b, y1, 0.0], [xt, y1, top], [xt, y0, top]],
        [[0, 1, 2], [0, 2, 3]],
        name="hopper wall +x",
    )
    g = b + GATE_OVERHANG * d
    gate = Mesh(
        [[-g, y0, 0.0], [g, y0, 0.0], [g, y1, 0.0], [-g, y1, 0.0]],
        [[0, 1, 2], [0, 2, 3]],
        name="gate",
    )
    return [left, right], gate


def _cone_meshes(test: HopperTest, top: float) -> tuple[list[Mesh], Mesh]:
    n = CONE_SIDES
    b = 0.5 * test.outlet_width
    rt = float(wall_radius(test, top))
    a = 2.0 * math.pi * np.arange(n) / n
    low = np.stack([b * np.cos(a), b * np.sin(a), np.zeros(n)], axis=1)
    high = np.stack([rt * np.cos(a), rt * np.sin(a), np.full(n, top)], axis=1)
    tri = []
    for i in range(n):
        j = (i + 1) % n
        tri += [[i, j, n + j], [i, n + j, n + i]]
    walls = Mesh(np.concatenate([low, high]), tri, name="hopper cone")
    g = b + GATE_OVERHANG * test.max_diameter
    gate = Mesh(
        [[-g, -g, 0.0], [g, -g, 0.0], [g, g, 0.0], [-g, g, 0.0]],
        [[0, 1, 2], [0, 2, 3]],
        name="gate",
    )
    return [walls], gate


def heap_height(test: HopperTest) -> float:
    """Height of the heap the whole fill makes on the catch floor [m], an upper estimate: its
    solid volume at :data:`HEAP_FRACTION`, as a ridge of triangular section along the slot's
    depth (A = h^2 / tan(alpha)) or a cone (V = pi h^3 / (3 tan^2(alpha))), alpha =
    :data:`HEAP_ANGLE`. The catch floor lies this much deeper, so that the heap never
    reaches the outlet (where it would hold the flow back, and pass for an arch)."""
    v = test.n_particles * test.mean_particle_volume / HEAP_FRACTION
    ta = math.tan(math.radians(HEAP_ANGLE))
    if test.shape == "slot":
        return math.sqrt(v / test.depth * ta)
    return (3.0 * v * ta * ta / math.pi) ** (1.0 / 3.0)


def lattice_fill(test: HopperTest) -> np.ndarray:
    """Centres of the poured fill [m], (N, 3): a cubic lattice of spacing
    :data:`LATTICE_SPACING` largest diameters inside the walls (every centre at least 1.05
    largest radii from the wall, measured normal to it) and above the gate, filled level by
    level from the outlet up (the top level's sites drawn at random), each site jittered by
    up to :data:`LATTICE_JITTER` spacings; seeded by ``test.seed``."""
    rng = np.random.default_rng(test.seed)
    n = test.n_particles
    d = test.max_diameter
    a = LATTICE_SPACING * d
    cos = math.cos(math.radians(test.half_angle))
    clear = 0.525 * d / cos  # 1.05 largest radii normal to the wall, horizontally
    if test.shape == "slot":
        ny = max(1, int(test.depth // a))
        ys = (np.arange(ny) + 0.5) * test.depth / ny
    else:
        clear /= math.cos(math.pi / CONE_SIDES)  # to the polygon's sides, not its corners
    out: list[np.ndarray] = []
    count = 0
    z = 0.5 * d + 2.0 * LATTICE_JITTER * a
    while count < n:
        reach = float(wall_radius(test, z)) - clear
        if test.shape == "slot":
            k = int(2 * reach // a) + 1 if reach >= 0 else 0
            xs = (np.arange(k) - 0.5 * (k - 1)) * a
            gx, gy = np.meshgrid(xs, ys, indexing="ij")
            pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
        else:
            inner = reach * math.cos(math.pi / CONE_SIDES) if reach > 0 else -1.0
            k = int(inner // a)
            xs = np.arange(-k, k + 1) * a
            gx, gy = np.meshgrid(xs, xs, indexing="ij")
            pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
            pts = pts[np.hypot(pts[:, 0], pts[:, 1]) <= inner] if inner >= 0 else pts[:0]
        if len(pts):
            if count + len(pts) > n:
                pts = pts[np.sort(rng.choice(len(pts), n - count, replace=False))]
            level = np.column_stack([pts, np.full(len(pts), z)])
            out.append(level)
            count += len(level)
        z += a
    pos = np.concatenate(out)
    pos += rng.uniform(-LATTICE_JITTER * a, LATTICE_JITTER * a, pos.shape)
    return pos


def radii_of(test: HopperTest) -> np.ndarray:
    """Particle radii [m]: uniform in [R(1-p), R(1+p)] (seeded by ``test.seed``, drawn after
    the lattice's numbers), or R."""
    n = test.n_particles
    if test.polydispersity == 0.0:
        return np.full(n, test.radius)
    rng = np.random.default_rng([test.seed, 1])
    p = test.polydispersity
    return rng.uniform(test.radius * (1 - p), test.radius * (1 + p), n)


def build_hopper(test: HopperTest) -> HopperGeometry:
    """The hopper of ``test``: walls, closed gate, catch floor and poured fill (module
    docstring)."""
    pos = lattice_fill(test)
    r = radii_of(test)
    d = test.max_diameter
    top = float(pos[:, 2].max()) + WALL_HEADROOM * d
    catch = CATCH_DIAMETERS * d + 2.0 * test.outlet_width + heap_height(test)
    if test.shape == "slot":
        walls, gate = _slot_meshes(test, top)
        lo_x = -float(wall_radius(test, top)) - d
        box = ((lo_x, -lo_x), (0.0, test.depth), (-catch - d, top + d))
        periodic = (False, True, False)
        depth = test.depth
    else:
        walls, gate = _cone_meshes(test, top)
        w = float(wall_radius(test, top)) + d
        box = ((-w, w), (-w, w), (-catch - d, top + d))
        periodic = (False, False, False)
        depth = None
    floor = Plane((0.0, 0.0, -catch), (0.0, 0.0, 1.0))
    scene = Scene(
        pos,
        r,
        test.density,
        box=box,
        periodic=periodic,
        walls=[floor],
        meshes=[*walls, gate],
        gravity=(0.0, 0.0, -test.gravity),
        pair_law=test.pair_law,
        wall_law=test.wall_law,
        wall_material=test.wall_material,
    )
    # the opened gate stops below the catch floor, out of reach of any particle on it
    stop = -catch - 2.0 * d - SKIN_FRACTION * d
    sink = -catch + heap_height(test) + SINK_DIAMETERS * d
    return HopperGeometry(
        scene,
        top,
        catch,
        stop,
        sink,
        parking_lattice(test, box, sink, -catch),
        tuple(range(len(walls))),
        len(walls),
        0.5 * test.outlet_width,
        math.tan(math.radians(test.half_angle)),
        depth,
    )


def parking_lattice(test: HopperTest, box, sink: float, floor: float) -> ParkingLattice:
    """The sink's sites [m]: spacing :data:`PARK_SPACING` largest diameters (the slot's
    depth divided evenly), rows across the box one diameter in from its sides, layers from
    :data:`PARK_BELOW` diameters below the ``sink`` down; every fill's sites lie above the
    floor by a diameter and more (a ValueError otherwise: the floor's depth, sized for the
    heap of the whole fill at a solid fraction of 0.5, leaves room for fifteen times as many
    sites)."""
    d = test.max_diameter
    a = PARK_SPACING * d
    (x0, x1), (y0, _), _ = box
    nx = int((x1 - x0 - 2.0 * d) // a) + 1
    if test.shape == "slot":
        ny = max(1, int(test.depth // a))
        ay, oy = test.depth / ny, 0.5 * test.depth / ny
    else:
        ny, ay, oy = nx, a, y0 + d
    lattice = ParkingLattice((x0 + d, oy, sink - PARK_BELOW * d), (a, ay, a), nx, ny)
    if lattice.lowest(test.n_particles) < floor + d:
        raise ValueError(
            f"the sink's {test.n_particles} sites reach below the catch floor "
            f"({lattice.lowest(test.n_particles):.4g} m < {floor + d:.4g} m)"
        )
    return lattice


def wall_bin_areas(test: HopperTest, edges: np.ndarray) -> np.ndarray:
    """Wall area [m^2] between consecutive heights ``edges`` [m] (both walls of a slot over
    its depth; the faces of the cone's polygonal frustum)."""
    edges = np.asarray(edges, dtype=float)
    dz = np.diff(edges)
    t = math.tan(math.radians(test.half_angle))
    if test.shape == "slot":
        return 2.0 * test.depth * dz * math.sqrt(1.0 + t * t)
    n = CONE_SIDES
    c = math.cos(math.pi / n)
    slant = dz * math.sqrt(1.0 + (t * c) ** 2)  # a face's midline leans at atan(t cos(pi/n))
    per = 2.0 * n * math.sin(math.pi / n) * wall_radius(test, edges)  # perimeter at height
    return 0.5 * (per[:-1] + per[1:]) * slant
