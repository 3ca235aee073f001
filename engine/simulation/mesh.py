"""Walls of finite extent: triangle meshes (:class:`Mesh`), their STL files and the arrays the
step kernel reads (:func:`pack_meshes`).

A mesh is validated once, on construction (a clear :class:`engine.ParameterError` naming the
mesh, its file for STL input, and the triangle): non-finite vertices, triangles with two equal
or three collinear vertices, edges shared by more than two triangles, and, with
``closed=True``, open edges and inconsistent orientation. Vertices with identical coordinates
are merged (an STL file lists every triangle's corners apart; without the merge, neighbouring
triangles would not know they are neighbours and every shared edge would count as a border
of the mesh); unused vertices are dropped.

The contact of a sphere with a mesh (docs/MESH.md, :mod:`engine.kernel.mesh`) resolves each
touching surface patch to one face, edge or vertex: the mesh's topology (which triangles
share an edge, which edges meet at a vertex, which triangle evaluates a shared edge or
vertex) is computed here, once, by :func:`pack_meshes`. Units: m, m/s.
"""

from __future__ import annotations

import math
import os
import struct
from pathlib import Path

import numpy as np

from ..core.errors import ParameterError

#: A triangle whose area is below this fraction of its longest edge squared is degenerate
#: (its normal is not defined to working precision).
DEGENERATE_AREA = 1e-12


def vec3(owner: str, name: str, value) -> tuple[float, float, float]:
    """``value`` as three finite floats (a vector in the unit of the field); bad input:
    ParameterError naming ``<owner>.<name>``. Shared by the scene's planes, gravity and
    meshes."""
    try:
        a = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise ParameterError(f"{owner}.{name}", value, "a sequence of 3 real numbers") from None
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ParameterError(f"{owner}.{name}", value, "3 finite real numbers")
    return (float(a[0]), float(a[1]), float(a[2]))


