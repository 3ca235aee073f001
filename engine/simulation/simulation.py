"""The :class:`Simulation`: state arrays, the compiled step, and the Python-side guards."""

from __future__ import annotations

import math
import os
import threading
import time
import warnings
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numba
import numpy as np

from ..contact.kernel import pack_params
from ..core.config import (
    MAX_OVERLAP_FRACTION,
    MAX_STEP_FRACTION,
    PARTICLES_PER_THREAD,
    SKIN_FRACTION,
)
from ..core.errors import InstabilityError, ParameterError, StabilityError
from ..kernel.mesh import (
    MESH_CONTACTS,
    SCRATCH_WIDTH,
    build_mesh_candidates,
    clear_idle_rows,
)
from ..kernel.neighbour import (
    build_neighbour_list,
    renumber_list,
    reverse_list,
    wrap_positions,
)
from ..kernel.specialise import (
    compiled_member,
    kernel_features,
    load_kernel,
    pair_slots,
    scene_features,
    wall_slots,
)
from ..kernel.state import NAN as _STATUS_NAN
from ..kernel.state import OK as _STATUS_OK
from ..kernel.state import OVERLAP as _STATUS_OVERLAP
from ..kernel.state import PAUSE as _STATUS_PAUSE
from ..kernel.state import REBUILD as _STATUS_REBUILD
from ..kernel.state import Meshes, NeighbourList, Particles, Scratch, StepParams, Walls
from ..kernel.team import SYNC_STATUS, SYNC_STEPS, sync_length
from ..kernel.virial import pair_virial
from .backend import resolve_backend
from .mesh import pack_meshes
from .parking import ParkingLattice, park_args
from .scene import Scene
from .timestep import TimeStepLimit, adhesion_overlap, critical_time_step

_pool: ThreadPoolExecutor | None = None
_pool_size = 0
_pool_lock = threading.Lock()


def _team_pool(helpers: int) -> ThreadPoolExecutor:
    """The engine's pool of team threads, with room for at least ``helpers`` at once (made
    on first use, grown when a larger team asks)."""
    global _pool, _pool_size
    with _pool_lock:
        if _pool is None or _pool_size < helpers:
            old = _pool
            _pool_size = max(helpers, numba.config.NUMBA_NUM_THREADS - 1)
            _pool = ThreadPoolExecutor(max_workers=_pool_size, thread_name_prefix="engine-team")
            if old is not None:
                old.shutdown(wait=False)
        return _pool


def _forget_pool() -> None:
    """In a forked child the parent's pool threads do not exist: start a new pool there."""
    global _pool, _pool_size
    _pool, _pool_size = None, 0


os.register_at_fork(after_in_child=_forget_pool)


def run_team(member, team: int, args: tuple) -> None:
    """Run the step kernel's ``member`` (a specialised module's ``run_member``) as a team of
    ``team`` threads: member 0 in the calling thread, members 1 to team - 1 on the engine's
    pool, all at once (compiled without the GIL), then wait for all. ``args`` follow the
    member's rank: (team, nsteps, pause, phase, P, L, W, prm, S)."""
    if team == 1:
        member(0, *args)
        return
    helpers = [_team_pool(team - 1).submit(member, t, *args) for t in range(1, team)]
    try:
        member(0, *args)
    finally:
        for h in helpers:
            h.result()


class StabilityWarning(UserWarning):
    """A time step below the stable limit but above an accuracy limit (Rayleigh time or Hertz
    contact duration)."""


@dataclass(frozen=True)
class Contacts:
    """Contacts at the last force evaluation (for analysis).

    Attributes:
        pairs: (M, 2) particle ids (i < j).
        overlaps: (M,) overlaps [m].
        forces: (M, 3) contact force on the first particle of each pair [N].
        normals: (M, 3) unit vectors from the second particle to the first.
        max_overlaps: (M,) largest overlap of each contact so far [m] (bilinear law; the
            current overlap for the Hertz law).
        tangential_springs: (M, 3) stored tangential spring of each contact [m] (zeros
            without friction).
        wall_particles: (K,) ids of particles touching a wall.
        wall_ids: (K,) index of the wall each touches.
        wall_overlaps: (K,) overlaps with the wall [m].
    """

    pairs: np.ndarray
    overlaps: np.ndarray
    forces: np.ndarray
    normals: np.ndarray
    max_overlaps: np.ndarray
    tangential_springs: np.ndarray
    wall_particles: np.ndarray
    wall_ids: np.ndarray
    wall_overlaps: np.ndarray


@dataclass(frozen=True)
class MeshContacts:
    """Particle-mesh contacts at the last force evaluation (:meth:`Simulation.mesh_contacts`),
    one per touching surface patch (a face, an edge or a vertex of the mesh), sorted by
    particle, then mesh.

    Attributes:
        particles: (K,) particle ids.
        meshes: (K,) index of the mesh in the scene's ``meshes``.
        overlaps: (K,) overlaps [m].
        points: (K, 3) the closest point of the mesh to the particle's centre [m].
    """

    particles: np.ndarray
    meshes: np.ndarray
    overlaps: np.ndarray
    points: np.ndarray


def _concat(parts: list, dtype) -> np.ndarray:
    return np.concatenate(parts) if parts else np.zeros(0, dtype)


