"""A snapshot of a simulation: the particles and their contacts at one moment (taken by the
stage driver at every stage end, or every interval), and the per-particle measures of its
contact forces (Love-Weber pressure). numpy only; files and figures are in :mod:`engine.io`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Snapshot:
    """The particles and their contacts at one moment of a run.

    Attributes:
        stage: the stage it was taken in.
        time: simulated time [s].
        steps: steps of the simulation so far.
        positions: (N, 3) centres [m], wrapped into the cell on periodic axes.
        radii: (N,) radii [m].
        velocities: (N, 3) [m/s].
        angular_velocities: (N, 3) [rad/s].
        contact_counts: (N,) particle-particle contacts of each particle.
        pairs: (M, 2) particle ids (i < j) of the particle-particle contacts.
        normal_forces: (M,) normal component of the contact force [N], F . n with n the unit
            vector from j to i: > 0 pushes the particles apart (compressive), < 0 pulls them
            together (adhesive).
        branches: (M, 3) x_i - x_j [m], periodic minimum image.
        platens: (K,) heights of the platens [m] (bottom first).
        mesh_points: (V, 3) the vertices of every mesh wall (:class:`engine.Mesh`) where it
            is now [m]: the scene's plus the mesh's displacement (a gate that opened).
        mesh_triangles: (T, 3) each triangle's rows of ``mesh_points``.
        mesh_ids: (T,) the mesh each triangle belongs to (its index in the scene's meshes).
        (All three empty in a scene without meshes.)
    """

    stage: str
    time: float
    steps: int
    positions: np.ndarray
    radii: np.ndarray
    velocities: np.ndarray
    angular_velocities: np.ndarray
    contact_counts: np.ndarray
    pairs: np.ndarray
    normal_forces: np.ndarray
    branches: np.ndarray
    platens: np.ndarray
    mesh_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    mesh_triangles: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.int32))
    mesh_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))

    @property
    def nbytes(self) -> int:
        """Bytes held by the arrays."""
        return sum(v.nbytes for v in vars(self).values() if isinstance(v, np.ndarray))


def capture(sim, stage: str) -> Snapshot:
    """A :class:`Snapshot` of the :class:`engine.Simulation` ``sim`` taken in ``stage``.

    Positions and radii are kept in double precision; velocities, forces and branch vectors
    in single precision (snapshots are for looking at, and a run keeps one per stage)."""
    c = sim.contacts()
    dist = sim.radii[c.pairs[:, 0]] + sim.radii[c.pairs[:, 1]] - c.overlaps
    f32 = np.float32
    meshes = {}
    if sim.scene.meshes:
        meshes = _mesh_arrays(sim.scene.meshes, sim.mesh_displacements)
    return Snapshot(
        stage=stage,
        time=float(sim.time),
        steps=int(sim.steps),
        positions=sim.positions,
        radii=sim.radii,
        velocities=sim.velocities.astype(f32),
        angular_velocities=sim.angular_velocities.astype(f32),
        contact_counts=sim.contact_counts().astype(np.int32),
        pairs=c.pairs.astype(np.int32),
        normal_forces=np.einsum("ij,ij->i", c.forces, c.normals).astype(f32),
        branches=(c.normals * dist[:, None]).astype(f32),
        platens=sim.wall_positions[:, 2].copy(),
        **meshes,
    )


def _mesh_arrays(meshes, displacements: np.ndarray) -> dict[str, np.ndarray]:
    """A snapshot's mesh fields: every mesh's vertices moved by its displacement [m], its
    triangles numbered into the joined vertices, and which mesh each triangle is of."""
    points, triangles, ids = [], [], []
    start = 0
    for k, m in enumerate(meshes):
        points.append(m.vertices + displacements[k])
        triangles.append(m.triangles + start)
        ids.append(np.full(len(m.triangles), k, np.int32))
        start += len(m.vertices)
    return {
        "mesh_points": np.concatenate(points),
        "mesh_triangles": np.concatenate(triangles).astype(np.int32),
        "mesh_ids": np.concatenate(ids),
    }


def particle_fields(snap: Snapshot) -> dict[str, np.ndarray]:
    r"""Per-particle measures of the contact forces (units in :data:`FIELD_UNITS`).

    ``mean_normal_force`` [N]: mean of the normal forces of the particle's contacts (0 with
    none). ``pressure`` [Pa]: minus one third of the trace of the particle's Love-Weber
    stress,

    .. math:: p_i = \frac{1}{3 V_i} \sum_{c \in i} a_{ic} F^n_c, \qquad
              a_{ic} = r_i - \delta_c / 2,

    with :math:`V_i = 4 \pi r_i^3 / 3`, :math:`F^n_c` the normal force of contact c
    (> 0 compressive) and :math:`a_{ic}` the distance from the centre to the contact point
    (the middle of the overlap :math:`\delta_c`); > 0 in compression. Particle-particle
    contacts only: a particle touching a platen misses the platen's share.
    """
    n = len(snap.radii)
    i, j = snap.pairs[:, 0], snap.pairs[:, 1]
    fn = snap.normal_forces.astype(np.float64)
    dist = np.sqrt(np.sum(snap.branches.astype(np.float64) ** 2, axis=1))
    half_overlap = 0.5 * (snap.radii[i] + snap.radii[j] - dist)
    force_sum = np.bincount(i, fn, n) + np.bincount(j, fn, n)
    counts = np.bincount(i, minlength=n) + np.bincount(j, minlength=n)
    moment = np.bincount(i, (snap.radii[i] - half_overlap) * fn, n) + np.bincount(
        j, (snap.radii[j] - half_overlap) * fn, n
    )
    volume = 4.0 / 3.0 * np.pi * snap.radii**3
    return {
        "mean_normal_force": np.divide(force_sum, counts, out=np.zeros(n), where=counts > 0),
        # a parked particle (radius 0, Simulation.park_below) has no volume: 0, not 0 / 0
        "pressure": np.divide(moment, 3.0 * volume, out=np.zeros(n), where=volume > 0),
    }
