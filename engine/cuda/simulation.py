"""The :class:`engine.Simulation` on an NVIDIA GPU (numba-cuda): ``Simulation(scene,
backend="cuda")`` returns a :class:`CudaSimulation`.

It is the CPU class with three things done on the device instead: the kernel calls of
:meth:`Simulation.run` (the same loop: bounded calls, rebuilds, pauses, instabilities), the
neighbour-list build (cell sort, counts, scans, the sorted half list with its history carried
over, the reverse list) and the force evaluation. The state lives on the device; the host
arrays of the CPU class are refreshed from it only when something reads them (an accessor,
:meth:`contacts`, a change between runs), per group (particles, walls, list). A change
between runs (``set_*``) is made by the CPU class on the refreshed host arrays and then sent
to the device whole. Inside :meth:`run` only the control record of a call (32 bytes) crosses:
after a batch of queued steps, and after a rebuild the entry count (8 bytes) to size the list.
A curve sample crosses only its numbers: the walls' rows (point, velocity, force), the sums
of :meth:`sample_sums` (:mod:`engine.cuda.measures`; also :meth:`kinetic_energy`,
:meth:`pair_stress`, :meth:`n_contacts`), a platen's new speed and the pour's speed cap; the
whole state is copied for checkpoints, snapshots and explicit reads (positions, contacts).
Every launch and copy goes on the simulation's CUDA stream (:meth:`set_stream`, or the
thread's, :mod:`engine.cuda.batch`), so that several simulations run side by side on a card.

Same trajectory as the CPU engine up to rounding order: the per-particle work is the CPU's own
code (:mod:`engine.cuda.device`), gathered in the CPU's order; the only sums in another order
are the wall forces over chunks (a fixed tree): run twice on one card, bit-identical.
"""

from __future__ import annotations

import logging
import math
import os
import threading
from types import SimpleNamespace

import numpy as np
from numba import cuda

from ..kernel.mesh import MESH_CONTACTS, SCRATCH_WIDTH
from ..kernel.state import OK, PAUSE, Meshes, NeighbourList, Particles, StepParams, Walls
from ..simulation.parking import ParkingLattice, park_args
from ..simulation.simulation import Simulation
from . import _sources as src
from .batch import current_stream
from .device import SIMULATOR
from .kernels import RED_T, SCAN_SEG, SCAN_T, THREADS, search_kernels, step_kernels
from .measures import NV, SampleSums, sums_from
from .measures import kernels as measure_kernels

#: First and largest number of steps queued before the control record is read.
_FIRST_BATCH = 16
_MAX_BATCH = 256
_GROUPS = ("particles", "walls", "list")
#: Most steps of one launch of the cooperative kernel (the control record is read between)
_STEPS_PER_LAUNCH = 1024
_ON_DEVICE = """

        On the CUDA backend summed on the device (engine.cuda.measures, a fixed order): the
        host's sum of the same state to round-off, no state copied."""
#: numba-cuda's simulator runs one kernel at a time in a process (see CudaSimulation._go)
_SIMULATOR_LOCK = threading.Lock()
log = logging.getLogger("engine.cuda")


