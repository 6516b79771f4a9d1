"""Finite-strain von Mises plasticity with Hencky elasticity: vectorized return mapping.

Multiplicative split F = F_e F_p with the exponential-map integrator of Simo (1992) (also
Eterovic & Bathe 1990): state per quadrature point = plastic right Cauchy-Green inverse
C_p^-1 (6 Voigt components xx, yy, zz, xy, xz, yz) and equivalent plastic strain eps_p.

Given F_{n+1}:
    b_e^trial = F C_p,n^-1 F^T = sum_A x_A n_A (x) n_A        (x_A = lambda_A^2)
    eps^trial_A = 1/2 ln x_A                                   (logarithmic elastic strain)
    tau = K tr(eps_e) 1 + 2 mu dev(eps_e)                      (Hencky, Kirchhoff stress, MPa)
    f = sqrt(3/2) |dev tau| - sigma_y(eps_p) <= 0               (thesis eq. 2.1 for sigma_y)
Radial return in principal logarithmic space (the small-strain algorithm, exactly), with a
bracketed Newton on the plastic multiplier that stays robust when d sigma_y / d eps_p is
infinite at eps_p = 0 (power law with n < 1).

Plastic flow is isochoric, so tr(eps_e) = ln J: the volumetric Kirchhoff stress K ln J only
depends on J and is left to the UFL form (integrated with one point per hexahedron, see
``mpfem_fenicsx.forms.bulk``). This kernel returns the *deviatoric* first Piola stress
P_dev = dev(tau) F^-T and its consistent tangent A_dev = dP_dev/dF (Simo 1992, eigen-projection
derivative with the stable divided difference (ln x_A - ln x_B)/(x_A - x_B)).

Two realizations of the same update. With the tangent (implicit solver), in principal axes:
the eigen-decomposition is closed-form (``eig_sym3``: accurate for repeated eigenvalues, no
iterations, no LAPACK call per point). Without it (explicit solver) and while |b_e^trial - 1|
<= ``SERIES_RADIUS`` (elastic strains up to ~5 %, i.e. always for a metal), in tensor form: the
radial return is coaxial, so eps^trial = 1/2 ln b_e^trial by the artanh series and
b_e = exp(2 eps_e) by the Taylor series, each cut at a truncation error of 1e-17, and an elastic
point keeps its C_p^-1 as it is; no eigenvectors, logarithms or exponentials per principal value.
The two agree to round-off (tests/test_material.py). Everything runs in one ``numba.prange``
loop over quadrature points.
"""

from __future__ import annotations

import numba
import numpy as np

_SQRT_3_2 = np.sqrt(1.5)


@numba.njit(cache=True, inline="always")
def _null_vector(b00, b01, b02, b11, b12, b22, beta):
    """Unit vector spanning the null space of the symmetric B - beta I when beta is a simple
    eigenvalue of B (rank 2): the longest of the cross products of two of its rows."""
    r00 = b00 - beta
    r11 = b11 - beta
    r22 = b22 - beta
    c0x = b01 * b12 - b02 * r11  # row 0 x row 1
    c0y = b02 * b01 - r00 * b12
    c0z = r00 * r11 - b01 * b01
    c1x = b01 * r22 - b02 * b12  # row 0 x row 2
    c1y = b02 * b02 - r00 * r22
    c1z = r00 * b12 - b01 * b02
    c2x = r11 * r22 - b12 * b12  # row 1 x row 2
    c2y = b12 * b02 - b01 * r22
    c2z = b01 * b12 - r11 * b02
    n0 = c0x * c0x + c0y * c0y + c0z * c0z
    n1 = c1x * c1x + c1y * c1y + c1z * c1z
    n2 = c2x * c2x + c2y * c2y + c2z * c2z
    if n0 >= n1 and n0 >= n2:
        inv = 1.0 / np.sqrt(n0)
        return c0x * inv, c0y * inv, c0z * inv
    if n1 >= n2:
        inv = 1.0 / np.sqrt(n1)
        return c1x * inv, c1y * inv, c1z * inv
    inv = 1.0 / np.sqrt(n2)
    return c2x * inv, c2y * inv, c2z * inv


