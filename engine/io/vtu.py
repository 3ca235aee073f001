"""Snapshots as VTK XML unstructured grids (``.vtu``, one file per time step) with a ParaView
collection (``.pvd``) that orders them in time: the format every ParaView (5.9 and
earlier) and meshio read, beside the temporal VTKHDF files ParaView 5.12+ reads
(:mod:`engine.io.vtkhdf`). numpy only.

A particle is a ``VTK_VERTEX`` cell at its centre, a contact a ``VTK_LINE`` between two
points, a wall's triangle a ``VTK_TRIANGLE``; every array is stored raw, base64-encoded
after a 64-bit byte count (the VTK XML ``binary`` encoding, ``header_type="UInt64"``), in
little-endian order.
"""

from __future__ import annotations

import base64
import os
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

__all__ = ["VTK_LINE", "VTK_TRIANGLE", "VTK_VERTEX", "write_pvd", "write_vtu"]

#: VTK cell types used.
VTK_VERTEX = 1
VTK_LINE = 3
VTK_TRIANGLE = 5

_TYPES = {
    np.dtype("<f8"): "Float64",
    np.dtype("<f4"): "Float32",
    np.dtype("<i8"): "Int64",
    np.dtype("<i4"): "Int32",
    np.dtype("u1"): "UInt8",
}


def _array(name: str, values) -> str:
    a = np.asarray(values)
    if a.dtype.kind == "f":
        a = a.astype("<f8" if a.dtype.itemsize == 8 else "<f4")
    elif a.dtype.kind in "iu" and a.dtype != np.uint8:
        a = a.astype("<i8")
    a = np.ascontiguousarray(a)
    comps = 1 if a.ndim == 1 else int(np.prod(a.shape[1:]))
    raw = a.tobytes()
    data = base64.b64encode(np.array([len(raw)], dtype="<u8").tobytes() + raw).decode()
    # a scalar array leaves NumberOfComponents out (VTK's default of 1), as VTK writes it:
    # readers then give it one dimension
    comps_attr = f' NumberOfComponents="{comps}"' if a.ndim > 1 else ""
    return (
        f'<DataArray type="{_TYPES[a.dtype]}" Name={quoteattr(name)}{comps_attr} '
        f'format="binary">{data}</DataArray>'
    )


def write_vtu(
    path,
    points: np.ndarray,
    connectivity: np.ndarray,
    cell_type: int,
    point_data: dict[str, np.ndarray] | None = None,
    cell_data: dict[str, np.ndarray] | None = None,
    time: float | None = None,
) -> Path:
    """Write one ``.vtu`` file: ``points`` (P, 3) [m], cells of one ``cell_type`` whose point
    ids are the rows of ``connectivity`` (C, k), arrays with a row per point or per cell, and
    the simulated ``time`` [s] as the field ``TimeValue``. Written to a temporary file and
    renamed, so that a reader never sees half a file."""
    path = Path(path)
    pts = np.asarray(points, dtype="<f8").reshape(-1, 3)
    conn = np.asarray(connectivity, dtype="<i8")
    conn = conn.reshape(len(conn), -1) if conn.size else conn.reshape(0, 1)
    n, k = conn.shape
    parts = [
        '<?xml version="1.0"?>',
        '<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" '
        'header_type="UInt64">',
        "<UnstructuredGrid>",
    ]
    if time is not None:
        parts += ["<FieldData>", _array("TimeValue", np.array([float(time)])), "</FieldData>"]
    parts.append(f'<Piece NumberOfPoints="{len(pts)}" NumberOfCells="{n}">')
    parts.append("<PointData>")
    parts += [_array(name, v) for name, v in (point_data or {}).items()]
    parts.append("</PointData><CellData>")
    parts += [_array(name, v) for name, v in (cell_data or {}).items()]
    parts.append("</CellData>")
    parts += ["<Points>", _array("Points", pts), "</Points>"]
    parts += [
        "<Cells>",
        _array("connectivity", conn.reshape(-1)),
        _array("offsets", np.arange(1, n + 1, dtype="<i8") * k),
        _array("types", np.full(n, cell_type, dtype=np.uint8)),
        "</Cells>",
        "</Piece>",
        "</UnstructuredGrid>",
        "</VTKFile>",
    ]
    _replace(path, "\n".join(parts) + "\n")
    return path


def write_pvd(path, entries: list[tuple[float, str]]) -> Path:
    """Write a ParaView collection: one ``DataSet`` per (time [s], file relative to
    ``path``'s folder), in order; ParaView plays them as the time steps of one source."""
    rows = [
        f'<DataSet timestep="{t!r}" group="" part="0" file={quoteattr(f)}/>' for t, f in entries
    ]
    text = "\n".join(
        [
            '<?xml version="1.0"?>',
            '<VTKFile type="Collection" version="1.0" byte_order="LittleEndian">',
            "<Collection>",
            *rows,
            "</Collection>",
            "</VTKFile>",
        ]
    )
    path = Path(path)
    _replace(path, text + "\n")
    return path


def _replace(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)
