"""Contact search: broad phase on body bounding boxes, narrow phase on surface facets.

Broad phase: axis-aligned bounding boxes of every body's current surface, inflated by the search
distance; candidate (slave body, master body, lattice shift) triples whose boxes overlap, found
with a k-d tree on box centres. Periodic images enter as a shift added to the master surface
(``shifts``: (m, 3) lattice vectors, the zero shift included).

Narrow phase (numba, parallel over candidate pairs): every slave node inside the master's
inflated box is projected onto the master facets whose inflated boxes contain it (closest-point
projection, Gauss-Newton on the bilinear / linear facet map). Result per contact point: master
facet, parametric coordinates, normal gap (mm, < 0 = overlap) and the master's outward unit
normal at the projection. Both bodies of a pair are searched as slave in turn (two-pass,
symmetric: no body is privileged); the forces of each pass are weighted by 1/2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from scipy.spatial import cKDTree

#: a slave facet carries contact area only if n_slave_facet . n_master < -FACING
FACING = 0.2
#: a master facet is a candidate for a slave node only if n_master . n_node < -SEARCH_FACING
#: (opposing surfaces; 0 = anything beyond perpendicular)
SEARCH_FACING = 0.0
#: facets meeting at less than this angle (degrees) share their corner normals (smoothed master
#: normal); the facets of a particle mesh meet at ~10-30 degrees, a block's edges at 90
FEATURE_ANGLE = 45.0


@dataclass
class ContactPoints:
    """Contact points found by the narrow phase (arrays of equal length n)."""

    slave: np.ndarray  # (n,) surface node of the slave body
    master_body: np.ndarray  # (n,) body id of the master
    facet: np.ndarray  # (n,) master facet
    xi: np.ndarray  # (n, 2) parametric coordinates on the facet
    gap: np.ndarray  # (n,) normal gap, mm (< 0: overlap)
    normal: np.ndarray  # (n, 3) master outward unit normal
    shift: np.ndarray  # (n, 3) lattice shift applied to the master (mm)
    shift_index: np.ndarray  # (n,) index of that shift in the search's ``shifts``

    @property
    def size(self) -> int:
        """Number of slave points."""
        return self.slave.size

    @staticmethod
    def empty() -> ContactPoints:
        """No slave points."""
        i0 = np.zeros(0, np.int64)
        return ContactPoints(
            i0, i0, i0, np.zeros((0, 2)), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)), i0
        )


def body_boxes(x: np.ndarray, node_body: np.ndarray, num_bodies: int) -> np.ndarray:
    """(num_bodies, 2, 3) min/max corners of every body's surface nodes."""
    boxes = np.empty((num_bodies, 2, 3))
    for d in range(3):  # 3 vectorized reductions, not a loop over nodes
        boxes[:, 0, d] = np.full(num_bodies, np.inf)
        boxes[:, 1, d] = np.full(num_bodies, -np.inf)
        np.minimum.at(boxes[:, 0, d], node_body, x[:, d])
        np.maximum.at(boxes[:, 1, d], node_body, x[:, d])
    return boxes


@numba.njit(cache=True)
def _sphere_radii(x, node_body, spheres):
    for i in range(x.shape[0]):
        b = node_body[i]
        r = np.sqrt(
            (x[i, 0] - spheres[b, 0]) ** 2
            + (x[i, 1] - spheres[b, 1]) ** 2
            + (x[i, 2] - spheres[b, 2]) ** 2
        )
        spheres[b, 3] = max(spheres[b, 3], r)


def body_spheres(
    x: np.ndarray, node_body: np.ndarray, num_bodies: int, boxes: np.ndarray
) -> np.ndarray:
    """(num_bodies, 4): centre (the box centre) and radius of a sphere holding every surface node
    of each body (a tighter filter than the box for round particles)."""
    spheres = np.zeros((num_bodies, 4))
    spheres[:, :3] = 0.5 * (boxes[:, 0] + boxes[:, 1])
    _sphere_radii(x, node_body, spheres)
    return spheres


