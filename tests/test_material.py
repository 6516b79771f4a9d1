"""Hencky / von Mises kernel: eigen-solver, objectivity, tangent, and the assembled Jacobian."""

import numpy as np
import pytest
from mpfem_fenicsx.meshes import particle_mesh
from mpi4py import MPI

import dolfinx

from mpfem_fenicsx.material import LEAD, STEEL_LINEAR, ElastoPlastic, HenckyJ2, eig_sym3
from mpfem_fenicsx.problem import SolidProblem


def _random_F(rng, n, amplitude):
    return np.eye(3) + amplitude * rng.standard_normal((n, 3, 3))


def test_eigen_solver_handles_repeated_eigenvalues():
    rng = np.random.default_rng(0)
    for eigenvalues in (
        [1.0, 1.0, 1.0],
        [2.0, 2.0, 0.5],
        [3.0, 1e-3, 1e-3],
        [1.0, 1.0 + 1e-12, 4.0],
    ):
        R, _ = np.linalg.qr(rng.standard_normal((3, 3)))
        a = R @ np.diag(eigenvalues) @ R.T
        w = np.empty(3)
        Q = np.empty((3, 3))
        eig_sym3(a.copy(), w, Q)
        assert np.allclose(np.sort(w), np.sort(eigenvalues), atol=1e-13)
        assert np.allclose(Q @ np.diag(w) @ Q.T, a, atol=1e-13)
        assert np.allclose(Q.T @ Q, np.eye(3), atol=1e-13)


def test_eigen_solver_keeps_deviator_of_near_identity_tensors():
    """b_e near 1 (small elastic strains) with two principal values equal or nearly so, as under
    die loading: the deviatoric part of ln(b_e) / 2, which sets the stress, must come out to
    round-off of its own size, not of b_e's (LAPACK's eigh as the reference)."""
    rng = np.random.default_rng(1)
    worst = 0.0
    for gap in (1e-2, 1e-6, 1e-10, 1e-14, 0.0):
        for sign in (1.0, -1.0):
            for _ in range(50):
                R, _ = np.linalg.qr(rng.standard_normal((3, 3)))
                x = rng.uniform(0.8, 1.2) * np.array([1.0, 1.0 + gap * 1e-3, 1.0 + sign * 1e-3])
                a = R @ np.diag(x) @ R.T
                w = np.empty(3)
                Q = np.empty((3, 3))
                eig_sym3(a.copy(), w, Q)
                log_strain = Q @ np.diag(0.5 * np.log(w)) @ Q.T
                w_ref, Q_ref = np.linalg.eigh(a)
                reference = Q_ref @ np.diag(0.5 * np.log(w_ref)) @ Q_ref.T
                dev = reference - np.trace(reference) / 3.0 * np.eye(3)
                worst = max(worst, np.linalg.norm(log_strain - reference) / np.linalg.norm(dev))
                assert np.allclose(Q.T @ Q, np.eye(3), atol=1e-14)
    assert worst < 1e-9, worst


def test_eigen_solver_on_tensors_within_rounding_of_the_identity():
    """b_e = 1 to a few ulps (elastic points at rest, e.g. the first increment of a contact test):
    the deviator is rounding noise, a - tr(a)/3 is not traceless to its own precision, and the
    closed form once picked a double root there (a division by zero in the CI's Hertz and wedge
    runs, 2026-11-27: the first matrix below). No exception, and a decomposition to rounding."""
    rng = np.random.default_rng(2)
    eps = np.finfo(float).eps
    matrices = [
        np.array(
            [
                [0.99999999999999978, 0.0, -1.1102230246251565e-16],
                [0.0, 0.99999999999999989, 0.0],
                [-1.1102230246251565e-16, 0.0, 0.99999999999999978],
            ]
        )
    ]
    for _ in range(20000):
        c = rng.choice([1.0, 0.7, 1.3])
        a = c * np.eye(3)
        for (i, j), k in zip(
            [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)],
            rng.integers(-3, 4, 6) * (rng.random(6) < 0.6),
            strict=True,
        ):
            a[i, j] += k * eps * c / 2
            a[j, i] = a[i, j]
        matrices.append(a)
    w = np.empty(3)
    Q = np.empty((3, 3))
    for a in matrices:
        eig_sym3(a.copy(), w, Q)
        assert np.abs(Q @ np.diag(w) @ Q.T - a).max() < 1e-14
        assert np.abs(Q.T @ Q - np.eye(3)).max() < 1e-14