class Mesh:
    """A wall of finite extent: a triangle mesh, two-sided (a particle meets a triangle from
    either side), moving by translation.

    Args:
        vertices: (V, 3) vertex coordinates at time 0 of the simulation [m], finite.
        triangles: (T, 3) vertex indices of each triangle, T >= 1.
        velocity: translation velocity of the whole mesh [m/s] (a gate that opens);
            changeable between runs with :meth:`engine.Simulation.set_mesh_velocity`.
        closed: require a closed surface (every edge shared by exactly two triangles, all
            triangles oriented alike); refused otherwise, naming a triangle. Contact is
            two-sided either way.
        name: how errors name the mesh (:meth:`from_stl`: the file).

    Attributes (read-only arrays): ``vertices`` (V, 3) [m], after exact duplicates are merged
    and unused vertices dropped; ``triangles`` (T, 3); ``normals`` (T, 3) unit normals (right
    hand around the triangle's vertex order); ``areas`` (T,) [m^2]; ``velocity`` [m/s].
    """

    def __init__(
        self, vertices, triangles, velocity=(0.0, 0.0, 0.0), *, closed: bool = False, name=None
    ) -> None:
        self.name = "Mesh" if name is None else f"Mesh({name})"
        field = self.name
        try:
            v = np.array(vertices, dtype=np.float64)
        except (TypeError, ValueError):
            raise ParameterError(f"{field}.vertices", vertices, "(V, 3) real numbers") from None
        if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 3:
            raise ParameterError(
                f"{field}.vertices", f"array of shape {v.shape}", "shape (V, 3) with V >= 3"
            )
        try:
            t = np.array(triangles)
        except (TypeError, ValueError):
            raise ParameterError(f"{field}.triangles", triangles, "(T, 3) integers") from None
        if t.ndim != 2 or t.shape[1] != 3 or t.shape[0] < 1:
            raise ParameterError(
                f"{field}.triangles", f"array of shape {t.shape}", "shape (T, 3) with T >= 1"
            )
        if not np.issubdtype(t.dtype, np.integer):
            raise ParameterError(f"{field}.triangles", f"dtype {t.dtype}", "integer indices")
        t = t.astype(np.int64)
        bad = np.nonzero((t < 0) | (t >= v.shape[0]))[0]
        if bad.size:
            k = int(bad[0])
            raise ParameterError(
                f"{field}.triangles[{k}]", t[k].tolist(), f"vertex indices in [0, {v.shape[0]})"
            )
        finite = np.all(np.isfinite(v), axis=1)
        bad = np.nonzero(~np.all(finite[t], axis=1))[0]
        if bad.size:
            k = int(bad[0])
            q = int(t[k][~finite[t[k]]][0])
            raise ParameterError(
                f"{field}.triangles[{k}]",
                f"vertex {q} = {v[q].tolist()}",
                "finite vertex coordinates",
            )
        self.closed = bool(closed)
        self.velocity = vec3(field, "velocity", velocity)
        v, t = _merge_vertices(v, t)
        self._check_triangles(v, t)
        self.vertices = v
        self.triangles = t
        self.vertices.setflags(write=False)
        self.triangles.setflags(write=False)
        cross = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
        norm = np.sqrt(np.sum(cross * cross, axis=1))
        self.normals = cross / norm[:, None]
        self.areas = 0.5 * norm
        self.normals.setflags(write=False)
        self.areas.setflags(write=False)

    # ------------------------------------------------------------------ validation
    def _check_triangles(self, v: np.ndarray, t: np.ndarray) -> None:
        field = self.name
        same = (t[:, 0] == t[:, 1]) | (t[:, 1] == t[:, 2]) | (t[:, 2] == t[:, 0])
        bad = np.nonzero(same)[0]
        if bad.size:
            k = int(bad[0])
            raise ParameterError(
                f"{field}.triangles[{k}]",
                "two of its corners at the same point",
                "a triangle of three distinct vertices (degenerate)",
            )
        e0 = v[t[:, 1]] - v[t[:, 0]]
        e1 = v[t[:, 2]] - v[t[:, 1]]
        e2 = v[t[:, 0]] - v[t[:, 2]]
        longest2 = np.max(np.stack([np.sum(e * e, axis=1) for e in (e0, e1, e2)]), axis=0)
        area2 = np.sum(np.cross(e0, -e2) ** 2, axis=1)  # (2 A)^2
        bad = np.nonzero(~(area2 > (2 * DEGENERATE_AREA) ** 2 * longest2 * longest2))[0]
        if bad.size:
            k = int(bad[0])
            raise ParameterError(
                f"{field}.triangles[{k}]",
                f"area {0.5 * math.sqrt(area2[k]):.3g} m^2",
                f"above {DEGENERATE_AREA:g} x its longest edge squared (degenerate: "
                "collinear vertices)",
            )
        # every edge once per triangle: (triangle, local edge q from corner q to q + 1)
        a = t.reshape(-1)
        b = np.roll(t, -1, axis=1).reshape(-1)
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        key = lo * v.shape[0] + hi
        order = np.argsort(key, kind="stable")
        ks = key[order]
        _, first, counts = np.unique(ks, return_index=True, return_counts=True)
        if np.any(counts > 2):
            g = int(np.nonzero(counts > 2)[0][0])
            k = int(order[first[g] + 2] // 3)
            raise ParameterError(
                f"{field}.triangles[{k}]",
                f"edge ({int(lo[order[first[g]]])}, {int(hi[order[first[g]]])}) shared by "
                f"{int(counts[g])} triangles",
                "an edge shared by at most two triangles (a non-manifold mesh cannot tell "
                "an edge contact from a face contact)",
            )
        if self.closed:
            if np.any(counts == 1):
                g = int(np.nonzero(counts == 1)[0][0])
                k = int(order[first[g]] // 3)
                raise ParameterError(
                    f"{field}.triangles[{k}]",
                    f"open edge ({int(lo[order[first[g]]])}, {int(hi[order[first[g]]])})",
                    "a closed mesh (closed=True): every edge shared by two triangles",
                )
            # a closed, consistently oriented surface runs each edge once each way
            two = np.nonzero(counts == 2)[0]
            x, y = order[first[two]], order[first[two] + 1]
            bad = np.nonzero(a[x] == a[y])[0]
            if bad.size:
                k = int(y[bad[0]] // 3)
                raise ParameterError(
                    f"{field}.triangles[{k}]",
                    "oriented against its neighbour "
                    f"{int(x[bad[0]] // 3)} (they run their shared edge the same way)",
                    "a closed mesh (closed=True) with every triangle oriented alike",
                )

    # ------------------------------------------------------------------ properties
    @property
    def n_triangles(self) -> int:
        """Number of triangles."""
        return int(self.triangles.shape[0])

    @property
    def n_vertices(self) -> int:
        """Number of vertices (after merging)."""
        return int(self.vertices.shape[0])

    def translated(self, offset) -> Mesh:
        """The same mesh moved by ``offset`` [m] (a new mesh)."""
        d = np.asarray(vec3(self.name, "offset", offset))
        return Mesh(
            self.vertices + d,
            self.triangles,
            self.velocity,
            closed=self.closed,
            name=self.name[5:-1] if self.name != "Mesh" else None,
        )

    def __repr__(self) -> str:
        return (
            f"{self.name}: {self.n_triangles} triangles, {self.n_vertices} vertices, "
            f"velocity {self.velocity}"
        )

    # ------------------------------------------------------------------ STL files
    @classmethod
    def from_stl(
        cls,
        path,
        *,
        scale: float = 1.0,
        offset=(0.0, 0.0, 0.0),
        velocity=(0.0, 0.0, 0.0),
        closed: bool = False,
    ) -> Mesh:
        """A mesh read from an STL file, ASCII or binary (as LIGGGHTS' ``mesh/surface``
        reads it, with its ``scale`` and ``move`` options: vertices ``x * scale + offset``
        [m]). The facets' stored normals are not used (each triangle's normal follows its
        vertex order, as in LIGGGHTS). Errors name the file and the triangle (its facet
        number in the file, from 0)."""
        p = Path(path)
        try:
            s = float(scale)
        except (TypeError, ValueError):
            raise ParameterError(f"Mesh({p}).scale", scale, "a positive number") from None
        if not (math.isfinite(s) and s > 0):
            raise ParameterError(f"Mesh({p}).scale", scale, "a positive finite number")
        move = np.asarray(vec3(f"Mesh({p})", "offset", offset))
        corners = read_stl(p)
        n = corners.shape[0]
        vertices = corners.reshape(-1, 3) * s + move
        triangles = np.arange(3 * n, dtype=np.int64).reshape(n, 3)
        return cls(vertices, triangles, velocity, closed=closed, name=str(p))

    def to_stl(self, path, *, binary: bool = False, solid: str = "demscale") -> None:
        """Write the mesh as an STL file (ASCII with 17 significant digits, so that reading
        it back gives the same doubles; binary stores float32)."""
        write_stl(path, self.vertices[self.triangles], binary=binary, solid=solid)


def _merge_vertices(v: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertices with identical coordinates merged and unused ones dropped, the first use
    keeping its place (vertex order follows the triangles)."""
    used = np.unique(t)
    uniq, inverse = np.unique(v[used], axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    # number the unique points in the order their first use appears in the triangles
    remap = np.full(v.shape[0], -1, dtype=np.int64)
    remap[used] = inverse
    tt = remap[t]
    first = np.full(uniq.shape[0], tt.size, dtype=np.int64)
    np.minimum.at(first, tt.reshape(-1), np.arange(tt.size))
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return uniq[order].copy(), rank[tt]


def read_stl(path) -> np.ndarray:
    """The triangles of an STL file as (T, 3, 3) corner coordinates (float64), ASCII or binary
    (a file whose size is 84 + 50 T bytes for the count T in its header is binary, whatever
    its first word). Refuses an empty or malformed file naming it and the facet."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as e:
        raise ParameterError(f"Mesh({p})", str(p), "a readable STL file", str(e)) from None
    if len(data) >= 84:
        (count,) = struct.unpack_from("<I", data, 80)
        if len(data) == 84 + 50 * count:
            if count == 0:
                raise ParameterError(f"Mesh({p})", "0 facets", "at least one triangle")
            rec = np.dtype([("n", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")], align=False)
            return np.frombuffer(data, dtype=rec, count=count, offset=84)["v"].astype(np.float64)
    try:
        text = data.decode("ascii")
    except UnicodeDecodeError:
        raise ParameterError(
            f"Mesh({p})",
            "undecodable bytes",
            "an ASCII STL file, or a binary one of 84 + 50 T bytes",
        ) from None
    words = text.split()
    if not words or words[0].lower() != "solid":
        raise ParameterError(f"Mesh({p})", "no 'solid' keyword", "an ASCII STL file")
    corners: list[list[float]] = []
    facet = -1
    k = 0
    n = len(words)
    while k < n:
        w = words[k].lower()
        if w == "facet":
            facet += 1
            if len(corners) != 3 * facet:
                raise ParameterError(
                    f"Mesh({p}).triangles[{facet - 1}]",
                    f"{len(corners) - 3 * (facet - 1)} vertices",
                    "exactly 3 vertices per facet",
                )
        elif w == "vertex":
            if facet < 0:
                raise ParameterError(f"Mesh({p})", "a vertex before any facet", "an STL file")
            try:
                corners.append([float(words[k + 1]), float(words[k + 2]), float(words[k + 3])])
            except (IndexError, ValueError):
                raise ParameterError(
                    f"Mesh({p}).triangles[{max(facet, 0)}]",
                    " ".join(words[k : k + 4]),
                    "'vertex x y z' with three numbers",
                ) from None
            k += 3
        k += 1
    if facet < 0:
        raise ParameterError(f"Mesh({p})", "0 facets", "at least one triangle")
    if len(corners) != 3 * (facet + 1):
        raise ParameterError(
            f"Mesh({p}).triangles[{facet}]",
            f"{len(corners) - 3 * facet} vertices",
            "exactly 3 vertices per facet",
        )
    return np.asarray(corners, dtype=np.float64).reshape(-1, 3, 3)


def write_stl(path, corners, *, binary: bool = False, solid: str = "demscale") -> None:
    """Write (T, 3, 3) triangle corners [m] as an STL file (facet normals from the vertex
    order), atomically (a temporary file, then renamed)."""
    c = np.asarray(corners, dtype=np.float64).reshape(-1, 3, 3)
    cross = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    norm = np.sqrt(np.sum(cross * cross, axis=1))
    nrm = np.divide(cross, norm[:, None], out=np.zeros_like(cross), where=norm[:, None] > 0)
    p = Path(path)
    tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp")
    if binary:
        rec = np.dtype([("n", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")], align=False)
        out = np.zeros(c.shape[0], dtype=rec)
        out["n"] = nrm
        out["v"] = c
        header = solid.encode("ascii", "replace")[:80].ljust(80, b" ")
        tmp.write_bytes(header + struct.pack("<I", c.shape[0]) + out.tobytes())
    else:
        lines = [f"solid {solid}"]
        for k in range(c.shape[0]):
            lines.append("  facet normal {:.17g} {:.17g} {:.17g}".format(*nrm[k]))
            lines.append("    outer loop")
            for q in range(3):
                lines.append("      vertex {:.17g} {:.17g} {:.17g}".format(*c[k, q]))
            lines.append("    endloop")
            lines.append("  endfacet")
        lines.append(f"endsolid {solid}")
        tmp.write_text("\n".join(lines) + "\n")
    os.replace(tmp, p)


#: Most bin cells of one mesh's grid (the cell size grows until it fits).
MAX_CELLS = 2_000_000


def pack_meshes(meshes, margin: float) -> dict[str, np.ndarray]:
    """The kernel's arrays of ``meshes`` (see :mod:`engine.kernel.mesh`): vertices,
    triangles with their edges, mesh and owner bits, normals, edges with their triangles,
    the edges at each vertex, and each mesh's bin grid for particles within ``margin`` [m]
    (the largest radius plus the skin) of its triangles. Empty arrays without meshes."""
    from ..kernel.mesh import bin_mesh  # compiled on first use

    verts, tris, norms, edges, grids_f, grids_i = [], [], [], [], [], []
    cell_starts, cell_tris = [], []
    vo = to = eo = co = 0
    for m, mesh in enumerate(meshes):
        v, t = mesh.vertices, mesh.triangles
        nv, nt = v.shape[0], t.shape[0]
        a = t.reshape(-1)
        b = np.roll(t, -1, axis=1).reshape(-1)
        key = np.minimum(a, b) * nv + np.maximum(a, b)
        uniq, inv = np.unique(key, return_inverse=True)
        inv = inv.reshape(-1)
        ne = uniq.size
        occ = np.lexsort((np.arange(3 * nt), inv))  # by edge, then by triangle
        start = np.searchsorted(inv[occ], np.arange(ne))
        count = np.bincount(inv, minlength=ne)
        first = occ[start]
        second = np.where(count == 2, occ[np.minimum(start + 1, occ.size - 1)], -1)
        e = np.empty((ne, 6), dtype=np.int64)
        e[:, 0] = uniq // nv + vo
        e[:, 1] = uniq % nv + vo
        e[:, 2] = first // 3 + to
        e[:, 3] = first % 3
        e[:, 4] = np.where(second >= 0, second // 3 + to, -1)
        e[:, 5] = np.where(second >= 0, second % 3, 0)
        own = np.zeros(nt, dtype=np.int64)
        np.bitwise_or.at(own, first // 3, 1 << (first % 3))
        _, vfirst = np.unique(a, return_index=True)  # every vertex is used (merged)
        np.bitwise_or.at(own, vfirst // 3, 8 << (vfirst % 3))
        tri = np.empty((nt, 8), dtype=np.int64)
        tri[:, 0:3] = t + vo
        tri[:, 3:6] = inv.reshape(nt, 3) + eo
        tri[:, 6] = m
        tri[:, 7] = own
        verts.append(v)
        tris.append(tri)
        norms.append(mesh.normals)
        edges.append(e)
        # the bin grid, in the mesh's own frame: its bounding box widened by the margin
        lo = v.min(axis=0) - margin
        ext = v.max(axis=0) + margin - lo
        h = 2.0 * margin
        ncell = np.maximum(1, np.ceil(ext / h)).astype(np.int64)
        while int(np.prod(ncell)) > MAX_CELLS:
            h *= 1.25
            ncell = np.maximum(1, np.ceil(ext / h)).astype(np.int64)
        grids_f.append([lo[0], lo[1], lo[2], h])
        grids_i.append([ncell[0], ncell[1], ncell[2], co])
        mv = np.concatenate(verts)
        cs, ct = bin_mesh(mv, np.concatenate(tris), to, to + nt, lo, h, ncell, float(margin))
        cell_starts.append(cs[:-1] + sum(c.size for c in cell_tris))
        cell_tris.append(ct)
        vo += nv
        to += nt
        eo += ne
        co += int(np.prod(ncell))
    nv_all = vo
    medge = np.concatenate(edges) if edges else np.zeros((0, 6), dtype=np.int64)
    ends = np.concatenate([medge[:, 0], medge[:, 1]])
    ids = np.concatenate([np.arange(medge.shape[0])] * 2)
    order = np.argsort(ends, kind="stable")
    vert_start = np.zeros(nv_all + 1, dtype=np.int64)
    np.add.at(vert_start, ends + 1, 1)
    cell_tri = np.concatenate(cell_tris) if cell_tris else np.zeros(0, dtype=np.int32)
    cell_start = np.concatenate([*cell_starts, [cell_tri.size]]).astype(np.int64)
    return {
        "mvert": np.concatenate(verts) if verts else np.zeros((0, 3)),
        "mtri": np.concatenate(tris) if tris else np.zeros((0, 8), dtype=np.int64),
        "mtri_n": np.concatenate(norms) if norms else np.zeros((0, 3)),
        "medge": medge,
        "mvert_start": np.cumsum(vert_start),
        "mvert_edge": ids[order].astype(np.int64),
        "gridf": np.array(grids_f, dtype=np.float64).reshape(-1, 4),
        "gridi": np.array(grids_i, dtype=np.int64).reshape(-1, 4),
        "cell_start": cell_start,
        "cell_tri": cell_tri.astype(np.int32),
    }
