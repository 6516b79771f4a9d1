"""Numba kernels of the contact model (:mod:`.model`): facet shape functions and point
weights, the per-point forces of the law (``point_forces``), their central-difference tangents
over the point's nodal coordinates (``point_tangents``, parallel over points), COO entries of the
tangent, contact areas per node; numpy helpers for key lookup and relative motion. Plain arrays
in, plain arrays out: the model owns the state."""

from __future__ import annotations

import numba
import numpy as np

from .laws import SLIP, SOFTENING, law_point
from .search import FACING, project_point


@numba.njit(cache=True)
def shape(nv, xi, eta, out):
    """Shape functions at (xi, eta) of a facet with ``nv`` vertices (4: Q1, 3: P1) into ``out``."""
    if nv == 4:
        out[0] = (1 - xi) * (1 - eta)
        out[1] = xi * (1 - eta)
        out[2] = (1 - xi) * eta
        out[3] = xi * eta
    else:
        out[0] = 1 - xi - eta
        out[1] = xi
        out[2] = eta
        out[3] = 0.0


@numba.njit(cache=True)
def point_weights(facets, nv, slave, facet, xi, nodes, weights):
    """Nodes (n, 5) and weights c_a (n, 5) of every contact point (unused slots: node -1)."""
    N = np.empty(4)
    for p in range(slave.size):
        shape(nv, xi[p, 0], xi[p, 1], N)
        nodes[p, 0] = slave[p]
        weights[p, 0] = 1.0
        for v in range(4):
            if v < nv:
                nodes[p, 1 + v] = facets[facet[p], v]
                weights[p, 1 + v] = -N[v]
            else:
                nodes[p, 1 + v] = -1
                weights[p, 1 + v] = 0.0