@numba.njit(cache=True)
def eig_sym3(a, w, Q):
    """Eigenvalues ``w`` and orthonormal eigenvectors (columns of ``Q``) of the symmetric 3x3 ``a``
    (its two triangles averaged), without iterations.

    The deviator d = a - tr(a)/3 I scaled to B = d / p (p^2 = |d|^2 / 6) has its eigenvalues
    2 cos(acos(det(B)/2)/3 + 2 pi k/3) (Smith 1961). Only the eigenvalue farthest from the other
    two (the largest if det B >= 0, else the smallest) is taken from that formula: it is
    well-conditioned, and its eigenvector is a cross product of two rows of B - beta I. The other
    two come from the 2x2 restriction of B to the plane normal to it, diagonalized by one Jacobi
    rotation, which stays accurate when they are equal or nearly so (the approach of Eberly 2014,
    "A robust eigensolver for 3x3 symmetric matrices"). Working on the scaled deviator keeps the
    relative accuracy of the deviatoric part when a is close to a multiple of the identity (an
    elastic left Cauchy-Green tensor near 1 at small elastic strains). It replaced cyclic Jacobi
    sweeps: faster and at least as accurate (bench/README.md, the material kernel).
    """
    q = (a[0, 0] + a[1, 1] + a[2, 2]) / 3.0
    d00 = a[0, 0] - q
    d11 = a[1, 1] - q
    d22 = a[2, 2] - q
    # re-centred: when the deviator is at the rounding level of a (b_e = 1 to 1e-16), a - q is
    # not traceless to its own precision, and the formula's largest or smallest root may then be
    # a double eigenvalue of it (B - beta I of rank 1: no cross product, a division by zero)
    shift = (d00 + d11 + d22) / 3.0
    q += shift
    d00 -= shift
    d11 -= shift
    d22 -= shift
    d01 = 0.5 * (a[0, 1] + a[1, 0])
    d02 = 0.5 * (a[0, 2] + a[2, 0])
    d12 = 0.5 * (a[1, 2] + a[2, 1])
    p2 = (d00 * d00 + d11 * d11 + d22 * d22 + 2.0 * (d01 * d01 + d02 * d02 + d12 * d12)) / 6.0
    if p2 <= 1e-300:  # a multiple of the identity: every basis is an eigenbasis
        for i in range(3):
            w[i] = q
            for j in range(3):
                Q[i, j] = 1.0 if i == j else 0.0
        return
    p = np.sqrt(p2)
    b00 = d00 / p
    b11 = d11 / p
    b22 = d22 / p
    b01 = d01 / p
    b02 = d02 / p
    b12 = d12 / p
    half_det = 0.5 * (
        b00 * (b11 * b22 - b12 * b12)
        - b01 * (b01 * b22 - b12 * b02)
        + b02 * (b01 * b12 - b11 * b02)
    )
    half_det = min(1.0, max(-1.0, half_det))
    angle = np.arccos(half_det) / 3.0
    beta = 2.0 * np.cos(angle) if half_det >= 0.0 else 2.0 * np.cos(angle + 2.0 * np.pi / 3.0)
    e0x, e0y, e0z = _null_vector(b00, b01, b02, b11, b12, b22, beta)
    # orthonormal basis (u, v) of the plane normal to e0
    if abs(e0x) > abs(e0y):
        inv = 1.0 / np.sqrt(e0x * e0x + e0z * e0z)
        ux, uy, uz = -e0z * inv, 0.0, e0x * inv
    else:
        inv = 1.0 / np.sqrt(e0y * e0y + e0z * e0z)
        ux, uy, uz = 0.0, e0z * inv, -e0y * inv
    vx = e0y * uz - e0z * uy
    vy = e0z * ux - e0x * uz
    vz = e0x * uy - e0y * ux
    # B restricted to that plane: [[m00, m01], [m01, m11]], diagonalized by one rotation (c, s)
    bux = b00 * ux + b01 * uy + b02 * uz
    buy = b01 * ux + b11 * uy + b12 * uz
    buz = b02 * ux + b12 * uy + b22 * uz
    bvx = b00 * vx + b01 * vy + b02 * vz
    bvy = b01 * vx + b11 * vy + b12 * vz
    bvz = b02 * vx + b12 * vy + b22 * vz
    m00 = ux * bux + uy * buy + uz * buz
    m01 = vx * bux + vy * buy + vz * buz
    m11 = vx * bvx + vy * bvy + vz * bvz
    t = 0.0
    c = 1.0
    s = 0.0
    if abs(m01) > 1e-300:
        theta = (m11 - m00) / (2.0 * m01)
        t = 1.0 / (abs(theta) + np.sqrt(theta * theta + 1.0))
        if theta < 0.0:
            t = -t
        c = 1.0 / np.sqrt(t * t + 1.0)
        s = t * c
    # the isolated eigenvalue from its Rayleigh quotient (error quadratic in e0's)
    beta0 = (
        e0x * (b00 * e0x + b01 * e0y + b02 * e0z)
        + e0y * (b01 * e0x + b11 * e0y + b12 * e0z)
        + e0z * (b02 * e0x + b12 * e0y + b22 * e0z)
    )
    w[0] = q + p * beta0
    w[1] = q + p * (m00 - t * m01)
    w[2] = q + p * (m11 + t * m01)
    Q[0, 0] = e0x
    Q[1, 0] = e0y
    Q[2, 0] = e0z
    Q[0, 1] = c * ux - s * vx
    Q[1, 1] = c * uy - s * vy
    Q[2, 1] = c * uz - s * vz
    Q[0, 2] = s * ux + c * vx
    Q[1, 2] = s * uy + c * vy
    Q[2, 2] = s * uz + c * vz


