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
    walls.vtkhdf       PolyData, the mesh walls' triangles where they are at each step (a
                       scene with meshes only: a hopper's walls and gate); cell data: mesh [-]
    particles.pvd,     the same, as every ParaView (5.9 and earlier) and meshio read them:
    contacts.pvd,      a collection of one VTK XML file per time step,
    (walls.pvd)        particles-NNNN.vtu, contacts-NNNN.vtu (and walls-NNNN.vtu)
                       (engine.io.vtu)
    <stage>.png        section through the middle of the sample at the stage's end; or,
    sections.npz       with ``save(..., sections=False)``, what each section is drawn from
                       (positions, radii, contacts at each stage end), drawn on first request
                       by :func:`render_section` (a worker stores a run without drawing)

Each file holds every snapshot of the run as one time step (``/VTKHDF/Steps``): ParaView
plays the run as an animation. Snapshots are appended to resizable, chunked datasets, so a
run's snapshots are written as they come and never held in memory together.

:class:`engine.simulation.snapshot.Snapshot` and its ``capture`` need only numpy. h5py (the
files) and matplotlib (the PNG sections, drawn by :func:`engine.io.figures.section_figure`) are
imported when something is written: ``pip install "demscale[snapshots]"``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..simulation.snapshot import Snapshot, particle_fields

__all__ = [
    "FIELD_UNITS",
    "SECTION_DATA",
    "VTKHDF_VERSION",
    "SnapshotWriter",
    "render_section",
    "save",
    "save_study",
    "section_stages",
]

#: The file a run's snapshot folder keeps its sections' data in when they are drawn later.
SECTION_DATA = "sections.npz"

#: The fields of a :class:`Snapshot` a section is drawn from (engine.io.figures.section_figure).
_SECTION_FIELDS = ("positions", "radii", "pairs", "normal_forces", "branches", "platens")

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
    "mesh": "1",
}

_TOPOLOGIES = ("Vertices", "Lines", "Polygons", "Strips")


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


def _particle_data(snap: Snapshot) -> dict[str, np.ndarray]:
    """The point data of a snapshot's particles: radius [m], velocity [m/s], angular
    velocity [rad/s], contact count [-], mean normal force [N], pressure [Pa] and id."""
    fields = particle_fields(snap)
    return {
        "radius": snap.radii,
        "velocity": snap.velocities,
        "angular_velocity": snap.angular_velocities,
        "contact_count": snap.contact_counts,
        "mean_normal_force": fields["mean_normal_force"],
        "pressure": fields["pressure"],
        "id": np.arange(len(snap.radii), dtype=np.int64),
    }


