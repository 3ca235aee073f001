"""Particle snapshots ParaView opens: the particles and the contact network (force chains) at
the end of every stage of a uniaxial test, and optionally every given interval of simulated
time, as temporal VTKHDF files; and a PNG section through the middle of the sample.

Per run directory (docs/SNAPSHOTS.md)::

    particles.vtkhdf   PolyData, one vertex per particle; point data: radius [m],
                       velocity [m/s], angular_velocity [rad/s], contact_count [-],
                       mean_normal_force [N], pressure [Pa], id [-]
    contacts.vtkhdf    PolyData, one line per particle-particle contact (from the first
                       particle's centre to the second's nearest periodic image); cell data:
                       normal_force [N] (> 0 compressive, < 0 adhesive), particle_i, particle_j
    <stage>.png        section through the middle of the sample at the stage's end

Each file holds every snapshot of the run as one time step (``/VTKHDF/Steps``): ParaView
plays the run as an animation. Snapshots are appended to resizable, chunked datasets, so a
run's snapshots are written as they come and never held in memory together.

:class:`Snapshot` and :func:`capture` need only numpy. h5py (the files) and matplotlib (the
PNG views) are imported when something is written: ``pip install "demscale[snapshots]"``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = [
    "FIELD_UNITS",
    "VTKHDF_VERSION",
    "Snapshot",
    "SnapshotWriter",
    "capture",
    "particle_fields",
    "save",
    "save_study",
    "section_figure",
]

#: VTKHDF format version written: 2.0 is the first with PolyData and time steps
#: (VTK 9.3, ParaView 5.12) and every later 2.x reader reads it.
VTKHDF_VERSION = (2, 0)

#: Units of the arrays of the snapshot files.
FIELD_UNITS = {
    "radius": "m",
    "velocity": "m/s",
    "angular_velocity": "rad/s",
    "contact_count": "1",
    "mean_normal_force": "N",
    "pressure": "Pa",
    "id": "1",
    "normal_force": "N",
    "particle_i": "1",
    "particle_j": "1",
}

_TOPOLOGIES = ("Vertices", "Lines", "Polygons", "Strips")


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
    )


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
        "pressure": moment / (3.0 * volume),
    }


def _h5py():
    try:
        import h5py
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError('snapshot files need h5py: pip install "demscale[snapshots]"') from e
    return h5py


class _TemporalPolyData:
    """One temporal VTKHDF PolyData file, one part per time step, appended step by step."""

    def __init__(self, path: Path):
        h5py = _h5py()
        self.path = Path(path)
        self.file = h5py.File(self.path, "w")
        root = self.file.create_group("VTKHDF")
        root.attrs["Version"] = np.array(VTKHDF_VERSION, dtype=np.int64)
        root.attrs.create("Type", b"PolyData", dtype=h5py.string_dtype("ascii", 8))
        self.root = root
        steps = root.create_group("Steps")
        steps.attrs["NSteps"] = np.int64(0)
        self.steps = steps
        for g in ("PointData", "CellData", "FieldData"):
            root.create_group(g)
        steps.create_group("PointDataOffsets")
        steps.create_group("CellDataOffsets")
        self.points = 0
        self.cells = dict.fromkeys(_TOPOLOGIES, 0)
        self.ids = dict.fromkeys(_TOPOLOGIES, 0)
        self.n = 0

    def _append(self, group, name: str, data) -> None:
        data = np.asarray(data)
        if name not in group:
            compress = {"compression": "gzip", "shuffle": True} if data.dtype.kind == "f" else {}
            group.create_dataset(
                name,
                data=data,
                maxshape=(None, *data.shape[1:]),
                chunks=(max(1, min(65536, len(data))), *data.shape[1:]) if len(data) else True,
                **compress,
            )
            return
        ds = group[name]
        start = ds.shape[0]
        ds.resize(start + len(data), axis=0)
        ds[start:] = data

    def add(
        self,
        time: float,
        points: np.ndarray,
        cells: dict[str, np.ndarray],
        point_data: dict[str, np.ndarray],
        cell_data: dict[str, np.ndarray],
    ) -> None:
        """Append one time step: ``points`` (P, 3), ``cells`` topology -> (C, k) point ids
        (k = 1 for vertices, 2 for lines), data arrays with one row per point or cell."""
        r, s = self.root, self.steps
        npts = len(points)
        self._append(s, "Values", [float(time)])
        self._append(s, "PartOffsets", np.array([self.n], dtype=np.int64))
        self._append(s, "NumberOfParts", np.array([1], dtype=np.int64))
        self._append(s, "PointOffsets", np.array([self.points], dtype=np.int64))
        self._append(
            s, "CellOffsets", np.array([[self.cells[t] for t in _TOPOLOGIES]], dtype=np.int64)
        )
        self._append(
            s,
            "ConnectivityIdOffsets",
            np.array([[self.ids[t] for t in _TOPOLOGIES]], dtype=np.int64),
        )
        self._append(r, "NumberOfPoints", np.array([npts], dtype=np.int64))
        self._append(r, "Points", np.asarray(points, dtype=np.float64).reshape(-1, 3))
        total_cells = 0
        for t in _TOPOLOGIES:
            conn = np.asarray(cells.get(t, np.zeros((0, 1))), dtype=np.int64)
            nc, k = conn.shape[0], (conn.shape[1] if conn.ndim == 2 else 1)
            g = r.require_group(t)
            self._append(g, "NumberOfCells", np.array([nc], dtype=np.int64))
            self._append(g, "NumberOfConnectivityIds", np.array([nc * k], dtype=np.int64))
            self._append(g, "Offsets", np.arange(nc + 1, dtype=np.int64) * k)
            self._append(g, "Connectivity", conn.reshape(-1))
            self.cells[t] += nc
            self.ids[t] += nc * k
            total_cells += nc
        for name, v in point_data.items():
            self._append(s["PointDataOffsets"], name, np.array([self.points], dtype=np.int64))
            self._append(r["PointData"], name, v)
        cell_start = sum(self.cells.values()) - total_cells
        for name, v in cell_data.items():
            self._append(s["CellDataOffsets"], name, np.array([cell_start], dtype=np.int64))
            self._append(r["CellData"], name, v)
        self.points += npts
        self.n += 1
        s.attrs["NSteps"] = np.int64(self.n)
        self.file.flush()

    def close(self) -> None:
        self.file.close()


class SnapshotWriter:
    """Writes the snapshots of one run into ``directory`` as they come: ``particles.vtkhdf``
    and ``contacts.vtkhdf``, one time step per snapshot (see the module docstring).

    A snapshot with the same step count as the one before it (a stage that ended where the
    previous one did) adds its stage name to that time step instead of repeating it. Use it
    as ``run_uniaxial(test, on_snapshot=writer.add, snapshot_interval=...)`` and close it (or
    use it as a context manager)."""

    def __init__(self, directory):
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.particles = _TemporalPolyData(self.directory / "particles.vtkhdf")
        self.contacts = _TemporalPolyData(self.directory / "contacts.vtkhdf")
        self.labels: list[str] = []
        self.last_steps: int | None = None

    def add(self, snap: Snapshot) -> None:
        """Append ``snap`` to both files."""
        if snap.steps == self.last_steps:
            self.labels[-1] += f"+{snap.stage}"
            self._write_labels()
            return
        n = len(snap.radii)
        fields = particle_fields(snap)
        self.particles.add(
            snap.time,
            snap.positions,
            {"Vertices": np.arange(n, dtype=np.int64)[:, None]},
            {
                "radius": snap.radii,
                "velocity": snap.velocities,
                "angular_velocity": snap.angular_velocities,
                "contact_count": snap.contact_counts,
                "mean_normal_force": fields["mean_normal_force"],
                "pressure": fields["pressure"],
                "id": np.arange(n, dtype=np.int64),
            },
            {},
        )
        m = len(snap.pairs)
        first = snap.positions[snap.pairs[:, 0]]
        ends = np.empty((2 * m, 3))
        ends[0::2] = first
        ends[1::2] = first - snap.branches  # the second particle's nearest image
        self.contacts.add(
            snap.time,
            ends,
            {"Lines": np.arange(2 * m, dtype=np.int64).reshape(m, 2)},
            {},
            {
                "normal_force": snap.normal_forces,
                "particle_i": snap.pairs[:, 0],
                "particle_j": snap.pairs[:, 1],
            },
        )
        self.labels.append(snap.stage)
        self.last_steps = snap.steps
        self._write_labels()

    def _write_labels(self) -> None:
        # outside /VTKHDF (ignored by VTK): what each time step is, and the units
        for f in (self.particles.file, self.contacts.file):
            g = f.require_group("demscale")
            g.attrs["stages"] = json.dumps(self.labels)
            g.attrs["units"] = json.dumps(FIELD_UNITS)
            g.attrs["time_units"] = "s"

    def close(self) -> None:
        """Close both files."""
        self.particles.close()
        self.contacts.close()

    def __enter__(self) -> SnapshotWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _signed_ticks(bar, norm) -> None:
    """Ticks on both sides of zero for a colour bar with a two-slope norm (matplotlib's
    default ticks leave the shorter side bare)."""
    from matplotlib.colors import TwoSlopeNorm

    if isinstance(norm, TwoSlopeNorm):
        ticks = np.unique(np.r_[np.linspace(norm.vmin, 0.0, 3), np.linspace(0.0, norm.vmax, 5)])
        bar.set_ticks(ticks, labels=[f"{t:.2g}" for t in ticks])


def section_figure(snap: Snapshot, title: str = ""):
    """A matplotlib Figure (Agg canvas, no pyplot) of a vertical section through the middle
    of the sample: left, the particles cut by the plane (true cross-section circles) coloured
    by their pressure [kPa] (1st to 99th percentile; red compression, blue tension when both
    occur); right, the force chains among the particles the plane cuts
    (line width and colour by the normal force [N]). The plane is normal to the shorter
    horizontal side of the cell, so the section shows the wider one."""
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection, PatchCollection
    from matplotlib.colors import ListedColormap, Normalize, TwoSlopeNorm
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    pos, rad = snap.positions, snap.radii
    lo, hi = pos.min(axis=0) - rad.max(), pos.max(axis=0) + rad.max()
    normal = 0 if hi[0] - lo[0] < hi[1] - lo[1] else 1  # cut across the shorter side
    across = 1 - normal
    mid = 0.5 * (lo[normal] + hi[normal])
    depth = pos[:, normal] - mid
    cut = np.abs(depth) < rad
    section = np.sqrt(np.maximum(rad[cut] ** 2 - depth[cut] ** 2, 0.0))
    pressure = particle_fields(snap)["pressure"]

    width = hi[across] - lo[across]
    height = max(hi[2], float(np.max(snap.platens))) - min(lo[2], float(np.min(snap.platens)))
    panel_h = max(2.4, min(5.2, 6.0 * height / width))  # a slumped sample: low and wide
    panel_w = float(np.clip(panel_h * width / height, 1.6, 6.0))
    fig = Figure(figsize=(2 * panel_w + 2.6, panel_h + 0.9), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    ax_p, ax_f = fig.subplots(1, 2, sharex=True, sharey=True)
    mm = 1e3

    kpa = pressure[cut] * 1e-3
    p_lo = float(np.percentile(kpa, 1)) if kpa.size else 0.0
    p_hi = float(np.percentile(kpa, 99)) if kpa.size else 1.0
    if p_lo < 0 < p_hi:  # adhesion holds some particles in tension: diverging, as the chains
        p_cmap, p_norm = "RdBu_r", TwoSlopeNorm(0.0, p_lo, p_hi)
    else:
        p_cmap, p_norm = "viridis", Normalize(min(p_lo, 0.0), max(p_hi, 1e-30))
    discs = PatchCollection(
        [
            Circle((x * mm, z * mm), r * mm)
            for x, z, r in zip(pos[cut, across], pos[cut, 2], section)
        ],
        cmap=p_cmap,
        norm=p_norm,
        edgecolor="0.25",
        linewidth=0.3,
    )
    discs.set_array(kpa)
    ax_p.add_collection(discs)
    bar = fig.colorbar(discs, ax=ax_p, label="particle pressure (Love-Weber) [kPa]", shrink=0.8)
    _signed_ticks(bar, p_norm)
    ax_p.set_title(f"section through the middle: {int(cut.sum())} particles", fontsize=9)

    # force chains: contacts whose two particles the plane cuts, drawn to the second
    # particle's nearest image (a chain through a periodic side stays short)
    i, j = snap.pairs[:, 0], snap.pairs[:, 1]
    keep = cut[i] & cut[j] if len(i) else np.zeros(0, dtype=bool)
    a = pos[i[keep]]
    b = a - snap.branches[keep]
    fn = snap.normal_forces[keep].astype(np.float64)
    ax_f.add_collection(
        PatchCollection(
            [
                Circle((x * mm, z * mm), r * mm)
                for x, z, r in zip(pos[cut, across], pos[cut, 2], section)
            ],
            facecolor="0.93",
            edgecolor="0.75",
            linewidth=0.3,
        )
    )
    if fn.size:
        f_lo, f_hi = float(fn.min()), float(fn.max())
        scale = max(abs(f_lo), abs(f_hi), 1e-30)
        if f_lo < 0 < f_hi:  # adhesive contacts too: blue pulls, red pushes
            cmap, norm = "RdBu_r", TwoSlopeNorm(0.0, f_lo, f_hi)
        else:  # one sign: the lower end of "Reds" cut off, so weak chains show on grey
            cmap = ListedColormap(colormaps["Reds"](np.linspace(0.3, 1.0, 256)))
            norm = Normalize(min(f_lo, 0.0), max(f_hi, 1e-30))
        chains = LineCollection(
            np.stack([a[:, [across, 2]], b[:, [across, 2]]], axis=1) * mm,
            cmap=cmap,
            norm=norm,
            linewidths=0.4 + 3.6 * np.abs(fn) / scale,
        )
        chains.set_array(fn)
        ax_f.add_collection(chains)
        bar = fig.colorbar(
            chains, ax=ax_f, label="normal contact force [N] (> 0 compressive)", shrink=0.8
        )
        _signed_ticks(bar, norm)
    ax_f.set_title(f"force chains: {int(keep.sum())} contacts in the section", fontsize=9)
    axis_name = "xy"[across]
    for ax in (ax_p, ax_f):
        for z in snap.platens:
            ax.axhline(z * mm, color="black", lw=2)
        ax.set_xlim(lo[across] * mm, hi[across] * mm)
        ax.set_ylim(
            min(lo[2], float(np.min(snap.platens))) * mm - 1,
            max(hi[2], float(np.max(snap.platens))) * mm + 1,
        )
        ax.set_aspect("equal")
        ax.set_xlabel(f"{axis_name} [mm]")
        ax.tick_params(labelsize=7)
    ax_p.set_ylabel("z [mm]")
    fig.suptitle(
        f"{title + ': ' if title else ''}{snap.stage} end, t = {snap.time:.4g} s, "
        f"section at {'xy'[normal]} = {mid * mm:.3g} mm",
        fontsize=10,
    )
    return fig


def save(result, directory, label: str = "") -> list[Path]:
    """Write the stage-end snapshots of the :class:`engine.UniaxialResult` ``result`` into
    ``directory``: ``particles.vtkhdf``, ``contacts.vtkhdf`` and ``<stage>.png`` per stage.
    Returns the paths. Stages without a snapshot (a result read back from a file that did
    not keep them) are skipped; none at all raises ValueError."""
    snaps = [st.snapshot for st in result.stages.values() if st.snapshot is not None]
    if not snaps:
        raise ValueError("the result keeps no snapshots (read back from a file without them?)")
    d = Path(directory)
    paths = []
    with SnapshotWriter(d) as w:
        for s in snaps:
            w.add(s)
        paths += [w.particles.path, w.contacts.path]
    for s in snaps:
        path = d / f"{s.stage}.png"
        section_figure(s, label).savefig(path, format="png")
        paths.append(path)
    return paths


def save_study(study, directory) -> dict[str, list[Path]]:
    """Snapshots of every run of the :class:`engine.StudyResult` ``study``, one directory per
    run (``directory/<run key>/``); returns run key -> paths."""
    return {key: save(run.result, Path(directory) / key, key) for key, run in study.runs.items()}
