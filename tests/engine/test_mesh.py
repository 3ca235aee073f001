"""Walls of finite extent: triangle meshes (engine.Mesh, docs/MESH.md).

- A flat mesh of many triangles is the infinite plane: particles at rest on a face, on an
  edge and on a vertex, rolling along a line of edges through vertices and sliding across
  edges, on a level and on a tilted mesh, follow the trajectories of the same scene with an
  engine.Plane, and the mesh feels the plane's force, to 1e-9 relative (one contact per
  particle: no double counting where triangles meet; the tangential springs carried from
  triangle to triangle). A sphere in a V-groove of triangles is the sphere between two
  planes (two contacts at once).
- Edge and corner impacts match the Hertz closed forms of a sphere on a plane (the wall law
  of a contact is the plane's, its normal from the closest point to the centre), and the
  restitution matches the plane's.
- A moving mesh pushes as the moving plane does (its candidate triangles found again as it
  comes), results do not depend on the thread count, the renumbering carries the mesh
  contacts, and a scene without meshes compiles the kernel it did before meshes existed.
- STL files round-trip; bad meshes are refused naming the file and the triangle.

Three kernels are compiled here (a plane scene's, a mesh scene's, and the undamped mesh
scene's of the closed forms): every scene shares the laws of one of them.
"""

from __future__ import annotations

import math
import pickle

import numba
import numpy as np
import pytest

import engine
import engine.simulation.simulation
from engine.contact.hertz import hertz_contact_time, hertz_impact_overlap
from engine.kernel import specialise

R = 2.5e-3
RHO = 2000.0
M = 4 / 3 * math.pi * R**3 * RHO
H = 2.0**-9  # mesh spacing [m] (a binary fraction: the level grid's vertices are exact)
#: the wall law of every scene but the closed forms': damping, friction and rolling
LAW = engine.HertzMindlin(E=1e8, nu=0.25, restitution=0.5, mu=0.3, mu_r=0.01)
PAIR = engine.BilinearAdhesive(k1=5e3, k2=5e3)
REL = 1e-9


