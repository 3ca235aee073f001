"""Snapshots of a tiny run: what the driver captures at each stage's end and every interval,
the VTKHDF files read back with h5py (and with VTK's own reader, the one ParaView uses, when
the ``vtk`` package is installed), the per-particle stress against a naive sum, the PNGs."""

from __future__ import annotations

import json

import numpy as np
import pytest

import engine
from engine.io.vtkhdf import FIELD_UNITS, SnapshotWriter
from engine.simulation.snapshot import particle_fields
from engine.uniaxial.driver import stages_of

h5py = pytest.importorskip("h5py")

INTERVAL = 0.05  # s of simulated time between snapshots during the stages


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A tiny run streamed to a writer every INTERVAL, then its stage ends saved."""
    d = tmp_path_factory.mktemp("snapshots")
    test = engine.UniaxialTest(
        cell=(0.015, 0.015, 0.015), output_interval=1e-3, platen_speed=0.02, inertial_number=None
    )
    streamed = []

    def keep(snap):
        streamed.append(snap)
        writer.add(snap)

    with SnapshotWriter(d / "interval") as writer:
        res = engine.run_uniaxial(test, on_snapshot=keep, snapshot_interval=INTERVAL)
    paths = res.save_snapshots(d / "stages", "tiny")
    return res, streamed, writer.labels, d, paths


def _step(f, k: int, group: str, name: str, offsets: str, count):
    """Rows of ``/VTKHDF/<group>/<name>`` of time step k (a part per step)."""
    start = int(f[f"VTKHDF/Steps/{offsets}"][k])
    return (
        f[f"VTKHDF/{group}/{name}"][start : start + count]
        if group
        else f[f"VTKHDF/{name}"][start : start + count]
    )


def test_every_stage_end_keeps_a_consistent_snapshot(run):
    res = run[0]
    assert list(res.stages) == list(stages_of(res.test))
    t_prev = -1.0
    for name, st in res.stages.items():
        s = st.snapshot
        assert s.stage == name and s.time > t_prev
        t_prev = s.time
        assert s.time == pytest.approx(st.curves["time"][-1])
        np.testing.assert_array_equal(s.positions, st.positions)
        n = len(s.radii)
        assert s.velocities.shape == s.angular_velocities.shape == (n, 3)
        counts = np.bincount(s.pairs.ravel(), minlength=n)
        np.testing.assert_array_equal(s.contact_counts, counts)
        assert np.all(s.pairs[:, 0] < s.pairs[:, 1])
        # the branch is the centre distance, shorter than the radii's sum (overlap)
        dist = np.linalg.norm(s.branches, axis=1)
        rsum = s.radii[s.pairs[:, 0]] + s.radii[s.pairs[:, 1]]
        assert np.all(dist < rsum) and np.all(dist > 0.9 * rsum)
        # the mean coordination of the snapshot is the stage curve's last value
        assert counts.sum() / n == pytest.approx(st.curves["coordination"][-1])
        assert s.nbytes < 200 * n + 100 * len(s.pairs) + 1000
    cons = res.stages["consolidation"].snapshot
    assert np.all(cons.normal_forces > 0) or cons.normal_forces.max() > 0


def test_particle_pressure_is_the_love_weber_trace(run):
    """-trace/3 of sum over contacts of (contact point - centre) (x) force, / volume, in
    plain loops, against the vectorised per-particle fields."""
    s = run[0].stages["consolidation"].snapshot
    n = len(s.radii)
    trace = np.zeros(n)
    force_sum, count = np.zeros(n), np.zeros(n)
    for (i, j), fn, b in zip(s.pairs, s.normal_forces.astype(float), s.branches.astype(float)):
        d = np.linalg.norm(b)
        nrm = b / d  # from j to i
        delta = s.radii[i] + s.radii[j] - d
        force = fn * nrm  # normal part of the force on i
        point_i = -(s.radii[i] - delta / 2) * nrm  # contact point from i's centre
        point_j = +(s.radii[j] - delta / 2) * nrm
        trace[i] += np.trace(np.outer(point_i, force))
        trace[j] += np.trace(np.outer(point_j, -force))
        for k in (i, j):
            force_sum[k] += fn
            count[k] += 1
    volume = 4 / 3 * np.pi * s.radii**3
    f = particle_fields(s)
    np.testing.assert_allclose(f["pressure"], -trace / volume / 3, rtol=1e-9, atol=1e-12)
    mean = np.divide(force_sum, count, out=np.zeros(n), where=count > 0)
    np.testing.assert_allclose(f["mean_normal_force"], mean, rtol=1e-12)
    assert np.median(f["pressure"][count > 0]) > 0  # consolidated: compressed


def test_stage_files_read_back_with_h5py(run):
    res, _, _, d, paths = run
    snaps = [st.snapshot for st in res.stages.values()]
    assert {p.name for p in paths} == {
        "particles.vtkhdf",
        "contacts.vtkhdf",
        "particles.pvd",
        "contacts.pvd",
        *(f"{kind}-{k:04d}.vtu" for k in range(len(snaps)) for kind in ("particles", "contacts")),
        *(f"{s}.png" for s in stages_of(res.test)),
    }
    with h5py.File(d / "stages" / "particles.vtkhdf", "r") as f:
        root = f["VTKHDF"]
        assert root.attrs["Type"] == b"PolyData"
        assert tuple(root.attrs["Version"]) == (2, 0)
        assert int(root["Steps"].attrs["NSteps"]) == len(snaps)
        np.testing.assert_allclose(root["Steps/Values"][()], [s.time for s in snaps])
        assert json.loads(f["demscale"].attrs["stages"]) == list(stages_of(res.test))
        assert json.loads(f["demscale"].attrs["units"]) == FIELD_UNITS
        for k, s in enumerate(snaps):
            n = len(s.radii)
            assert root["NumberOfPoints"][k] == n
            np.testing.assert_array_equal(_step(f, k, "", "Points", "PointOffsets", n), s.positions)
            for name, want in (
                ("radius", s.radii),
                ("velocity", s.velocities),
                ("angular_velocity", s.angular_velocities),
                ("contact_count", s.contact_counts),
                ("pressure", particle_fields(s)["pressure"]),
            ):
                got = _step(f, k, "PointData", name, f"PointDataOffsets/{name}", n)
                np.testing.assert_array_equal(got, want)
            assert root["Vertices/NumberOfCells"][k] == n
            assert root["Lines/NumberOfCells"][k] == 0
    with h5py.File(d / "stages" / "contacts.vtkhdf", "r") as f:
        root = f["VTKHDF"]
        for k, s in enumerate(snaps):
            m = len(s.pairs)
            assert root["Lines/NumberOfCells"][k] == m
            pts = _step(f, k, "", "Points", "PointOffsets", 2 * m)
            c0 = int(root["Steps/ConnectivityIdOffsets"][k, 1])
            conn = root["Lines/Connectivity"][c0 : c0 + 2 * m].reshape(m, 2)
            # each line runs from the first particle's centre along minus the branch vector
            np.testing.assert_array_equal(pts[conn[:, 0]], s.positions[s.pairs[:, 0]])
            np.testing.assert_allclose(pts[conn[:, 1]] - pts[conn[:, 0]], -s.branches, atol=1e-9)
            fn = _step(f, k, "CellData", "normal_force", "CellDataOffsets/normal_force", m)
            np.testing.assert_array_equal(fn, s.normal_forces)
            pj = _step(f, k, "CellData", "particle_j", "CellDataOffsets/particle_j", m)
            np.testing.assert_array_equal(pj, s.pairs[:, 1])


def test_interval_snapshots_stream_in_time_order(run):
    res, streamed, labels, d, _ = run
    times = [s.time for s in streamed]
    assert np.all(np.diff(times) >= 0)  # equal only for a stage that ended where it began
    unique = sorted({s.steps: s.time for s in streamed}.values())
    ends = {st.snapshot.time for st in res.stages.values()}
    assert ends <= set(times)  # every stage end is in the stream
    assert len(streamed) > len(ends) + 5  # and snapshots in between
    gaps = np.diff([s.time for s in streamed if s.time not in ends])
    # taken at a curve sample's end (the driver's unit of work), so within one sample (the
    # fixture's output_interval, 1 ms, plus a step: a time step chosen from the laws need not
    # divide the sample) of the interval
    slack = 1e-3 + res.scalars["dt"]
    assert np.all(np.abs(gaps - INTERVAL) <= slack), gaps
    with h5py.File(d / "interval" / "particles.vtkhdf", "r") as f:
        assert int(f["VTKHDF/Steps"].attrs["NSteps"]) == len(unique) == len(labels)
        np.testing.assert_allclose(f["VTKHDF/Steps/Values"][()], unique)
        last = streamed[-1]
        n = len(last.radii)
        np.testing.assert_array_equal(
            _step(f, len(unique) - 1, "", "Points", "PointOffsets", n), last.positions
        )


def test_pngs_are_images(run):
    matplotlib_image = pytest.importorskip("matplotlib.image")
    for p in run[4]:
        if p.suffix == ".png":
            img = matplotlib_image.imread(p)
            assert img.ndim == 3 and img.shape[0] > 150 and img.shape[1] > 400
            assert img[..., :3].std() > 0.05  # not blank


def test_sections_kept_as_data_are_drawn_on_request_as_the_eager_ones(run, tmp_path):
    """save(sections=False) (the service's worker) keeps each section's data and draws no
    PNG; render_section draws the same image, byte for byte, when first asked for, and
    refuses a stage it has no data of."""
    from engine.io.vtkhdf import SECTION_DATA, render_section, save, section_stages

    res, *_, d, paths = run
    paths = save(res, tmp_path, "tiny", sections=False)
    assert tmp_path / SECTION_DATA in paths and not list(tmp_path.glob("*.png"))
    assert section_stages(tmp_path) == list(res.stages)
    for stage in res.stages:
        drawn = render_section(tmp_path, stage)
        assert drawn == tmp_path / f"{stage}.png"
        assert drawn.read_bytes() == (d / "stages" / f"{stage}.png").read_bytes()
    assert not list(tmp_path.glob(".*.tmp"))
    with pytest.raises(KeyError, match="other"):
        render_section(tmp_path, "other")


def test_vtk_reader_reads_every_step(run):
    """VTK's vtkHDFReader (ParaView's reader of .vtkhdf) on the files."""
    vtk_hdf = pytest.importorskip("vtkmodules.vtkIOHDF")
    from vtkmodules.util.numpy_support import vtk_to_numpy

    res, _, _, d, _ = run
    snaps = [st.snapshot for st in res.stages.values()]
    for name in ("particles", "contacts"):
        reader = vtk_hdf.vtkHDFReader()
        reader.SetFileName(str(d / "stages" / f"{name}.vtkhdf"))
        reader.UpdateInformation()
        assert reader.GetNumberOfSteps() == len(snaps)
        for k, s in enumerate(snaps):
            reader.SetStep(k)
            reader.Update()
            out = reader.GetOutput()
            if name == "particles":
                assert out.GetNumberOfVerts() == len(s.radii)
                pts = vtk_to_numpy(out.GetPoints().GetData())
                np.testing.assert_array_equal(pts, s.positions)
                rad = vtk_to_numpy(out.GetPointData().GetArray("radius"))
                np.testing.assert_array_equal(rad, s.radii)
            else:
                assert out.GetNumberOfLines() == len(s.pairs)
                fn = vtk_to_numpy(out.GetCellData().GetArray("normal_force"))
                np.testing.assert_array_equal(fn, s.normal_forces)


def _pvd(path) -> list[tuple[float, str]]:
    import xml.etree.ElementTree as ET

    root = ET.parse(path).getroot()
    assert root.get("type") == "Collection"
    return [(float(e.get("timestep")), e.get("file")) for e in root.iter("DataSet")]


def test_legacy_vtk_files_list_every_step_in_time_order(run):
    """Beside the VTKHDF files: a .pvd collection of one VTK XML (.vtu) file per time step,
    what every ParaView (5.9 and earlier) opens."""
    res, _, labels, d, paths = run
    snaps = [st.snapshot for st in res.stages.values()]
    for name in ("particles", "contacts"):
        steps = _pvd(d / "stages" / f"{name}.pvd")
        assert [t for t, _ in steps] == [s.time for s in snaps]
        assert all((d / "stages" / f).is_file() and f.endswith(".vtu") for _, f in steps)
        assert d / "stages" / f"{name}.pvd" in paths
        interval = _pvd(d / "interval" / f"{name}.pvd")
        assert len(interval) == len(labels) and np.all(np.diff([t for t, _ in interval]) > 0)


def test_meshio_reads_the_legacy_vtk_files(run):
    """meshio (an independent reader of VTK XML) reads every .vtu back: the points, the
    cells and every array, bit for bit."""
    meshio = pytest.importorskip("meshio")
    res, _, _, d, _ = run
    snaps = [st.snapshot for st in res.stages.values()]
    parts = _pvd(d / "stages" / "particles.pvd")
    lines = _pvd(d / "stages" / "contacts.pvd")
    for s, (_, pf), (_, cf) in zip(snaps, parts, lines):
        m = meshio.read(d / "stages" / pf)
        np.testing.assert_array_equal(m.points, s.positions)
        (block,) = m.cells
        assert block.type == "vertex" and len(block.data) == len(s.radii)
        np.testing.assert_array_equal(m.point_data["radius"], s.radii)
        np.testing.assert_array_equal(m.point_data["velocity"], s.velocities)
        np.testing.assert_array_equal(m.point_data["pressure"], particle_fields(s)["pressure"])
        assert float(np.ravel(m.field_data["TimeValue"])[0]) == s.time
        c = meshio.read(d / "stages" / cf)
        (block,) = c.cells
        assert block.type == "line" and len(block.data) == len(s.pairs)
        np.testing.assert_array_equal(c.cell_data["normal_force"][0], s.normal_forces)
        np.testing.assert_array_equal(c.cell_data["particle_j"][0], s.pairs[:, 1])
        # a line runs from the first particle's centre to the second's nearest image
        np.testing.assert_allclose(
            c.points[block.data[:, 0]] - c.points[block.data[:, 1]], s.branches
        )


def test_interval_needs_a_receiver():
    test = engine.UniaxialTest(cell=(0.015, 0.015, 0.015))
    with pytest.raises(ValueError, match="on_snapshot"):
        engine.run_uniaxial(test, snapshot_interval=0.01)
    with pytest.raises(ValueError, match="> 0"):
        engine.run_uniaxial(test, on_snapshot=print, snapshot_interval=0.0)


def test_the_curves_as_csv(run, tmp_path):
    """Every stage's curves, a row per sample, the stage first and each unit in its
    heading; the numbers exactly the run's."""
    import csv

    from engine.io.curves import write_curves_csv
    from engine.uniaxial.results import CURVE_UNITS

    res = run[0]
    path = write_curves_csv(res, tmp_path / "curves.csv")
    rows = list(csv.reader(path.read_text().splitlines()))
    head, body = rows[0], rows[1:]
    assert head[0] == "stage" and "time [s]" in head and "stress_top [Pa]" in head
    assert all(h.split(" [")[0] in CURVE_UNITS for h in head[1:])
    assert len(body) == sum(len(st.curves["time"]) for st in res.stages.values())
    cons = [r for r in body if r[0] == "consolidation"]
    col = head.index("stress_top [Pa]")
    np.testing.assert_array_equal(
        [float(r[col]) for r in cons], res.stages["consolidation"].curves["stress_top"]
    )
    # several runs in one text: the run first
    from engine.io.curves import runs_csv

    both = runs_csv({"a": res, "b": res}).splitlines()
    assert both[0] == "run," + ",".join(head) and len(both) == 2 * len(body) + 1
    assert both[1] == "a," + ",".join(rows[1]) and both[-1] == "b," + ",".join(rows[-1])