def cell_order(
    pos: np.ndarray, rad: np.ndarray, lo: np.ndarray, length: np.ndarray, periodic
) -> np.ndarray:
    """Particle ids sorted by the cell (one particle diameter wide, z fastest) they lie in:
    neighbours get nearby ids, so the step's loops over neighbours stay in cache, and the
    fixed chunks of consecutive ids are compact in space. The grid does not depend on the
    Verlet skin, so neither does the order (nor, then, the trajectory). [m]"""
    n = len(pos)
    cut = 2.0 * float(rad.max())
    origin = np.empty(3)
    ext = np.empty(3)
    p = pos.copy()
    for a in range(3):
        if periodic[a]:
            p[:, a] = lo[a] + np.mod(p[:, a] - lo[a], length[a])
            origin[a], ext[a] = lo[a], length[a]
        else:
            origin[a], ext[a] = p[:, a].min(), np.ptp(p[:, a])
    ncell = np.maximum(1, (ext / cut).astype(np.int64))
    while int(np.prod(ncell)) > 4 * n + 64:
        a = int(np.argmax(ncell))
        ncell[a] = max(1, ncell[a] // 2)
    size = np.where(ext > 0, ext / ncell, 1.0)
    c = np.clip(((p - origin) / size).astype(np.int64), 0, ncell - 1)
    key = (c[:, 0] * ncell[1] + c[:, 1]) * ncell[2] + c[:, 2]
    return np.argsort(key, kind="stable")


#: Wall time a kernel call of :meth:`Simulation.run` aims at [s]: the longest wait for a
#: progress report, a stop request or a signal handler.
CALL_SECONDS = 0.2
#: Steps of the first kernel call (then adapted to its wall time).
_FIRST_CALL_STEPS = 16
#: Steps between two renumberings of the particles in cell order (see
#: :meth:`Simulation._renumber`): at every multiple of it, counted from step 0, so that when
#: they happen depends on nothing but the step count (not on the skin, the list builds or
#: the wall time).
RENUMBER_STEPS = 1000
_UNBOUNDED = 2**62


class Simulation:
    """A DEM simulation of a :class:`Scene`.

    Args:
        scene: the scene (copied; later changes to it have no effect).
        dt: time step [s]; None chooses ``DT_FRACTION`` of the smallest limit of
            :func:`engine.critical_time_step`. A step above the stable limit raises
            :class:`engine.StabilityError` naming both numbers.
        skin: Verlet skin [m]; default ``SKIN_FRACTION`` x the largest radius.
        max_speed: impact speed assumed by the Hertz time-step limits [m/s].
        max_overlap_fraction: an overlap beyond this fraction of the (smaller) radius stops
            the run with :class:`engine.InstabilityError`.
        max_step_fraction: a particle moving more than this fraction of its radius in one step
            stops the run with :class:`engine.InstabilityError`.
        threads: threads of the parallel passes, at most numba's thread count; None takes one
            thread per ``engine.core.config.PARTICLES_PER_THREAD`` (1,000) particles (small scenes
            run on one thread: a second gains little and loses when other processes share
            the cores). Results do not depend on it.

        backend: ``"cpu"``, ``"cuda"`` (an NVIDIA GPU with numba-cuda, the ``gpu`` extra:
            a :class:`engine.cuda.CudaSimulation` is made) or ``"auto"`` (the GPU when one is
            usable); None: ``DEMSCALE_BACKEND``, else ``"cpu"`` (see engine.simulation.backend). The
            one taken is :attr:`backend`.

    Only the features the scene uses are compiled in (see :attr:`features`).
    """

    #: the engine that runs it: "cpu" or "cuda"
    backend = "cpu"

    def __new__(cls, *args, backend: str | None = None, **kwargs):
        if cls is Simulation and resolve_backend(backend) == "cuda":
            from ..cuda import CudaSimulation  # numba-cuda: imported only for the GPU

            return super().__new__(CudaSimulation)
        return super().__new__(cls)

    def __init__(
        self,
        scene: Scene,
        dt: float | None = None,
        *,
        skin: float | None = None,
        max_speed: float | None = None,
        max_overlap_fraction: float = MAX_OVERLAP_FRACTION,
        max_step_fraction: float = MAX_STEP_FRACTION,
        threads: int | None = None,
        backend: str | None = None,
    ) -> None:
        if not isinstance(scene, Scene):
            raise ParameterError("Simulation.scene", scene, "an engine.Scene")
        self.scene = scene
        for name, v in (
            ("max_overlap_fraction", max_overlap_fraction),
            ("max_step_fraction", max_step_fraction),
        ):
            if not (isinstance(v, (int, float)) and 0 < v < 1):
                raise ParameterError(f"Simulation.{name}", v, "in (0, 1)")
        if threads is not None and (
            isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1
        ):
            raise ParameterError("Simulation.threads", threads, "an integer >= 1 or None")
        self._threads = None if threads is None else int(threads)
        self.limit: TimeStepLimit = critical_time_step(scene, max_speed)
        self._dt = self._choose_dt(dt)
        self._check_adhesion(max_overlap_fraction)

        rmax = float(scene.radii.max())
        if skin is None:
            skin = SKIN_FRACTION * rmax
        if not (isinstance(skin, (int, float)) and math.isfinite(skin) and skin > 0):
            raise ParameterError("Simulation.skin", skin, "> 0 m")
        self.skin = float(skin)
        self._periodic = np.array(scene.periodic, dtype=np.bool_)
        self._check_box()
        self._check_meshes()

        n = scene.n
        nw = len(scene.walls)
        nm = len(scene.meshes)
        self._n_planes = nw
        self._lo = scene.box[:, 0].copy()
        self._images = np.zeros((n, 3), dtype=np.int64)
        # the kernel mode (DEMSCALE_KERNELS) is read once, here: a simulation keeps its
        # kernel's features (set_periodic changes only the periodic axes; a checkpoint
        # resumes with the features it was written with)
        self._load(kernel_features(scene_features(scene)))
        k = self._k
        # internal id k is particle order[k] of the scene; every accessor maps back
        self._order = cell_order(
            scene.positions, scene.radii, self._lo, scene.box_lengths, self._periodic
        )
        self._rank = np.empty(n, dtype=np.int64)
        self._rank[self._order] = np.arange(n)
        o = self._order
        pos = scene.positions[o].copy()
        self._particles = Particles(
            pos=pos,
            vel=scene.velocities[o].copy(),
            omg=scene.angular_velocities[o].copy(),
            frc=np.zeros((n, 3)),
            trq=np.zeros((n, 3)),
            roll=np.zeros(n if self._features["rolling"] else 0),
            rad=scene.radii[o].copy(),
            mass=scene.masses[o].copy(),
            inv_mass=1.0 / scene.masses[o],
            inv_inertia=1.0 / scene.inertia[o],
            pos_build=pos.copy(),
        )
        nchunk = -(-n // k.CHUNK)
        # rows 0 .. nw - 1: the planes; nw + m: mesh m (its translation since time 0)
        point = [w.point for w in scene.walls] + [(0.0, 0.0, 0.0)] * nm
        vel = [w.velocity for w in (*scene.walls, *scene.meshes)]
        #: the meshes' bin grids and topology (engine.kernel.mesh), made once
        self._mesh_arrays = pack_meshes(scene.meshes, rmax + self.skin)
        ma = self._mesh_arrays
        self._walls = Walls(
            point=np.array(point, dtype=np.float64).reshape(nw + nm, 3),
            normal=np.array([w.normal for w in scene.walls], dtype=np.float64).reshape(nw, 3),
            vel=np.array(vel, dtype=np.float64).reshape(nw + nm, 3),
            hist=np.zeros((n * nw, k.N_WALL_HIST)),
            force=np.zeros((nw + nm, 3)),
            acc=np.zeros((nchunk, nw + nm, 3)),
            # a kernel without meshes takes no mesh arrays (an empty tuple: nothing changes)
            mesh=Meshes(
                mvert=ma["mvert"],
                mtri=ma["mtri"],
                mtri_n=ma["mtri_n"],
                medge=ma["medge"],
                mvert_start=ma["mvert_start"],
                mvert_edge=ma["mvert_edge"],
                cand_start=np.zeros(n + 1, dtype=np.int64),
                cand_t=np.zeros(16 if nm else 0, dtype=np.int32),
                mhist=np.zeros((n * k.MESH_ROWS if nm else 0, k.N_MESH_HIST)),
                mscr=np.zeros((nchunk if nm else 0, MESH_CONTACTS, SCRATCH_WIDTH)),
                mshift0=np.zeros((nm, 3)),
                box=np.stack([self._lo, scene.box_lengths]),
            )
            if self._features["meshes"]
            else (),
        )
        self._params = StepParams(
            pair=self._pair_params(),
            wall=self._wall_params(),
            gravity=np.array(scene.gravity, dtype=np.float64),
            length=scene.box_lengths.copy(),
            dt=self._dt,
            skin=self.skin,
            max_overlap=float(max_overlap_fraction),
            max_step=float(max_step_fraction),
        )
        self._scratch = Scratch(
            chunk_stat=np.zeros((nchunk, 4)),
            chunk_disp=np.zeros(nchunk),
            info=np.zeros(3),
            sync=np.zeros(sync_length(numba.config.NUMBA_NUM_THREADS), dtype=np.int64),
        )
        self._list = NeighbourList(
            start=np.zeros(n + 1, dtype=np.int64),
            j=np.zeros(0, dtype=np.int32),
            entry=np.zeros((0, k.N_SLOT)),
            rev_start=np.zeros(n + 1, dtype=np.int64),
            rev_k=np.zeros(0, dtype=np.int32),
        )
        self._n_rebuilds = 0
        self._n_entries = 0
        self._steps = 0
        self._failed: InstabilityError | None = None
        #: called with no argument between two bounded kernel calls of :meth:`run`, at
        #: least every ``CALL_SECONDS`` of wall time while it runs (see :meth:`run`)
        self.between_calls: Callable[[], object] | None = None
        self._pause = _UNBOUNDED  # steps one kernel call may take (adapted in run)
        self._call_steps = _FIRST_CALL_STEPS
        self._phase = 0  # 1: the next step is opened (a bounded call, or an exception after it)
        self._next_renumber = RENUMBER_STEPS  # the step of the next renumbering
        self._n_renumbers = 0
        self._rebuild()
        self._compute_forces()

    # ------------------------------------------------------------------ set-up and checks
    def _choose_dt(self, dt: float | None) -> float:
        lim = self.limit
        if dt is None:
            if not math.isfinite(lim.recommended):
                raise ParameterError(
                    "Simulation.dt",
                    None,
                    "given explicitly",
                    "no contact law limits the time step of this scene",
                )
            return lim.recommended
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise ParameterError("Simulation.dt", dt, "> 0 s and finite")
        dt = float(dt)
        if dt > lim.dt:
            raise StabilityError(
                f"dt = {dt:.4g} s is above the stable limit {lim.dt:.4g} s set by {lim.reason}; "
                f"use dt <= {lim.dt:.4g} s (recommended {lim.recommended:.4g} s) or dt=None",
                dt=dt,
                limit=lim.dt,
            )
        soft = [c for c in lim.candidates if not c.hard and dt > c.value]
        if soft:
            c = min(soft, key=lambda c: c.value)
            warnings.warn(
                f"dt = {dt:.4g} s exceeds the {c.name} ({c.value:.4g} s): contacts "
                f"are poorly resolved (recommended {lim.recommended:.4g} s)",
                StabilityWarning,
                stacklevel=3,
            )
        return dt

    def _check_adhesion(self, ovl: float) -> None:
        law = self.scene.pair_law
        rmin = float(self.scene.radii.min())
        d_eq = adhesion_overlap(law, rmin, ovl)
        if d_eq is not None:
            what = "|f0|/k1" if law.n == 1.0 else "(|f0|/k1)^(1/n)"
            raise StabilityError(
                f"adhesion f0 = {law.f0:g} N pulls contacts to the overlap {what} = "
                f"{d_eq:.4g} m, beyond max_overlap_fraction {ovl:g} x the smallest radius "
                f"{rmin:g} m: raise k1 or reduce |f0|"
            )

    def _check_box(self) -> None:
        cut = 2.0 * float(self.scene.radii.max()) + self.skin
        for a, axis in enumerate("xyz"):
            if self._periodic[a] and self.scene.box_lengths[a] < 2.0 * cut:
                raise ParameterError(
                    "Scene.box",
                    f"{self.scene.box_lengths[a]:g} m along {axis}",
                    f">= {2 * cut:.4g} m on a periodic axis (twice the neighbour cut-off "
                    f"2 Rmax + skin, for the minimum image)",
                )

    def _check_meshes(self) -> None:
        """A mesh is not repeated across a periodic face: along a periodic axis it must reach
        beyond both faces of the box by the largest radius plus the skin (a wall extruded
        along the axis, as a slot hopper's: every particle, wrapped into the box or a little
        past a face between two list builds, meets the mesh around it), or keep that far
        inside them (no particle meets it across a face)."""
        margin = float(self.scene.radii.max()) + self.skin
        for k, mesh in enumerate(self.scene.meshes):
            for a, axis in enumerate("xyz"):
                if not self._periodic[a]:
                    continue
                lo, hi = self.scene.box[a]
                mn, mx = float(mesh.vertices[:, a].min()), float(mesh.vertices[:, a].max())
                if (mn <= lo - margin and mx >= hi + margin) or (
                    mn >= lo + margin and mx <= hi - margin
                ):
                    continue
                raise ParameterError(
                    f"Scene.meshes[{k}]",
                    f"{mesh.name} from {mn:.6g} to {mx:.6g} m along the periodic axis {axis}",
                    f"beyond both faces of the box ({lo:.6g}, {hi:.6g} m) by the largest "
                    f"radius plus the skin ({margin:.4g} m), or that far inside them",
                    "a mesh is not repeated across a periodic face",
                )

    def _pair_params(self) -> np.ndarray:
        """The pair law's kernel parameters in the slots the specialised kernel names."""
        return pack_params(self.scene.pair_law.pair_values(), pair_slots(self._features))

    def _wall_params(self) -> np.ndarray:
        """The wall law's kernel parameters in the slots the specialised kernel names."""
        slots = wall_slots(self._features)
        if not (self.scene.walls or self.scene.meshes):
            return np.full(len(slots) + 1, math.nan)
        return pack_params(self.scene.wall_law.wall_values(self.scene.wall_material), slots)

    def _load(self, features: dict[str, bool]) -> None:
        """Load the step kernel of these kernel ``features`` (a scene's features in the
        ``DEMSCALE_KERNELS`` mode read at construction: specialise.kernel_features)."""
        self._features = dict(features)
        self._k = load_kernel(self._features)

    # ------------------------------------------------------------------ neighbour list
    def _grow(self, needed: int) -> None:
        cap = int(needed * 1.25) + 16
        old = self._list
        m = self._n_entries
        nbr_j = np.zeros(cap, dtype=np.int32)
        entry = np.zeros((cap, self._k.N_SLOT))
        nbr_j[:m] = old.j[:m]
        entry[:m] = old.entry[:m]
        self._list = old._replace(j=nbr_j, entry=entry, rev_k=np.zeros(cap, dtype=np.int32))

    @property
    def threads(self) -> int:
        """Threads the parallel passes use now (see the ``threads`` argument)."""
        avail = numba.get_num_threads()
        if self._threads is not None:
            return min(self._threads, avail)
        return max(1, min(avail, self.n // PARTICLES_PER_THREAD))

    def _call(self, nsteps: int, phase: int = 0) -> tuple[int, int]:
        return self._call_kernel(nsteps, phase, self.threads)

    def _call_kernel(self, nsteps: int, phase: int, team: int) -> tuple[int, int]:
        """One call of the step kernel by a team of ``team`` threads; (steps, status)."""
        sync = self._scratch.sync
        sync[:] = 0
        args = (
            team,
            nsteps,
            self._pause,
            phase,
            self._particles,
            self._list,
            self._walls,
            self._params,
            self._scratch,
        )
        self._run_team(team, args)
        return int(sync[SYNC_STEPS]), int(sync[SYNC_STATUS])

    def _run_team(self, team: int, args: tuple) -> None:
        run_team(compiled_member(self._k, args), team, args)

    def _rebuild(self) -> None:
        p = self._particles
        while True:
            lst = self._list
            total = build_neighbour_list(
                p.pos,
                p.rad,
                self._lo,
                self._params.length,
                self._periodic,
                self.skin,
                self._images,
                lst.start,
                lst.j,
                lst.entry,
                self._k.N_HIST,
                lst.rev_start,
                lst.rev_k,
                p.pos_build,
            )
            self._n_rebuilds += 1
            if total >= 0:
                self._n_entries = int(total)
                break
            self._grow(-int(total))
        self._build_mesh_candidates()

    def _build_mesh_candidates(self) -> None:
        """Each particle's candidate triangles, from the positions of this list build (those
        within its radius plus the skin), and the meshes' translations at it."""
        if not self.scene.meshes:
            return
        nw = self._n_planes
        ma = self._mesh_arrays
        p = self._particles
        while True:
            m = self._walls.mesh
            total = build_mesh_candidates(
                p.pos,
                p.rad,
                self.skin,
                self._walls.point,
                nw,
                m.mvert,
                m.mtri,
                ma["gridf"],
                ma["gridi"],
                ma["cell_start"],
                ma["cell_tri"],
                m.cand_start,
                m.cand_t,
            )
            if total >= 0:
                break
            m = m._replace(cand_t=np.zeros(int(-total * 1.25) + 16, np.int32))
            self._walls = self._walls._replace(mesh=m)
        clear_idle_rows(m.cand_start, m.mhist)
        m.mshift0[:] = self._walls.point[nw:]

    def _renumber(self) -> bool:
        """Renumber the particles in the cell order of their current positions (called at
        every multiple of ``RENUMBER_STEPS``; the next one is set here). The particles move
        after the order of the Simulation's start is made: where they mix, pair partners
        drift apart in memory and the pair pass and the gather miss the cache (a random order
        costs about 40 % more per step at 20,626 particles, 4 % at 2,578; a poured fill
        keeps its order, falling in columns: benchmarks/paper_speed.py). Every per-particle
        array, the image counts, the wall histories and the id map are permuted, and the
        list is renumbered with its contact histories (:meth:`permute`). The sort is
        stable, so particles that stayed in order keep their places; nothing is done when
        none moved (False). Deterministic: the same state gives the same order, whatever
        the threads, the skin or where the kernel calls ended. On the CUDA backend the
        particles keep their order (its state lives on the device)."""
        self._next_renumber = (self._steps // RENUMBER_STEPS + 1) * RENUMBER_STEPS
        if self.backend != "cpu":
            return False
        p = self._particles
        # the scene's radii (only their largest counts): a parked particle's zero radius
        # (park_below) changes neither the grid nor the order
        perm = cell_order(p.pos, self.scene.radii, self._lo, self._params.length, self._periodic)
        n = len(perm)
        if np.array_equal(perm, np.arange(n)):
            return False
        self.permute(perm)
        return True

    def permute(self, perm: np.ndarray) -> None:
        """Give internal id k to the particle of internal id ``perm[k]`` (a permutation of
        range(N)), carrying everything the particles hold: state, positions at the last list
        build, image counts, wall contact histories, the neighbour list with the contact
        histories and forces (renumbered: the same pairs, so it stays valid and is not built
        again), and the id map (the accessors and :meth:`contacts` keep the scene's order and
        values). The physics is unchanged; sums over a particle's contacts and over chunks
        run in the new order, so later steps round differently. (For :meth:`_renumber` and
        for benchmarks/paper_speed.py's order comparisons.)"""
        n = self.n
        perm = np.asarray(perm, dtype=np.int64)
        if perm.shape != (n,) or not np.array_equal(np.sort(perm), np.arange(n)):
            raise ParameterError(
                "Simulation.permute.perm", f"shape {perm.shape}", "a permutation of range(N)"
            )
        rank = np.empty(n, dtype=np.int64)
        rank[perm] = np.arange(n)
        for a in self._particles:
            if a.shape[0] == n:
                a[:] = a[perm]
        self._images[:] = self._images[perm]
        nw = self._n_planes
        if nw:
            hist = self._walls.hist.reshape(n, nw, -1)
            hist[:] = hist[perm]
        if self.scene.meshes:
            m = self._walls.mesh
            mhist = m.mhist.reshape(n, -1, m.mhist.shape[1])
            mhist[:] = mhist[perm]
            # each particle's candidate triangles move with it (the same list, renumbered)
            counts = np.diff(m.cand_start)[perm]
            start = np.zeros(n + 1, dtype=np.int64)
            np.cumsum(counts, out=start[1:])
            src = np.repeat(m.cand_start[:-1][perm] - start[:-1], counts)
            src += np.arange(start[-1])
            cand_t = m.cand_t.copy()
            cand_t[: start[-1]] = m.cand_t[src]
            m = m._replace(cand_start=start, cand_t=cand_t)
            self._walls = self._walls._replace(mesh=m)
        lst = self._list
        start = np.empty_like(lst.start)
        j = np.zeros_like(lst.j)
        entry = np.zeros_like(lst.entry)
        k = self._k
        renumber_list(rank, lst.start, lst.j, lst.entry, k.N_HIST, k.F_SLOT, start, j, entry)
        reverse_list(start, j, lst.rev_start, lst.rev_k)
        self._list = lst._replace(start=start, j=j, entry=entry)
        self._order = self._order[perm]
        self._rank[self._order] = np.arange(n)
        self._n_renumbers += 1

    def _compute_forces(self) -> None:
        status = self._call(0)[1]
        if status != _STATUS_OK:
            self._fail(status, self._steps)

    # ------------------------------------------------------------------ running
    def run(self, steps: int) -> None:
        """Advance ``steps`` time steps (``steps * dt`` seconds).

        However many steps are asked for, no kernel call takes much more than
        ``CALL_SECONDS`` of wall time: a call stops at a step boundary where a
        neighbour-list rebuild would, and the next one resumes there, so the trajectory is
        bit-identical to that of one call. Between two calls ``between_calls`` (if set) is
        called, and Python's signal handlers run: a progress report, a stop request or a
        SIGTERM is heard within a fraction of a second. An exception from ``between_calls``
        leaves the simulation between two calls; a later ``run`` goes on from there."""
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 0:
            raise ParameterError("Simulation.run.steps", steps, "an integer >= 0")
        if self._failed is not None:
            raise RuntimeError(
                f"this simulation stopped with an instability and cannot go on: {self._failed}"
            )
        remaining = int(steps)
        heard = time.perf_counter()  # when between_calls last ran (or the run began)
        if remaining > 0 and self._steps >= self._next_renumber:
            self._renumber()  # the last run ended on a renumbering step (at a whole step)
        while remaining > 0:
            # a call ends at the next renumbering step at the latest (a pause there)
            self._pause = max(1, min(self._call_steps, self._next_renumber - self._steps))
            t0 = time.perf_counter()
            done, status = self._call(remaining, self._phase)
            self._adapt(done, time.perf_counter() - t0)
            self._steps += done
            remaining -= done
            if status == _STATUS_OK:
                self._phase = 0
                break
            if status != _STATUS_PAUSE and status != _STATUS_REBUILD:
                self._fail(status, self._steps + 1)
            if self._steps >= self._next_renumber:
                self._renumber()
            if status == _STATUS_REBUILD:
                self._rebuild()
            self._phase = 1  # the next step is opened: resume as after a rebuild
            now = time.perf_counter()
            if self.between_calls is not None and now - heard >= CALL_SECONDS:
                heard = now
                self.between_calls()

    def _adapt(self, done: int, seconds: float) -> None:
        """Steps of the next kernel call: what takes about ``CALL_SECONDS`` at the rate of
        the last one (wall time decides only where calls end, never the result)."""
        if done <= 0:
            return
        if seconds <= 0:
            self._call_steps = min(2 * self._call_steps, _UNBOUNDED)
            return
        want = int(done * CALL_SECONDS / seconds)
        # grow at most 4x a call, so that a slow stretch after a fast one stays short
        self._call_steps = max(1, min(want, 4 * self._call_steps, _UNBOUNDED))

    def _fail(self, status: int, step: int) -> None:
        info = self._scratch.info
        i, j, value = int(info[0]), int(info[1]), float(info[2])
        i = int(self._order[i])  # scene ids
        if j >= 0:
            j = int(self._order[j])
        t = step * self.dt
        where = f"step {step} (t = {t:.6g} s)"
        hint = f"; dt = {self.dt:.4g} s, stable limit {self.limit.dt:.4g} s ({self.limit.reason})"
        if status == _STATUS_NAN:
            msg, reason, ids = (
                f"{where}: non-finite force, velocity or position of particle {i}",
                "nan",
                (i,),
            )
        elif status == _STATUS_OVERLAP:
            w = -1 - j
            other = (
                f"particle {j}"
                if j >= 0
                else (f"wall {w}" if w < self._n_planes else f"mesh {w - self._n_planes}")
            )
            msg = (
                f"{where}: overlap between particle {i} and {other} is {value:.3g} x the "
                f"radius, beyond max_overlap_fraction = {self._params.max_overlap:g}"
            )
            reason, ids = "overlap", (i, j) if j >= 0 else (i,)
        else:
            msg = (
                f"{where}: particle {i} moved {value:.3g} x its radius in one step, beyond "
                f"max_step_fraction = {self._params.max_step:g} (runaway kinetic energy)"
            )
            reason, ids = "speed", (i,)
        err = InstabilityError(msg + hint, step=step, time=t, particles=ids, reason=reason)
        self._failed = err
        raise err

    # ------------------------------------------------------------------ changes between runs
    def set_wall_velocity(self, index: int, velocity) -> None:
        """Set the velocity [m/s] of wall ``index`` for the following runs."""
        self._check_wall(index)
        v = np.asarray(velocity, dtype=np.float64)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ParameterError(
                "Simulation.set_wall_velocity.velocity", velocity, "3 finite numbers [m/s]"
            )
        self._walls.vel[index] = v

    def set_mesh_velocity(self, index: int, velocity) -> None:
        """Set the translation velocity [m/s] of mesh ``index`` (of the scene's ``meshes``)
        for the following runs (a gate that opens)."""
        nm = len(self.scene.meshes)
        if not (isinstance(index, (int, np.integer)) and 0 <= index < nm):
            raise ParameterError("Simulation.set_mesh_velocity.index", index, f"in [0, {nm})")
        v = np.asarray(velocity, dtype=np.float64)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ParameterError(
                "Simulation.set_mesh_velocity.velocity", velocity, "3 finite numbers [m/s]"
            )
        self._walls.vel[self._n_planes + index] = v

    def set_gravity(self, gravity) -> None:
        """Set the acceleration of gravity [m/s^2] (3 numbers) for the following runs; forces
        are updated. A simulation built without gravity (its scene's is zero) has no gravity
        in its compiled step, so only zero is accepted there."""
        g = np.asarray(gravity, dtype=np.float64)
        if g.shape != (3,) or not np.all(np.isfinite(g)):
            raise ParameterError("Simulation.set_gravity.gravity", gravity, "3 finite numbers")
        if not any(x != 0 for x in self.scene.gravity) and np.any(g != 0):
            raise ParameterError(
                "Simulation.set_gravity.gravity",
                gravity,
                "zero: this simulation was built without gravity (give its Scene the gravity "
                "to switch it off and on)",
            )
        self._params.gravity[:] = g
        self._compute_forces()

    def set_wall_position(self, index: int, point) -> None:
        """Move wall ``index`` so that it passes through ``point`` [m]; forces are updated."""
        self._check_wall(index)
        p = np.asarray(point, dtype=np.float64)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ParameterError(
                "Simulation.set_wall_position.point", point, "3 finite numbers [m]"
            )
        self._walls.point[index] = p
        self._compute_forces()

    def set_velocities(self, velocities=None, angular_velocities=None) -> None:
        """Replace particle velocities [m/s] and/or angular velocities [rad/s] (e.g. zero
        them to quench a packing); forces are updated."""
        n = self.n
        for name, value, target in (
            ("velocities", velocities, self._particles.vel),
            ("angular_velocities", angular_velocities, self._particles.omg),
        ):
            if value is None:
                continue
            a = np.broadcast_to(np.asarray(value, dtype=np.float64), (n, 3))
            if not np.all(np.isfinite(a)):
                raise ParameterError(f"Simulation.set_velocities.{name}", "non-finite", "finite")
            target[:] = a[self._order]
        self._compute_forces()

    def set_driven(self, ids, velocity) -> None:
        """Move particles ``ids`` (scene ids) at ``velocity`` [m/s] (3 numbers, the same for
        all) from now on, whatever the forces on them: the glued grains of a rough platen
        moved as one body (:mod:`engine.shear`). Their inverse mass and inverse moment of
        inertia become zero, so the kick leaves their velocity as set and their angular
        velocity (set to zero) at zero; the forces on them are still computed
        (:attr:`forces`, gravity included) and their masses still enter the contact damping.
        Called again with particles already driven, it sets their new velocity. Forces are
        not evaluated again (the kick of the next step uses those of the last evaluation; no
        contact history advances), so a driven velocity changed between two runs changes
        nothing else. A particle once driven stays driven. The CPU backend only."""
        if self.backend != "cpu":
            raise ParameterError(
                "Simulation.set_driven", self.backend, "the cpu backend (driven particles)"
            )
        idx = np.asarray(ids)
        if idx.ndim != 1 or idx.size == 0 or not np.issubdtype(idx.dtype, np.integer):
            raise ParameterError("Simulation.set_driven.ids", ids, "a non-empty list of ids")
        if idx.min() < 0 or idx.max() >= self.n:
            raise ParameterError("Simulation.set_driven.ids", "out of range", f"in [0, {self.n})")
        v = np.asarray(velocity, dtype=np.float64)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ParameterError("Simulation.set_driven.velocity", velocity, "3 finite numbers")
        k = self._rank[idx]  # internal ids
        p = self._particles
        p.inv_mass[k] = 0.0
        p.inv_inertia[k] = 0.0
        p.vel[k] = v
        p.omg[k] = 0.0

    def park_below(self, height: float, lattice: ParkingLattice) -> None:
        """Park every live particle whose centre lies below ``height`` [m] (z as stored): move
        it to its site of ``lattice`` (its scene id's), at rest, radius 0, inverse mass and
        inverse moment of inertia 0, out of every contact for good (:mod:`engine.simulation.
        parking`: why nothing touches it again). A particle once parked stays parked; a
        driven one (:meth:`set_driven`) is parked like any other. The hopper's sink.
        Forces are not evaluated again (as :meth:`set_driven`) and no rebuild is made: the
        parked particle's pair, plane and mesh contacts are deleted with their history (its
        old neighbours find it out of reach from then on). The lattice is checked once, against
        the planes where they are then (:meth:`_check_parking`).
        On the CUDA backend a kernel on the device: nothing crosses to the host."""
        h = park_args(height, lattice)
        self._check_parking(lattice)
        p = self._particles
        k = np.nonzero((p.pos[:, 2] < h) & (p.rad > 0.0))[0]
        if not len(k):
            return
        site = lattice.sites(self._order[k])
        p.pos[k] = site
        p.pos_build[k] = site
        p.vel[k] = 0.0
        p.omg[k] = 0.0
        p.rad[k] = 0.0
        p.inv_mass[k] = 0.0
        p.inv_inertia[k] = 0.0
        self._images[k] = 0
        lst = self._list  # its contacts open now (contacts() reads none of them)
        for i in k:
            lst.entry[lst.start[i] : lst.start[i + 1]] = 0.0
            lst.entry[lst.rev_k[lst.rev_start[i] : lst.rev_start[i + 1]]] = 0.0
        w = self._walls  # and its wall contacts (mesh_contacts() reads none of them)
        nw = self._n_planes
        if nw:
            w.hist.reshape(self.n, nw, -1)[k] = 0.0
        if self.scene.meshes:
            w.mesh.mhist.reshape(self.n, -1, w.mesh.mhist.shape[1])[k] = 0.0

    def _check_parking(self, lattice: ParkingLattice) -> None:
        """Once per lattice: its spacing beyond the skin, and the sites of all N particles
        inside the box and on the particles' side of every plane (a radius-0 particle behind
        a plane would be pushed back through it). Meshes are the caller's to keep clear."""
        if getattr(self, "_parking_checked", None) == lattice:
            return
        lattice.check(self.skin)
        sites = lattice.sites(np.arange(self.n))
        hi = self._lo + self._params.length
        if np.any(sites < self._lo) or np.any(sites >= hi):
            raise ParameterError(
                "Simulation.park_below.lattice",
                f"sites from {sites.min(axis=0).tolist()} to {sites.max(axis=0).tolist()} m",
                f"inside the box {self._lo.tolist()} to {hi.tolist()} m",
            )
        w = self._walls
        for k in range(self._n_planes):
            gap = (sites - w.point[k]) @ w.normal[k]
            if gap.min() <= 0.0:
                raise ParameterError(
                    "Simulation.park_below.lattice",
                    f"a site {-gap.min():.4g} m behind wall {k}",
                    "every site on the particles' side of every plane",
                )
        self._parking_checked = lattice

    def rebuild_neighbour_list(self) -> None:
        """Rebuild the neighbour list now (it is rebuilt automatically when needed); the
        contact history is carried over unchanged."""
        self._rebuild()

    def set_positions(self, positions) -> None:
        """Replace particle positions [m] (N, 3). The neighbour list is rebuilt (contact
        history of pairs still in range is kept) and forces are updated; the contact
        histories advance exactly as in one force evaluation."""
        p = np.asarray(positions, dtype=np.float64)
        if p.shape != (self.n, 3) or not np.all(np.isfinite(p)):
            raise ParameterError(
                "Simulation.set_positions.positions",
                f"shape {p.shape}",
                f"finite, shape ({self.n}, 3)",
            )
        self._particles.pos[:] = p[self._order]
        self._images[:] = 0
        self._rebuild()
        self._compute_forces()

    def set_periodic(self, periodic) -> None:
        """Change which axes are periodic (e.g. remove the lateral confinement of a sample).
        Contacts across a face that stops being periodic disappear with their history; the
        step kernel is re-specialised."""
        per = np.array([bool(p) for p in periodic], dtype=np.bool_)
        if per.shape != (3,):
            raise ParameterError("Simulation.set_periodic.periodic", periodic, "three booleans")
        if np.any(per & ~self._periodic):
            raise ParameterError(
                "Simulation.set_periodic.periodic",
                tuple(per.tolist()),
                "a subset of the current periodic axes",
                "periodicity can be removed, not added",
            )
        # the sample is cut at the box faces: wrap once more, then forget the wraps there
        wrap_positions(
            self._particles.pos, self._lo, self._params.length, self._periodic, self._images
        )
        self._images[:, ~per] = 0
        self._periodic = per
        self._load({**self._features, **{f"periodic_{a}": bool(p) for a, p in zip("xyz", per)}})
        self._rebuild()
        self._compute_forces()

    def _check_wall(self, index: int) -> None:
        if not (isinstance(index, (int, np.integer)) and 0 <= index < self._n_planes):
            raise ParameterError("wall index", index, f"in [0, {self._n_planes})")

    # ------------------------------------------------------------------ checkpoints
    def __getstate__(self) -> dict:
        """The full state for a checkpoint (pickle): particles, neighbour list with the
        contact history, walls, parameters, step count and the phase of the next kernel call.
        The compiled kernel and ``between_calls`` are left out; unpickling loads the kernel
        for the same features again, so the resumed trajectory is bit-identical to the one
        that was not interrupted (tests/engine/test_checkpoint.py)."""
        state = self.__dict__.copy()
        del state["_k"]
        state["between_calls"] = None
        return state

    def __setstate__(self, state: dict) -> None:
        # a state pickled before the renumbering (issue 40) renumbers at its next multiple
        self._next_renumber = (state["_steps"] // RENUMBER_STEPS + 1) * RENUMBER_STEPS
        self._n_renumbers = 0
        self.__dict__.update(state)
        self._k = load_kernel(self._features)
        # the thread team's counters are cleared by every kernel call; sized for this process
        self._scratch = self._scratch._replace(
            sync=np.zeros(sync_length(numba.config.NUMBA_NUM_THREADS), dtype=np.int64)
        )

    # ------------------------------------------------------------------ state
    @property
    def n(self) -> int:
        """Number of particles."""
        return self._particles.pos.shape[0]

    @property
    def dt(self) -> float:
        """Time step [s] (fixed for the life of the simulation)."""
        return self._dt

    @property
    def time(self) -> float:
        """Simulated time since the start [s]."""
        return self._steps * self.dt

    @property
    def steps(self) -> int:
        """Steps since the start."""
        return self._steps

    @property
    def features(self) -> dict[str, bool]:
        """The compile-time features of the step kernel in use (see
        engine.kernel.specialise.FEATURES)."""
        return dict(self._features)

    @property
    def periodic(self) -> tuple[bool, bool, bool]:
        """Periodic flags in use."""
        return tuple(bool(p) for p in self._periodic)

    @property
    def positions(self) -> np.ndarray:
        """(N, 3) positions [m], wrapped into the box on periodic axes."""
        return self._particles.pos[self._rank]

    @property
    def unwrapped_positions(self) -> np.ndarray:
        """(N, 3) positions [m] with the periodic wraps undone."""
        return (self._particles.pos + self._images * self._params.length)[self._rank]

    @property
    def velocities(self) -> np.ndarray:
        """(N, 3) velocities [m/s]."""
        return self._particles.vel[self._rank]

    @property
    def angular_velocities(self) -> np.ndarray:
        """(N, 3) angular velocities [rad/s]."""
        return self._particles.omg[self._rank]

    @property
    def radii(self) -> np.ndarray:
        """(N,) radii [m]."""
        return self._particles.rad[self._rank]

    @property
    def masses(self) -> np.ndarray:
        """(N,) masses [kg]."""
        return self._particles.mass[self._rank]

    @property
    def forces(self) -> np.ndarray:
        """(N, 3) total force on each particle at the last evaluation [N] (gravity included)."""
        return self._particles.frc[self._rank]

    @property
    def wall_forces(self) -> np.ndarray:
        """(n_walls, 3) force exerted by the particles on each wall [N]."""
        return self._walls.force[: self._n_planes].copy()

    @property
    def wall_positions(self) -> np.ndarray:
        """(n_walls, 3) current point of each wall [m]."""
        return self._walls.point[: self._n_planes].copy()

    @property
    def wall_velocities(self) -> np.ndarray:
        """(n_walls, 3) wall velocities [m/s]."""
        return self._walls.vel[: self._n_planes].copy()

    @property
    def mesh_forces(self) -> np.ndarray:
        """(n_meshes, 3) force exerted by the particles on each mesh [N] (summed over chunks
        in a fixed order: the same for any thread count)."""
        return self._walls.force[self._n_planes :].copy()

    @property
    def mesh_displacements(self) -> np.ndarray:
        """(n_meshes, 3) translation of each mesh since the start [m] (its vertices are the
        scene's plus this)."""
        return self._walls.point[self._n_planes :].copy()

    @property
    def mesh_velocities(self) -> np.ndarray:
        """(n_meshes, 3) mesh velocities [m/s]."""
        return self._walls.vel[self._n_planes :].copy()

    @property
    def n_rebuilds(self) -> int:
        """Neighbour-list builds so far."""
        return self._n_rebuilds

    @property
    def n_renumbers(self) -> int:
        """Renumberings of the particles in cell order so far (see ``RENUMBER_STEPS``)."""
        return self._n_renumbers

    @property
    def n_neighbour_entries(self) -> int:
        """Pairs in the neighbour list."""
        return self._n_entries

    def kinetic_energy(self) -> float:
        """Translational plus rotational kinetic energy [J]. Velocities are those of the last
        whole step."""
        p = self._particles
        trans = 0.5 * float(np.sum(p.mass * np.sum(p.vel**2, axis=1)))
        w2 = np.sum(p.omg**2, axis=1)
        # driven particles (inverse inertia zero, see set_driven) do not spin
        rot = 0.5 * float(
            np.sum(np.divide(w2, p.inv_inertia, out=np.zeros_like(w2), where=p.inv_inertia > 0))
        )
        return trans + rot

    def memory_bytes(self) -> int:
        """Bytes held by the engine's state arrays (list buffers at their capacity)."""
        arrays = [v for v in vars(self).values() if isinstance(v, np.ndarray)]
        recs = (self._particles, self._list, self._walls, self._walls.mesh)
        for rec in (*recs, self._params, self._scratch):
            arrays += [v for v in rec if isinstance(v, np.ndarray)]
        return sum(a.nbytes for a in arrays)

    def n_contacts(self) -> int:
        """Number of particle-particle contacts at the last force evaluation (the count of
        :meth:`contacts`, without building its arrays)."""
        return int(np.count_nonzero(self._list.entry[: self._n_entries, 0]))

    def contact_counts(self) -> np.ndarray:
        """Particle-particle contacts of every particle at the last force evaluation, (N,)
        integers (the per-particle coordination number; wall contacts not counted)."""
        m = self._n_entries
        active = np.nonzero(self._list.entry[:m, 0] != 0.0)[0]
        owner = np.searchsorted(self._list.start, active, side="right") - 1
        j = self._list.j[active].astype(np.int64)
        counts = np.bincount(owner, minlength=self.n) + np.bincount(j, minlength=self.n)
        return counts[self._rank]

    def pair_stress(self, volume: float) -> np.ndarray:
        r"""The particle-particle contact part of the stress tensor in ``volume`` [m^3], at the
        last force evaluation [Pa]: the virial (Love-Weber) sum over contacts,
        :math:`\sigma_{ab} = \frac{1}{V} \sum_c f_a\, l_b`, with :math:`f` the force on one
        particle of a contact and :math:`l` the branch vector from the other's centre to
        its centre (nearest periodic image), so that compression is positive. Platen
        contacts, whose branch vectors are normal to the platens, and the (quasi-static:
        small) kinetic part are left out: in a periodic cell between two horizontal platens
        the horizontal components are the whole lateral stress."""
        sums = pair_virial(
            self._list.start,
            self._list.j,
            self._list.entry,
            self._k.F_SLOT,
            self._particles.pos,
            self._params.length,
            self._periodic,
            self._n_entries,
        )
        return sums / float(volume)

    def mesh_contacts(self) -> MeshContacts:
        """Particle-mesh contacts at the last force evaluation (:class:`MeshContacts`: one per
        touching face, edge or vertex; a particle's contacts beyond the ``MESH_SLOTS`` kept
        of engine.kernel.mesh, which keep no history, are not listed)."""
        w = self._walls
        k = self._k
        if not self.scene.meshes:
            none = np.zeros(0, dtype=np.int64)
            return MeshContacts(none, none.copy(), np.zeros(0), np.zeros((0, 3)))
        rows = w.mesh.mhist.reshape(self.n, k.MESH_ROWS, -1)[:, : k.MESH_SLOTS]
        tag = rows[:, :, k.MH_TAG]
        ii, ss = np.nonzero(tag > 0)
        mesh = tag[ii, ss].astype(np.int64) - 1
        points = rows[ii, ss, k.MH_POINT : k.MH_POINT + 3] + w.point[self._n_planes + mesh]
        ids = self._order[ii]
        srt = np.lexsort((mesh, ids))
        return MeshContacts(ids[srt], mesh[srt], rows[ii, ss, k.MH_OVERLAP][srt], points[srt])

    def contacts(self) -> Contacts:
        """Particle-particle and particle-wall contacts at the last force evaluation."""
        m = self._n_entries
        owner = np.repeat(np.arange(self.n), np.diff(self._list.start))
        active = np.nonzero(self._list.entry[:m, 0] != 0.0)[0]
        i = owner[active]
        j = self._list.j[active].astype(np.int64)
        pos, rad, length = self._particles.pos, self._particles.rad, self._params.length
        dx = pos[i] - pos[j]
        for a in range(3):
            if self._periodic[a]:
                dx[:, a] -= length[a] * np.floor(dx[:, a] / length[a] + 0.5)
        dist = np.sqrt(np.sum(dx**2, axis=1))
        f = self._k.F_SLOT
        forces = -self._list.entry[active, f : f + 3]
        wp, wi, wo = [], [], []
        for w in range(self._n_planes):
            d = rad - (pos - self._walls.point[w]) @ self._walls.normal[w]
            idx = np.nonzero(d > 0)[0]
            wp.append(idx)
            wi.append(np.full(idx.size, w))
            wo.append(d[idx])
        entry = self._list.entry
        springs = entry[active, 1:4] if self._k.N_HIST == 4 else np.zeros((active.size, 3))
        # scene ids, the smaller first (seen from it: force, normal and spring flip), sorted
        oi, oj = self._order[i], self._order[j]
        sign = np.where(oi < oj, 1.0, -1.0)[:, None]
        pairs = np.stack([np.minimum(oi, oj), np.maximum(oi, oj)], axis=1)
        # each pair once: sorting the one key first * N + second is the lexicographic sort
        # (an eighth of lexsort's time: contacts() is part of every curve sample)
        srt = np.argsort(pairs[:, 0] * self.n + pairs[:, 1])
        wparts = self._order[_concat(wp, np.int64)]
        wsrt = np.argsort(wparts * max(1, len(wp)) + _concat(wi, np.int64))
        return Contacts(
            pairs[srt],
            (rad[i] + rad[j] - dist)[srt],
            (sign * forces)[srt],
            (sign * dx / dist[:, None])[srt],
            entry[active, 0][srt],
            (sign * springs)[srt],
            wparts[wsrt],
            _concat(wi, np.int64)[wsrt],
            _concat(wo, np.float64)[wsrt],
        )