def _updates_by_both_paths(material, F, cp_inv=None, eps_p=None):
    """The stress update of the explicit solver (no tangent: the series path near b_e = 1) and of
    the implicit one (tangent: eigen-decomposition), from the same state."""
    results = []
    for tangent in (False, True):
        m = HenckyJ2(material, len(F))
        if cp_inv is not None:
            m.load_state({"cp_inv": cp_inv, "eps_p": eps_p})
        m.update(F, tangent=tangent)
        results.append(
            {
                "P_dev": m.P_dev.copy(),
                "tau": m.tau.copy(),
                "cp_inv": m.cp_inv_trial.copy(),
                "eps_p": m.eps_p_trial.copy(),
                "dissipation": m.dissipation.copy(),
                "psi": m.psi.copy(),
            }
        )
    return results


def _largest_relative_gap(a, b):
    return max(np.abs(a[k] - b[k]).max() / max(np.abs(b[k]).max(), 1e-300) for k in a)


def test_series_update_equals_eigen_update_along_plastic_flow():
    """Two realizations of the same return mapping: the series path (1/2 ln b_e by artanh, exp by
    Taylor, tensor form) against principal axes (closed-form eigen-decomposition), after plastic
    history, on elastic and plastic trial states, within round-off of the outputs."""
    rng = np.random.default_rng(7)
    n = 400
    m = HenckyJ2(LEAD, n)
    F0 = _random_F(rng, n, 0.05)
    m.update(F0)
    m.commit()
    F = F0 + 0.003 * rng.standard_normal((n, 3, 3))
    F[: n // 4] = F0[: n // 4] + 1e-5 * rng.standard_normal((n // 4, 3, 3))  # elastic unloading
    series, eigen = _updates_by_both_paths(LEAD, F, m.cp_inv.copy(), m.eps_p.copy())
    plastic = series["eps_p"] > m.eps_p
    assert 0.2 * n < plastic.sum() < 0.9 * n
    assert _largest_relative_gap(series, eigen) < 1e-12


def test_series_update_to_the_edge_of_its_radius():
    """Elastic strains from none (b_e = 1, points at rest) up to the series' radius |b_e - 1| = 0.1
    (far beyond a metal's, e.g. an elastomer-like material): the truncated series still give the
    principal-axes stress to round-off; beyond the radius the kernel takes the
    eigen-decomposition."""
    from mpfem_fenicsx.material.hencky_j2 import SERIES_RADIUS

    rng = np.random.default_rng(8)
    material = ElastoPlastic(E=10.0, sigma_0=1e3)  # elastic throughout
    F = []
    for radius in np.concatenate(
        [[0.0, 1e-15, 1e-9, 1e-5], np.linspace(0.02, 1.3 * SERIES_RADIUS, 200)]
    ):
        R, _ = np.linalg.qr(rng.standard_normal((3, 3)))
        d = rng.standard_normal(3)
        b = R @ np.diag(1.0 + radius * d / np.linalg.norm(d)) @ R.T  # |b - 1| = radius
        w, V = np.linalg.eigh(b)
        F.append(V @ np.diag(np.sqrt(w)) @ V.T)
    series, eigen = _updates_by_both_paths(material, np.array(F))
    assert np.all(series["eps_p"] == 0.0)
    assert _largest_relative_gap(series, eigen) < 1e-12


def test_elastic_response_is_hencky():
    """Below yield: tau = K ln J I + 2 mu dev(ln V) for a stretch F = diag(l1, l2, l3)."""
    mat = ElastoPlastic(sigma_0=1e9)
    m = HenckyJ2(mat, 1)
    stretches = np.array([1.02, 0.99, 1.005])
    m.update(np.diag(stretches)[None])
    h = np.log(stretches)
    expected = mat.bulk * h.sum() + 2 * mat.mu * (h - h.mean())
    assert np.allclose(m.tau[0, :3], expected, rtol=1e-12)
    assert m.eps_p_trial[0] == 0.0


def test_objectivity():
    """tau(R F) = R tau(F) R^T, also after plastic flow."""
    rng = np.random.default_rng(3)
    F = _random_F(rng, 20, 0.1)
    R, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    R *= np.sign(np.linalg.det(R))
    a, b = HenckyJ2(LEAD, 20), HenckyJ2(LEAD, 20)
    a.update(F)
    b.update(np.einsum("ij,qjk->qik", R, F))

    def full(t):
        return np.array([[t[0], t[3], t[4]], [t[3], t[1], t[5]], [t[4], t[5], t[2]]])

    for q in range(20):
        assert np.allclose(R @ full(a.tau[q]) @ R.T, full(b.tau[q]), atol=1e-10)
    assert np.allclose(a.eps_p_trial, b.eps_p_trial, rtol=1e-12)
    assert (a.eps_p_trial > 0).sum() > 10


@pytest.mark.parametrize("material", [LEAD, STEEL_LINEAR], ids=["power", "linear"])
def test_consistent_tangent_matches_finite_differences(material):
    rng = np.random.default_rng(1)
    n = 60
    m = HenckyJ2(material, n)
    F0 = _random_F(rng, n, 0.03)
    m.update(F0)
    m.commit()  # plastic history: C_p != I, eps_p > 0 at most points
    F = F0 + 0.002 * rng.standard_normal((n, 3, 3))
    for q in range(5):  # a few points unloaded elastically: F ~ U_p, so that b_e^trial ~ I
        c = m.cp_inv[q]
        cp_inv = np.array([[c[0], c[3], c[4]], [c[3], c[1], c[5]], [c[4], c[5], c[2]]])
        w, R = np.linalg.eigh(cp_inv)
        F[q] = R @ np.diag(w**-0.5) @ R.T + 1e-5 * rng.standard_normal((3, 3))
    m.update(F)
    A = m.A_dev.copy()
    assert (m.eps_p_trial == m.eps_p).sum() == 5  # the unloaded points stay elastic
    h = 1e-7
    fd = np.empty_like(A)
    for k in range(3):
        for L in range(3):
            Fp, Fm = F.copy(), F.copy()
            Fp[:, k, L] += h
            Fm[:, k, L] -= h
            m.update(Fp, tangent=False)
            Pp = m.P_dev.copy()
            m.update(Fm, tangent=False)
            fd[..., k, L] = (Pp - m.P_dev) / (2 * h)
    assert np.abs(fd - A).max() < 1e-6 * np.abs(A).max()


def test_power_law_first_yield_is_robust():
    """n < 1: d sigma_y/d eps_p is infinite at eps_p = 0; the local Newton must still converge."""
    m = HenckyJ2(LEAD, 3)
    F = np.array([np.diag([1.0 + e, 1.0, 1.0]) for e in (7.5e-4, 1e-3, 0.2)])
    m.update(F)
    q = m.von_mises_kirchhoff()
    assert np.allclose(q, LEAD.yield_stress(m.eps_p_trial), rtol=1e-10)
    assert np.all(m.eps_p_trial > 0)


def test_jacobian_matches_residual_on_distorted_hexahedra():
    """Consistent Jacobian of the SRI forms on curved (non-affine) cube-sphere cells."""
    a = particle_mesh([[0, 0, 0]], [1.0], MPI.COMM_SELF)
    prob = SolidProblem(a.mesh, LEAD)
    rng = np.random.default_rng(1)
    x = prob.V.tabulate_dof_coordinates()
    u0 = np.zeros((x.shape[0], 3))
    u0[:, 2] = -0.05 * x[:, 2]
    u0 = u0.ravel() + 1e-3 * rng.standard_normal(u0.size)
    du = rng.standard_normal(u0.size)
    b = prob.create_vector()

    def residual(u):
        prob.u.x.array[:] = u
        prob.update_material(tangent=True)
        prob.assemble_residual(b)
        return b.array.copy()

    residual(u0)
    K = prob.create_matrix()
    prob.assemble_jacobian(K)
    vin, vout = K.createVecs()
    vin.array[:] = du
    K.mult(vin, vout)
    h = 1e-7
    fd = (residual(u0 + h * du) - residual(u0 - h * du)) / (2 * h)
    assert np.abs(vout.array - fd).max() < 1e-8 * np.abs(fd).max()


def _mesh_of_kind(kind):
    """Two curved cube-sphere particles (Q1), or a unit cube of tetrahedra (P2 displacement)."""
    import dolfinx

    if kind.startswith("cube"):
        return particle_mesh([[0, 0, 0], [2.1, 0, 0]], [1.0, 1.0], MPI.COMM_SELF).mesh, None
    return dolfinx.mesh.create_unit_cube(
        MPI.COMM_SELF, 2, 3, 2, dolfinx.mesh.CellType.tetrahedron
    ), 2


@pytest.mark.parametrize("kind", ["cube-sphere Q1", "tetrahedra P2"])
def test_deformation_gradient_kernel_matches_compiled_expression(kind):
    """The threaded F kernel (forms.kinematics) reproduces FFCx's Expression of I + Grad u on
    curved hexahedra and on P2 tetrahedra, for a random displacement and a subset of cells, and
    the problem uses it (the residual packing is handed the kernel's P_dev directly as well)."""
    import warnings

    import dolfinx

    mesh, degree = _mesh_of_kind(kind)
    cells = np.arange(0, mesh.topology.index_map(3).size_local, 3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        prob = SolidProblem(mesh, LEAD, degree=degree, active_cells=cells)
    assert prob._F_kernel is not None and prob._residual_key is not None
    rng = np.random.default_rng(3)
    prob.u.x.array[:] = 0.05 * rng.standard_normal(prob.u.x.array.size)
    F_expr = prob._F_expr.eval(prob.mesh, prob.material_cells).reshape(-1, 3, 3)
    F = prob.deformation_gradients()
    assert F.shape == F_expr.shape and np.abs(F - np.eye(3)).max() > 1e-2
    assert np.allclose(F, F_expr, rtol=0, atol=1e-13)
    prob.update_material(tangent=True)
    packed = dolfinx.fem.pack_coefficients(prob.residual_forms[0])[prob._residual_key]
    assert np.array_equal(packed, prob.material.P_dev.reshape(cells.size, -1))


def _plastic_problem(kind, subset, seed, tangent=False):
    """A problem on ``_mesh_of_kind(kind)`` (material on every third cell if ``subset``) after
    plastic flow at a random displacement (no cell inverted, with the consistent tangent if
    ``tangent``), and the random generator."""
    import warnings

    mesh, degree = _mesh_of_kind(kind)
    cells = np.arange(0, mesh.topology.index_map(3).size_local, 3) if subset else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        prob = SolidProblem(mesh, LEAD, degree=degree, active_cells=cells, tangent=tangent)
    rng = np.random.default_rng(seed)
    prob.u.x.array[:] = 0.01 * rng.standard_normal(prob.u.x.array.size)
    prob.update_material(tangent=tangent)
    return prob, rng


def _internal_force(prob):
    b = prob.create_vector()
    prob.assemble_residual(b)
    return b.array.copy()


@pytest.mark.parametrize("kind", ["cube-sphere Q1", "tetrahedra P2"])
@pytest.mark.parametrize("subset", [False, True], ids=["all cells", "a third of the cells"])
def test_deviatoric_force_loop_equals_the_compiled_form(kind, subset):
    """The residual's deviatoric part by the numba loop (forms.kinematics.DeviatoricForces, stored
    inverse Jacobians) and by FFCx's compiled form, after plastic flow at a random displacement:
    the same internal force to round-off, on curved hexahedra and P2 tetrahedra."""
    prob, _ = _plastic_problem(kind, subset, seed=4)
    assert prob._deviatoric_forces is not None
    assert (prob.material.eps_p_trial > 0).mean() > 0.5
    ours = _internal_force(prob)
    prob._deviatoric_forces = None  # the compiled form
    reference = _internal_force(prob)
    assert np.abs(ours - reference).max() <= 1e-13 * np.abs(reference).max()


@pytest.mark.parametrize("kind", ["cube-sphere Q1", "tetrahedra P2"])
@pytest.mark.parametrize("subset", [False, True], ids=["all cells", "a third of the cells"])
def test_tangent_loop_equals_the_compiled_forms(kind, subset):
    """The Jacobian by the numba loops (forms.kinematics.TangentStiffness, deviatoric and
    volumetric element matrices inserted block by block) and by FFCx's two compiled forms, at the
    consistent tangent after plastic flow at a random displacement: the same matrix to round-off,
    on curved hexahedra and P2 tetrahedra, and not the same for the tangent of another state."""
    from petsc4py import PETSc

    prob, rng = _plastic_problem(kind, subset, seed=5, tangent=True)
    assert prob._tangent_loop is not None
    assert (prob.material.eps_p_trial > 0).mean() > 0.5

    def jacobian():
        K = prob.create_matrix()
        prob.assemble_jacobian(K)
        return K

    ours = jacobian()
    prob._tangent_loop, kernel = None, prob._tangent_loop  # the compiled forms
    reference = jacobian()
    scale = reference.norm(PETSc.NormType.FROBENIUS)
    ours.axpy(-1.0, reference)
    assert ours.norm(PETSc.NormType.FROBENIUS) <= 1e-13 * scale
    # a measure that can disagree: the loop's matrix at another state is not the compiled one's
    prob._tangent_loop = kernel
    prob.u.x.array[:] += 0.002 * rng.standard_normal(prob.u.x.array.size)
    prob.update_material(tangent=True)
    other = jacobian()
    other.axpy(-1.0, reference)
    assert other.norm(PETSc.NormType.FROBENIUS) > 1e-3 * scale


@pytest.mark.parametrize("kind", ["cube-sphere Q1", "tetrahedra P2"])
@pytest.mark.parametrize("subset", [False, True], ids=["all cells", "a third of the cells"])
def test_volumetric_and_viscosity_loops_equal_compiled_forms(kind, subset):
    """The residual's volumetric part and the explicit solver's bulk-viscosity force by the numba
    loops at the volumetric points (forms.kinematics.VolumetricForces) and by FFCx's compiled
    forms, at a random displacement and a random velocity whose volumetric rates, of both signs,
    make the quadratic (compression-only) term as large as the linear one: the same forces to
    round-off, on curved hexahedra (one SRI point) and P2 tetrahedra (four points)."""
    from mpfem_fenicsx.loading import PrescribedDisplacements
    from mpfem_fenicsx.solvers.explicit import ExplicitSettings, ExplicitSolver

    prob, rng = _plastic_problem(kind, subset, seed=6)
    assert prob._volumetric_loop
    ours = _internal_force(prob)
    prob._volumetric_loop = False  # the compiled form
    reference = _internal_force(prob)
    assert np.abs(ours - reference).max() <= 1e-13 * np.abs(reference).max()

    solver = ExplicitSolver(
        prob, PrescribedDisplacements(prob.V), ExplicitSettings(t_end=1e-5, target_dt=1e-7)
    )
    assert solver._viscous_loop
    rate = solver._rate_scale()  # |tr grad_x v| at which both terms are equal
    solver.velocity.x.array[:] = rate * 0.05 * rng.standard_normal(solver.velocity.x.array.size)
    solver._forces()
    ours = solver.f_visc.array.copy()
    solver._viscous_loop = False
    solver._forces()
    reference = solver.f_visc.array
    assert np.abs(ours - reference).max() <= 1e-12 * np.abs(reference).max()


def test_cell_stress_integrals_match_the_internal_forces():
    """``SolidProblem.cell_stress_integrals`` (int sigma dv per cell, the volume-averaged stress of
    thesis eq. C.7) against two independent measures: the analytic Hencky stress of a homogeneous
    stretch times the deformed volume, and, for a non-homogeneous plastic state, the first moment
    sum_nodes f_int (x) x of the assembled internal forces (the discrete divergence theorem)."""
    mesh = particle_mesh([[0, 0, 0]], [1.0], MPI.COMM_SELF).mesh
    elastic = ElastoPlastic(sigma_0=1e9)
    prob = SolidProblem(mesh, elastic, tangent=False)
    X = prob.V.tabulate_dof_coordinates()
    stretches = np.array([1.004, 0.997, 0.999])
    prob.u.x.array[:] = (X * (stretches - 1.0)).ravel()
    prob.update_material()
    total = prob.cell_stress_integrals().sum(axis=0)
    h = np.log(stretches)
    # SRI: the deviatoric stress on the 8-point volume, the pressure on the one-point volume (1.2 %
    # smaller on the curved cube-sphere cells: the internal forces carry this stress, not tau V8)
    volume_8 = prob.point_volumes.sum()
    volume_1 = dolfinx.fem.assemble_scalar(
        dolfinx.fem.form(dolfinx.fem.Constant(mesh, 1.0) * prob.dx_vol)
    )
    expected = 2 * elastic.mu * (h - h.mean()) * volume_8 + elastic.bulk * h.sum() * volume_1
    assert np.allclose(total, np.diag(expected), rtol=1e-9, atol=1e-9 * np.abs(expected).max())

    plastic = SolidProblem(mesh, LEAD, tangent=False)
    rng = np.random.default_rng(5)
    u = np.zeros_like(X)
    u[:, 2] = -0.08 * X[:, 2]  # squeezed past yield, plus a non-affine wobble
    plastic.u.x.array[:] = (
        u + 0.01 * np.sin(3 * X[:, [1, 2, 0]]) + 1e-3 * rng.standard_normal(X.shape)
    ).ravel()
    plastic.update_material()
    assert plastic.material.eps_p_trial.max() > 0.01
    f = plastic.create_vector()
    plastic.assemble_residual(f)
    x = X + plastic.u.x.array.reshape(-1, 3)
    moment = np.einsum("na,nb->ab", f.array.reshape(-1, 3), x)
    integral = plastic.cell_stress_integrals().sum(axis=0)
    assert np.abs(integral).max() > 1.0  # N mm
    assert np.allclose(integral, moment, rtol=0, atol=1e-10 * np.abs(integral).max())