def lookup(sorted_keys: np.ndarray, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions of ``keys`` in ``sorted_keys`` (non-empty) and the mask of those found."""
    pos = np.minimum(np.searchsorted(sorted_keys, keys), sorted_keys.size - 1)
    return pos, sorted_keys[pos] == keys


def relative_motion(nodes: np.ndarray, weights: np.ndarray, dU: np.ndarray) -> np.ndarray:
    """(n, 3) motion of each contact point's slave relative to its master point,
    sum_a c_a dU_a over the point's nodes (unused slots: node -1)."""
    used = nodes >= 0
    return np.einsum("pa,pad->pd", weights * used, dU[np.where(used, nodes, 0)])


@numba.njit(cache=True)
def point_forces(
    pos,
    pos_n,
    nv,
    cn,
    branch,
    t1_held,
    alpha_n,
    smax_n,
    tpx,
    tpy,
    tpz,
    scale,
    k,
    kt,
    mu,
    sigma_c,
    delta_max,
    p0,
    alpha_forced,
    forces,
    res,
    law_out,
    facet_index,
    N,
):
    """Nodal forces (on the bodies) of one contact point for node positions ``pos`` (nn, 3):
    projection of pos[0] on the facet pos[1:] (corner normals ``cn``), gap, normal, slip since
    pos_n, law."""
    project_point(pos[0], pos, facet_index, nv, cn, res)
    shape(nv, res[0], res[1], N)
    nx, ny, nz = res[3], res[4], res[5]
    s = np.zeros(3)
    for d in range(3):
        s[d] = pos[0, d] - pos_n[0, d]
        for v in range(nv):
            s[d] -= N[v] * (pos[1 + v, d] - pos_n[1 + v, d])
    law_point(
        res[2],
        s[0],
        s[1],
        s[2],
        nx,
        ny,
        nz,
        alpha_n,
        smax_n,
        tpx,
        tpy,
        tpz,
        k,
        kt,
        mu,
        sigma_c,
        delta_max,
        p0,
        alpha_forced,
        branch,
        t1_held,
        law_out,
    )
    fx = scale * (law_out[0] * nx + law_out[1])
    fy = scale * (law_out[0] * ny + law_out[2])
    fz = scale * (law_out[0] * nz + law_out[3])
    forces[0, 0] = fx
    forces[0, 1] = fy
    forces[0, 2] = fz
    for v in range(nv):
        forces[1 + v, 0] = -N[v] * fx
        forces[1 + v, 1] = -N[v] * fy
        forces[1 + v, 2] = -N[v] * fz


@numba.njit(parallel=True, cache=True)
def point_tangents(
    x,
    x_n,
    facets,
    nv,
    corner,
    slave,
    facet,
    branch,
    held,
    T1,
    shift,
    shift_n,
    alpha_n,
    smax_n,
    tt_n,
    scale,
    k,
    kt,
    mu,
    sigma_c,
    delta_max,
    p0,
    alpha_forced,
    K,
):
    """Consistent tangent of every contact point by central differences of :func:`point_forces`
    over the positions of its nodes: K (n, 3 nn, 3 nn) = d r / d u, r = -forces on the bodies.
    The law stays on the branches of the current state (``branch``), so the differences never
    straddle a kink of the law (e.g. gap = 0 between overlap and opening).

    Differentiating the whole point evaluation (projection, normal, gap, slip, law) gives the
    complete node-to-surface linearization (normal rotation, sliding of the projection point)
    that the frozen-normal tangent misses, at 2 x 3 nn point evaluations per point. The corner
    normals of the master facets are those of the last converged configuration (constant over
    an increment), so the tangent is that of the residual Newton actually solves.

    Exception: at the points flagged ``held`` that are on the softening branch, the traction is
    held at its current value ``T1`` (zero slope; see ``ContactModel.evaluate``).
    """
    n = slave.size
    nn = 1 + nv
    for p in numba.prange(n):
        pos = np.empty((nn, 3))
        pos_n = np.empty((nn, 3))
        nodes = np.empty(nn, np.int64)
        nodes[0] = slave[p]
        for v in range(nv):
            nodes[1 + v] = facets[facet[p], v]
        size2 = 0.0
        for a in range(nn):
            for d in range(3):
                pos[a, d] = x[nodes[a], d]
                pos_n[a, d] = x_n[nodes[a], d]
        for d in range(3):  # slave seen in the frame of the (unshifted) master, as in the search
            pos[0, d] -= shift[p, d]
            pos_n[0, d] -= shift_n[p, d]
        for d in range(3):
            size2 += (pos[1, d] - pos[2, d]) ** 2
        h = 1e-7 * np.sqrt(size2)
        fp = np.empty((nn, 3))
        fm = np.empty((nn, 3))
        res = np.empty(8)
        law_out = np.empty(9)
        N = np.empty(4)
        facet_index = np.arange(1, 5)
        hold = T1[p] if (held[p] and branch[p] % 4 == SOFTENING) else np.nan
        for b in range(nn):
            for j in range(3):
                pos[b, j] += h
                point_forces(
                    pos,
                    pos_n,
                    nv,
                    corner[facet[p]],
                    branch[p],
                    hold,
                    alpha_n[p],
                    smax_n[p],
                    tt_n[p, 0],
                    tt_n[p, 1],
                    tt_n[p, 2],
                    scale[p],
                    k,
                    kt,
                    mu,
                    sigma_c,
                    delta_max,
                    p0,
                    alpha_forced,
                    fp,
                    res,
                    law_out,
                    facet_index,
                    N,
                )
                pos[b, j] -= 2.0 * h
                point_forces(
                    pos,
                    pos_n,
                    nv,
                    corner[facet[p]],
                    branch[p],
                    hold,
                    alpha_n[p],
                    smax_n[p],
                    tt_n[p, 0],
                    tt_n[p, 1],
                    tt_n[p, 2],
                    scale[p],
                    k,
                    kt,
                    mu,
                    sigma_c,
                    delta_max,
                    p0,
                    alpha_forced,
                    fm,
                    res,
                    law_out,
                    facet_index,
                    N,
                )
                pos[b, j] += h
                for a in range(nn):
                    for i in range(3):
                        K[p, 3 * a + i, 3 * b + j] = -(fp[a, i] - fm[a, i]) / (2.0 * h)


@numba.njit(cache=True)
def coo_entries(nodes, blocks, K, rows, cols, vals):
    """(3 nn)^2 tangent entries per point, global dof indices."""
    k = 0
    nn = nodes.shape[1]
    for p in range(nodes.shape[0]):
        for a in range(nn):
            for b in range(nn):
                for i in range(3):
                    for j in range(3):
                        rows[k] = blocks[nodes[p, a]] * 3 + i
                        cols[k] = blocks[nodes[p, b]] * 3 + j
                        vals[k] = K[p, 3 * a + i, 3 * b + j]
                        k += 1
    return k


@numba.njit(cache=True)
def contact_areas(
    slave, master_normal, node_facet_ptr, node_facets, facet_area, facet_normal, nv, out
):
    """Tributary area of each contact point's slave node, counting only the slave facets that
    face the master (n_slave_facet . n_master < -FACING): a node on an edge of a block gets the
    share of its contact face only, not of the side faces."""
    for p in range(slave.size):
        s = slave[p]
        acc = 0.0
        for j in range(node_facet_ptr[s], node_facet_ptr[s + 1]):
            f = node_facets[j]
            dot = 0.0
            for d in range(3):
                dot += facet_normal[f, d] * master_normal[p, d]
            if dot < -FACING:
                acc += facet_area[f] / nv
        out[p] = acc


def trial_shear(Tt: np.ndarray, dissipation: np.ndarray, kt: np.ndarray | float) -> np.ndarray:
    """Magnitude of each point's trial tangential traction |T_t,n - k_t delta_t| (MPa) from its
    returned traction ``Tt`` (n, 3) and its frictional dissipation per unit area (mJ/mm^2): a
    slipping point dissipates |T_t| (|T_t,trial| - |T_t|) / k_t (thesis eq. 3.17-3.19), a
    sticking one nothing (its trial is its traction)."""
    magnitude = np.linalg.norm(Tt, axis=1)
    return magnitude + kt * dissipation / np.maximum(magnitude, 1e-300)


def slip_reversal_limit(
    motion: np.ndarray,
    normal: np.ndarray,
    Tt: np.ndarray,
    trial: np.ndarray,
    branch: np.ndarray,
    kt: np.ndarray | float,
) -> float:
    """Largest fraction (0, 1] of a Newton update that brings no slipping point back past the
    centre of its Coulomb cone, on the linearized slips.

    ``motion`` (n, 3): each point's slave motion relative to its master along the update (mm);
    ``normal``, ``Tt`` (MPa), ``trial`` (:func:`trial_shear`, MPa), ``branch`` of the
    evaluation the update was computed at; ``kt``: the tangential penalty (N/mm^3), one or per
    point. A slipping point's tangent has no stiffness along its slip, so an update that
    reverses it can carry it through its whole stick range (2 mu T1 / kt, ~1e-7 mm) and out on
    the far side, where the full step raises the residual and the line search crawls. Its trial
    traction shrinks by kt x the reversal: reversing by at most |T_t,trial| / kt lands it at
    worst at the cone's centre, on the stick branch whose stiffness the next iterate carries
    (thesis eq. 3.14-3.17)."""
    slip = branch // 4 == SLIP
    if not slip.any():
        return 1.0
    kt = np.broadcast_to(np.asarray(kt, dtype=float), branch.shape)[slip]
    d, n, t = motion[slip], normal[slip], Tt[slip]
    d = d - np.einsum("pd,pd->p", d, n)[:, None] * n
    # the traction opposes the slave's slip: a motion along it reverses the slip
    back = np.einsum("pd,pd->p", d, t) / np.maximum(np.linalg.norm(t, axis=1), 1e-300)
    room = trial[slip] / kt
    limited = back > room
    return float(np.min(room[limited] / back[limited])) if limited.any() else 1.0
