"""Homogenization (thesis §2.3, §2.6, ch. 4, appendix C): pure numpy, no finite elements."""

import itertools
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from mpfem_fenicsx.homogenization import (
    branch_vectors,
    contact_weights,
    coordination,
    copy_centroids,
    first_crossing,
    gradient_fit_noise_hd,
    hencky_strain,
    least_squares_gradient,
    love_weber_stress,
    piola_to_cauchy,
    relative_density,
    rendulic_strain,
    rendulic_stress,
    reported_stress,
    schmidt_piola,
    schmidt_stress,
    second_order_work,
    solid_volume,
    specific_contact_surface,
    strain_invariants,
    stress_invariants,
)


def rotation(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def random_gradient(rng):
    F = np.eye(3) + 0.3 * rng.standard_normal((3, 3))
    return F if np.linalg.det(F) > 0 else F @ np.diag([1.0, 1.0, -1.0])


# -- least squares (appendix C.1) ---------------------------------------------------------------
def test_least_squares_recovers_affine_motion():
    rng = np.random.default_rng(0)
    X = rng.uniform(0, 2.0, (25, 3))
    F = random_gradient(rng)
    c = rng.standard_normal(3)
    Fr, cr = least_squares_gradient(X, X @ F.T + c)
    assert np.allclose(Fr, F, atol=1e-12, rtol=0) and np.allclose(cr, c, atol=1e-12, rtol=0)
    # a stack of current configurations (e.g. one per output time), and weights
    Fs = np.stack([random_gradient(rng) for _ in range(4)])
    cs = rng.standard_normal((4, 3))
    xs = np.einsum("tij,nj->tni", Fs, X) + cs[:, None, :]
    Fr, cr = least_squares_gradient(X, xs, weights=rng.uniform(0.5, 2.0, 25))
    assert Fr.shape == (4, 3, 3) and np.allclose(Fr, Fs, atol=1e-12, rtol=0)
    assert np.allclose(cr, cs, atol=1e-12, rtol=0)


def test_fit_noise_hd_matches_sampled_fits():
    """The closed-form noise floor of h_d (first order, residual variance from the fit's own
    residuals) against 4000 least-squares fits of scattered centroids on an isotropic path, on a
    cubic and an elongated cloud: the mean h_d^2 agree within 4 %."""
    rng = np.random.default_rng(3)
    for extent in ([0.82, 0.82, 0.82], [1.6, 0.8, 0.5]):
        X = rng.uniform(0.0, 1.0, (50, 3)) * extent
        F = 0.86 * np.eye(3)
        x = X @ F.T + 0.005 * rng.standard_normal((4000, 50, 3))
        Fs, cs = least_squares_gradient(X, x)
        residual = x - np.einsum("tij,nj->tni", Fs, X) - cs[:, None, :]
        rms = np.sqrt(np.mean(np.sum(residual**2, axis=2), axis=1))
        h_v, h_d = strain_invariants(hencky_strain(Fs))
        predicted = gradient_fit_noise_hd(X, rms, h_v)
        assert predicted.shape == (4000,)
        assert np.mean(h_d**2) / np.mean(predicted**2) == pytest.approx(1.0, abs=0.04)
    with pytest.raises(ValueError, match="residual_rms"):
        gradient_fit_noise_hd(X, -1.0)


def test_least_squares_matches_thesis_normal_equations():
    """Noisy displacements: same minimiser as H~ = B A^-1 (eq. C.5-C.6, 4x4 augmented)."""
    rng = np.random.default_rng(1)
    X = rng.uniform(0, 1.0, (30, 3))
    u = X @ (0.1 * rng.standard_normal((3, 3))).T + 0.01 * rng.standard_normal((30, 3))
    xt = np.column_stack([X, np.ones(30)])
    ut = np.column_stack([u, np.ones(30)])
    A = xt.T @ xt
    B = ut.T @ xt
    Ht = B @ np.linalg.inv(A)
    F, c = least_squares_gradient(X, X + u)
    assert np.allclose(F, np.eye(3) + Ht[:3, :3], atol=1e-12)
    assert np.allclose(c, Ht[:3, 3], atol=1e-12)


def test_least_squares_rank_deficient_raises():
    rng = np.random.default_rng(2)
    X = rng.standard_normal((3, 3))
    with pytest.raises(ValueError, match="at least 4"):
        least_squares_gradient(X, X)
    planar = (
        np.column_stack([rng.standard_normal((10, 2)), np.zeros(10)]) @ rotation([1, 2, 3], 0.7).T
    )
    with pytest.raises(ValueError, match="coplanar"):
        least_squares_gradient(planar, planar)
    line = np.outer(np.linspace(0, 1, 6), [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="coplanar"):
        least_squares_gradient(line, line)
    X = rng.standard_normal((6, 3))
    with pytest.raises(ValueError, match="at least 4"):
        least_squares_gradient(X, X, weights=[1, 1, 1, 0, 0, 0])
    with pytest.raises(ValueError):
        least_squares_gradient(X, X[:5])


# -- Hencky strain and invariants -------------------------------------------------------------
def test_hencky_stretch_rotation_objectivity():
    lam = np.array([0.8, 1.1, 1.3])
    assert np.allclose(hencky_strain(np.diag(lam)), np.diag(np.log(lam)), atol=1e-14)
    Q = rotation([1.0, -2.0, 0.5], 1.1)
    assert np.allclose(hencky_strain(Q), 0.0, atol=1e-14)
    rng = np.random.default_rng(3)
    F = random_gradient(rng)
    h = hencky_strain(F)
    assert np.allclose(hencky_strain(Q @ F), Q @ h @ Q.T, atol=1e-13)  # left tensor: objective
    assert np.allclose(hencky_strain(F @ Q), h, atol=1e-13)  # insensitive to a prior rotation
    assert np.isclose(np.trace(h), np.log(np.linalg.det(F)), atol=1e-13)  # h_v = ln det F
    stack = hencky_strain(np.stack([F, Q, np.diag(lam)]))
    assert stack.shape == (3, 3, 3) and np.allclose(stack[0], h)
    # thesis eq. 2.18: h = 1/2 ln(grad u + grad u^T + grad u grad u^T + I) is the same tensor
    Hu = F - np.eye(3)
    B = Hu + Hu.T + Hu @ Hu.T + np.eye(3)
    w, V = np.linalg.eigh(B)
    assert np.allclose(h, V @ np.diag(0.5 * np.log(w)) @ V.T, atol=1e-13)
    with pytest.raises(ValueError):
        hencky_strain(np.diag([1.0, 1.0, 0.0]))


def test_strain_invariants_and_rendulic_strain():
    lam = 0.7
    h = hencky_strain(np.diag([1.0, 1.0, lam]))  # die compaction along e3
    h_v, h_d = strain_invariants(h)
    assert np.isclose(h_v, np.log(lam)) and h_v < 0
    assert np.isclose(h_d, 2.0 / 3.0 * abs(np.log(lam)))
    hv, htd = rendulic_strain(h)  # axis e3 by default
    assert np.isclose(hv, h_v) and np.isclose(htd, 2.0 / 3.0 * np.log(lam)) and htd < 0
    assert np.isclose(abs(htd), h_d)
    # same path along x: the axis follows the argument
    _, htd_x = rendulic_strain(hencky_strain(np.diag([lam, 1.0, 1.0])), axis=0)
    assert np.isclose(htd_x, htd)
    assert np.isclose(rendulic_strain(h, axis=[0.0, 0.0, -2.0])[1], htd)
    # isotropic: no deviatoric strain
    h_v, h_d = strain_invariants(hencky_strain(0.9 * np.eye(3)))
    assert np.isclose(h_v, 3 * np.log(0.9)) and np.isclose(h_d, 0.0, atol=1e-15)
    # reload fan (eq. 4.8, axis I first as in eq. 4.9): a circle of radius A in (h_v, h~_d);
    # with eq. 4.3-4.4 as printed, h_v = -A cos(phi), h~_d = -A sin(phi)
    A = 0.02
    phi = np.linspace(0, 2 * np.pi, 13)
    hI = -A * (np.cos(phi) / 3 + np.sin(phi))
    hII = -A * (np.cos(phi) / 3 - np.sin(phi) / 2)
    hs = np.zeros((phi.size, 3, 3))
    hs[:, 0, 0], hs[:, 1, 1], hs[:, 2, 2] = hI, hII, hII
    hv, htd = rendulic_strain(hs, axis=0)
    assert np.allclose(hv, -A * np.cos(phi)) and np.allclose(htd, -A * np.sin(phi))
    _, hd = strain_invariants(hs)
    assert np.allclose(hd, np.abs(htd))


def test_stress_invariants_and_rendulic_signs():
    p = 12.5
    sm, sd = stress_invariants(-p * np.eye(3))  # hydrostatic pressure, tension-positive tensor
    assert np.isclose(sm, p) and np.isclose(sd, 0.0, atol=1e-14)
    q = 7.0
    uni = np.diag([0.0, 0.0, -q])  # uniaxial compression along e3
    sm, sd = stress_invariants(uni)
    assert np.isclose(sm, q / 3) and np.isclose(sd, q)
    sm, std = rendulic_stress(uni)
    assert np.isclose(std, q) and np.isclose(std, 3 * sm)  # on the line sigma~_d = 3 sigma_m, > 0
    sm, std = rendulic_stress(np.diag([0.0, 0.0, q]))  # uniaxial tension
    assert np.isclose(std, -q) and np.isclose(std, 3 * sm) and sm < 0
    sm, std = rendulic_stress(np.diag([-q, 0.0, 0.0]), axis=0)
    assert np.isclose(std, q)
    # die compaction: axial compression larger than the lateral one -> sigma~_d > 0
    die = -np.diag([4.0, 4.0, 10.0])
    sm, std = rendulic_stress(die)
    assert np.isclose(sm, 6.0) and np.isclose(std, 6.0)
    assert np.isclose(abs(std), stress_invariants(die)[1])
    assert np.allclose(reported_stress(die), np.diag([4.0, 4.0, 10.0]))
    # stacks; invariants insensitive to a rotation, sigma_d to the sign convention
    rng = np.random.default_rng(4)
    S = rng.standard_normal((5, 3, 3))
    S = S + np.swapaxes(S, 1, 2)
    Q = rotation([0.3, 1.0, -0.2], 0.4)
    a, b = stress_invariants(S)
    c, d = stress_invariants(Q @ S @ Q.T)
    assert a.shape == (5,) and np.allclose(a, c) and np.allclose(b, d)
    assert np.allclose(stress_invariants(-S)[1], b) and np.allclose(stress_invariants(-S)[0], -a)


def test_relative_density_simple_cubic():
    r, a = 0.5, 1.0
    Vp = solid_volume([r])
    assert np.isclose(relative_density(Vp, a**3, np.eye(3)), np.pi / 6)
    F = np.diag([0.9, 0.95, 0.85])
    assert np.isclose(relative_density(Vp, a**3, F), np.pi / (6 * np.linalg.det(F)))  # eq. 2.17
    stack = relative_density(Vp, a**3, np.stack([np.eye(3), F]))
    assert stack.shape == (2,) and np.isclose(stack[1], np.pi / (6 * np.linalg.det(F)))


# -- Love-Weber (eq. 2.6, appendix C.2) -------------------------------------------------------
def test_love_weber_two_particles_hand_computed():
    """Two spheres pressed along x with force f, centres d apart, in a volume V."""
    f, d, V = 3.0, 0.2, 0.05
    x = np.array([[0.0, 0.0, 0.0], [d, 0.0, 0.0]])
    force_on_0_by_1 = np.array([[-f, 0.0, 0.0]])  # 1 pushes 0 towards -x
    sigma = love_weber_stress(force_on_0_by_1, branch_vectors(x, [0], [1]), V)
    expected = np.zeros((3, 3))
    expected[0, 0] = -f * d / V  # compressive, mechanics convention
    assert np.allclose(sigma, expected)
    # the same contact listed the other way round gives the same tensor
    assert np.allclose(
        love_weber_stress(-force_on_0_by_1, branch_vectors(x, [1], [0]), V), expected
    )
    sm, sd = stress_invariants(sigma)
    assert np.isclose(sm, f * d / (3 * V)) and np.isclose(sd, f * d / V)
    # thesis eq. 2.6, l = x_alpha - x_beta
    assert np.allclose(reported_stress(sigma)[0, 0], f * d / V)


def test_love_weber_simple_cubic_with_periodic_images():
    """One sphere per cubic cell (side a), contacts with its images across the faces: with
    F = diag(l), contact forces f_k along axis k, sigma_kk = -f_k / (current face area),
    equal to the Schmidt stress of the auxiliary-node reactions."""
    a = 1.0
    lam = np.array([0.9, 0.95, 0.8])
    F = np.diag(lam)
    fk = np.array([2.0, 3.0, 5.0])
    x = np.zeros((1, 3))
    # three physical contacts per cell: with the image +e_k (one side of each pair of faces)
    pair_shift = np.eye(3, dtype=int)
    offset = copy_centroids(np.zeros((3, 3)), pair_shift, [a, a, a], F)
    lv = branch_vectors(x, [0, 0, 0], [0, 0, 0], offset=offset)
    assert np.allclose(lv, np.diag(lam * a))
    forces = -fk[:, None] * np.eye(3)  # on the sphere by its +e_k image: towards -e_k
    w = contact_weights([0, 0, 0], [0, 0, 0], [0], [[0, 0, 0]], "CLPS", pair_shift=pair_shift)
    assert np.allclose(w, 1.0)
    V = a**3 * np.prod(lam)
    sigma = love_weber_stress(forces, lv, V, weights=w)
    areas = np.array([lam[1] * lam[2], lam[0] * lam[2], lam[0] * lam[1]]) * a * a
    assert np.allclose(sigma, np.diag(-fk / areas))
    # hydrostatic contact forces f on an undeformed lattice: sigma_m = f 2r n_c / (3 V) = f / a^2
    sm, sd = stress_invariants(love_weber_stress(-2.0 * np.eye(3), a * np.eye(3), a**3))
    assert np.isclose(sm, 2.0 * a * 3 / (3 * a**3)) and np.isclose(sd, 0.0)
    # Schmidt: the constraint holds face k with the force -f_k e_k (inwards)
    reactions = -fk[:, None] * np.eye(3)
    assert np.allclose(schmidt_stress(reactions, F, [a, a, a]), sigma)


def simple_cubic_assembly(n, a, shifts):
    """n^3 VEP spheres (cell side n a) plus, for every shift s, copies of the VEP particles
    whose image lies next to the cell (all particles if ``shifts`` is 'all faces')."""
    idx = np.array(list(itertools.product(range(n), repeat=3)))
    X = a * (idx + 0.5)
    centres, original, shift = [X], [np.arange(len(X))], [np.zeros((len(X), 3), int)]
    for s, layer in shifts:
        sel = (
            np.flatnonzero(np.all(idx[:, np.flatnonzero(s)] == layer, axis=1))
            if layer is not None
            else np.arange(len(X))
        )
        centres.append(X[sel] + n * a * np.asarray(s))
        original.append(sel)
        shift.append(np.tile(s, (sel.size, 1)))
    return np.concatenate(centres), np.concatenate(original), np.concatenate(shift)


def touching_pairs(x, a):
    d = np.linalg.norm(x[:, None] - x[None], axis=2)
    i, j = np.nonzero(np.triu(np.isclose(d, a), 1))
    return i, j


def physical_groups(x, original, i, j):
    """Independent grouping of the modelled contacts by physical contact: same pair of
    originals and same branch vector (orientation normalized)."""
    lv = x[j] - x[i]
    keys = []
    for oi, oj, v in zip(original[i], original[j], lv, strict=True):
        if (oi, tuple(np.round(v, 9))) > (oj, tuple(np.round(-v, 9))):
            oi, oj, v = oj, oi, -v
        keys.append((oi, oj) + tuple(np.round(v, 9)))
    _, inverse, counts = np.unique(np.array(keys), axis=0, return_inverse=True, return_counts=True)
    return inverse.ravel(), counts


def test_counting_rules_solid_copies_gdf():
    """2x2x2 simple cubic VEP with solid copies on all six faces: every VEP-VEP contact once,
    each periodic contact modelled twice (alpha+ beta+ and alpha- beta-) -> 1/2 each,
    copy-copy contacts 0; the Love-Weber stress is the exact lattice stress -f/a^2 I."""
    n, a, f = 2, 1.0, 4.0
    faces = [(s * e, None) for e in np.eye(3, dtype=int) for s in (1, -1)]
    x, original, shift = simple_cubic_assembly(n, a, faces)
    i, j = touching_pairs(x, a)
    w = contact_weights(i, j, original, shift, "GDF")
    copy = np.any(shift != 0, axis=1)
    assert np.all(w[~copy[i] & ~copy[j]] == 1.0)
    assert np.all(w[copy[i] & copy[j]] == 0.0)
    assert np.allclose(w[copy[i] ^ copy[j]], 0.5)
    assert np.isclose(w.sum(), 3 * n**3)  # three physical contacts per particle
    lv = x[j] - x[i]
    forces = -f * lv / a
    V = (n * a) ** 3
    sigma = love_weber_stress(forces, lv, V, weights=w)
    assert np.allclose(sigma, -f / a**2 * np.eye(3))
    assert not np.allclose(love_weber_stress(forces, lv, V), sigma)  # counting matters
    # the rule agrees with the independent grouping by branch vector (counted contacts)
    group, counts = physical_groups(x, original, i, j)
    counted = ~(copy[i] & copy[j])
    per_group = np.bincount(group[counted], weights=w[counted])
    assert np.allclose(per_group[per_group > 0], 1.0)
    # the same with the contacts listed in the other orientation (force on j by i, l = x_i - x_j)
    w2 = contact_weights(j, i, original, shift, "GDF")
    assert np.allclose(w2, w)
    assert np.allclose(love_weber_stress(-forces, -lv, V, weights=w2), sigma)


def test_counting_rules_clp_shells():
    """Thesis §2.6 cell: 8 VEP spheres and 12 shell copies on half of the faces. The coupling
    spreads each physical contact force over its modelled images (VEP-VEP and shell-shell):
    with CLP every contact counts (weight 1) and the sum is the lattice stress."""
    n, a, f = 2, 1.0, 4.0
    x, original, shift = simple_cubic_assembly(n, a, [(e, 0) for e in np.eye(3, dtype=int)])
    assert len(x) == 8 + 12
    i, j = touching_pairs(x, a)
    copy = np.any(shift != 0, axis=1)
    assert np.count_nonzero(copy[i] & copy[j]) > 0  # shell-shell contacts exist
    w = contact_weights(i, j, original, shift, "CLP")
    assert np.all(w == 1.0)
    group, counts = physical_groups(x, original, i, j)
    assert counts.size == 3 * n**3  # every physical contact is modelled
    rng = np.random.default_rng(5)
    share = rng.uniform(0.2, 1.0, i.size)
    share /= np.bincount(group, weights=share)[group]  # random split of f over the images
    lv = x[j] - x[i]
    sigma = love_weber_stress(-f * share[:, None] * lv / a, lv, (n * a) ** 3, weights=w)
    assert np.allclose(sigma, -f / a**2 * np.eye(3))


def test_coordination_counts_weighted_contacts_per_particle():
    """3 particles; bodies 3, 4 are copies of 0 and 2. Contacts: 0-1, 1-2, 1-3 (periodic 1-0),
    2-4 (2 with its own image) and a half-weighted pair of realizations 0-2 / 3-4."""
    original = np.array([0, 1, 2, 0, 2])
    i, j = np.array([0, 1, 1, 2, 0, 3]), np.array([1, 2, 3, 4, 2, 4])
    w = np.array([1, 1, 1, 1, 0.5, 0.5])
    contacts, z, rattlers = coordination(i, j, original, w, 3)
    # per particle: 0: 1 + 1 + 0.5 + 0.5 = 3, 1: 3, 2: 1 + 2 + 0.5 + 0.5 = 4
    assert contacts == 5.0 and z == pytest.approx(10 / 3) and rattlers == 2
    assert coordination(i, j, original, w, 3, rattler_below=3)[2] == 0
    assert coordination([], [], original, [], 3) == (0.0, 0.0, 3)


def test_contact_weights_input_checks():
    with pytest.raises(ValueError, match="bc"):
        contact_weights([0], [1], [0, 1], np.zeros((2, 3)), "periodic")
    with pytest.raises(ValueError, match="itself"):
        contact_weights([0], [1], [0, 0], np.zeros((2, 3)), "GDF")
    # a particle touching its own image, modelled on both sides: counted once
    w = contact_weights([0, 1], [2, 0], [0, 0, 0], [[0, 0, 0], [-1, 0, 0], [1, 0, 0]], "GDH")
    assert np.allclose(w, 0.5)
    assert contact_weights([], [], [0], [[0, 0, 0]], "GDF").shape == (0,)


# -- Schmidt stress (§2.6, eq. 2.19) ----------------------------------------------------------
def test_schmidt_recovers_piola_on_sheared_cell():
    rng = np.random.default_rng(6)
    C = np.diag([1.2, 0.9, 1.5]) + 0.2 * rng.standard_normal((3, 3))  # rows: cell vectors
    C = C if np.linalg.det(C) > 0 else C[[1, 0, 2]]
    V0 = np.linalg.det(C)
    P = rng.standard_normal((3, 3))
    # force on face b (spanned by the two other cell vectors, outward area vector c_c x c_d)
    R = np.array([P @ np.cross(C[(b + 1) % 3], C[(b + 2) % 3]) for b in range(3)])
    assert np.allclose(schmidt_piola(R, C), P)
    # virtual work: aux node b moves by dF c_b, dW = sum_b R_b . dF c_b = V0 P : dF
    dF = rng.standard_normal((3, 3))
    assert np.isclose(sum(R[b] @ dF @ C[b] for b in range(3)), V0 * np.sum(P * dF))
    # box: P_ab = R_b,a / A_b (thesis §2.6)
    L = np.array([1.0, 2.0, 3.0])
    Rb = rng.standard_normal((3, 3))
    A = np.array([L[1] * L[2], L[0] * L[2], L[0] * L[1]])
    assert np.allclose(schmidt_piola(Rb, L), Rb.T / A[None, :])
    # homogeneous state: a symmetric Cauchy stress and its Piola stress P = J sigma F^-T
    F = random_gradient(rng)
    S = rng.standard_normal((3, 3))
    S = S + S.T
    P = np.linalg.det(F) * S @ np.linalg.inv(F).T
    R = np.array([P @ np.cross(C[(b + 1) % 3], C[(b + 2) % 3]) for b in range(3)])
    assert np.allclose(schmidt_stress(R, F, C), S)
    assert np.allclose(piola_to_cauchy(np.stack([P, P]), np.stack([F, F])), S)


# -- chapter 4 indicators --------------------------------------------------------------------
def test_second_order_work_sign():
    rng = np.random.default_rng(7)
    dh = rng.standard_normal((4, 3, 3)) * 1e-3
    dh = dh + np.swapaxes(dh, 1, 2)
    lam, mu = 50.0, 30.0
    tr = np.trace(dh, axis1=1, axis2=2)
    dsigma = lam * tr[:, None, None] * np.eye(3) + 2 * mu * dh  # elastic (mechanics convention)
    W2 = second_order_work(dsigma, dh)
    assert W2.shape == (4,) and np.all(W2 > 0)
    assert np.all(second_order_work(-0.5 * dh, dh) < 0)  # softening: Hill's instability
    # die compaction increment: axial shortening, axial stress more compressive -> W2 > 0
    assert second_order_work(np.diag([-0.4, -0.4, -1.0]), np.diag([0.0, 0.0, -1e-3])) > 0


def test_specific_contact_surface():
    F = np.diag([0.9, 0.9, 0.8])
    V0 = 8.0
    areas = np.array([0.1, 0.2, 0.3, 0.4])
    assert np.isclose(specific_contact_surface(1.0, V0, F), 1.0 / (V0 * np.linalg.det(F)))
    assert np.isclose(specific_contact_surface(areas, V0, F), 1.0 / (V0 * np.linalg.det(F)))
    w = np.array([1.0, 0.5, 0.5, 0.0])
    assert np.isclose(
        specific_contact_surface(areas, V0, F, weights=w), 0.35 / (V0 * np.linalg.det(F))
    )


def test_first_crossing_interpolates():
    E = np.array([1.0, 1.0, 1.001, 1.002, 1.004, 1.01])
    sm = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    pos, v = first_crossing(E, 1.0 * 1.003, sm)
    assert np.isclose(pos, 3.5) and np.isclose(v, 3.5)
    pos, v = first_crossing(E, 2.0, sm)
    assert np.isnan(pos) and np.isnan(v)
    W2 = np.array([1.0, 0.5, -0.5, -1.0])
    pos, v = first_crossing(W2, 0.0, np.column_stack([sm[:4], 2 * sm[:4]]), rising=False)
    assert np.isclose(pos, 1.5) and np.allclose(v, [1.5, 3.0])


def test_package_does_not_import_fe_stack(root):
    code = textwrap.dedent(f"""
        import sys, types
        pkg = types.ModuleType("mpfem_fenicsx")
        pkg.__path__ = [{str(root / "mpfem_fenicsx")!r}]
        sys.modules["mpfem_fenicsx"] = pkg  # skip the top-level __init__ (it loads dolfinx_solver)
        import mpfem_fenicsx.homogenization
        compiled = ("dolfinx", "petsc4py", "mpi4py", "ufl")
        bad = [m for m in sys.modules if m.split(".")[0] in compiled]
        assert not bad, bad
    """)
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)