@numba.njit(cache=True, inline="always")
def _log_divided_difference(xa, xb):
    """(ln xa - ln xb) / (xa - xb), stable when xa -> xb (limit 1/xb)."""
    t = (xa - xb) / xb
    if abs(t) < 1e-5:
        return (1.0 - 0.5 * t + t * t / 3.0) / xb
    return np.log1p(t) / (xa - xb)


@numba.njit(cache=True, inline="always")
def _mul_ab(a, b, out):
    """out = a b (3 x 3)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]


@numba.njit(cache=True, inline="always")
def _mul_abt(a, b, out):
    """out = a b^T (3 x 3)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[j, 0] + a[i, 1] * b[j, 1] + a[i, 2] * b[j, 2]


@numba.njit(cache=True, inline="always")
def _store_cp_inv(be, Finv, M, C, out):
    """out = the 6 components of C_p^-1 = F^-1 b_e F^-T (its two triangles averaged); M, C
    scratch."""
    _mul_abt(be, Finv, M)
    _mul_ab(Finv, M, C)
    out[0] = C[0, 0]
    out[1] = C[1, 1]
    out[2] = C[2, 2]
    out[3] = 0.5 * (C[0, 1] + C[1, 0])
    out[4] = 0.5 * (C[0, 2] + C[2, 0])
    out[5] = 0.5 * (C[1, 2] + C[2, 1])


@numba.njit(cache=True, inline="always")
def inverse3(F, Finv):
    """Finv = F^-1 of a 3 x 3 matrix (cofactors over the determinant; numba kernel, shared with
    the forms' gradient kernel)."""
    det = (
        F[0, 0] * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1])
        - F[0, 1] * (F[1, 0] * F[2, 2] - F[1, 2] * F[2, 0])
        + F[0, 2] * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0])
    )
    inv = 1.0 / det
    Finv[0, 0] = (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1]) * inv
    Finv[0, 1] = (F[0, 2] * F[2, 1] - F[0, 1] * F[2, 2]) * inv
    Finv[0, 2] = (F[0, 1] * F[1, 2] - F[0, 2] * F[1, 1]) * inv
    Finv[1, 0] = (F[1, 2] * F[2, 0] - F[1, 0] * F[2, 2]) * inv
    Finv[1, 1] = (F[0, 0] * F[2, 2] - F[0, 2] * F[2, 0]) * inv
    Finv[1, 2] = (F[0, 2] * F[1, 0] - F[0, 0] * F[1, 2]) * inv
    Finv[2, 0] = (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]) * inv
    Finv[2, 1] = (F[0, 1] * F[2, 0] - F[0, 0] * F[2, 1]) * inv
    Finv[2, 2] = (F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]) * inv
    return det


@numba.njit(cache=True, inline="always")
def _hardening_power(p, exponent, law):
    """p^n of the power law (0 at p = 0), the one power its yield stress, slope and plastic work
    share; unused (1) for linear hardening."""
    if law == 0:
        return p**exponent if p > 0.0 else 0.0
    return 1.0


@numba.njit(cache=True, inline="always")
def _yield_and_slope(p, power, s0, modulus, exponent, law):
    """sigma_y(p) and d sigma_y / d eps_p (MPa) from p^n = ``power`` (eq. 2.1); the slope is
    infinite at p = 0 for the power law."""
    if law == 0:
        if p <= 0.0:
            return s0, np.inf
        return s0 + modulus * power, modulus * exponent * power / p
    return s0 + modulus * p, modulus