def grid_mesh(n=24, rot=None, **kw) -> engine.Mesh:
    """A flat square of n x n squares of side H centred on the origin in z = 0, each cut
    along a diagonal into two triangles (2 n^2 triangles), turned by ``rot``."""
    xs = (np.arange(n + 1) - n // 2) * H
    x, y = np.meshgrid(xs, xs, indexing="ij")
    v = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    tri = []
    for i in range(n):
        for j in range(n):
            a = i * (n + 1) + j
            tri += [[a, a + n + 1, a + n + 2], [a, a + n + 2, a + 1]]
    return engine.Mesh(v if rot is None else v @ rot.T, tri, **kw)


def cube(side=0.02) -> engine.Mesh:
    """A closed cube of 12 triangles centred on the origin, normals outwards."""
    h = side / 2
    v = [[x, y, z] for x in (-h, h) for y in (-h, h) for z in (-h, h)]  # 4 ix + 2 iy + iz
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return engine.Mesh(v, [t for a, b, c, d in quads for t in ([a, b, c], [a, c, d])], closed=True)


def scene(pos, vel=None, omg=None, walls=(), meshes=(), gravity=(0, 0, -9.81), law=LAW, **kw):
    return engine.Scene(
        pos,
        R,
        RHO,
        velocities=vel,
        angular_velocities=omg,
        gravity=gravity,
        **kw,
        pair_law=PAIR,
        walls=walls,
        meshes=meshes,
        wall_law=law,
        wall_material=engine.WallMaterial(),
    )


def _rel(a, b) -> float:
    scale = float(np.max(np.abs(a)))
    return float(np.max(np.abs(a - b))) / scale if scale > 0 else float(np.max(np.abs(b)))


# ---------------------------------------------------------------------- a flat mesh is a plane
#: particles, each alone (more than a diameter apart): on a face, on an axis-parallel edge,
#: on a diagonal edge, on a vertex, rolling along the line of edges y = 6 H through its
#: vertices, sliding across the grid, sliding along the diagonal x = y (through vertices)
Z0 = R * (1 - 1e-4)
FLAT = np.array(
    [
        [-7.7 * H, -7.55 * H, Z0],
        [-7.63 * H, 2 * H, Z0],
        [4.5 * H, -7.5 * H, Z0],
        [7 * H, 7 * H, Z0],
        [-8 * H, 6 * H, Z0],
        [1 * H, -2 * H, Z0],
        [3 * H, 3 * H, Z0],
    ]
)
FLAT_V = np.zeros_like(FLAT)
FLAT_W = np.zeros_like(FLAT)
FLAT_V[4], FLAT_W[4] = (0.3, 0, 0), (0, 0.3 / R, 0)
FLAT_V[5], FLAT_W[5] = (0.25, 0.17, 0), (30, -80, 40)
FLAT_V[6], FLAT_W[6] = (-0.2, -0.2, 0), (50, -50, 0)


def _tilt():
    th, ph = 0.3, 0.7
    rz = np.array([[math.cos(ph), -math.sin(ph), 0], [math.sin(ph), math.cos(ph), 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, math.cos(th), -math.sin(th)], [0, math.sin(th), math.cos(th)]])
    return rz @ rx


def _side_by_side(plane_sim, mesh_sim, blocks, steps):
    """Step both, compare after each block; the worst relative differences, and the mesh
    contacts of every block."""
    worst = dict.fromkeys(("positions", "velocities", "angular_velocities", "force"), 0.0)
    contacts = []
    for _ in range(blocks):
        plane_sim.run(steps)
        mesh_sim.run(steps)
        for q in ("positions", "velocities", "angular_velocities"):
            worst[q] = max(worst[q], _rel(getattr(plane_sim, q), getattr(mesh_sim, q)))
        f = plane_sim.wall_forces
        worst["force"] = max(worst["force"], _rel(f.sum(axis=0), mesh_sim.mesh_forces.sum(axis=0)))
        mc = mesh_sim.mesh_contacts()
        pc = plane_sim.contacts()
        assert np.array_equal(mc.particles, pc.wall_particles), (mc, pc)  # one per plane
        np.testing.assert_allclose(np.sort(mc.overlaps), np.sort(pc.wall_overlaps), rtol=1e-6)
        contacts.append(mc)
    return worst, contacts


@pytest.mark.parametrize("tilted", [False, True], ids=["level", "tilted"])
def test_a_flat_mesh_of_many_triangles_is_the_plane(tilted):
    rot = _tilt() if tilted else np.eye(3)
    pos, vel, omg = FLAT @ rot.T, FLAT_V @ rot.T, FLAT_W @ rot.T
    mesh = grid_mesh(rot=rot)
    assert mesh.n_triangles == 1152
    plane = engine.Plane((0, 0, 0), tuple(rot[:, 2]))
    a = engine.Simulation(scene(pos, vel, omg, walls=[plane]), dt=1e-6)
    b = engine.Simulation(scene(pos, vel, omg, meshes=[mesh]), dt=1e-6)
    fa, fb = specialise.scene_features(a.scene), specialise.scene_features(b.scene)
    assert not fa["meshes"] and fb["meshes"] and not fb["walls"]
    worst, contacts = _side_by_side(a, b, 20, 1000)
    for q, rel in worst.items():
        assert rel <= REL, (q, rel)
    # every particle on the mesh all along, one contact each
    assert all(np.array_equal(c.particles, np.arange(len(FLAT))) for c in contacts)
    # the contact points (in the mesh's plane): those that moved crossed triangles
    local = contacts[-1].points @ rot
    np.testing.assert_allclose(local[:, 2], 0.0, atol=1e-15)
    assert local[4, 0] - FLAT[4, 0] > 2.5 * H  # through two vertices at least
    assert np.hypot(*(local[5, :2] - FLAT[5, :2])) > 2.5 * H
    assert local[6, 0] - FLAT[6, 0] < -1.5 * H  # along the diagonal, through a vertex
    if not tilted:
        # at rest on the edge and on the vertex (the face tests there read exact zeros: the
        # edge and the vertex alone hold them up); rolling on its line of edges; along
        # the diagonal x = y
        assert np.abs(b.velocities[:4]).max() < 1e-4
        assert local[1, 1] == 2 * H
        np.testing.assert_array_equal(local[3, :2], (7 * H, 7 * H))
        assert local[4, 1] == 6 * H
        assert local[6, 0] == local[6, 1]
        # exact normals and overlaps: the same doubles as the plane's
        np.testing.assert_array_equal(a.positions, b.positions)
        np.testing.assert_array_equal(a.wall_forces, b.mesh_forces)


def test_a_mesh_across_a_periodic_face_is_the_plane(monkeypatch):
    """Periodic along y, the mesh reaching beyond both faces (as the walls of a slot hopper
    extruded along its depth): particles rolling and sliding across the periodic face keep
    meeting it (wrapped into the box at each list build, a little past a face between two)
    and keep their tangential springs across it: the plane's trajectories. A mesh that ends
    at the faces is refused (a particle past a face would meet its border)."""
    box = [(-12 * H, 12 * H), (-12 * H, 12 * H), (-0.01, 0.02)]
    pos = np.array([[2 * H, 10 * H, Z0], [-3.3 * H, -10.6 * H, Z0], [5.1 * H, 11.2 * H, Z0]])
    vel = np.array([[0.0, 0.3, 0.0], [0.07, -0.25, 0.0], [-0.1, 0.2, 0.0]])
    omg = np.array([[-0.3 / R, 0.0, 0.0], [40.0, 10.0, -20.0], [0.0, 0.0, 30.0]])
    kw = {"box": box, "periodic": (False, True, False)}
    plane = [engine.Plane((0, 0, 0), (0, 0, 1))]
    with monkeypatch.context() as m:
        # the plane's run on a kernel with the meshes' switch on (no mesh in its scene),
        # the kernel of the mesh's run and the slot hopper's, instead of one of its own to
        # compile (about 15 s of CPU on a cold cache); the bit-for-bit positions below
        # then also hold that switch neutral here
        meshes_on = lambda f, mode=None: {**specialise.kernel_features(f, mode), "meshes": True}  # noqa: E731
        m.setattr(engine.simulation.simulation, "kernel_features", meshes_on)
        a = engine.Simulation(scene(pos, vel, omg, walls=plane, **kw), dt=1e-6)
    assert a.features["meshes"] and not a.scene.meshes
    b = engine.Simulation(scene(pos, vel, omg, meshes=[grid_mesh(28)], **kw), dt=1e-6)
    with pytest.raises(engine.ParameterError, match=r"Scene.meshes\[0\].*periodic axis y"):
        engine.Simulation(scene(pos, vel, omg, meshes=[grid_mesh(24)], **kw), dt=1e-6)
    worst, contacts = _side_by_side(a, b, 20, 1000)
    for q, rel in worst.items():
        assert rel <= REL, (q, rel)
    assert sum(len(c.particles) for c in contacts) >= 40  # on the mesh most of the time
    crossed = np.abs(b.unwrapped_positions[:, 1] - b.positions[:, 1]) > 0
    assert crossed.sum() == 3  # each crossed the periodic face
    np.testing.assert_array_equal(a.positions, b.positions)


def test_a_sphere_in_a_groove_of_triangles_is_between_two_planes():
    """A V-groove of two strips of triangles (a concave edge along x): a sphere in it touches
    both sides at once, two contacts of one mesh, as between two planes."""
    half = math.radians(50)  # each side 50 degrees from the vertical
    n1 = np.array([0.0, math.cos(half), math.sin(half)])
    n2 = np.array([0.0, -math.cos(half), math.sin(half)])
    ys = np.array([-1, 0, 1]) * 0.01 * math.sin(half)
    zs = np.array([1, 0, 1]) * 0.01 * math.cos(half)
    xs = np.arange(-6, 7) * H
    v = np.array([[x, y, z] for x in xs for y, z in zip(ys, zs)])
    tri = []
    for i in range(len(xs) - 1):
        for j in range(2):
            a = 3 * i + j
            tri += [[a, a + 3, a + 4], [a, a + 4, a + 1]]
    groove = engine.Mesh(v, tri)
    # on the groove's axis, each side R sin(50 deg) below the centre: touching both
    pos = np.array([[-2.2 * H, 0.0, R / math.sin(half) * (1 - 1e-4)]])
    vel = np.array([[0.5, 0.0, 0.0]])
    planes = [engine.Plane((0, 0, 0), tuple(n1)), engine.Plane((0, 0, 0), tuple(n2))]
    a = engine.Simulation(scene(pos, vel, walls=planes), dt=1e-6)
    b = engine.Simulation(scene(pos, vel, meshes=[groove]), dt=1e-6)
    worst, contacts = _side_by_side(a, b, 10, 1000)
    for q, rel in worst.items():
        assert rel <= REL, (q, rel)
    assert all(len(c.particles) == 2 for c in contacts)  # both sides, all along
    assert b.positions[0, 0] - pos[0, 0] > 2 * H  # along the groove, across triangles


# ---------------------------------------------------------------------- closed forms
def _impact(normal, target, law, v0=1.0, tangential=(0.0, 0.0, 0.0), plane=False):
    """A sphere sent at ``v0`` [m/s] along -``normal`` onto the point ``target`` of a cube
    (a face, an edge or a corner; or onto the plane through it), with a ``tangential``
    velocity besides. Returns the simulation and the records of the contact: largest
    overlap [m], largest force [N], duration [s], the largest sine between the force and
    the line from the closest point to the centre, and the closest points."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    p0 = np.asarray(target) + (R + 1e-6) * n
    v = -v0 * n + np.asarray(tangential)
    walls = [engine.Plane(tuple(target), tuple(n))] if plane else []
    sc = scene([p0], [v], walls=walls, meshes=[] if plane else [cube()], gravity=(0, 0, 0), law=law)
    e_star, _ = law.wall_moduli(engine.WallMaterial())
    tc = hertz_contact_time(M, R, e_star, v0)
    sim = engine.Simulation(sc, dt=tc / 1000)
    dmax = fmax = sine = 0.0
    t_on = t_off = None
    points = []
    for _ in range(5000):
        sim.run(1)
        if plane:
            ovl = sim.contacts().wall_overlaps
            f = sim.wall_forces[0]
        else:
            c = sim.mesh_contacts()
            assert len(c.overlaps) <= 1  # one contact: the face, the edge or the vertex
            ovl = c.overlaps
            f = sim.mesh_forces[0]
            if ovl.size:
                points.append(c.points[0])
                line = sim.positions[0] - c.points[0]
                line /= np.linalg.norm(line)
                sine = max(sine, float(np.linalg.norm(np.cross(-f / np.linalg.norm(f), line))))
        if ovl.size:
            t_on = sim.time if t_on is None else t_on
            dmax = max(dmax, float(ovl[0]))
            fmax = max(fmax, float(np.linalg.norm(f)))
        elif t_on is not None:
            t_off = sim.time
            break
    return sim, dmax, fmax, t_off - t_on, sine, np.array(points)


ELASTIC = engine.HertzMindlin(E=1e8, nu=0.25, restitution=1.0, mu=0.3, mu_r=0.01)
EDGE = ((1, 0, 1), (0.01, 0.0013, 0.01))  # the edge x = z = 0.01 of the cube, along y
CORNER = ((1, 1, 1), (0.01, 0.01, 0.01))


@pytest.mark.parametrize("where", ["edge", "corner"])
def test_edge_and_corner_impacts_match_the_hertz_closed_forms(where):
    normal, target = EDGE if where == "edge" else CORNER
    v0 = 1.0
    e_star, _ = ELASTIC.wall_moduli(engine.WallMaterial())
    sim, dmax, fmax, duration, sine, _ = _impact(normal, target, ELASTIC, v0)
    d_th = hertz_impact_overlap(M, R, e_star, v0)
    assert dmax == pytest.approx(d_th, rel=0.02)
    assert fmax == pytest.approx(4 / 3 * e_star * math.sqrt(R) * d_th**1.5, rel=0.02)
    assert duration == pytest.approx(hertz_contact_time(M, R, e_star, v0), rel=0.02)
    assert sine < 1e-9  # the force along the line from the edge (corner) to the centre
    n = np.asarray(normal) / np.linalg.norm(normal)
    np.testing.assert_allclose(sim.velocities[0], v0 * n, rtol=1e-3, atol=1e-9)  # sent back


def test_an_oblique_edge_impact_slides_along_the_edge():
    """Sliding along the edge while hitting it: one contact all along, its point sliding on
    the edge's line; the normal velocity turns back whole (elastic), friction only slows
    the slide along the edge."""
    normal, target = EDGE
    n = np.asarray(normal) / np.linalg.norm(normal)
    sim, _, _, _, _, points = _impact(normal, target, ELASTIC, tangential=(0.0, 0.3, 0.0))
    assert len(points) > 500 and np.ptp(points[:, 1]) > 1e-5  # slid along the edge
    np.testing.assert_allclose(points[:, [0, 2]], 0.01, rtol=1e-12)  # on the edge's line
    v = sim.velocities[0]
    assert v @ n == pytest.approx(1.0, rel=1e-3)
    assert 0.0 < v[1] < 0.3


@pytest.mark.parametrize("where", ["edge", "corner"])
def test_edge_and_corner_impacts_restitute_as_the_plane(where):
    normal, target = EDGE if where == "edge" else CORNER
    n = np.asarray(normal) / np.linalg.norm(normal)
    mesh, dm, fm, tm, _, _ = _impact(normal, target, LAW, v0=0.5)
    plane, dp, fp, tp, _, _ = _impact(normal, target, LAW, v0=0.5, plane=True)
    e = mesh.velocities[0] @ n / 0.5
    assert e == pytest.approx(0.5, rel=0.03)  # Tsuji damping: close to the input
    assert e == pytest.approx(plane.velocities[0] @ n / 0.5, rel=1e-9)  # the plane's law
    assert (dm, fm, tm) == pytest.approx((dp, fp, tp), rel=1e-9)


# ---------------------------------------------------------------------- moving meshes
def test_a_moving_mesh_pushes_as_the_moving_plane():
    """A square plate of two triangles comes from 2 radii away at 0.4 m/s and pushes a
    sphere: as a moving plane does. The plate is far beyond the sphere's candidates at the
    start: its own drift must rebuild them in time (else it would pass through)."""
    plate = engine.Mesh(
        [[0.01, -0.01, -0.01], [0.01, 0.01, -0.01], [0.01, 0.01, 0.01], [0.01, -0.01, 0.01]],
        [[0, 1, 2], [0, 2, 3]],
        velocity=(-0.4, 0.0, 0.0),
    )
    pos = [[0.01 - 3 * R, 0.0011, 0.0007]]
    wall = engine.Plane((0.01, 0, 0), (-1, 0, 0), velocity=(-0.4, 0.0, 0.0))
    a = engine.Simulation(scene(pos, walls=[wall], gravity=(0, 0, 0)), dt=1e-6)
    b = engine.Simulation(scene(pos, meshes=[plate], gravity=(0, 0, 0)), dt=1e-6)
    rebuilds = b.n_rebuilds
    worst, contacts = _side_by_side(a, b, 300, 100)
    for q, rel in worst.items():
        assert rel <= REL, (q, rel)
    assert sum(len(c.particles) for c in contacts) >= 1  # pushed
    assert b.velocities[0, 0] < -0.4  # and sent off faster than the plate
    np.testing.assert_allclose(b.mesh_displacements[0], (-0.4 * b.time, 0, 0), rtol=1e-9)
    assert b.n_rebuilds - rebuilds >= 3  # the plate's drift rebuilt the candidates
    b.set_mesh_velocity(0, (0.0, 0.0, 0.0))
    np.testing.assert_array_equal(b.mesh_velocities, [[0.0, 0.0, 0.0]])
    with pytest.raises(engine.ParameterError, match="set_mesh_velocity.index"):
        b.set_mesh_velocity(1, (0, 0, 0))


# ---------------------------------------------------------------------- the engine's rules
def _poured(threads: int, permute_at: int | None = None) -> engine.Simulation:
    """160 particles thrown into a box of triangles with a V-shaped floor (concave edges:
    several contacts at once) for 6,600 steps (six renumberings)."""
    rng = np.random.default_rng(5)
    k = np.arange(160)
    pos = np.stack([k % 6, (k // 6) % 6, k // 36], axis=1) * 2.2 * R + (-5.5 * R, -5.5 * R, 3 * R)
    pos += rng.uniform(-0.1 * R, 0.1 * R, pos.shape)
    box = 0.034
    v = np.array(
        [[x, y, z] for z in (0.0, 0.06) for y in (-box / 2, box / 2) for x in (-box / 2, box / 2)]
        + [[-box / 2, 0.0, -0.01], [box / 2, 0.0, -0.01]]
    )
    # vertices 0-3 the bottom corners, 4-7 the top ones, 8-9 the groove's ends
    quads = [(0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]  # the four sides
    tri = [t for a, b, c, d in quads for t in ([a, b, c], [a, c, d])]
    tri += [[0, 8, 9], [0, 9, 1], [2, 3, 9], [2, 9, 8]]  # the floor: two slopes to a groove
    tri += [[0, 2, 8], [1, 9, 3]]  # the groove's two ends
    old = numba.get_num_threads()
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    try:
        vel = rng.normal(0, 0.1, pos.shape) - (0.0, 0.0, 0.4)
        sc = scene(pos, vel, meshes=[engine.Mesh(v, tri)])
        sim = engine.Simulation(sc, dt=5e-6, threads=threads)
        most = 0
        for block in range(11):
            if block == permute_at:
                sim.permute(np.random.default_rng(1).permutation(sim.n))
            sim.run(600)
            c = sim.mesh_contacts()
            most = max(most, int(np.bincount(c.particles).max()) if c.particles.size else 0)
        sim.most_contacts = most
    finally:
        numba.set_num_threads(old)
    return sim


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs 2 numba threads")
def test_mesh_forces_do_not_depend_on_the_thread_count():
    a = _poured(1)
    b = _poured(2)
    assert b.threads == 2 and a.n_renumbers == b.n_renumbers >= 2
    assert len(a.mesh_contacts().particles) > 10 and a.most_contacts >= 2
    for q in ("positions", "velocities", "angular_velocities", "mesh_forces"):
        np.testing.assert_array_equal(getattr(a, q), getattr(b, q), err_msg=q)
    mc_a, mc_b = a.mesh_contacts(), b.mesh_contacts()
    np.testing.assert_array_equal(mc_a.particles, mc_b.particles)
    np.testing.assert_array_equal(mc_a.overlaps, mc_b.overlaps)


def test_a_renumbering_carries_the_mesh_contacts():
    """Particles resting and rolling on a mesh, apart from each other (nothing sums in
    another order when they are renumbered): renumbered at random halfway, the same
    trajectories to the bit, the tangential springs and candidate triangles carried."""
    sims = []
    for permute in (False, True):
        sim = engine.Simulation(scene(FLAT, FLAT_V, FLAT_W, meshes=[grid_mesh()]), dt=1e-6)
        sim.run(3000)
        if permute:
            sim.permute(np.random.default_rng(2).permutation(sim.n))
        sim.run(3000)
        sims.append(sim)
    a, b = sims
    for q in ("positions", "velocities", "angular_velocities"):
        np.testing.assert_array_equal(getattr(a, q), getattr(b, q), err_msg=q)
    np.testing.assert_array_equal(a.mesh_contacts().points, b.mesh_contacts().points)


def test_a_pickled_mesh_simulation_resumes_bit_identically():
    """A checkpoint (pickle) of a run on a moving mesh resumes with its contact rows,
    candidates and the mesh's translation: the same bits as the run not interrupted."""
    sc = scene(FLAT, FLAT_V, FLAT_W, meshes=[grid_mesh(velocity=(0.01, 0.0, 0.0))])
    a = engine.Simulation(sc, dt=1e-6)
    b = engine.Simulation(sc, dt=1e-6)
    for sim in (a, b):
        sim.run(2000)
    b = pickle.loads(pickle.dumps(b))
    for sim in (a, b):
        sim.run(2000)
    for q in ("positions", "velocities", "angular_velocities", "mesh_forces"):
        np.testing.assert_array_equal(getattr(a, q), getattr(b, q), err_msg=q)
    np.testing.assert_array_equal(a.mesh_displacements, b.mesh_displacements)


def test_a_scene_without_meshes_compiles_the_kernel_it_compiled_before():
    """The meshes' code is a branch on the constant MESHES: off for a scene of planes, so
    its kernel is the one of before meshes (bit-identity of every kernel with the all-
    features one, meshes on without meshes: tests/engine/test_kernels.py)."""
    plane = scene(FLAT, walls=[engine.Plane((0, 0, 0), (0, 0, 1))])
    f = specialise.scene_features(plane)
    assert f["meshes"] is False and f["walls"] is True
    src = specialise._source(f)
    assert "\nMESHES = False\n" in src
    g = specialise.scene_features(scene(FLAT, meshes=[grid_mesh(4)]))
    assert g["meshes"] is True and g["walls"] is False
    assert specialise.wall_slots(g) == specialise.wall_slots(f)  # the same wall law, read alike
    assert {k for k in f if f[k] != g[k]} == {"walls", "meshes"}


# ---------------------------------------------------------------------- meshes and STL files
def test_stl_files_round_trip(tmp_path):
    mesh = cube(0.02).translated((0.001, -0.002, 0.5))
    for binary in (False, True):
        path = tmp_path / f"cube_{binary}.stl"
        mesh.to_stl(path, binary=binary)
        back = engine.Mesh.from_stl(path, closed=True)
        assert back.name == f"Mesh({path})"
        # 36 corners in the file, merged again into the 8 vertices of the cube
        assert back.n_vertices == 8 and back.n_triangles == 12
        tol = 1e-7 if binary else 0.0  # binary STL stores float32
        np.testing.assert_allclose(
            back.vertices[back.triangles], mesh.vertices[mesh.triangles], rtol=tol, atol=0
        )
        np.testing.assert_array_equal(back.normals.round(12), mesh.normals.round(12))
    moved = engine.Mesh.from_stl(path, scale=1000.0, offset=(1, 2, 3))  # LIGGGHTS scale, move
    np.testing.assert_allclose(
        moved.vertices, back.vertices * 1000 + (1, 2, 3), rtol=1e-12, atol=1e-9
    )
    text = (tmp_path / "cube_False.stl").read_text()
    assert text.startswith("solid demscale") and text.count("facet normal") == 12
    # an ASCII file whose name starts like a binary header still reads as ASCII
    (tmp_path / "one.stl").write_text(
        "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
        "vertex 0 1 0\nendloop\nendfacet\nendsolid x\n"
    )
    one = engine.Mesh.from_stl(tmp_path / "one.stl")
    assert one.n_triangles == 1 and one.areas[0] == 0.5


def _refused(tmp_path, corners, match, **kw):
    path = tmp_path / "bad.stl"
    engine.simulation.mesh.write_stl(path, np.asarray(corners, float))
    with pytest.raises(engine.ParameterError, match=match) as err:
        engine.Mesh.from_stl(path, **kw)
    assert str(path) in str(err.value)
    return err.value


def test_bad_meshes_are_refused_naming_the_file_and_the_triangle(tmp_path):
    good = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    e = _refused(tmp_path, [good, [[0, 0, 0], [1, 1, 0], [2, 2, 0]]], r"triangles\[1\]")
    assert "degenerate" in str(e) and e.field == f"Mesh({tmp_path / 'bad.stl'}).triangles[1]"
    _refused(tmp_path, [good, good, [[0, 0, 0], [0, 0, 0], [1, 1, 1]]], r"triangles\[2\].*degen")
    _refused(tmp_path, [good, [[0, 0, 0], [1, 0, 0], [0, 0, np.nan]]], r"triangles\[1\].*finite")
    fan = [good, [[0, 0, 0], [1, 0, 0], [0, -1, 0]], [[0, 0, 0], [1, 0, 0], [0, 0, 1]]]
    _refused(tmp_path, fan, r"triangles\[2\].*shared by 3 triangles")
    _refused(tmp_path, [good], r"triangles\[0\].*open edge.*closed", closed=True)
    tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    faces = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]  # outward
    engine.Mesh(tet, faces, closed=True)
    flipped = [*faces[:3], [0, 2, 3]]
    _refused(tmp_path, tet[flipped], r"triangles\[3\].*oriented", closed=True)
    (tmp_path / "short.stl").write_text(
        "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
        "endloop\nendfacet\nendsolid x\n"
    )
    with pytest.raises(engine.ParameterError, match=r"short.stl\)\.triangles\[0\].*3 vertices"):
        engine.Mesh.from_stl(tmp_path / "short.stl")
    with pytest.raises(engine.ParameterError, match=r"Mesh\.triangles\[0\].*in \[0, 3\)"):
        engine.Mesh(good, [[0, 1, 3]])
    with pytest.raises(engine.ParameterError, match=r"Mesh\(gate\)\.velocity"):
        engine.Mesh(good, [[0, 1, 2]], velocity=(0, np.inf, 0), name="gate")