def _contact_data(snap: Snapshot) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A snapshot's contacts as lines: their end points [m] (two rows a contact: the first
    particle's centre, then the second's nearest image) and their cell data (normal force
    [N] and the two particles' ids)."""
    m = len(snap.pairs)
    first = snap.positions[snap.pairs[:, 0]]
    ends = np.empty((2 * m, 3))
    ends[0::2] = first
    ends[1::2] = first - snap.branches  # the second particle's nearest image
    cells = {
        "normal_force": snap.normal_forces,
        "particle_i": snap.pairs[:, 0],
        "particle_j": snap.pairs[:, 1],
    }
    return ends, cells


class SnapshotWriter:
    """Writes the snapshots of one run into ``directory`` as they come: ``particles.vtkhdf``
    and ``contacts.vtkhdf``, one time step per snapshot (see the module docstring).

    A snapshot with the same step count as the one before it (a stage that ended where the
    previous one did) adds its stage name to that time step instead of repeating it. Use it
    as ``run_uniaxial(test, on_snapshot=writer.add, snapshot_interval=...)`` and close it (or
    use it as a context manager)."""

    def __init__(self, directory, legacy: bool = True):
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.particles = _TemporalPolyData(self.directory / "particles.vtkhdf")
        self.contacts = _TemporalPolyData(self.directory / "contacts.vtkhdf")
        #: the mesh walls' file, opened by the first snapshot with meshes (a run's snapshots
        #: all have them or none)
        self.walls: _TemporalPolyData | None = None
        self.labels: list[str] = []
        self.last_steps: int | None = None
        self.legacy = legacy  # also .vtu per time step and a .pvd of each (every ParaView)
        self.times: list[float] = []

    def add(self, snap: Snapshot) -> None:
        """Append ``snap`` to both files."""
        if snap.steps == self.last_steps:
            self.labels[-1] += f"+{snap.stage}"
            self._write_labels()
            return
        n = len(snap.radii)
        point_data = _particle_data(snap)
        self.particles.add(
            snap.time,
            snap.positions,
            {"Vertices": np.arange(n, dtype=np.int64)[:, None]},
            point_data,
            {},
        )
        m = len(snap.pairs)
        ends, cell_data = _contact_data(snap)
        self.contacts.add(
            snap.time,
            ends,
            {"Lines": np.arange(2 * m, dtype=np.int64).reshape(m, 2)},
            {},
            cell_data,
        )
        if len(snap.mesh_triangles):
            if self.walls is None:
                self.walls = _TemporalPolyData(self.directory / "walls.vtkhdf")
            self.walls.add(
                snap.time,
                snap.mesh_points,
                {"Polygons": snap.mesh_triangles},
                {},
                {"mesh": snap.mesh_ids},
            )
        self.labels.append(snap.stage)
        self.last_steps = snap.steps
        self._write_labels()
        if self.legacy:
            self._write_vtu(snap, point_data, ends, cell_data)

    def _write_vtu(self, snap: Snapshot, point_data: dict, ends, cell_data: dict) -> None:
        """The same time step as ``particles-NNNN.vtu`` and ``contacts-NNNN.vtu`` (the
        arrays :meth:`add` wrote to the VTKHDF files), and the two ``.pvd`` collections
        rewritten with it (:mod:`engine.io.vtu`)."""
        from .vtu import VTK_LINE, VTK_TRIANGLE, VTK_VERTEX, write_pvd, write_vtu

        i, n, m = len(self.times), len(snap.radii), len(snap.pairs)
        write_vtu(
            self.directory / f"particles-{i:04d}.vtu",
            snap.positions,
            np.arange(n)[:, None],
            VTK_VERTEX,
            point_data,
            time=snap.time,
        )
        write_vtu(
            self.directory / f"contacts-{i:04d}.vtu",
            ends,
            np.arange(2 * m).reshape(m, 2),
            VTK_LINE,
            cell_data=cell_data,
            time=snap.time,
        )
        if self.walls is not None:
            write_vtu(
                self.directory / f"walls-{i:04d}.vtu",
                snap.mesh_points,
                snap.mesh_triangles,
                VTK_TRIANGLE,
                cell_data={"mesh": snap.mesh_ids},
                time=snap.time,
            )
        self.times.append(float(snap.time))
        for kind in self._kinds():
            write_pvd(
                self.directory / f"{kind}.pvd",
                [(t, f"{kind}-{k:04d}.vtu") for k, t in enumerate(self.times)],
            )

    def _kinds(self) -> tuple[str, ...]:
        """The files' kinds: particles and contacts, and walls in a scene with meshes."""
        return ("particles", "contacts", *(("walls",) if self.walls is not None else ()))

    def _files(self) -> list[_TemporalPolyData]:
        return [self.particles, self.contacts, *([self.walls] if self.walls else [])]

    def paths(self) -> list[Path]:
        """Every file written so far: the VTKHDF files, and the ``.pvd`` collections and
        ``.vtu`` files."""
        out = [f.path for f in self._files()]
        if self.legacy and self.times:
            out += [self.directory / f"{kind}.pvd" for kind in self._kinds()]
            out += [
                self.directory / f"{kind}-{k:04d}.vtu"
                for k in range(len(self.times))
                for kind in self._kinds()
            ]
        return out

    def _write_labels(self) -> None:
        # outside /VTKHDF (ignored by VTK): what each time step is, and the units
        for f in (t.file for t in self._files()):
            g = f.require_group("demscale")
            g.attrs["stages"] = json.dumps(self.labels)
            g.attrs["units"] = json.dumps(FIELD_UNITS)
            g.attrs["time_units"] = "s"

    def close(self) -> None:
        """Close the files."""
        for f in self._files():
            f.close()

    def __enter__(self) -> SnapshotWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def save(result, directory, label: str = "", sections: bool = True) -> list[Path]:
    """Write the stage-end snapshots of the :class:`engine.UniaxialResult` ``result`` into
    ``directory``: ``particles.vtkhdf``, ``contacts.vtkhdf`` (and their ``.pvd``/``.vtu``) and
    ``<stage>.png`` per stage; with ``sections=False`` the PNGs are not drawn now (about a
    second of matplotlib each) but their data kept in ``sections.npz``, for
    :func:`render_section` to draw one when it is asked for. Returns the paths. Stages without
    a snapshot (a result read back from a file that did not keep them) are skipped; none at
    all raises ValueError."""
    snaps = [st.snapshot for st in result.stages.values() if st.snapshot is not None]
    if not snaps:
        raise ValueError("the result keeps no snapshots (read back from a file without them?)")
    d = Path(directory)
    paths = []
    with SnapshotWriter(d) as w:
        for s in snaps:
            w.add(s)
        paths += w.paths()
    if not sections:
        data = {"stages": np.array([s.stage for s in snaps]), "label": np.array(label)}
        for s in snaps:
            data.update({f"{s.stage}/{name}": getattr(s, name) for name in _SECTION_FIELDS})
            data.update(
                {f"{s.stage}/time": np.array(s.time), f"{s.stage}/steps": np.array(s.steps)}
            )
        path = d / SECTION_DATA
        np.savez_compressed(path, **data)
        return [*paths, path]
    from .figures import section_figure

    for s in snaps:
        path = d / f"{s.stage}.png"
        section_figure(s, label).savefig(path, format="png")
        paths.append(path)
    return paths


def section_stages(directory) -> list[str]:
    """The stages whose PNG section :func:`render_section` can draw from ``directory``'s
    ``sections.npz`` (none without it)."""
    path = Path(directory) / SECTION_DATA
    if not path.is_file():
        return []
    with np.load(path) as z:
        return [str(x) for x in z["stages"]]


def render_section(directory, stage: str) -> Path:
    """``directory/<stage>.png``, drawn from ``sections.npz`` if it is not there yet (written
    to a temporary name, then renamed: a reader never sees half a file, and two drawing at
    once both leave a whole one). Raises KeyError for a stage the folder has no data of."""
    d = Path(directory)
    out = d / f"{stage}.png"
    if out.is_file():
        return out
    if stage not in section_stages(d):
        raise KeyError(f"no section data of stage {stage!r} in {d}")
    with np.load(d / SECTION_DATA) as z:
        fields = {name: z[f"{stage}/{name}"] for name in _SECTION_FIELDS}
        label = str(z["label"])
        time, steps = float(z[f"{stage}/time"]), int(z[f"{stage}/steps"])
    empty = np.zeros((len(fields["radii"]), 3), dtype=np.float32)
    snap = Snapshot(
        stage=stage,
        time=time,
        steps=steps,
        velocities=empty,
        angular_velocities=empty,
        contact_counts=np.zeros(len(fields["radii"]), dtype=np.int32),
        **fields,
    )
    import os
    import tempfile

    from .figures import section_figure

    fd, tmp = tempfile.mkstemp(prefix=f".{stage}.", suffix=".png.tmp", dir=d)
    try:
        with os.fdopen(fd, "wb") as f:
            section_figure(snap, label).savefig(f, format="png")
        os.replace(tmp, out)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return out


def save_study(study, directory) -> dict[str, list[Path]]:
    """Snapshots of every run of the :class:`engine.StudyResult` ``study``, one directory per
    run (``directory/<run key>/``); returns run key -> paths."""
    return {key: save(run.result, Path(directory) / key, key) for key, run in study.runs.items()}