@numba.njit(cache=True, inline="always")
def _plastic_multiplier(q_tr, p_n, three_mu, s0, modulus, exponent, law):
    """Radial return of the trial von Mises stress q_tr (MPa) at eps_p = p_n: the increment of
    eps_p, whether the trial state is plastic, and the exact plastic work of the increment,
    int_p_n^(p_n + dgamma) sigma_y dp (MPa = mJ/mm^3; the rectangle overestimates it where the
    power law is steep). dgamma is the root of q_tr - 3 mu dgamma - sigma_y(p_n + dgamma) = 0,
    by a Newton kept inside its bracket (robust where the slope is infinite at eps_p = 0)."""
    if q_tr <= s0:  # below the initial yield stress: elastic whatever the hardening
        return 0.0, False, 0.0
    power_n = _hardening_power(p_n, exponent, law)
    sy_n, slope = _yield_and_slope(p_n, power_n, s0, modulus, exponent, law)
    if not q_tr - sy_n > 1e-12 * sy_n:
        return 0.0, False, 0.0
    lo = 0.0
    hi = (q_tr - s0) / three_mu
    dgamma = (q_tr - sy_n) / (three_mu + slope) if np.isfinite(slope) else 0.5 * hi
    evaluated, power = -1.0, 0.0  # the last dgamma whose p^n was computed, and that power
    for _it in range(200):
        p = p_n + dgamma
        evaluated, power = dgamma, _hardening_power(p, exponent, law)
        sy, slope = _yield_and_slope(p, power, s0, modulus, exponent, law)
        r = q_tr - three_mu * dgamma - sy
        if abs(r) <= 1e-13 * q_tr:
            break
        if r > 0.0:
            lo = dgamma
        else:
            hi = dgamma
        if hi - lo <= 1e-16 * hi:
            break
        trial = dgamma + r / (three_mu + slope)
        if not (lo < trial < hi):
            trial = 0.5 * (lo + hi)
        dgamma = trial
    if law == 0:
        p = p_n + dgamma
        if dgamma != evaluated:  # the loop ended on an update (not on convergence)
            power = _hardening_power(p, exponent, law)
        work = s0 * dgamma + modulus / (exponent + 1.0) * (p * power - p_n * power_n)
    else:
        work = (s0 + modulus * (p_n + 0.5 * dgamma)) * dgamma
    return dgamma, True, work


# Symmetric 3 x 3 matrices as 6-tuples (xx, yy, zz, xy, xz, yz). ``_sym_mul`` is the product of
# two matrices that commute (functions of the same tensor), whose product is symmetric.
@numba.njit(cache=True, inline="always")
def _sym_mul(a, b):
    return (
        a[0] * b[0] + a[3] * b[3] + a[4] * b[4],
        a[3] * b[3] + a[1] * b[1] + a[5] * b[5],
        a[4] * b[4] + a[5] * b[5] + a[2] * b[2],
        a[0] * b[3] + a[3] * b[1] + a[4] * b[5],
        a[0] * b[4] + a[3] * b[5] + a[4] * b[2],
        a[3] * b[4] + a[1] * b[5] + a[5] * b[2],
    )


@numba.njit(cache=True, inline="always")
def _sym_norm2(a):
    """Squared Frobenius norm."""
    return a[0] * a[0] + a[1] * a[1] + a[2] * a[2] + 2.0 * (a[3] * a[3] + a[4] * a[4] + a[5] * a[5])


@numba.njit(cache=True, inline="always")
def _sym_axpi(alpha, a, c):
    """alpha a + c 1."""
    return (
        alpha * a[0] + c,
        alpha * a[1] + c,
        alpha * a[2] + c,
        alpha * a[3],
        alpha * a[4],
        alpha * a[5],
    )


@numba.njit(cache=True, inline="always")
def _sym_to_full(a, out):
    """The 3 x 3 matrix ``out`` of the 6 components (xx, yy, zz, xy, xz, yz) ``a``."""
    out[0, 0] = a[0]
    out[1, 1] = a[1]
    out[2, 2] = a[2]
    out[0, 1] = out[1, 0] = a[3]
    out[0, 2] = out[2, 0] = a[4]
    out[1, 2] = out[2, 1] = a[5]


#: series path of the kernel for |b_e - 1| up to this (Frobenius): elastic log strains to ~5 %
SERIES_RADIUS = 0.1
_SERIES_TOLERANCE = 1e-17  # truncation error of the series, absolute on the log strain


