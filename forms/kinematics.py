"""Deformation gradient F = I + Grad u at the quadrature points, as one threaded numba kernel.

Same values as ``fem.Expression(deformation_gradient(u), points).eval`` (total Lagrangian: the
mesh stays in the reference configuration), but parallel over cells with numba threads and
written into a preallocated array: ``Expression.eval`` runs on one thread, packs u and allocates
nq x 9 values at every call, which made it ~25 % of the material phase of an explicit step.

Per cell and point: J = sum_a X_a (x) dpsi_a/dxi (geometry), dphi_b/dX = J^-T dphi_b/dxi,
Grad u = sum_b u_b (x) dphi_b/dX. Valid for Lagrange spaces whose cell dofs need no
permutation (degree <= 2, e.g. Q1 hexahedra, P1/P2 tetrahedra): :meth:`DeformationGradients.matches`
checks it against the Expression once, and the caller falls back to the Expression otherwise.

The residual's deviatoric part int P_dev : Grad v dX (:class:`DeviatoricForces`) is assembled the
same way, with the inverse Jacobians J^-1 and the points' reference volumes stored once: 35-40 %
less time than the FFCx-compiled form on Q1 hexahedra (bench/README.md), checked against it once;
:class:`VolumetricForces` does the same at the volumetric (SRI) points for the residual's
volumetric part K ln(J) F^-T and the explicit solver's bulk viscosity. The Jacobian's two parts
(:class:`TangentStiffness`) have their element matrices computed by threaded loops and inserted
into the PETSc matrix block by block.
"""

from __future__ import annotations

import numba
import numpy as np

from ..material.hencky_j2 import inverse3

_CHUNK = 64  # cells per parallel chunk: scratch matrices are allocated once per chunk


@numba.njit(cache=True, inline="always")
def _reference_jacobian(cell, q, x, gdofs, dpsi, J):
    """J = sum_a X_a (x) dpsi_a/dxi at point q of ``cell`` (the reference-to-mesh map's
    gradient)."""
    J[:] = 0.0
    for a in range(dpsi.shape[1]):
        node = gdofs[cell, a]
        for i in range(3):
            xi = x[node, i]
            for j in range(3):
                J[i, j] += xi * dpsi[q, a, j]


@numba.njit(parallel=True, cache=True)
def _gradients(cells, x, gdofs, dpsi, u, dofs, dphi, out):
    """out[c * npts + q] = I + Grad u at point q of cell cells[c] (dpsi, dphi: (npts, n, 3))."""
    npts = dpsi.shape[0]
    nd = dphi.shape[1]
    nchunks = (cells.size + _CHUNK - 1) // _CHUNK
    for chunk in numba.prange(nchunks):
        J = np.empty((3, 3))
        K = np.empty((3, 3))
        G = np.empty((3, 3))
        for c in range(chunk * _CHUNK, min(cells.size, (chunk + 1) * _CHUNK)):
            cell = cells[c]
            for q in range(npts):
                _reference_jacobian(cell, q, x, gdofs, dpsi, J)
                inverse3(J, K)
                G[:] = 0.0  # G = sum_b u_b (x) dphi_b/dxi, so that Grad u = G J^-1
                for b in range(nd):
                    dof = dofs[cell, b]
                    for i in range(3):
                        ui = u[3 * dof + i]
                        for k in range(3):
                            G[i, k] += ui * dphi[q, b, k]
                row = c * npts + q
                for i in range(3):
                    for j in range(3):
                        out[row, i, j] = (
                            (1.0 if i == j else 0.0)
                            + G[i, 0] * K[0, j]
                            + G[i, 1] * K[1, j]
                            + G[i, 2] * K[2, j]
                        )