def _blocks(count: int, threads: int = THREADS) -> int:
    return max(1, -(-int(count) // threads))


class CudaSimulation(Simulation):
    """A :class:`engine.Simulation` whose state and kernels are on the GPU (see the module
    docstring); made by ``Simulation(..., backend="cuda")``. Same arguments and methods."""

    backend = "cuda"
    _dev: SimpleNamespace | None = None
    _dk: SimpleNamespace | None = None
    _dirty = False  # host arrays changed by a set_* method: send them before device work
    _stream = None  # the CUDA stream set by set_stream (None: see _init_device)

    # ------------------------------------------------------------------ streams
    def _to(self, host: np.ndarray):
        """A device copy of ``host``, sent on this simulation's stream."""
        return cuda.to_device(host, stream=self._dev.stream)

    def _go(self, kern, grid: int, block: int):
        """``kern`` configured for ``grid`` blocks of ``block`` threads on this simulation's
        stream. The simulator runs one kernel at a time (numba-cuda's, process-wide): there a
        launch takes a lock, so that simulations stepped together from several threads
        (:mod:`engine.cuda.batch`) take turns per launch."""
        stream = self._dev.stream
        if not SIMULATOR:
            return kern[grid, block, stream]

        def launch(*args):
            with _SIMULATOR_LOCK:
                kern[grid, block, stream](*args)

        return launch

    @property
    def stream(self):
        """The CUDA stream this simulation's kernels and copies run on."""
        self._ensure_device()
        return self._dev.stream

    def set_stream(self, stream) -> None:
        """Run this simulation's kernels and copies on ``stream`` (a ``numba.cuda`` stream)
        from now on, after the work queued on its current one has finished. Simulations on
        separate streams run side by side on one device (:mod:`engine.cuda.batch`); the
        results do not depend on the stream."""
        if self._dev is not None:
            self._dev.stream.synchronize()
            self._dev.stream = stream
        self._stream = stream

    @property
    def pull_counts(self) -> dict[str, int]:
        """How many times each group of the state (``particles``, ``walls``, ``list``) was
        copied whole to the host since the state was sent to the device."""
        return dict(self._dev.pulls) if self._dev is not None else {}

    # ------------------------------------------------------------------ device state
    def _load(self, features: dict[str, bool]) -> None:
        super()._load(features)
        self._dk = step_kernels(self._features)  # the kernel's features (DEMSCALE_KERNELS)
        if self._dev is not None:  # new kernels (set_periodic): choose their launch again
            self._dev.persistent = None
            self._dev.steps_launch = None

    def _ensure_device(self) -> None:
        if self._dk is None:
            self._dk = step_kernels(self._features)
        if self._dev is None:
            self._init_device()
        elif self._dirty:
            self._push_all()
        self._dirty = False

    def _init_device(self) -> None:
        n = self.n
        k = self._k
        p = self._particles
        nw = len(self._walls.point)
        nchunk = -(-n // k.CHUNK)
        maxc = 4 * n + 64  # the CPU build's bound on cells
        d = SimpleNamespace()
        d.stale = set()
        d.pulls = {}
        # the stream of this simulation's launches and copies: the one set_stream gave, or
        # that of the thread that first sends the state (engine.cuda.batch), or the default
        stream = self._stream if self._stream is not None else current_stream()
        d.stream = stream if stream is not None else cuda.default_stream()
        self._dev = d
        d.ctl = self._to(np.zeros(4, dtype=np.int64))
        d.ctl_host = np.zeros(4, dtype=np.int64)
        d.info = self._to(np.zeros(3))
        d.stat = self._to(np.zeros((n, 4)))
        d.wpart = self._to(np.zeros((n, nw, 3)))
        d.cstat = self._to(np.zeros((nchunk, 4)))
        d.cdisp = self._to(np.zeros(nchunk))
        d.disp = self._to(np.zeros(n))
        d.maxc = maxc
        d.cut = 2.0 * float(p.rad.max()) + self.skin
        d.bounds = self._to(np.zeros((3, 2)))
        d.grid = self._to(np.zeros((2, 3)))
        d.ncell = self._to(np.ones(3, dtype=np.int64))
        d.cell3 = self._to(np.zeros((n, 3), dtype=np.int64))
        d.key = self._to(np.zeros(n, dtype=np.int64))
        d.cell_count = self._to(np.zeros(maxc, dtype=np.int64))
        d.cell_start = self._to(np.zeros(maxc + 1, dtype=np.int64))
        d.cell_fill = self._to(np.zeros(maxc, dtype=np.int64))
        d.cell_list = self._to(np.zeros(n, dtype=np.int64))
        d.cnt = self._to(np.zeros(n, dtype=np.int64))
        d.new_start = self._to(np.zeros(n + 1, dtype=np.int64))
        d.rev_count = self._to(np.zeros(n, dtype=np.int64))
        d.rev_fill = self._to(np.zeros(n, dtype=np.int64))
        d.none = self._to(np.zeros(0, dtype=np.int32))
        # meshes: the scratch of each particle's contacts (a row per particle, as the
        # particle pass runs one thread per particle), the counts of a candidate build and
        # the bin grids (made once, never changed)
        nm = len(self.scene.meshes)
        d.mscr = self._to(np.zeros((n if nm else 0, MESH_CONTACTS, SCRATCH_WIDTH)))
        d.mcnt = self._to(np.zeros(n, dtype=np.int64))
        d.mgrid = tuple(
            self._to(self._mesh_arrays[k]) for k in ("gridf", "gridi", "cell_start", "cell_tri")
        )
        d.total_host = np.zeros(1, dtype=np.int64)
        d.scan_bufs = {}
        d.batch = _FIRST_BATCH
        d.persistent = None  # decided at the first call (_choose_launch)
        d.steps_launch = None  # the steps kernel specialised to the state's types
        d.measure = None  # the measure kernels' buffers (sample_sums)
        try:
            self._push_all()
        except BaseException:
            self._dev = None
            raise

    def _push_all(self) -> None:
        """Send every host array to the device (after construction or a set_* change)."""
        d = self._dev
        p = self._particles
        d.P = Particles(*(self._to(np.ascontiguousarray(a)) for a in p))
        w = self._walls
        cacc = np.zeros((len(d.cdisp), len(w.point), 3))
        d.W = Walls(
            point=self._to(w.point),
            normal=self._to(w.normal),
            vel=self._to(w.vel),
            hist=self._to(w.hist),
            force=self._to(w.force),
            acc=self._to(cacc),
            mesh=self._device_meshes(),
        )
        prm = self._params
        d.prm = StepParams(
            pair=self._to(prm.pair),
            wall=self._to(prm.wall),
            gravity=self._to(prm.gravity),
            length=self._to(prm.length),
            dt=float(prm.dt),
            skin=float(prm.skin),
            max_overlap=float(prm.max_overlap),
            max_step=float(prm.max_step),
        )
        d.lo = self._to(self._lo)
        d.periodic = self._to(self._periodic.astype(np.bool_))
        d.images = self._to(self._images)
        lst = self._list
        cap = max(16, len(lst.j))
        j = np.zeros(cap, dtype=np.int32)
        entry = np.zeros((cap, self._k.N_SLOT))
        rev_k = np.zeros(cap, dtype=np.int32)
        m = len(lst.j)
        j[:m] = lst.j
        entry[:m] = lst.entry[:, : self._k.N_SLOT]
        rev_k[:m] = lst.rev_k
        d.L = NeighbourList(
            start=self._to(lst.start),
            j=self._to(j),
            entry=self._to(entry),
            rev_start=self._to(lst.rev_start),
            rev_k=self._to(rev_k),
        )
        d.new_j = self._to(np.zeros(cap, dtype=np.int32))
        d.new_entry = self._to(np.zeros((cap, self._k.N_SLOT)))
        d.stale = set()

    def _device_meshes(self) -> Meshes:
        """The meshes' arrays on the device: always a record of arrays (empty without
        meshes, where the kernels never read them; the CPU passes an empty tuple)."""
        m = self._walls.mesh
        if not isinstance(m, Meshes):
            n = self.n
            m = Meshes(
                mvert=np.zeros((0, 3)),
                mtri=np.zeros((0, 8), dtype=np.int64),
                mtri_n=np.zeros((0, 3)),
                medge=np.zeros((0, 6), dtype=np.int64),
                mvert_start=np.zeros(1, dtype=np.int64),
                mvert_edge=np.zeros(0, dtype=np.int64),
                cand_start=np.zeros(n + 1, dtype=np.int64),
                cand_t=np.zeros(0, dtype=np.int32),
                mhist=np.zeros((0, self._k.N_MESH_HIST)),
                mscr=np.zeros((0, MESH_CONTACTS, SCRATCH_WIDTH)),
                mshift0=np.zeros((0, 3)),
                box=np.zeros((2, 3)),
            )
        arrays = {k: self._to(v) for k, v in m._asdict().items() if k != "mscr"}
        if not len(m.cand_t):
            arrays["cand_t"] = self._to(np.zeros(1, dtype=np.int32))
        return Meshes(mscr=self._dev.mscr, **arrays)

    def _pull(self, *groups: str) -> None:
        """Refresh the host arrays of ``groups`` from the device where the device is newer."""
        d = self._dev
        if d is None:
            return
        for g in groups:
            if g not in d.stale:
                continue
            if g == "particles":
                for host, dev in zip(self._particles, d.P):
                    dev.copy_to_host(host, stream=d.stream)
                d.images.copy_to_host(self._images, stream=d.stream)
                d.stale.discard("radii")  # copied with the rest
            elif g == "radii":
                d.P.rad.copy_to_host(self._particles.rad, stream=d.stream)
            elif g == "walls":
                w = self._walls
                for name in ("point", "vel", "hist", "force"):
                    getattr(d.W, name).copy_to_host(getattr(w, name), stream=d.stream)
                if isinstance(w.mesh, Meshes):
                    dm = d.W.mesh
                    for name in ("cand_start", "mhist", "mshift0"):
                        getattr(dm, name).copy_to_host(getattr(w.mesh, name), stream=d.stream)
                    mesh = w.mesh._replace(cand_t=dm.cand_t.copy_to_host(stream=d.stream))
                    self._walls = w._replace(mesh=mesh)
            else:
                self._list = NeighbourList(*(a.copy_to_host(stream=d.stream) for a in d.L))
            d.stale.discard(g)
            if g == "walls":
                d.stale.discard("wall_rows")
            d.pulls[g] = d.pulls.get(g, 0) + 1
        d.stream.synchronize()

    def _pull_wall_rows(self) -> None:
        """Refresh the walls' points, velocities and forces on the host (a few numbers a
        wall; the walls' contact histories stay on the device): what a curve sample reads
        of the walls."""
        d = self._dev
        if d is None or "wall_rows" not in d.stale or "walls" not in d.stale:
            return
        w = self._walls
        for name in ("point", "vel", "force"):
            getattr(d.W, name).copy_to_host(getattr(w, name), stream=d.stream)
        d.stream.synchronize()
        d.stale.discard("wall_rows")

    def sample_sums(self, bottom: float, top: float, lo: float, hi: float) -> SampleSums:
        """The sums a uniaxial curve sample reads (:class:`engine.cuda.measures.SampleSums`),
        computed on the device at the last force evaluation: only their :data:`NV` numbers
        cross to the host. ``bottom`` and ``top`` [m]: the heights of the bottom and top
        platens (``inf`` without a top one); [``lo``, ``hi``] [m]: the interior window of
        centre heights above ``bottom``. Deterministic (fixed-order sums); equal to the
        host's measures of the same state to round-off."""
        self._ensure_device()
        d = self._dev
        mk = measure_kernels()
        n = self.n
        nchunk = len(d.cdisp)
        m = self._measure_buffers()
        P, L = d.P, d.L
        self._go(mk.rows, _blocks(n), THREADS)(
            P.pos,
            P.vel,
            P.omg,
            P.rad,
            P.mass,
            P.inv_inertia,
            L.start,
            L.j,
            L.entry,
            L.rev_start,
            L.rev_k,
            int(self._n_entries),
            int(self._k.F_SLOT),
            d.prm.length,
            d.periodic,
            float(bottom),
            float(top),
            float(lo),
            float(hi),
            m.rows,
        )
        self._go(mk.chunk, _blocks(nchunk * NV), THREADS)(m.rows, m.csum)
        self._go(mk.final, NV, RED_T)(m.csum, m.out)
        m.out.copy_to_host(m.host, stream=d.stream)
        d.stream.synchronize()
        return sums_from(m.host)

    def _sums(self) -> SampleSums:
        """:meth:`sample_sums` without platens or window (the state's own sums)."""
        return self.sample_sums(-math.inf, math.inf, 0.0, -1.0)

    def kinetic_energy(self) -> float:
        s = self._sums()
        return 0.5 * s.trans + 0.5 * s.rot

    def pair_stress(self, volume: float) -> np.ndarray:
        return self._sums().virial / float(volume)

    def n_contacts(self) -> int:
        return round(self._sums().counts) // 2

    kinetic_energy.__doc__ = (Simulation.kinetic_energy.__doc__ or "") + _ON_DEVICE
    pair_stress.__doc__ = (Simulation.pair_stress.__doc__ or "") + _ON_DEVICE
    n_contacts.__doc__ = (Simulation.n_contacts.__doc__ or "") + _ON_DEVICE

    def cap_speed(self, cap: float) -> bool:
        """Scale down the velocity of every particle faster than ``cap`` [m/s] to ``cap``
        on the device, then (where any was) evaluate the forces again, as
        ``set_velocities`` does: a capped pour's fill without copying the state (one
        8-byte flag crosses). Returns whether any particle was capped."""
        self._ensure_device()
        d = self._dev
        m = self._measure_buffers()
        m.flag.copy_to_device(m.flag_zero, stream=d.stream)
        self._go(measure_kernels().cap, _blocks(self.n), THREADS)(d.P.vel, float(cap), m.flag)
        m.flag.copy_to_host(m.flag_host, stream=d.stream)
        d.stream.synchronize()
        d.stale.add("particles")
        if not m.flag_host[0]:
            return False
        self._compute_forces()
        return True

    def park_below(self, height: float, lattice: ParkingLattice) -> None:
        h = park_args(height, lattice)
        self._check_parking(lattice)
        self._ensure_device()
        d = self._dev
        if getattr(d, "order", None) is None:  # the particles keep their order on the device
            d.order = self._to(self._order.astype(np.int64))
        if getattr(d, "park_lattice", None) != lattice:
            d.park_o = self._to(np.asarray(lattice.origin))
            d.park_a = self._to(np.asarray(lattice.spacing))
            d.park_lattice = lattice
        P = d.P
        self._go(measure_kernels().park, _blocks(self.n), THREADS)(
            P.pos,
            P.vel,
            P.omg,
            P.rad,
            P.inv_mass,
            P.inv_inertia,
            P.pos_build,
            d.images,
            d.L.start,
            d.L.entry,
            d.L.rev_start,
            d.L.rev_k,
            d.W.hist,
            self._n_planes,
            d.W.mesh.mhist,
            d.W.mesh.mhist.shape[0] // self.n,
            d.order,
            h,
            d.park_o,
            d.park_a,
            lattice.nx,
            lattice.ny,
        )
        d.stale.update(("particles", "radii", "list", "walls"))

    park_below.__doc__ = Simulation.park_below.__doc__

    def _measure_buffers(self) -> SimpleNamespace:
        d = self._dev
        if d.measure is None:
            d.measure = SimpleNamespace(
                rows=self._to(np.zeros((self.n, NV))),
                csum=self._to(np.zeros((len(d.cdisp), NV))),
                out=self._to(np.zeros(NV)),
                host=np.zeros(NV),
                flag=self._to(np.zeros(1, dtype=np.int64)),
                flag_zero=np.zeros(1, dtype=np.int64),
                flag_host=np.zeros(1, dtype=np.int64),
            )
        return d.measure

    def _pull_all(self) -> None:
        self._pull(*_GROUPS)

    def _host_edit(self, method, *args):
        """A set_* change: made by the CPU class on fresh host arrays, then sent whole."""
        self._pull_all()
        self._dirty = True
        try:
            return method(self, *args)
        finally:
            if self._dirty and self._dev is not None:
                self._push_all()
            self._dirty = False

    # ------------------------------------------------------------------ kernel calls
    def _call(self, nsteps: int, phase: int = 0) -> tuple[int, int]:
        return self._call_kernel(nsteps, phase, 1)

    def _read_ctl(self) -> np.ndarray:
        d = self._dev
        d.ctl.copy_to_host(d.ctl_host, stream=d.stream)
        d.stream.synchronize()
        return d.ctl_host

    def _call_kernel(self, nsteps: int, phase: int, team: int) -> tuple[int, int]:
        self._ensure_device()
        d, dk = self._dev, self._dk
        mod = dk.cpu
        n = self.n
        nchunk = len(d.cdisp)
        pair = self._go(dk.pair_kernel, _blocks(n), THREADS)
        particle = self._go(dk.particle_kernel, _blocks(n), THREADS)
        chunk = self._go(dk.chunk_kernel, _blocks(nchunk), THREADS)
        finish = self._go(dk.finish_kernel, 1, RED_T)
        P, L, W, prm = d.P, d.L, d.W, d.prm
        # entries hold the contact history and the stored forces
        d.stale.update((*_GROUPS, "wall_rows"))
        self._go(dk.reset_ctl, 1, 1)(d.ctl)
        if d.persistent is None:
            self._choose_launch()
        if d.persistent:
            return self._call_persistent(nsteps, phase)

        def step(s: int, mode: int) -> None:
            pair(d.ctl, P, L, prm, d.stat)
            particle(d.ctl, mode, P, L, W, prm, d.stat, d.wpart, d.disp)
            chunk(d.ctl, mode, d.stat, d.wpart, d.disp, d.cstat, d.cdisp, W.acc, W, prm.dt)
            finish(d.ctl, s, nsteps, 0, W, prm, d.cstat, d.cdisp, W.acc, d.info)

        if nsteps == 0:
            step(0, mod.FORCES)
            ctl = self._read_ctl()
        else:
            if phase == 0:
                particle(d.ctl, mod.OPEN, P, L, W, prm, d.stat, d.wpart, d.disp)
                chunk(d.ctl, mod.OPEN, d.stat, d.wpart, d.disp, d.cstat, d.cdisp, W.acc, W, prm.dt)
                finish(d.ctl, 0, nsteps, 1, W, prm, d.cstat, d.cdisp, W.acc, d.info)
            todo = min(int(nsteps), int(self._pause))
            s = 0
            ctl = None
            while s < todo:
                end = min(todo, s + d.batch)
                while s < end:
                    step(s, mod.STEP if s < nsteps - 1 else mod.CLOSE)
                    s += 1
                ctl = self._read_ctl()
                if ctl[src.CTL_STOP]:
                    break
                d.batch = min(2 * d.batch, _MAX_BATCH)
            if ctl is None:
                ctl = self._read_ctl()
        return self._outcome(ctl)

    def _outcome(self, ctl) -> tuple[int, int]:
        d = self._dev
        mod = self._dk.cpu
        if not ctl[src.CTL_STOP]:
            return int(ctl[src.CTL_STEPS]), PAUSE
        steps, status = int(ctl[src.CTL_STEPS]), int(ctl[src.CTL_STATUS])
        if status != OK and status != mod.REBUILD:
            d.info.copy_to_host(self._scratch.info, stream=d.stream)
            d.stream.synchronize()
        if status == mod.REBUILD:
            # queue about half the steps a list lasted, so that few queued steps are idle
            d.batch = max(4, min(_MAX_BATCH, steps // 2))
        return steps, status

    def _steps_args(self) -> tuple:
        d = self._dev
        return (d.P, d.L, d.W, d.prm, d.stat, d.wpart, d.disp, d.cstat, d.cdisp, d.W.acc, d.info)

    def _choose_launch(self) -> None:
        """One launch per batch of steps (cooperative grid, ``steps_kernel``) unless
        ``DEMSCALE_CUDA_LAUNCH=passes`` or the device cannot run it: then four launches a
        step. The grid: as many resident blocks of ``RED_T`` threads as the particles fill,
        at most what the device keeps resident at once (a grid barrier needs all)."""
        d = self._dev
        d.persistent = os.environ.get("DEMSCALE_CUDA_LAUNCH", "persistent") != "passes"
        if not d.persistent:
            return
        want = _blocks(self.n, RED_T)
        if SIMULATOR:
            d.coop_blocks = 1  # the simulator runs cooperative grids of one block
            return
        try:
            args = (d.ctl, 0, 1, 1, 0, *self._steps_args())
            spec = self._dk.steps_kernel.specialize(*args)
            kern = next(iter(spec.overloads.values()))
            d.coop_blocks = max(1, min(want, int(kern.max_cooperative_grid_blocks(RED_T))))
            d.steps_launch = spec
        except Exception as e:  # no cooperative launch here: the four-launch step
            log.warning(
                "CUDA: cooperative launch unavailable (%s: %s), one launch per pass",
                type(e).__name__,
                e,
            )
            d.persistent = False

    def _call_persistent(self, nsteps: int, phase: int) -> tuple[int, int]:
        d = self._dev
        kernel = d.steps_launch or self._dk.steps_kernel
        launch = self._go(kernel, d.coop_blocks, RED_T)
        tail = self._steps_args()
        if nsteps == 0:
            launch(d.ctl, 0, 1, 0, 0, *tail)
            return self._outcome(self._read_ctl())
        todo = min(int(nsteps), int(self._pause))
        s = 0
        opening = 1 if phase == 0 else 0
        ctl = None
        while s < todo or opening:
            end = min(todo, s + _STEPS_PER_LAUNCH)
            launch(d.ctl, s, end, int(nsteps), opening, *tail)
            opening = 0
            s = end
            ctl = self._read_ctl()
            if ctl[src.CTL_STOP]:
                break
        return self._outcome(ctl)

    # ------------------------------------------------------------------ neighbour list
    def _scan(self, src_arr, n: int, dst) -> None:
        """Exclusive prefix sum: ``dst[0] = 0``, ``dst[k + 1] = sum(src[:k + 1])`` (int64)."""
        d = self._dev
        sk = search_kernels()
        per = SCAN_T * SCAN_SEG
        nb = max(1, -(-int(n) // per))
        bufs = d.scan_bufs.get(n)
        if bufs is None:
            bufs = d.scan_bufs[n] = (
                self._to(np.zeros(nb, dtype=np.int64)),
                self._to(np.zeros(nb + 1, dtype=np.int64)),
            )
        sums, offs = bufs
        self._go(sk.scan_block_kernel, nb, SCAN_T)(src_arr, n, dst, sums)
        if nb > 1:
            self._scan(sums, nb, offs)
            self._go(sk.scan_add_kernel, _blocks(n), THREADS)(n, dst, offs)

    def _rebuild(self) -> None:
        self._ensure_device()
        d = self._dev
        sk = search_kernels()
        n = self.n
        P, L = d.P, d.L
        nb = _blocks(n)
        if self._periodic.any():
            self._go(sk.wrap_kernel, nb, THREADS)(P.pos, d.lo, d.prm.length, d.periodic, d.images)
        if not self._periodic.all():
            self._go(sk.bounds_kernel, 1, RED_T)(P.pos, d.bounds)
        self._go(sk.grid_kernel, 1, 1)(
            d.bounds, d.lo, d.prm.length, d.periodic, d.cut, d.maxc, d.grid, d.ncell
        )
        self._go(sk.zero_kernel, _blocks(d.maxc), THREADS)(d.cell_count)
        self._go(sk.zero_kernel, _blocks(d.maxc), THREADS)(d.cell_fill)
        self._go(sk.cell_kernel, nb, THREADS)(P.pos, d.grid, d.ncell, d.cell3, d.key, d.cell_count)
        self._scan(d.cell_count, d.maxc, d.cell_start)
        self._go(sk.cell_fill_kernel, nb, THREADS)(d.key, d.cell_start, d.cell_fill, d.cell_list)
        args = (
            P.pos,
            P.rad,
            float(self.skin),
            d.cell3,
            d.ncell,
            d.cell_start,
            d.cell_list,
            d.periodic,
            d.prm.length,
        )
        self._go(sk.count_kernel, nb, THREADS)(*args, d.cnt, d.none)
        self._scan(d.cnt, n, d.new_start)
        # the one read of a build: its size
        d.new_start[n:].copy_to_host(d.total_host, stream=d.stream)
        d.stream.synchronize()
        total = int(d.total_host[0])
        cap = len(d.new_j)
        if total > cap:
            cap = int(total * 1.25) + 16
            d.new_j = self._to(np.zeros(cap, dtype=np.int32))
            d.new_entry = self._to(np.zeros((cap, self._k.N_SLOT)))
        self._go(sk.list_kernel, nb, THREADS)(
            *args, d.new_start, d.new_j, d.new_entry, L.start, L.j, L.entry, self._k.N_HIST
        )
        if cap > len(L.j):
            L = d.L = L._replace(
                j=self._to(np.zeros(cap, dtype=np.int32)),
                entry=self._to(np.zeros((cap, self._k.N_SLOT))),
                rev_k=self._to(np.zeros(cap, dtype=np.int32)),
            )
        self._go(sk.zero_kernel, nb, THREADS)(d.rev_count)
        self._go(sk.zero_kernel, nb, THREADS)(d.rev_fill)
        self._go(sk.commit_kernel, _blocks(max(total, n + 1)), THREADS)(
            total, d.new_start, d.new_j, d.new_entry, L.start, L.j, L.entry, d.rev_count
        )
        self._scan(d.rev_count, n, L.rev_start)
        self._go(sk.rev_fill_kernel, _blocks(max(total, 1)), THREADS)(
            total, L.j, L.rev_start, d.rev_fill, L.rev_k
        )
        self._go(sk.rev_sort_kernel, nb, THREADS)(L.rev_start, L.rev_k, P.pos, P.pos_build)
        if self.scene.meshes:
            self._mesh_rebuild()
        d.stale.update((*_GROUPS, "wall_rows"))
        self._n_entries = total
        self._n_rebuilds += 1

    def _mesh_rebuild(self) -> None:
        """Each particle's candidate triangles on the device (counts, scan, one 8-byte read of
        the total, fill: the CPU build's lists), the rows of particles without any cleared,
        the meshes' translations at this build kept."""
        d = self._dev
        sk = search_kernels()
        n = self.n
        nb = _blocks(n)
        W = d.W
        m = W.mesh
        args = (d.P.pos, d.P.rad, float(self.skin), W.point, self._n_planes, m.mvert, m.mtri)
        args += d.mgrid
        self._go(sk.mesh_count_kernel, nb, THREADS)(*args, d.mcnt, d.none)
        self._scan(d.mcnt, n, m.cand_start)
        m.cand_start[n:].copy_to_host(d.total_host, stream=d.stream)
        d.stream.synchronize()
        total = int(d.total_host[0])
        if total > len(m.cand_t):
            m = m._replace(cand_t=self._to(np.zeros(int(total * 1.25) + 16, np.int32)))
            d.W = W._replace(mesh=m)
        self._go(sk.mesh_fill_kernel, nb, THREADS)(*args, m.cand_start, m.cand_t)
        self._go(sk.mesh_clear_kernel, nb, THREADS)(m.cand_start, m.mhist)
        self._go(sk.mesh_shift_kernel, 1, 1)(W.point, self._n_planes, m.mshift0)

    # ------------------------------------------------------------------ host side
    def set_wall_velocity(self, index: int, velocity) -> None:
        # a curve sample's platen speed (every sample at an inertial number): the walls'
        # rows are refreshed and the velocities sent back, the rest stays on the device
        if self._dev is None or self._dirty:
            return self._host_edit(Simulation.set_wall_velocity, index, velocity)
        self._pull_wall_rows()
        Simulation.set_wall_velocity(self, index, velocity)
        d = self._dev
        d.W.vel.copy_to_device(self._walls.vel, stream=d.stream)
        d.stream.synchronize()
        return None

    def set_wall_position(self, index: int, point) -> None:
        return self._host_edit(Simulation.set_wall_position, index, point)

    def set_velocities(self, velocities=None, angular_velocities=None) -> None:
        return self._host_edit(Simulation.set_velocities, velocities, angular_velocities)

    def set_mesh_velocity(self, index: int, velocity) -> None:
        return self._host_edit(Simulation.set_mesh_velocity, index, velocity)

    def set_gravity(self, gravity) -> None:
        return self._host_edit(Simulation.set_gravity, gravity)

    def set_positions(self, positions) -> None:
        return self._host_edit(Simulation.set_positions, positions)

    def set_periodic(self, periodic) -> None:
        return self._host_edit(Simulation.set_periodic, periodic)

    def __getstate__(self):
        self._pull_all()
        base = getattr(super(), "__getstate__", None)
        state = base() if base is not None else self.__dict__.copy()
        if isinstance(state, dict):
            drop = ("_dev", "_dk", "_dirty", "_stream")
            state = {k: v for k, v in state.items() if k not in drop}
        return state

    def __setstate__(self, state) -> None:
        base = getattr(super(), "__setstate__", None)
        if base is not None:
            base(state)
        else:
            self.__dict__.update(state)
        self._dev = None  # sent to the device again at the next device call
        self._dk = None
        self._stream = None


def _pulling_property(name: str, *groups: str) -> property:
    prop = getattr(Simulation, name)

    def get(self):
        self._pull(*groups)
        return prop.fget(self)

    return property(get, doc=prop.__doc__)


def _pulling_method(name: str, *groups: str):
    method = getattr(Simulation, name)

    def call(self, *args, **kwargs):
        self._pull(*groups)
        return method(self, *args, **kwargs)

    call.__name__ = name
    call.__doc__ = method.__doc__
    return call


for _name in (
    "positions",
    "unwrapped_positions",
    "velocities",
    "angular_velocities",
    "forces",
):
    setattr(CudaSimulation, _name, _pulling_property(_name, "particles"))


# the radii change on the device only when particles are parked (park_below, which marks
# the group "radii" stale): a sample that reads them (the uniaxial recorder) copies nothing
# otherwise
CudaSimulation.radii = _pulling_property("radii", "radii")


def _wall_row_property(name: str) -> property:
    prop = getattr(Simulation, name)

    def get(self):
        self._pull_wall_rows()
        return prop.fget(self)

    return property(get, doc=prop.__doc__)


for _name in (
    "wall_forces",
    "wall_positions",
    "wall_velocities",
    "mesh_forces",
    "mesh_displacements",
    "mesh_velocities",
):
    setattr(CudaSimulation, _name, _wall_row_property(_name))
for _name in ("contact_counts", "contacts", "memory_bytes"):
    setattr(CudaSimulation, _name, _pulling_method(_name, *_GROUPS))
# the mesh contacts live in the walls' rows alone: a hopper's sample of its wall stress copies
# neither the particles nor the pair list (the largest of the state's arrays)
CudaSimulation.mesh_contacts = _pulling_method("mesh_contacts", "walls")
del _name