@numba.njit(cache=True, inline="always")
def _half_log_near_identity(b):
    """1/2 ln b of a symmetric positive b with |b - 1| <= SERIES_RADIUS: with
    y = (b - 1)(b + 1)^-1 (eigenvalues (x - 1)/(x + 1), |y| <= 0.053),
    1/2 ln b = artanh y = y (1 + y^2/3 + y^4/5 + ...), cut where the next term is below
    _SERIES_TOLERANCE (the Frobenius norm bounds every |y|)."""
    x = (b[0] - 1.0, b[1] - 1.0, b[2] - 1.0, b[3], b[4], b[5])
    # (2 + x)^-1 by cofactors
    s0, s1, s2 = x[0] + 2.0, x[1] + 2.0, x[2] + 2.0
    c0 = s1 * s2 - x[5] * x[5]
    c1 = s0 * s2 - x[4] * x[4]
    c2 = s0 * s1 - x[3] * x[3]
    c3 = x[4] * x[5] - x[3] * s2
    c4 = x[3] * x[5] - x[4] * s1
    c5 = x[3] * x[4] - s0 * x[5]
    inv_det = 1.0 / (s0 * c0 + x[3] * c3 + x[4] * c4)
    y = _sym_mul(
        x, (c0 * inv_det, c1 * inv_det, c2 * inv_det, c3 * inv_det, c4 * inv_det, c5 * inv_det)
    )
    z = _sym_mul(y, y)
    r2 = _sym_norm2(y)
    # the series' terms y^(2k+1)/(2k+1) from k = 1; keep them while r^(2k+1) > tolerance
    last = 0
    power = np.sqrt(r2)
    while last < 12 and power * r2 > _SERIES_TOLERANCE:
        power *= r2
        last += 1
    c = 1.0 / (2 * last + 1)
    poly = (c, c, c, 0.0, 0.0, 0.0)
    for k in range(last - 1, -1, -1):  # Horner in z
        poly = _sym_axpi(1.0, _sym_mul(z, poly), 1.0 / (2 * k + 1))
    return _sym_mul(y, poly)


@numba.njit(cache=True, inline="always")
def _exp_near_zero(a):
    """exp(a) of a small symmetric a (|a| <= ~0.2) by its Taylor series, cut where the next
    term's bound |a|^(k+1)/(k+1)! is below _SERIES_TOLERANCE."""
    r = np.sqrt(_sym_norm2(a))
    last = 1
    bound = r
    while last < 20 and bound * r / (last + 1) > _SERIES_TOLERANCE:
        last += 1
        bound *= r / last
    poly = (1.0, 1.0, 1.0, 0.0, 0.0, 0.0)
    for k in range(last, 0, -1):  # 1 + a/1 (1 + a/2 (1 + ... (1 + a/last)))
        poly = _sym_axpi(1.0 / k, _sym_mul(a, poly), 1.0)
    return poly


@numba.njit(cache=True, inline="always")
def _update_point_by_series(
    qp,
    b,
    Finv,
    cp_inv_n,
    eps_p_n,
    mu,
    bulk,
    s0,
    modulus,
    exponent,
    law,
    P_dev,
    cp_inv_new,
    eps_p_new,
    tau,
    dissipation,
    psi,
    M1,
    M2,
    M3,
    C,
):
    """The stress update of one point without eigen-decomposition, for b_e^trial = ``b`` within
    SERIES_RADIUS of 1 (every elastic strain of a metal): the same radial return in tensor form,
    eps^trial = 1/2 ln b by the artanh series, b_e = exp(2 eps_e) by the Taylor series (exact to
    _SERIES_TOLERANCE), an elastic point keeps C_p^-1 as it is. No tangent."""
    three_mu = 3.0 * mu
    eps = _half_log_near_identity(b)
    vol = eps[0] + eps[1] + eps[2]
    dev = _sym_axpi(1.0, eps, -vol / 3.0)
    norm_s = 2.0 * mu * np.sqrt(_sym_norm2(dev))
    q_tr = _SQRT_3_2 * norm_s
    p_n = eps_p_n[qp]
    dgamma, plastic, work = _plastic_multiplier(q_tr, p_n, three_mu, s0, modulus, exponent, law)
    beta = 1.0 - three_mu * dgamma / q_tr if plastic else 1.0
    if plastic:
        # dev eps_e = beta dev eps^trial, tr eps_e = tr eps^trial:
        # b_e = e^(2 vol / 3) exp(2 beta dev)
        e = _exp_near_zero(_sym_axpi(2.0 * beta, dev, 0.0))
        scale = np.exp(2.0 * vol / 3.0)
        _sym_to_full(_sym_axpi(scale, e, 0.0), M1)
        _store_cp_inv(M1, Finv, M3, C, cp_inv_new[qp])
    else:
        for k in range(6):  # b_e = b_e^trial: C_p^-1 unchanged
            cp_inv_new[qp, k] = cp_inv_n[qp, k]
    eps_p_new[qp] = p_n + dgamma
    s = _sym_axpi(2.0 * mu * beta, dev, 0.0)  # dev tau
    pressure = bulk * vol
    tau[qp, 0] = s[0] + pressure
    tau[qp, 1] = s[1] + pressure
    tau[qp, 2] = s[2] + pressure
    tau[qp, 3] = s[3]
    tau[qp, 4] = s[4]
    tau[qp, 5] = s[5]
    dissipation[qp] = work
    psi[qp] = mu * beta * beta * _sym_norm2(dev)
    _sym_to_full(s, M2)
    _mul_abt(M2, Finv, P_dev[qp])  # P_dev = dev(tau) F^-T