def reference_derivatives(V, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Reference derivatives (npts, n, 3) of the geometry basis functions and of the (scalar)
    basis of the space ``V`` at ``points``."""
    psi = V.mesh.ufl_domain().ufl_coordinate_element().basix_element.tabulate(1, points)
    phi = V.element.basix_element.tabulate(1, points)  # (4, npts, ndofs, 1) for the scalar element
    return (
        np.ascontiguousarray(np.moveaxis(psi[1:4, :, :, 0], 0, -1)),
        np.ascontiguousarray(np.moveaxis(phi[1:4, :, :, 0], 0, -1)),
    )


def smooth_field(x: np.ndarray, k: int = 0, scale: float = 1.0) -> np.ndarray:
    """A smooth non-affine vector field (mm) at points x (3, n), the k-th of a family: what the
    kernels' checks against the compiled forms interpolate."""
    return scale * np.stack(
        [
            0.01 * np.sin(x[1] + 2 * x[2] + k),
            0.02 * np.cos(x[0] * x[2] - k),
            0.015 * np.sin(x[0] - x[1] + 2 * k) * x[2],
        ]
    )


class DeformationGradients:
    """F at the quadrature ``points`` (reference cell coordinates) of ``cells``, (n, 3, 3)."""

    def __init__(self, u, points: np.ndarray, cells: np.ndarray):
        V = u.function_space
        mesh = V.mesh
        self.u = u
        self.cells = np.asarray(cells, dtype=np.int32)
        self.points = points
        self.x = mesh.geometry.x
        self.gdofs = mesh.geometry.dofmaps[0]
        self.dofs = V.dofmap.list
        self.dpsi, self.dphi = reference_derivatives(V, points)
        self.out = np.empty((self.cells.size * points.shape[0], 3, 3))

    def __call__(self, u=None) -> np.ndarray:
        """F of ``u`` (default: the Function given at construction); the returned array is
        overwritten by the next call."""
        u = self.u if u is None else u
        _gradients(
            self.cells, self.x, self.gdofs, self.dpsi, u.x.array, self.dofs, self.dphi, self.out
        )
        return self.out

    def matches(self, rtol: float = 1e-12) -> bool:
        """Whether the kernel reproduces the FFCx-compiled Expression of F on a smooth non-affine
        displacement field (a check, once, of the dof orderings it assumes)."""
        import dolfinx

        from .bulk import deformation_gradient

        if not self.cells.size:
            return True
        w = dolfinx.fem.Function(self.u.function_space)
        w.interpolate(smooth_field)
        expression = dolfinx.fem.Expression(deformation_gradient(w), self.points)
        F_ref = expression.eval(self.u.function_space.mesh, self.cells).reshape(-1, 3, 3)
        return bool(np.abs(self(w) - F_ref).max() <= rtol * max(1.0, np.abs(F_ref).max()))


@numba.njit(cache=True)
def _inverse_jacobians(cells, x, gdofs, dpsi, out, dets):
    """out[c * npts + q] = J^-1 and dets[c * npts + q] = |det J| of the reference-to-mesh map at
    point q of cell cells[c]."""
    npts = dpsi.shape[0]
    J = np.empty((3, 3))
    for c in range(cells.size):
        cell = cells[c]
        for q in range(npts):
            _reference_jacobian(cell, q, x, gdofs, dpsi, J)
            dets[c * npts + q] = abs(inverse3(J, out[c * npts + q]))


def _point_geometry(
    V, points: np.ndarray, cells: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What a force loop over ``points`` of ``cells`` needs once (total Lagrangian): the reference
    derivatives of V's scalar basis (npts, n, 3), J^-1 (n_cells npts, 3, 3) and |det J|."""
    mesh = V.mesh
    dpsi, dphi = reference_derivatives(V, points)
    Kinv = np.empty((cells.size * points.shape[0], 3, 3))
    dets = np.empty(cells.size * points.shape[0])
    _inverse_jacobians(cells, mesh.geometry.x, mesh.geometry.dofmaps[0], dpsi, Kinv, dets)
    return dphi, Kinv, dets


@numba.njit(cache=True, inline="always")
def _spatial_derivatives(q, dphi, K, scale, d):
    """d[b, J] = scale dphi_b/dX_J at point q, dphi_b/dX_J = sum_k dphi_b/dxi_k (J^-1)_kJ."""
    for b in range(dphi.shape[1]):
        for j in range(3):
            d[b, j] = (
                dphi[q, b, 0] * K[0, j] + dphi[q, b, 1] * K[1, j] + dphi[q, b, 2] * K[2, j]
            ) * scale


@numba.njit(cache=True, inline="always")
def _nodal_gradient(cell, dofs, d, w, G):
    """G = sum_b w_b (x) d_b over the dofs of ``cell`` (w a blocked (3) nodal array, d the
    derivatives of :func:`_spatial_derivatives` with scale 1: G = Grad w)."""
    G[:] = 0.0
    for b in range(d.shape[0]):
        dof = dofs[cell, b]
        for i in range(3):
            wi = w[3 * dof + i]
            for j in range(3):
                G[i, j] += wi * d[b, j]


@numba.njit(cache=True, inline="always")
def _add_pressure_forces(cell, dofs, d, scale, Finv, out):
    """out[3 dof_b + i] += scale sum_J d_bJ (F^-1)_Ji: the nodal forces of P = scale F^-T, i.e.
    of a Kirchhoff pressure stress scale I at a point of reference volume 1 (d in 1/mm)."""
    for b in range(d.shape[0]):
        dof = dofs[cell, b]
        for i in range(3):
            out[3 * dof + i] += scale * (
                d[b, 0] * Finv[0, i] + d[b, 1] * Finv[1, i] + d[b, 2] * Finv[2, i]
            )


@numba.njit(cache=True)
def _add_deviatoric_forces(cells, dofs, dphi, Kinv, volumes, P, out):
    """out[3 dof + i] += sum_q P_iJ dphi_b/dX_J dV_q over the points of ``cells`` (one thread:
    cells share nodes)."""
    npts = dphi.shape[0]
    nd = dphi.shape[1]
    g = np.empty((nd, 3))
    for c in range(cells.size):
        cell = cells[c]
        for q in range(npts):
            row = c * npts + q
            _spatial_derivatives(q, dphi, Kinv[row], volumes[row], g)
            p = P[row]
            for b in range(nd):
                dof = dofs[cell, b]
                for i in range(3):
                    out[3 * dof + i] += p[i, 0] * g[b, 0] + p[i, 1] * g[b, 1] + p[i, 2] * g[b, 2]


def _write_random(cells: np.ndarray, material: np.ndarray, function) -> None:
    """Random values in [-1, 1] in a material points' array and in the quadrature Function that
    a compiled form reads (unless they share memory), for a check against the form."""
    rng = np.random.default_rng(0)
    material[:] = rng.uniform(-1.0, 1.0, material.shape)
    if function.x.array.size and not np.shares_memory(material, function.x.array):
        width = material[0].size * (material.shape[0] // cells.size)
        function.x.array.reshape(-1, width)[cells] = material.reshape(cells.size, width)


class DeviatoricForces:
    """The deviatoric internal force int P_dev : Grad v dX (N), added into a local (ghosted) vector
    array: the residual's first form (``bulk.internal_work``) at the kernel's points, with the
    inverse Jacobians and the points' reference volumes computed once (total Lagrangian: the mesh
    does not move). Same assumptions as :class:`DeformationGradients`; :meth:`matches` checks it
    once against the FFCx-compiled form, and the caller falls back to it otherwise."""

    def __init__(self, V, points: np.ndarray, cells: np.ndarray, point_volumes: np.ndarray):
        self.cells = np.asarray(cells, dtype=np.int32)
        self.dofs = V.dofmap.list
        self.dphi, self.Kinv, _ = _point_geometry(V, points, self.cells)
        self.volumes = np.ascontiguousarray(point_volumes)

    def add_to(self, P_dev: np.ndarray, array: np.ndarray) -> None:
        """array += the force of the first Piola stresses ``P_dev`` ((cell, point) order, (n, 3, 3),
        MPa) of the cells; ``array`` is the local array of a blocked (3) vector, ghosts included."""
        _add_deviatoric_forces(
            self.cells, self.dofs, self.dphi, self.Kinv, self.volumes, P_dev, array
        )

    def matches(self, form, P_function, material_P: np.ndarray, rtol: float = 1e-12) -> bool:
        """Whether :meth:`add_to` reproduces the assembled ``form`` (int P : Grad v, P the
        quadrature Function ``P_function`` that the form reads) for random stresses written into
        ``material_P`` (the material points' array, restored afterwards)."""
        import dolfinx.fem

        if not self.cells.size:
            return True
        saved_P, saved_fn = material_P.copy(), P_function.x.array.copy()
        _write_random(self.cells, material_P, P_function)
        reference = dolfinx.fem.assemble_vector(form)  # local array, ghosts not summed
        ours = np.zeros_like(reference.array)
        self.add_to(material_P, ours)
        material_P[:] = saved_P
        P_function.x.array[:] = saved_fn
        scale = max(np.abs(reference.array).max(), 1e-300)
        return bool(np.abs(ours - reference.array).max() <= rtol * scale)


@numba.njit(cache=True, inline="always")
def _deformation_at(cell, q, dofs, dphi, K, u, d, F, Finv):
    """At point q of ``cell`` (K = J^-1 there): d = dphi/dX, F = I + Grad u, Finv = F^-1; returns
    det F."""
    _spatial_derivatives(q, dphi, K, 1.0, d)
    _nodal_gradient(cell, dofs, d, u, F)
    for i in range(3):
        F[i, i] += 1.0
    return inverse3(F, Finv)


@numba.njit(cache=True)
def _add_volumetric_forces(cells, dofs, dphi, Kinv, volumes, u, bulk, out):
    """out += int K ln(J) F^-T : Grad v dX at the points of ``cells`` (one thread)."""
    npts = dphi.shape[0]
    d = np.empty((dphi.shape[1], 3))
    F = np.empty((3, 3))
    Finv = np.empty((3, 3))
    for c in range(cells.size):
        cell = cells[c]
        for q in range(npts):
            row = c * npts + q
            J = _deformation_at(cell, q, dofs, dphi, Kinv[row], u, d, F, Finv)
            _add_pressure_forces(cell, dofs, d, bulk * np.log(J) * volumes[row], Finv, out)


@numba.njit(cache=True)
def _add_bulk_viscosity_forces(
    cells,
    dofs,
    dphi,
    Kinv,
    volumes,
    u,
    velocity,
    cell_dofs,
    density,
    wave_speed,
    cell_length,
    linear,
    quadratic,
    out,
):
    """out += int J sigma_bv : grad_x v dX at the points of ``cells`` (``bulk.bulk_viscosity_work``;
    density, wave_speed, cell_length: cell values at ``cell_dofs[cell]``; one thread)."""
    npts = dphi.shape[0]
    d = np.empty((dphi.shape[1], 3))
    F = np.empty((3, 3))
    Finv = np.empty((3, 3))
    L = np.empty((3, 3))
    for c in range(cells.size):
        cell = cells[c]
        k = cell_dofs[cell]
        rho, length = density[k], cell_length[k]
        for q in range(npts):
            row = c * npts + q
            J = _deformation_at(cell, q, dofs, dphi, Kinv[row], u, d, F, Finv)
            _nodal_gradient(cell, dofs, d, velocity, L)
            rate = 0.0  # tr(grad_x velocity) = tr(Grad velocity F^-1)
            for i in range(3):
                for j in range(3):
                    rate += L[i, j] * Finv[j, i]
            pressure = linear * rho * wave_speed[k] * length * rate
            if rate < 0.0:
                pressure -= rho * (quadratic * length * rate) ** 2
            _add_pressure_forces(cell, dofs, d, J * pressure * volumes[row], Finv, out)


class VolumetricForces:
    """The forces of the volumetric rule's points (one per hexahedron, SRI) by numba loops, with
    J^-1 and the points' reference volumes stored once (total Lagrangian): the residual's second
    form int K ln(J) F^-T : Grad v dX (``bulk.internal_work``) and the bulk viscosity's
    int J sigma_bv : grad_x v dX (``bulk.bulk_viscosity_work``), added into local (ghosted) vector
    arrays. Same assumptions as :class:`DeformationGradients`: :meth:`reproduces` checks each
    against its FFCx-compiled form once, and the caller falls back to the form otherwise."""

    def __init__(self, V, points: np.ndarray, weights: np.ndarray, cells: np.ndarray):
        self.cells = np.asarray(cells, dtype=np.int32)
        self.dofs = V.dofmap.list
        self.dphi, self.Kinv, dets = _point_geometry(V, points, self.cells)
        self.volumes = dets * np.tile(weights, self.cells.size)

    def add_volumetric(self, u, bulk: float, array: np.ndarray) -> None:
        """array += the volumetric internal force (N) of the displacement Function ``u`` (mm) for
        the bulk modulus ``bulk`` (MPa)."""
        _add_volumetric_forces(
            self.cells, self.dofs, self.dphi, self.Kinv, self.volumes, u.x.array, float(bulk), array
        )

    def add_bulk_viscosity(
        self,
        u,
        velocity,
        density,
        wave_speed,
        cell_length,
        linear: float,
        quadratic: float,
        array: np.ndarray,
    ) -> None:
        """array += the bulk-viscosity force (N) at displacement ``u`` (mm) and ``velocity`` (mm/s);
        ``density`` (t/mm^3), ``wave_speed`` (mm/s), ``cell_length`` (mm): cell-wise (DG0)
        Functions."""
        cell_dofs = density.function_space.dofmap.list[:, 0]
        _add_bulk_viscosity_forces(
            self.cells,
            self.dofs,
            self.dphi,
            self.Kinv,
            self.volumes,
            u.x.array,
            velocity.x.array,
            cell_dofs,
            density.x.array,
            wave_speed.x.array,
            cell_length.x.array,
            float(linear),
            float(quadratic),
            array,
        )

    @staticmethod
    def reproduces(form, add, fields, rtol: float = 1e-12) -> bool:
        """Whether ``add(array)`` reproduces the assembled ``form`` with the vector Functions
        ``fields`` (that the form reads) set to smooth non-affine fields, the k-th scaled by
        ``fields[k][1]`` (their values restored afterwards)."""
        import dolfinx.fem

        saved = [f.x.array.copy() for f, _ in fields]
        for k, (f, scale) in enumerate(fields):
            f.interpolate(lambda x, k=k, s=scale: smooth_field(x, k, s))
        reference = dolfinx.fem.assemble_vector(form)  # local array, ghosts not summed
        ours = np.zeros_like(reference.array)
        add(ours)
        for (f, _), values in zip(fields, saved, strict=True):
            f.x.array[:] = values
        scale = max(np.abs(reference.array).max(), 1e-300)
        return bool(np.abs(ours - reference.array).max() <= rtol * scale)


#: cells per block of element matrices handed to PETSc at once (bounds the scratch memory:
#: 4096 Q1 cells x 24 x 24 values = 19 MB)
_TANGENT_BLOCK = 4096


@numba.njit(cache=True, inline="always")
def _add_deviatoric_tangent(Ke, q, row, dphi, Kinv, volumes, A, d, T):
    """Ke += dV dphi_a/dX_j A_ijkm dphi_b/dX_m at row 3a + i, column 3b + k: point q (material
    point ``row``) of int (A : Grad du) : Grad v dX, A_ijkm = dP_ij/dF_km."""
    nd = d.shape[0]
    _spatial_derivatives(q, dphi, Kinv[row], 1.0, d)
    s = volumes[row]
    a4 = A[row]
    for i in range(3):
        for k in range(3):
            for a in range(nd):  # T_am = dV sum_j dphi_a/dX_j A_ijkm
                for m in range(3):
                    T[a, m] = s * (
                        d[a, 0] * a4[i, 0, k, m]
                        + d[a, 1] * a4[i, 1, k, m]
                        + d[a, 2] * a4[i, 2, k, m]
                    )
            for a in range(nd):
                for b in range(nd):
                    Ke[3 * a + i, 3 * b + k] += (
                        T[a, 0] * d[b, 0] + T[a, 1] * d[b, 1] + T[a, 2] * d[b, 2]
                    )


@numba.njit(cache=True, inline="always")
def _add_volumetric_tangent(Ke, cell, q, row, dofs, dphi, Kinv, volumes, u, bulk, d, g, F, Finv):
    """Ke += the linearization of int K ln(J) F^-T : Grad v dX at volumetric point q (``row``):
    K dV (g_ai g_bk - ln J g_ak g_bi) at row 3a + i, column 3b + k, g_ai = dphi_a/dX_j (F^-1)_ji
    (the spatial gradients)."""
    nd = d.shape[0]
    J = _deformation_at(cell, q, dofs, dphi, Kinv[row], u, d, F, Finv)
    s = bulk * volumes[row]
    log_J = np.log(J)
    for a in range(nd):
        for i in range(3):
            g[a, i] = d[a, 0] * Finv[0, i] + d[a, 1] * Finv[1, i] + d[a, 2] * Finv[2, i]
    for a in range(nd):
        for i in range(3):
            for b in range(nd):
                for k in range(3):
                    Ke[3 * a + i, 3 * b + k] += s * (g[a, i] * g[b, k] - log_J * g[a, k] * g[b, i])


@numba.njit(parallel=True, cache=True)
def _tangents(first, dphi, Kinv, volumes, A, cells, dofs, vdphi, vKinv, vvolumes, u, bulk, out):
    """out[c] = the element matrix of the internal work's tangent for material cell first + c:
    the deviatoric part at its points (dphi, Kinv, volumes; A (n_points, 3, 3, 3, 3) in (cell,
    point) order) and the volumetric part at the volumetric points (vdphi, vKinv, vvolumes; from
    the displacement array ``u`` and the bulk modulus)."""
    npts, vpts, nd = dphi.shape[0], vdphi.shape[0], dphi.shape[1]
    ncells = out.shape[0]
    nchunks = (ncells + _CHUNK - 1) // _CHUNK
    for chunk in numba.prange(nchunks):
        d = np.empty((nd, 3))
        T = np.empty((nd, 3))
        F = np.empty((3, 3))
        Finv = np.empty((3, 3))
        for c in range(chunk * _CHUNK, min(ncells, (chunk + 1) * _CHUNK)):
            Ke = out[c]
            Ke[:] = 0.0
            for q in range(npts):
                _add_deviatoric_tangent(Ke, q, (first + c) * npts + q, dphi, Kinv, volumes, A, d, T)
            cell = cells[first + c]
            for q in range(vpts):
                row = (first + c) * vpts + q
                _add_volumetric_tangent(
                    Ke, cell, q, row, dofs, vdphi, vKinv, vvolumes, u, bulk, d, T, F, Finv
                )


class TangentStiffness:
    """The tangent stiffness of the internal work (N/mm), added into a PETSc matrix: the
    Jacobian's two forms (``bulk.internal_work_tangent``), the deviatoric part
    int (A_dev : Grad du) : Grad v dX with the kernel's consistent tangent A_dev = dP_dev/dF at its
    points, and the volumetric part (the exact linearization of K ln(J) F^-T at the volumetric
    points, from the displacement). Element matrices by threaded numba loops (J^-1 and the
    points' reference volumes stored once: total Lagrangian), inserted block by block with the
    matrix's local-to-global map: half the time of the FFCx-compiled forms on Q1 hexahedra
    (bench/README.md). Same assumptions as :class:`DeformationGradients`; :meth:`matches` checks
    it once against the compiled forms, and the caller falls back to them otherwise."""

    def __init__(
        self,
        V,
        points: np.ndarray,
        cells: np.ndarray,
        point_volumes: np.ndarray,
        volumetric: VolumetricForces,
    ):
        self.cells = np.asarray(cells, dtype=np.int32)
        self.blocks = np.ascontiguousarray(V.dofmap.list[self.cells], dtype=np.int32)
        self.dphi, self.Kinv, _ = _point_geometry(V, points, self.cells)
        self.volumes = np.ascontiguousarray(point_volumes)
        self.volumetric = volumetric
        n = 3 * self.dphi.shape[1]
        self._scratch = np.empty((min(_TANGENT_BLOCK, self.cells.size), n, n))

    def add_to(self, A_dev: np.ndarray, u, bulk: float, K) -> None:
        """K += the tangent stiffness at the material tangents ``A_dev`` ((cell, point) order,
        (n, 3, 3, 3, 3), MPa) and the displacement Function ``u`` (mm), bulk modulus ``bulk``
        (MPa); ``K`` a PETSc matrix on V x V with block size 3 and its local-to-global map
        (DOLFINx's), assembled by the caller afterwards."""
        from petsc4py import PETSc

        vol = self.volumetric
        for first in range(0, self.cells.size, _TANGENT_BLOCK):
            count = min(_TANGENT_BLOCK, self.cells.size - first)
            out = self._scratch[:count]
            _tangents(
                first,
                self.dphi,
                self.Kinv,
                self.volumes,
                A_dev,
                vol.cells,
                vol.dofs,
                vol.dphi,
                vol.Kinv,
                vol.volumes,
                u.x.array,
                float(bulk),
                out,
            )
            rows = self.blocks[first : first + count]
            K.setValuesBlockedLocalRCV(
                rows, rows, out.reshape(count, -1), addv=PETSc.InsertMode.ADD_VALUES
            )

    def matches(
        self, forms, A_function, material_A: np.ndarray, u, bulk: float, rtol: float = 1e-12
    ) -> bool:
        """Whether :meth:`add_to` reproduces the sum of the assembled ``forms`` (the Jacobian's two,
        reading the quadrature Function ``A_function`` and ``u``) for random tangents written into
        ``material_A`` (the material points' array) and a smooth non-affine ``u`` (both restored
        afterwards)."""
        from petsc4py import PETSc

        import dolfinx.fem.petsc

        if not self.cells.size:
            return True
        saved_A, saved_fn, saved_u = material_A.copy(), A_function.x.array.copy(), u.x.array.copy()
        _write_random(self.cells, material_A, A_function)
        u.interpolate(smooth_field)
        reference = dolfinx.fem.petsc.assemble_matrix(forms[0])
        reference.assemble(PETSc.Mat.AssemblyType.FLUSH)
        dolfinx.fem.petsc.assemble_matrix(reference, forms[1])
        reference.assemble()
        ours = reference.duplicate(copy=False)
        ours.zeroEntries()
        self.add_to(material_A, u, bulk, ours)
        ours.assemble()
        scale = max(reference.norm(PETSc.NormType.FROBENIUS), 1e-300)
        ours.axpy(-1.0, reference, PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        error = ours.norm(PETSc.NormType.FROBENIUS)
        material_A[:] = saved_A
        A_function.x.array[:] = saved_fn
        u.x.array[:] = saved_u
        for mat in (reference, ours):
            mat.destroy()
        return bool(error <= rtol * scale)