def test_meshes_merge_duplicate_vertices_and_join_the_scene():
    # two triangles given with their own corners: the shared edge is found by the merge
    v = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 0, 0], [1, 1, 0], [0, 1, 0], [5, 5, 5]]
    m = engine.Mesh(v, [[0, 1, 2], [3, 4, 5]])
    assert m.n_vertices == 4  # merged, the unused vertex dropped
    np.testing.assert_array_equal(m.triangles, [[0, 1, 2], [0, 2, 3]])
    packed = engine.simulation.mesh.pack_meshes([m], 0.001)
    assert packed["medge"].shape == (5, 6)
    inner = packed["medge"][(packed["medge"][:, 4] >= 0)]
    assert inner[:, :2].tolist() == [[0, 2]]  # one edge shared, by both triangles
    with pytest.raises(engine.ParameterError, match=r"Scene.meshes\[0\]"):
        scene(FLAT, meshes=[engine.Plane((0, 0, 0), (0, 0, 1))])
    with pytest.raises(engine.ParameterError, match="Scene.wall_law.*meshes"):
        engine.Scene(FLAT, R, RHO, pair_law=PAIR, meshes=[m])
    sc = scene(FLAT, meshes=[m])
    lim = engine.critical_time_step(sc)
    assert "wall" in lim.reason  # the wall law's limits count for meshes