_CHUNK = 512  # points per parallel chunk: scratch arrays are allocated once per chunk


@numba.njit(cache=True)
def _update_range(
    q0,
    q1,
    F,
    cp_inv_n,
    eps_p_n,
    mu,
    bulk,
    s0,
    modulus,
    exponent,
    law,
    want_tangent,
    P_dev,
    A_dev,
    cp_inv_new,
    eps_p_new,
    tau,
    dissipation,
    psi,
    Finv,
    C,
    be,
    x,
    Q,
    eps_tr,
    s_tr,
    s,
    eps_e,
    M1,
    M2,
    M3,
    a,
    Cs,
    D,
):
    for qp in range(q0, q1):
        three_mu = 3.0 * mu
        f = F[qp]
        inverse3(f, Finv)
        _sym_to_full(cp_inv_n[qp], C)
        _mul_abt(C, f, M1)  # b_e^trial = f C f^T
        _mul_ab(f, M1, be)
        b = (
            be[0, 0],
            be[1, 1],
            be[2, 2],
            0.5 * (be[0, 1] + be[1, 0]),
            0.5 * (be[0, 2] + be[2, 0]),
            0.5 * (be[1, 2] + be[2, 1]),
        )
        if (
            not want_tangent
            and _sym_norm2(_sym_axpi(1.0, b, -1.0)) <= SERIES_RADIUS * SERIES_RADIUS
        ):
            _update_point_by_series(
                qp,
                b,
                Finv,
                cp_inv_n,
                eps_p_n,
                mu,
                bulk,
                s0,
                modulus,
                exponent,
                law,
                P_dev,
                cp_inv_new,
                eps_p_new,
                tau,
                dissipation,
                psi,
                M1,
                M2,
                M3,
                C,
            )
            continue
        eig_sym3(be, x, Q)

        vol = 0.0
        for A in range(3):
            eps_tr[A] = 0.5 * np.log(x[A])
            vol += eps_tr[A]
        norm2 = 0.0
        for A in range(3):
            s_tr[A] = 2.0 * mu * (eps_tr[A] - vol / 3.0)
            norm2 += s_tr[A] * s_tr[A]
        norm_s = np.sqrt(norm2)
        q_tr = _SQRT_3_2 * norm_s
        p_n = eps_p_n[qp]

        dgamma, plastic, work = _plastic_multiplier(q_tr, p_n, three_mu, s0, modulus, exponent, law)
        beta = 1.0 - three_mu * dgamma / q_tr if plastic else 1.0

        # updated elastic logarithmic strain, plastic state and energies
        for A in range(3):
            s[A] = beta * s_tr[A]
            eps_e[A] = eps_tr[A] - (dgamma * 1.5 * s_tr[A] / q_tr if plastic else 0.0)
        for i in range(3):
            for j in range(3):
                M1[i, j] = 0.0  # b_e new
                M2[i, j] = 0.0  # dev tau
        for A in range(3):
            e2 = np.exp(2.0 * eps_e[A])
            for i in range(3):
                for j in range(3):
                    nn = Q[i, A] * Q[j, A]
                    M1[i, j] += e2 * nn
                    M2[i, j] += s[A] * nn
        _store_cp_inv(M1, Finv, M3, C, cp_inv_new[qp])
        eps_p_new[qp] = p_n + dgamma
        pressure = bulk * vol
        tau[qp, 0] = M2[0, 0] + pressure
        tau[qp, 1] = M2[1, 1] + pressure
        tau[qp, 2] = M2[2, 2] + pressure
        tau[qp, 3] = M2[0, 1]
        tau[qp, 4] = M2[0, 2]
        tau[qp, 5] = M2[1, 2]
        dissipation[qp] = work
        tr_e = eps_e[0] + eps_e[1] + eps_e[2]
        dev2 = 0.0
        for A in range(3):
            dev2 += (eps_e[A] - tr_e / 3.0) ** 2
        # deviatoric part only: the volumetric energy follows the volumetric rule
        psi[qp] = mu * dev2

        _mul_abt(M2, Finv, P_dev[qp])  # P_dev = dev(tau) F^-T
        if not want_tangent:
            continue

        # principal algorithmic moduli a_AB = d s_A / d eps^trial_B (deviatoric part only)
        for A in range(3):
            for B in range(3):
                a[A, B] = 2.0 * mu * beta * ((1.0 if A == B else 0.0) - 1.0 / 3.0)
        if plastic:
            p = p_n + dgamma
            slope = _yield_and_slope(
                p, _hardening_power(p, exponent, law), s0, modulus, exponent, law
            )[1]
            coef = 6.0 * mu * mu * (dgamma / q_tr - 1.0 / (three_mu + slope))
            for A in range(3):
                for B in range(3):
                    a[A, B] += coef * s_tr[A] * s_tr[B] / (norm_s * norm_s)
        # spatial tangent: d tau_ij = Cs_ijkl L_kl, L = dF F^-1
        for i in range(3):
            for j in range(3):
                for k in range(3):
                    for m in range(3):
                        Cs[i, j, k, m] = 0.0
        for A in range(3):
            for B in range(3):
                coef = a[A, B]
                for i in range(3):
                    for j in range(3):
                        nAij = Q[i, A] * Q[j, A] * coef
                        for k in range(3):
                            for m in range(3):
                                Cs[i, j, k, m] += nAij * Q[k, B] * Q[m, B]
        for A in range(3):
            for B in range(3):
                if A == B:
                    continue
                theta = mu * beta * _log_divided_difference(x[A], x[B])
                for i in range(3):
                    for j in range(3):
                        nAB = theta * Q[i, A] * Q[j, B]
                        for k in range(3):
                            for m in range(3):
                                Cs[i, j, k, m] += nAB * (
                                    x[B] * Q[k, A] * Q[m, B] + x[A] * Q[k, B] * Q[m, A]
                                )
        # material tangent A_iJkL = Cs_ijkb Finv_Lb Finv_Jj - P_iL Finv_Jk
        for i in range(3):
            for j in range(3):
                for k in range(3):
                    for L in range(3):
                        acc = 0.0
                        for b in range(3):
                            acc += Cs[i, j, k, b] * Finv[L, b]
                        D[i, j, k, L] = acc
        for i in range(3):
            for J in range(3):
                for k in range(3):
                    for L in range(3):
                        acc = 0.0
                        for j in range(3):
                            acc += D[i, j, k, L] * Finv[J, j]
                        A_dev[qp, i, J, k, L] = acc - P_dev[qp, i, L] * Finv[J, k]


