"""Triangle-mesh walls in the step kernel: the geometry of a sphere against a mesh, the broad
phase (triangles binned once per mesh, each particle's candidate triangles rebuilt with the
Verlet list) and the layout of the mesh arrays (docs/MESH.md).

A sphere meets a mesh at the local minima of its distance to the mesh's surface: one contact
per touching surface patch, each on a face interior, an edge or a vertex, found by the
feature that holds the closest point (Ericson, Real-Time Collision Detection, 2005, 5.1.5:
the Voronoi regions of a triangle) and kept only where that point is a local minimum over
the whole mesh, not only over one triangle:

- face t: the projection of the centre p lies strictly inside t: every edge function
  ``s(t, q) = n_t . ((b - a) x (p - a))`` of its edges (a, b) is positive;
- edge e: the closest point of its segment lies strictly inside it (both end dots
  ``(p - v) . (w - v)`` positive) and no triangle beside e has p's projection on its side of
  e (``s <= 0`` for each of the one or two triangles that share it, the same numbers the
  face test reads);
- vertex v: ``(p - v) . (w - v) <= 0`` for every edge (v, w) that meets at v (the same
  numbers the edge test reads).

The three tests split space without overlap wherever they read the same numbers: a face and
its edge read ``s(t, q)`` (> 0 against <= 0), an edge and its end vertex the end dot (> 0
against <= 0), every copy of which is computed by the same function from the same vertices
(each shared edge and vertex is evaluated once, by its *owner*: the triangle of lowest index
that holds it). What the rounding of two different numbers can still double (two coplanar
faces both claiming a centre that lies on their shared edge to within rounding, a face and
its own corner) gives two closest points a rounding error apart: contacts of one mesh whose
closest points lie within ``SAME_POINT`` x the radius of one counted before are the same
contact and not counted again. Should the rounding leave a mesh that a particle touches with
no contact at all, its nearest point is taken (it is always a local minimum).

Arrays (every mesh of a scene concatenated, indices global):

- ``mvert`` (V, 3): vertex coordinates at time 0 [m]; a mesh's current position adds its
  translation (its row ``n_planes + m`` of the walls' ``point``);
- ``mtri`` (T, 8) int64: the three vertices, the edges from corner q to q + 1 (3), the mesh,
  the owner bits (bit q: owns its edge q; bit 3 + q: owns its corner q);
- ``mtri_n`` (T, 3): unit normals (right hand around the vertex order);
- ``medge`` (E, 6) int64: its vertices (lower id first), the first triangle that holds it and
  its local edge index there, the second (-1, 0 on the border of the mesh);
- ``mvert_start`` (V + 1,), ``mvert_edge`` (2E,): the edges that meet at each vertex (CSR);
- ``gridf`` (M, 4): each mesh's bin grid origin (3) and cell size [m], in the mesh's own
  frame; ``gridi`` (M, 4) int64: cells per axis (3) and the offset of its first cell in
  ``cell_start`` ((cells + 1,)) and ``cell_tri``: the triangles of each cell, increasing;
- ``cand_start`` (N + 1,), ``cand_t``: each particle's candidate triangles (increasing: by
  mesh, then triangle), those within its radius plus the skin at the last list build;
- ``mhist`` (N (MESH_SLOTS + 1), N_WALL_HIST + 5): per particle ``MESH_SLOTS`` contact rows
  (the composition's history, then the contact point in the mesh's frame (3) [m], the mesh
  + 1 (0: a free row) and the overlap [m]) and one spare row for a contact beyond them (no
  history kept);
- ``mscr`` (rows, MESH_CONTACTS, SCRATCH_WIDTH): the contacts of the particle in hand
  (point (3), normal (3), overlap, mesh, row); a row per CPU chunk, per particle on CUDA.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..core.config import NJIT, NJIT_INLINE

#: Contact rows kept per particle across steps (contacts with meshes at once).
MESH_SLOTS = 4
#: Contacts of one particle with the meshes in one step (more are not counted).
MESH_CONTACTS = 8
#: Columns of a contact in ``mscr``: point (3), normal (3), overlap, mesh, its ``mhist`` row.
SCRATCH_WIDTH = 9
#: Two contacts of one particle with one mesh whose closest points lie within this fraction
#: of its radius are one contact (rounding apart).
SAME_POINT = 1e-9
#: Columns of ``mtri``.
T_MESH = 6
T_OWN = 7


@njit(**NJIT_INLINE)
def edge_function(mvert, mtri_n, t, a, b, px, py, pz):
    """``n_t . ((b - a) x (p - a))`` for the edge (a, b) of triangle t (vertex ids): positive
    when p projects onto t's side of the line ab [m^2]. The one function every test that
    reads it calls (the face test and the edge test of its neighbour)."""
    ax = mvert[a, 0]
    ay = mvert[a, 1]
    az = mvert[a, 2]
    ex = mvert[b, 0] - ax
    ey = mvert[b, 1] - ay
    ez = mvert[b, 2] - az
    qx = px - ax
    qy = py - ay
    qz = pz - az
    return (
        mtri_n[t, 0] * (ey * qz - ez * qy)
        + mtri_n[t, 1] * (ez * qx - ex * qz)
        + mtri_n[t, 2] * (ex * qy - ey * qx)
    )


@njit(**NJIT_INLINE)
def end_dot(mvert, v, w, px, py, pz):
    """``(p - v) . (w - v)`` [m^2]: positive when p projects past v onto the edge (v, w)."""
    return (
        (px - mvert[v, 0]) * (mvert[w, 0] - mvert[v, 0])
        + (py - mvert[v, 1]) * (mvert[w, 1] - mvert[v, 1])
        + (pz - mvert[v, 2]) * (mvert[w, 2] - mvert[v, 2])
    )


@njit(**NJIT_INLINE)
def triangle_distance2(mvert, mtri, t, px, py, pz):
    """Squared distance from p to triangle t [m^2] (Ericson's closest point by Voronoi
    region; for the broad phase)."""
    a = mtri[t, 0]
    b = mtri[t, 1]
    c = mtri[t, 2]
    ax = mvert[a, 0]
    ay = mvert[a, 1]
    az = mvert[a, 2]
    abx = mvert[b, 0] - ax
    aby = mvert[b, 1] - ay
    abz = mvert[b, 2] - az
    acx = mvert[c, 0] - ax
    acy = mvert[c, 1] - ay
    acz = mvert[c, 2] - az
    apx = px - ax
    apy = py - ay
    apz = pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    qx = ax
    qy = ay
    qz = az
    if not (d1 <= 0.0 and d2 <= 0.0):
        bpx = px - mvert[b, 0]
        bpy = py - mvert[b, 1]
        bpz = pz - mvert[b, 2]
        d3 = abx * bpx + aby * bpy + abz * bpz
        d4 = acx * bpx + acy * bpy + acz * bpz
        cpx = px - mvert[c, 0]
        cpy = py - mvert[c, 1]
        cpz = pz - mvert[c, 2]
        d5 = abx * cpx + aby * cpy + abz * cpz
        d6 = acx * cpx + acy * cpy + acz * cpz
        vc = d1 * d4 - d3 * d2
        vb = d5 * d2 - d1 * d6
        va = d3 * d6 - d5 * d4
        if d3 >= 0.0 and d4 <= d3:
            qx = mvert[b, 0]
            qy = mvert[b, 1]
            qz = mvert[b, 2]
        elif d6 >= 0.0 and d5 <= d6:
            qx = mvert[c, 0]
            qy = mvert[c, 1]
            qz = mvert[c, 2]
        elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
            s = d1 / (d1 - d3)
            qx = ax + s * abx
            qy = ay + s * aby
            qz = az + s * abz
        elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
            s = d2 / (d2 - d6)
            qx = ax + s * acx
            qy = ay + s * acy
            qz = az + s * acz
        elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
            s = (d4 - d3) / ((d4 - d3) + (d5 - d6))
            qx = mvert[b, 0] + s * (mvert[c, 0] - mvert[b, 0])
            qy = mvert[b, 1] + s * (mvert[c, 1] - mvert[b, 1])
            qz = mvert[b, 2] + s * (mvert[c, 2] - mvert[b, 2])
        else:
            den = 1.0 / (va + vb + vc)
            v = vb * den
            w = vc * den
            qx = ax + abx * v + acx * w
            qy = ay + aby * v + acy * w
            qz = az + abz * v + acz * w
    dx = px - qx
    dy = py - qy
    dz = pz - qz
    return dx * dx + dy * dy + dz * dz


@njit(**NJIT)
def mesh_scan(
    i, pos, rad, skin, wpoint, nw, mvert, mtri, gridf, gridi, cell_start, cell_tri, out, offset
):
    """Count the candidate triangles of particle i (within its radius plus ``skin`` [m] of its
    centre ``pos[i]``, each mesh at its translation ``wpoint[nw + m]``), storing them from
    ``out[offset]`` while they fit; increasing triangle ids (the meshes in order, each
    cell's triangles in order). The CPU build's and the CUDA build's (a device function)."""
    cnt = 0
    cut = rad[i] + skin
    cut2 = cut * cut
    for m in range(gridf.shape[0]):
        px = pos[i, 0] - wpoint[nw + m, 0]
        py = pos[i, 1] - wpoint[nw + m, 1]
        pz = pos[i, 2] - wpoint[nw + m, 2]
        h = gridf[m, 3]
        cx = math.floor((px - gridf[m, 0]) / h)
        cy = math.floor((py - gridf[m, 1]) / h)
        cz = math.floor((pz - gridf[m, 2]) / h)
        if cx < 0 or cy < 0 or cz < 0:
            continue
        if cx >= gridi[m, 0] or cy >= gridi[m, 1] or cz >= gridi[m, 2]:
            continue
        cell = gridi[m, 3] + (int(cx) * gridi[m, 1] + int(cy)) * gridi[m, 2] + int(cz)
        for k in range(cell_start[cell], cell_start[cell + 1]):
            t = cell_tri[k]
            if triangle_distance2(mvert, mtri, t, px, py, pz) < cut2:
                if offset + cnt < out.shape[0]:
                    out[offset + cnt] = t
                cnt += 1
    return cnt


@njit(**NJIT_INLINE)
def clear_rows(i, cand_start, mhist):
    """Forget the mesh contacts of particle i when it has no candidate triangle (a contact
    always has one; rows left by a particle moved away by hand would otherwise wait there)."""
    if cand_start[i + 1] == cand_start[i]:
        per = mhist.shape[0] // (cand_start.shape[0] - 1)
        for r in range(i * per, (i + 1) * per):
            for s in range(mhist.shape[1]):
                mhist[r, s] = 0.0


@njit(**NJIT)
def build_mesh_candidates(
    pos, rad, skin, wpoint, nw, mvert, mtri, gridf, gridi, cell_start, cell_tri, cand_start, cand_t
):
    """Every particle's candidate triangles (:func:`mesh_scan`) into the CSR ``cand_start``,
    ``cand_t``. Returns the number of entries, or minus the number needed when it exceeds
    the capacity ``cand_t.shape[0]`` (then ``cand_start`` is stale: the caller grows
    ``cand_t`` and builds again)."""
    n = pos.shape[0]
    cand_start[0] = 0
    for i in range(n):
        cand_start[i + 1] = cand_start[i] + mesh_scan(
            i,
            pos,
            rad,
            skin,
            wpoint,
            nw,
            mvert,
            mtri,
            gridf,
            gridi,
            cell_start,
            cell_tri,
            cand_t,
            cand_start[i],
        )
    total = cand_start[n]
    if total > cand_t.shape[0]:
        return -total
    return total


@njit(**NJIT)
def clear_idle_rows(cand_start, mhist):
    """:func:`clear_rows` for every particle (after a build)."""
    for i in range(cand_start.shape[0] - 1):
        clear_rows(i, cand_start, mhist)


@njit(**NJIT)
def bin_mesh(mvert, mtri, t_lo, t_hi, origin, h, ncell, margin):
    """The triangles t_lo to t_hi - 1 of one mesh binned on its grid (``origin`` [m], cell
    size ``h`` [m], ``ncell`` cells per axis): a cell lists every triangle within
    ``margin`` [m] of some point of the cell (the distance from its centre below half its
    diagonal plus ``margin``), so that a particle in the cell finds there every triangle
    within ``margin`` of its centre. Returns (cell_start, cell_tri), triangles increasing."""
    nx = ncell[0]
    ny = ncell[1]
    nz = ncell[2]
    reach = 0.5 * math.sqrt(3.0) * h + margin
    reach2 = reach * reach
    cell_start = np.zeros(nx * ny * nz + 1, dtype=np.int64)
    lo = np.empty(3, dtype=np.int64)
    hi = np.empty(3, dtype=np.int64)
    for sweep in range(2):
        if sweep == 1:
            for c in range(nx * ny * nz):
                cell_start[c + 1] += cell_start[c]
            cell_tri = np.empty(cell_start[nx * ny * nz], dtype=np.int32)
            fill = cell_start[:-1].copy()
        else:
            cell_tri = np.empty(0, dtype=np.int32)
            fill = np.empty(0, dtype=np.int64)
        for t in range(t_lo, t_hi):
            for a in range(3):
                mn = min(mvert[mtri[t, 0], a], mvert[mtri[t, 1], a], mvert[mtri[t, 2], a])
                mx = max(mvert[mtri[t, 0], a], mvert[mtri[t, 1], a], mvert[mtri[t, 2], a])
                lo[a] = max(0, math.floor((mn - margin - origin[a]) / h))
                hi[a] = min(ncell[a] - 1, math.floor((mx + margin - origin[a]) / h))
            for cx in range(lo[0], hi[0] + 1):
                for cy in range(lo[1], hi[1] + 1):
                    for cz in range(lo[2], hi[2] + 1):
                        x = origin[0] + (cx + 0.5) * h
                        y = origin[1] + (cy + 0.5) * h
                        z = origin[2] + (cz + 0.5) * h
                        if triangle_distance2(mvert, mtri, t, x, y, z) > reach2:
                            continue
                        c = (cx * ny + cy) * nz + cz
                        if sweep == 0:
                            cell_start[c + 1] += 1
                        else:
                            cell_tri[fill[c]] = t
                            fill[c] += 1
    return cell_start, cell_tri


@njit(**NJIT)
def mesh_drift2(wpoint, wvel, mshift0, nw, dt):
    """The largest squared distance a mesh will have moved since the last list build after
    the coming step [m^2] (its translation ``wpoint[nw + m]`` plus ``wvel[nw + m] dt``
    against its translation at the build ``mshift0[m]``): a particle's candidate triangles
    hold while it and the meshes each moved less than half the skin."""
    d2 = 0.0
    for m in range(mshift0.shape[0]):
        dx = wpoint[nw + m, 0] + wvel[nw + m, 0] * dt - mshift0[m, 0]
        dy = wpoint[nw + m, 1] + wvel[nw + m, 1] * dt - mshift0[m, 1]
        dz = wpoint[nw + m, 2] + wvel[nw + m, 2] * dt - mshift0[m, 2]
        d2 = max(d2, dx * dx + dy * dy + dz * dz)
    return d2