@numba.njit(parallel=True, cache=True)
def _boxes_hold_a_point(lo, hi, points, cell_start, origin, cell, dims, out):
    for i in numba.prange(lo.shape[0]):
        first = np.empty(3, np.int64)
        last = np.empty(3, np.int64)
        empty = False
        for d in range(3):
            first[d] = max(int(np.floor((lo[i, d] - origin[d]) / cell)), 0)
            last[d] = min(int(np.floor((hi[i, d] - origin[d]) / cell)), dims[d] - 1)
            if first[d] > last[d]:
                empty = True
        if empty:
            continue
        found = False
        for a in range(first[0], last[0] + 1):
            for b in range(first[1], last[1] + 1):
                for c in range(first[2], last[2] + 1):
                    k = (a * dims[1] + b) * dims[2] + c
                    for j in range(cell_start[k], cell_start[k + 1]):
                        inside = True
                        for d in range(3):
                            if points[j, d] < lo[i, d] or points[j, d] > hi[i, d]:
                                inside = False
                        if inside:
                            found = True
                            break
                    if found:
                        break
                if found:
                    break
            if found:
                break
        out[i] = found


def boxes_hold_a_point(lo: np.ndarray, hi: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Which axis-aligned boxes [lo_i, hi_i] ((m, 3) each) hold at least one of ``points``
    (n, 3), bounds included: a uniform grid of cells as large as the largest box side (at most
    ~2 million cells), each box testing the points of the cells it overlaps."""
    out = np.zeros(lo.shape[0], dtype=np.bool_)
    if lo.shape[0] == 0 or points.shape[0] == 0:
        return out
    origin = points.min(axis=0)
    extent = points.max(axis=0) - origin
    cell = max(float((hi - lo).max()), float(extent.max()) / 128.0, 1e-300)
    dims = (extent // cell).astype(np.int64) + 1
    index = np.minimum(((points - origin) // cell).astype(np.int64), dims - 1)
    key = (index[:, 0] * dims[1] + index[:, 1]) * dims[2] + index[:, 2]
    order = np.argsort(key, kind="stable")
    cell_start = np.searchsorted(key[order], np.arange(int(dims.prod()) + 1)).astype(np.int64)
    _boxes_hold_a_point(lo, hi, points[order], cell_start, origin, cell, dims, out)
    return out


def candidate_pairs(
    boxes: np.ndarray,
    distance: float,
    shifts: np.ndarray | None = None,
    allowed: np.ndarray | None = None,
    slaves: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Ordered (slave, master) body pairs with overlapping inflated boxes, and the shift index.

    Returns pairs (m, 2) and shift indices (m,). ``allowed`` (num_bodies, num_bodies) bool can
    exclude pairs (e.g. a rigid base that never acts as slave); ``slaves``: the bodies that may
    be slaves (default: all).
    """
    if shifts is None:
        shifts = np.zeros((1, 3))
    slaves = np.arange(boxes.shape[0]) if slaves is None else np.asarray(slaves, np.int64)
    if slaves.size == 0 or boxes.shape[0] == 0:
        return np.zeros((0, 2), np.int64), np.zeros(0, np.int64)
    lo = boxes[:, 0] - distance
    hi = boxes[:, 1] + distance
    centres = 0.5 * (lo + hi)
    half = 0.5 * (hi - lo)
    reach = 2.0 * np.linalg.norm(half, axis=1).max()
    tree = cKDTree(centres[slaves])
    out_pairs, out_shift = [], []
    for k, shift in enumerate(shifts):  # a handful of lattice shifts (27 at most)
        # image of master b sits at box(b) + shift: query the tree of slave boxes around it
        hits = tree.query_ball_point(centres + shift, r=reach)
        slave = slaves[np.concatenate([np.asarray(h, dtype=np.int64) for h in hits])]
        master = np.repeat(np.arange(len(hits)), [len(h) for h in hits])
        overlap = np.all(
            (lo[slave] <= hi[master] + shift) & (lo[master] + shift <= hi[slave]), axis=1
        )
        keep = overlap & ((slave != master) | np.any(shift != 0.0))
        if allowed is not None:
            keep &= allowed[slave, master]
        out_pairs.append(np.stack([slave[keep], master[keep]], axis=1))
        out_shift.append(np.full(keep.sum(), k, dtype=np.int64))
    return np.concatenate(out_pairs).astype(np.int64), np.concatenate(out_shift)


@numba.njit(cache=True, inline="always")
def _facet_point(x, i0, i1, i2, i3, nv, xi, eta):
    """Point (px, py, pz) and tangents d/dxi (ax, ay, az), d/deta (bx, by, bz) at (xi, eta) of the
    bilinear quadrilateral (nv = 4, lexicographic corners) or linear triangle (nv = 3, i3 unused)
    with corners the rows i0..i3 of x; scalars, no arrays (called in every projection's Newton
    loop)."""
    if nv == 4:
        n0 = (1 - xi) * (1 - eta)
        n1 = xi * (1 - eta)
        n2 = (1 - xi) * eta
        n3 = xi * eta
        px = n0 * x[i0, 0] + n1 * x[i1, 0] + n2 * x[i2, 0] + n3 * x[i3, 0]
        py = n0 * x[i0, 1] + n1 * x[i1, 1] + n2 * x[i2, 1] + n3 * x[i3, 1]
        pz = n0 * x[i0, 2] + n1 * x[i1, 2] + n2 * x[i2, 2] + n3 * x[i3, 2]
        ax = (1 - eta) * (x[i1, 0] - x[i0, 0]) + eta * (x[i3, 0] - x[i2, 0])
        ay = (1 - eta) * (x[i1, 1] - x[i0, 1]) + eta * (x[i3, 1] - x[i2, 1])
        az = (1 - eta) * (x[i1, 2] - x[i0, 2]) + eta * (x[i3, 2] - x[i2, 2])
        bx = (1 - xi) * (x[i2, 0] - x[i0, 0]) + xi * (x[i3, 0] - x[i1, 0])
        by = (1 - xi) * (x[i2, 1] - x[i0, 1]) + xi * (x[i3, 1] - x[i1, 1])
        bz = (1 - xi) * (x[i2, 2] - x[i0, 2]) + xi * (x[i3, 2] - x[i1, 2])
    else:
        px = (1 - xi - eta) * x[i0, 0] + xi * x[i1, 0] + eta * x[i2, 0]
        py = (1 - xi - eta) * x[i0, 1] + xi * x[i1, 1] + eta * x[i2, 1]
        pz = (1 - xi - eta) * x[i0, 2] + xi * x[i1, 2] + eta * x[i2, 2]
        ax = x[i1, 0] - x[i0, 0]
        ay = x[i1, 1] - x[i0, 1]
        az = x[i1, 2] - x[i0, 2]
        bx = x[i2, 0] - x[i0, 0]
        by = x[i2, 1] - x[i0, 1]
        bz = x[i2, 2] - x[i0, 2]
    return px, py, pz, ax, ay, az, bx, by, bz


@numba.njit(cache=True, inline="always")
def _solve3(a00, a01, a02, a10, a11, a12, a20, a21, a22, b0, b1, b2):
    """Solution of the 3x3 system a y = b (Cramer); zeros if singular."""
    c00 = a11 * a22 - a12 * a21
    c01 = a12 * a20 - a10 * a22
    c02 = a10 * a21 - a11 * a20
    det = a00 * c00 + a01 * c01 + a02 * c02
    if det == 0.0:
        return 0.0, 0.0, 0.0
    y0 = (c00 * b0 + (a02 * a21 - a01 * a22) * b1 + (a01 * a12 - a02 * a11) * b2) / det
    y1 = (c01 * b0 + (a00 * a22 - a02 * a20) * b1 + (a02 * a10 - a00 * a12) * b2) / det
    y2 = (c02 * b0 + (a01 * a20 - a00 * a21) * b1 + (a00 * a11 - a01 * a10) * b2) / det
    return y0, y1, y2


@numba.njit(cache=True)
def project_point(p, x, f, nv, cn, res):
    """Projection of p on facet f along the facet's smoothed normal field.

    The master normal is interpolated from the facet's corner normals ``cn`` (nv, 3) with the
    facet's shape functions, m(xi) = sum_i N_i(xi) cn_i, and the projection solves
    p = x(xi) + t m(xi) for (xi, eta, t) by Newton: a ray from the surface along m through p.
    Corner normals shared by neighbouring facets make the normal, the projection and the gap
    continuous across facet edges (a penetrated node near an edge of a convex master no longer
    jumps between two facets' planes). With equal corner normals (a planar facet, or a sharp
    feature) this is the closest-point projection.

    res = [xi, eta, gap, nx, ny, nz, distance, inside]: parametric point (clamped to the facet
    when the ray leaves it), normal gap (mm, < 0 = overlap), unit normal m / |m|, distance from
    p to the facet point, and 1 if the ray hits the facet.
    """
    i0, i1, i2 = f[0], f[1], f[2]
    i3 = f[3] if nv == 4 else f[0]
    xi = 1.0 / 3.0 if nv == 3 else 0.5
    eta = xi
    qx, qy, qz, ax, ay, az, bx, by, bz = _facet_point(x, i0, i1, i2, i3, nv, xi, eta)
    mx, my, mz, max_, may, maz, mbx, mby, mbz = _facet_point(cn, 0, 1, 2, 3, nv, xi, eta)
    mm = mx * mx + my * my + mz * mz
    t = ((p[0] - qx) * mx + (p[1] - qy) * my + (p[2] - qz) * mz) / mm
    converged = False
    for _it in range(20):
        s0, s1, s2 = _solve3(
            ax + t * max_,
            bx + t * mbx,
            mx,
            ay + t * may,
            by + t * mby,
            my,
            az + t * maz,
            bz + t * mbz,
            mz,
            p[0] - qx - t * mx,
            p[1] - qy - t * my,
            p[2] - qz - t * mz,
        )
        xi += s0
        eta += s1
        t += s2
        qx, qy, qz, ax, ay, az, bx, by, bz = _facet_point(x, i0, i1, i2, i3, nv, xi, eta)
        mx, my, mz, max_, may, maz, mbx, mby, mbz = _facet_point(cn, 0, 1, 2, 3, nv, xi, eta)
        if abs(s0) + abs(s1) < 1e-12:
            converged = True
            break
        if abs(xi) + abs(eta) > 10.0:  # no ray through p near this facet
            break
    # a ray that did not converge does not hit the facet (far points, strongly curved fields):
    # the facet then only competes through its clamped point
    tol = 1e-6
    if nv == 4:
        inside = converged and (-tol <= xi <= 1 + tol) and (-tol <= eta <= 1 + tol)
        xi = min(max(xi, 0.0), 1.0)
        eta = min(max(eta, 0.0), 1.0)
    else:
        inside = converged and xi >= -tol and eta >= -tol and xi + eta <= 1 + tol
        xi = max(xi, 0.0)
        eta = max(eta, 0.0)
        s = xi + eta
        if s > 1.0:
            xi /= s
            eta /= s
    qx, qy, qz, ax, ay, az, bx, by, bz = _facet_point(x, i0, i1, i2, i3, nv, xi, eta)
    mx, my, mz, max_, may, maz, mbx, mby, mbz = _facet_point(cn, 0, 1, 2, 3, nv, xi, eta)
    norm = np.sqrt(mx * mx + my * my + mz * mz)
    nx = mx / norm
    ny = my / norm
    nz = mz / norm
    gap = (p[0] - qx) * nx + (p[1] - qy) * ny + (p[2] - qz) * nz
    dist = np.sqrt((p[0] - qx) ** 2 + (p[1] - qy) ** 2 + (p[2] - qz) ** 2)
    res[0] = xi
    res[1] = eta
    res[2] = gap
    res[3] = nx
    res[4] = ny
    res[5] = nz
    res[6] = dist
    res[7] = 1.0 if inside else 0.0


@numba.njit(cache=True, inline="always")
def _near_master(x, s, sh, mb, body_box, body_sphere, distance, p):
    """Slave node s, moved to the master's unshifted frame (written to p), lies within the
    search distance of master mb's box and of its bounding sphere (much tighter for a particle)."""
    for d in range(3):
        p[d] = x[s, d] - sh[d]
    for d in range(3):
        if p[d] < body_box[mb, 0, d] - distance or p[d] > body_box[mb, 1, d] + distance:
            return False
    r2 = 0.0
    for d in range(3):
        r2 += (p[d] - body_sphere[mb, d]) ** 2
    reach = body_sphere[mb, 3] + distance
    return r2 <= reach * reach


@numba.njit(parallel=True, cache=True)
def _near_counts(
    x, body_box, body_sphere, slave_ptr, slave_nodes, pairs, pair_shift, distance, counts
):
    """counts[k]: slave nodes of pair k near its master (``_near_master``), the narrow phase's
    candidates; sizing the outputs by them (not by every slave node of every pair, ~100x more)
    keeps the search's memory small."""
    for k in numba.prange(pairs.shape[0]):
        p = np.empty(3)
        n = 0
        for i in range(slave_ptr[pairs[k, 0]], slave_ptr[pairs[k, 0] + 1]):
            if _near_master(
                x, slave_nodes[i], pair_shift[k], pairs[k, 1], body_box, body_sphere, distance, p
            ):
                n += 1
        counts[k] = n


@numba.njit(parallel=True, cache=True)
def _narrow_phase(
    x,
    facets,
    nv,
    corner,
    facet_box,
    facet_normal,
    node_normal,
    body_box,
    body_sphere,
    body_facet_ptr,
    body_facets,
    slave_ptr,
    slave_nodes,
    pairs,
    pair_shift,
    distance,
    offsets,
    out_slave,
    out_master,
    out_facet,
    out_xi,
    out_gap,
    out_normal,
    out_shift,
    out_valid,
):
    npairs = pairs.shape[0]
    for k in numba.prange(npairs):
        sb = pairs[k, 0]
        mb = pairs[k, 1]
        sh = pair_shift[k]
        res = np.empty(8)
        p = np.empty(3)
        best = np.empty(8)
        pos = offsets[k]
        for i in range(slave_ptr[sb], slave_ptr[sb + 1]):
            s = slave_nodes[i]
            if _near_master(x, s, sh, mb, body_box, body_sphere, distance, p):
                out_valid[pos] = False
                best_score = np.inf
                found = False
                for j in range(body_facet_ptr[mb], body_facet_ptr[mb + 1]):
                    f = body_facets[j]
                    skip = False
                    for d in range(3):
                        if (
                            p[d] < facet_box[f, 0, d] - distance
                            or p[d] > facet_box[f, 1, d] + distance
                        ):
                            skip = True
                    if skip:
                        continue
                    # the master facet must face the slave surface (excludes, e.g., the side
                    # faces of a box seen from the corner of a block resting on it)
                    facing = 0.0
                    for d in range(3):
                        facing += facet_normal[f, d] * node_normal[s, d]
                    if facing > -SEARCH_FACING:
                        continue
                    project_point(p, x, facets[f], nv, corner[f], res)
                    # prefer projections inside a facet; among them the smallest distance
                    score = res[6] + (0.0 if res[7] > 0.5 else 1e3 * distance + res[6])
                    if score < best_score:
                        best_score = score
                        best[:] = res
                        found = True
                        out_facet[pos] = f
                if found and -distance < best[2] < distance:
                    out_valid[pos] = True
                    out_slave[pos] = s
                    out_master[pos] = mb
                    out_xi[pos, 0] = best[0]
                    out_xi[pos, 1] = best[1]
                    out_gap[pos] = best[2]
                    out_normal[pos, 0] = best[3]
                    out_normal[pos, 1] = best[4]
                    out_normal[pos, 2] = best[5]
                    for d in range(3):
                        out_shift[pos, d] = sh[d]
                pos += 1


@numba.njit(cache=True)
def _area_vectors_into(x, facets, nv, out):
    a = np.empty(3)
    b = np.empty(3)
    for f in range(facets.shape[0]):
        for d in range(3):
            if nv == 4:
                a[d] = x[facets[f, 3], d] - x[facets[f, 0], d]
                b[d] = x[facets[f, 2], d] - x[facets[f, 1], d]
            else:
                a[d] = x[facets[f, 1], d] - x[facets[f, 0], d]
                b[d] = x[facets[f, 2], d] - x[facets[f, 0], d]
        out[f, 0] = 0.5 * (a[1] * b[2] - a[2] * b[1])
        out[f, 1] = 0.5 * (a[2] * b[0] - a[0] * b[2])
        out[f, 2] = 0.5 * (a[0] * b[1] - a[1] * b[0])


def _area_vectors(x: np.ndarray, facets: np.ndarray, nv: int) -> np.ndarray:
    """Outward area vectors of the facets (mm^2): 1/2 d1 x d2 with the diagonals of a quad
    (lexicographic order: (x3 - x0) x (x2 - x1)), exact for planar facets."""
    out = np.empty((facets.shape[0], 3))
    _area_vectors_into(x, facets, nv, out)
    return out


def facet_areas(x: np.ndarray, facets: np.ndarray, nv: int) -> np.ndarray:
    """Facet areas (mm^2) in configuration x."""
    return np.linalg.norm(_area_vectors(x, facets, nv), axis=1)


@numba.njit(cache=True, error_model="numpy")
def _surface_normals(x, facets, nv, facet_n, node_n):
    """``surface_normals`` in one pass (called every increment): the area vectors of
    ``_area_vectors``, summed onto the nodes facet by facet, then normalized (numpy's error
    model: a degenerate facet gets a nan normal, as with numpy arrays, instead of an exception)."""
    _area_vectors_into(x, facets, nv, facet_n)
    node_n[:] = 0.0
    for f in range(facets.shape[0]):
        for v in range(nv):
            for d in range(3):
                node_n[facets[f, v], d] += facet_n[f, d]
    for f in range(facets.shape[0]):
        norm = np.sqrt(facet_n[f, 0] ** 2 + facet_n[f, 1] ** 2 + facet_n[f, 2] ** 2)
        for d in range(3):
            facet_n[f, d] /= norm
    for i in range(node_n.shape[0]):
        norm = np.sqrt(node_n[i, 0] ** 2 + node_n[i, 1] ** 2 + node_n[i, 2] ** 2)
        if norm > 0.0:
            for d in range(3):
                node_n[i, d] /= norm


def surface_normals(x: np.ndarray, facets: np.ndarray, nv: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit outward normals of the facets (at their centre) and of the nodes (area-weighted)."""
    facet_n = np.empty((facets.shape[0], 3))
    node_n = np.empty((x.shape[0], 3))
    _surface_normals(x, facets, nv, facet_n, node_n)
    return facet_n, node_n


@numba.njit(parallel=True, cache=True)
def _corner_normals(area_vectors, facets, nv, node_facet_ptr, node_facets, cos_feature, out):
    nf = facets.shape[0]
    for f in numba.prange(nf):
        af = area_vectors[f]
        nf_ = np.sqrt(af[0] ** 2 + af[1] ** 2 + af[2] ** 2)
        for v in range(4):
            if v >= nv:
                out[f, v, :] = 0.0
                continue
            node = facets[f, v]
            acc = np.zeros(3)
            for j in range(node_facet_ptr[node], node_facet_ptr[node + 1]):
                g = node_facets[j]
                ag = area_vectors[g]
                ng = np.sqrt(ag[0] ** 2 + ag[1] ** 2 + ag[2] ** 2)
                if ag[0] * af[0] + ag[1] * af[1] + ag[2] * af[2] >= cos_feature * nf_ * ng:
                    for d in range(3):
                        acc[d] += ag[d]
            norm = np.sqrt(acc[0] ** 2 + acc[1] ** 2 + acc[2] ** 2)
            for d in range(3):
                out[f, v, d] = acc[d] / norm


def corner_normals(x: np.ndarray, surface, feature_angle: float = FEATURE_ANGLE) -> np.ndarray:
    """(nF, 4, 3) unit normal at every facet corner in configuration x: the area-weighted mean
    of the normals of the facets around the vertex that meet the facet at less than
    ``feature_angle`` (degrees). Smooth surfaces get one normal per node (a continuous normal
    field); a sharper edge (a block's 90-degree edge) keeps each side's own normal. The 4th
    corner of a triangle is zero."""
    nv = surface.vertices_per_facet
    out = np.empty((surface.facets.shape[0], 4, 3))
    _corner_normals(
        _area_vectors(x, surface.facets, nv),
        surface.facets,
        nv,
        surface.node_facet_ptr,
        surface.node_facets,
        np.cos(np.radians(feature_angle)),
        out,
    )
    return out


@numba.njit(cache=True)
def _facet_boxes(x, facets, nv):
    nf = facets.shape[0]
    box = np.empty((nf, 2, 3))
    for f in range(nf):
        for d in range(3):
            lo = np.inf
            hi = -np.inf
            for v in range(nv):
                val = x[facets[f, v], d]
                lo = min(lo, val)
                hi = max(hi, val)
            box[f, 0, d] = lo
            box[f, 1, d] = hi
    return box


class ContactSearch:
    """Search on a :class:`~mpfem_fenicsx.contact.surface.ContactSurface`: this rank's slave nodes
    against the held bodies (``allowed``: (num_bodies, num_bodies) bool over the whole model)."""

    def __init__(
        self,
        surface,
        distance: float,
        shifts: np.ndarray | None = None,
        allowed: np.ndarray | None = None,
    ):
        if not distance > 0:
            raise ValueError(f"contact search distance must be > 0 mm, got {distance}")
        self.surface = surface
        self.distance = float(distance)
        self.shifts = np.zeros((1, 3)) if shifts is None else np.asarray(shifts, dtype=float)
        self.allowed = allowed
        self.pairs_examined = 0  # candidate body pairs of the broad phase, accumulated
        self._version = -1

    def _index(self) -> None:
        """Per held body: its facets and its slave nodes (CSR), the allowed pairs among held
        bodies; rebuilt when the surface's held set changes."""
        s = self.surface
        if self._version == s.version:
            return
        nb = s.bodies.size
        order = np.argsort(s.facet_body_local, kind="stable")
        self.body_facets = order.astype(np.int64)
        self.body_facet_ptr = np.searchsorted(s.facet_body_local[order], np.arange(nb + 1)).astype(
            np.int64
        )
        slaves = s.owned_nodes
        sbody = s.node_body_local[slaves]
        order = np.argsort(sbody, kind="stable")
        self.slave_nodes = slaves[order].astype(np.int64)
        self.slave_ptr = np.searchsorted(sbody[order], np.arange(nb + 1)).astype(np.int64)
        self.slave_bodies = np.flatnonzero(np.diff(self.slave_ptr) > 0)
        self.allowed_local = (
            None if self.allowed is None else self.allowed[np.ix_(s.bodies, s.bodies)]
        )
        self._version = s.version

    def __call__(self, x: np.ndarray, corner: np.ndarray | None = None) -> ContactPoints:
        """Contact points for current held surface positions ``x`` (nS, 3); ``corner``
        (nF, 4, 3): the masters' corner normals (:func:`corner_normals`; default: those of
        ``x``). ``master_body`` of the points is the held body index (``surface.bodies``)."""
        s = self.surface
        self._index()
        nb = s.bodies.size
        boxes = body_boxes(x, s.node_body_local, nb)
        pairs, shift_index = candidate_pairs(
            boxes, self.distance, self.shifts, self.allowed_local, slaves=self.slave_bodies
        )
        self.pairs_examined += len(pairs)
        pair_shift = self.shifts[shift_index]
        spheres = body_spheres(x, s.node_body_local, nb, boxes)
        counts = np.empty(len(pairs), np.int64)
        _near_counts(
            x,
            boxes,
            spheres,
            self.slave_ptr,
            self.slave_nodes,
            pairs,
            pair_shift,
            self.distance,
            counts,
        )
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        n = int(offsets[-1])
        out_slave = np.zeros(n, np.int64)
        out_master = np.zeros(n, np.int64)
        out_facet = np.zeros(n, np.int64)
        out_xi = np.zeros((n, 2))
        out_gap = np.zeros(n)
        out_normal = np.zeros((n, 3))
        out_shift = np.zeros((n, 3))
        valid = np.zeros(n, np.bool_)
        if n:
            facet_box = _facet_boxes(x, s.facets, s.vertices_per_facet)
            facet_normal, node_normal = surface_normals(x, s.facets, s.vertices_per_facet)
            if corner is None:
                corner = corner_normals(x, s)
            _narrow_phase(
                x,
                s.facets,
                s.vertices_per_facet,
                corner,
                facet_box,
                facet_normal,
                node_normal,
                boxes,
                spheres,
                self.body_facet_ptr,
                self.body_facets,
                self.slave_ptr,
                self.slave_nodes,
                pairs,
                pair_shift,
                self.distance,
                offsets,
                out_slave,
                out_master,
                out_facet,
                out_xi,
                out_gap,
                out_normal,
                out_shift,
                valid,
            )
        return ContactPoints(
            out_slave[valid],
            out_master[valid],
            out_facet[valid],
            out_xi[valid],
            out_gap[valid],
            out_normal[valid],
            out_shift[valid],
            np.repeat(shift_index, counts)[valid],  # the points of pair k follow offsets[k]
        )