@numba.njit(parallel=True, cache=True)
def return_mapping(
    F,
    cp_inv_n,
    eps_p_n,
    mu,
    bulk,
    s0,
    modulus,
    exponent,
    law,
    want_tangent,
    P_dev,
    A_dev,
    cp_inv_new,
    eps_p_new,
    tau,
    dissipation,
    psi,
):
    """Exponential-map return mapping at every quadrature point.

    Inputs:  F (nq, 3, 3); cp_inv_n (nq, 6); eps_p_n (nq,); material scalars (MPa).
    Outputs: P_dev (nq, 3, 3) deviatoric first Piola (MPa); A_dev (nq, 3, 3, 3, 3) its tangent
             dP_dev/dF (only if want_tangent); cp_inv_new, eps_p_new trial state; tau (nq, 6)
             total Kirchhoff stress (MPa); dissipation (nq,) plastic work increment
             sigma_y(eps_p,n+1) * d_eps_p (mJ/mm^3); psi (nq,) deviatoric Hencky stored energy
             mu |dev eps_e|^2 (mJ/mm^3; the volumetric part 1/2 K ln(J)^2 is integrated with the
             volumetric rule of the forms, see SolidProblem.stored_energy).
    """
    nq = F.shape[0]
    nchunks = (nq + _CHUNK - 1) // _CHUNK
    for chunk in numba.prange(nchunks):
        Finv = np.empty((3, 3))
        C = np.empty((3, 3))
        be = np.empty((3, 3))
        x = np.empty(3)
        Q = np.empty((3, 3))
        eps_tr = np.empty(3)
        s_tr = np.empty(3)
        s = np.empty(3)
        eps_e = np.empty(3)
        M1 = np.empty((3, 3))
        M2 = np.empty((3, 3))
        M3 = np.empty((3, 3))
        a = np.empty((3, 3))
        Cs = np.empty((3, 3, 3, 3))
        D = np.empty((3, 3, 3, 3))
        _update_range(
            chunk * _CHUNK,
            min(nq, (chunk + 1) * _CHUNK),
            F,
            cp_inv_n,
            eps_p_n,
            mu,
            bulk,
            s0,
            modulus,
            exponent,
            law,
            want_tangent,
            P_dev,
            A_dev,
            cp_inv_new,
            eps_p_new,
            tau,
            dissipation,
            psi,
            Finv,
            C,
            be,
            x,
            Q,
            eps_tr,
            s_tr,
            s,
            eps_e,
            M1,
            M2,
            M3,
            a,
            Cs,
            D,
        )


class HenckyJ2:
    """Quadrature-point state and update of the Hencky / von Mises material.

    Holds the converged state (C_p^-1, eps_p) of ``num_points`` points and the trial state of the
    current iterate; :meth:`commit` accepts the trial state at the end of a converged increment.
    """

    def __init__(
        self,
        params,
        num_points: int,
        want_tangent: bool = True,
        P_dev: np.ndarray | None = None,
        A_dev: np.ndarray | None = None,
    ):
        """``P_dev`` (nq, 3, 3) and ``A_dev`` (nq, 3, 3, 3, 3) may be views of the quadrature
        Functions read by the forms, so the kernel writes straight into them (no copy)."""
        self.params = params
        self.num_points = num_points
        self.want_tangent = want_tangent
        ident = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])
        self.cp_inv = np.tile(ident, (num_points, 1))
        self.eps_p = np.zeros(num_points)
        self.cp_inv_trial = self.cp_inv.copy()
        self.eps_p_trial = self.eps_p.copy()
        self.P_dev = np.zeros((num_points, 3, 3)) if P_dev is None else P_dev
        if A_dev is None:
            A_dev = np.zeros((num_points, 3, 3, 3, 3) if want_tangent else (1, 3, 3, 3, 3))
        self.A_dev = A_dev
        self.tau = np.zeros((num_points, 6))
        self.dissipation = np.zeros(num_points)
        self.psi = np.zeros(num_points)
        #: committed plastic work per unit reference volume (mJ/mm^3), the sum of the increments
        self.plastic_work = np.zeros(num_points)

    def update(self, F: np.ndarray, tangent: bool | None = None) -> None:
        """Evaluate stress (and tangent) at deformation gradients ``F`` (nq, 3, 3)."""
        tangent = self.want_tangent if tangent is None else tangent
        if tangent and self.A_dev.shape[0] != self.num_points:
            self.A_dev = np.zeros((self.num_points, 3, 3, 3, 3))
        return_mapping(
            F,
            self.cp_inv,
            self.eps_p,
            *self.params.kernel_parameters(),
            tangent,
            self.P_dev,
            self.A_dev,
            self.cp_inv_trial,
            self.eps_p_trial,
            self.tau,
            self.dissipation,
            self.psi,
        )

    def commit(self) -> None:
        """Accept the trial state (and its plastic work increment)."""
        self.cp_inv[:] = self.cp_inv_trial
        self.eps_p[:] = self.eps_p_trial
        self.plastic_work += self.dissipation

    def state_dict(self) -> dict[str, np.ndarray]:
        """Committed plastic state (C_p^-1, eps_p, plastic work) of this rank's points (for
        checkpoints)."""
        return {
            "cp_inv": self.cp_inv.copy(),
            "eps_p": self.eps_p.copy(),
            "plastic_work": self.plastic_work.copy(),
        }

    def load_state(self, data: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state` (ValueError when the number of points differs)."""
        if data["eps_p"].shape != self.eps_p.shape:
            raise ValueError(
                f"material state has {data['eps_p'].size} points, expected {self.num_points}"
            )
        self.cp_inv[:] = data["cp_inv"]
        self.eps_p[:] = data["eps_p"]
        # checkpoints written before the per-point tally: the work so far is not known per point
        self.plastic_work[:] = data.get("plastic_work", 0.0)
        self.cp_inv_trial[:] = self.cp_inv
        self.eps_p_trial[:] = self.eps_p

    def von_mises_kirchhoff(self) -> np.ndarray:
        """sqrt(3/2) |dev tau| at each point, MPa."""
        t = self.tau
        m = (t[:, 0] + t[:, 1] + t[:, 2]) / 3.0
        dev2 = (
            (t[:, 0] - m) ** 2
            + (t[:, 1] - m) ** 2
            + (t[:, 2] - m) ** 2
            + 2 * (t[:, 3] ** 2 + t[:, 4] ** 2 + t[:, 5] ** 2)
        )
        return np.sqrt(1.5 * dev2)
