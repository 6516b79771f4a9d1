"""Mesoscopic kinematics of a granular volume (thesis §2.3.1-2.3.2, §2.4.2, §4.2, §4.4, app. C.1).

Plain numpy arrays in and out (no dolfinx). Units: lengths mm, volumes mm^3, areas mm^2;
strains are dimensionless and keep their natural sign (compaction gives h_v < 0).
Tensor arguments may be a single (3, 3) array or a stack (..., 3, 3); scalar results then have
the leading shape (...) (a 0-d numpy float for a single tensor).
"""

from __future__ import annotations

import numpy as np

#: default axial (loading) axis of the Rendulic values: e3 (z), the die-compaction axis of
#: ``loading.macroscopic`` (the thesis' reload tensors, eq. 4.9, put axis I first: pass axis=0)
AXIAL = 2


def _tensor(a, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim < 2 or a.shape[-2:] != (3, 3):
        raise ValueError(f"{name} must have shape (3, 3) or (..., 3, 3), got {a.shape}")
    return a


def _trace(a: np.ndarray) -> np.ndarray:
    return np.trace(a, axis1=-2, axis2=-1)


def deviator(a) -> np.ndarray:
    """Deviatoric part a - tr(a)/3 I of a (3, 3) tensor or a stack (..., 3, 3)."""
    a = _tensor(a, "tensor")
    return a - (_trace(a) / 3.0)[..., None, None] * np.eye(3)


def axis_vector(axis) -> np.ndarray:
    """Unit vector of an axis given as 0, 1, 2 (x, y, z) or as a direction (3,)."""
    if np.ndim(axis) == 0:
        k = int(axis)
        if k not in (0, 1, 2):
            raise ValueError(f"axis must be 0, 1, 2 or a 3-vector, got {axis!r}")
        return np.eye(3)[k]
    n = np.asarray(axis, dtype=float)
    if n.shape != (3,) or not np.linalg.norm(n) > 0:
        raise ValueError(f"axis must be 0, 1, 2 or a non-zero 3-vector, got {axis!r}")
    return n / np.linalg.norm(n)


# -- least-squares gradient (appendix C.1) ------------------------------------------------------
def least_squares_gradient(X, x, weights=None, rtol: float = 1e-10):
    """Best affine fit ``x ~ F X + c`` of current centroids on reference centroids (app. C.1).

    Thesis eq. 2.2 and C.1-C.6 fit the centroid displacements u = x - X by u = H X + u0 in the
    least-squares sense (chi^2 = sum_a |H X^a + u0 - u^a|^2, eq. C.1/C.3); the normal equations
    C.4-C.6 are solved here in centred form, which is the same minimiser: F = I + H, c = u0.

    Args:
        X: (N, 3) reference centroids (mm), N >= 4 non-coplanar points (VEP particles only,
            copies excluded, thesis §2.3.1).
        x: (N, 3) current centroids (mm) or a stack (..., N, 3) of them (e.g. one per output
            time); positions must be *unwrapped* (continuous in time, not folded into the cell).
        weights: optional (N,) non-negative weights of the points (default 1; e.g. particle
            volumes). Only points with a positive weight count for N >= 4 / rank.
        rtol: smallest singular value of the centred, weighted reference cloud relative to the
            largest one below which the points are considered coplanar.

    Returns:
        (F, c): F (3, 3) (or (..., 3, 3)) the mesoscopic deformation gradient, c (3,) (or
        (..., 3)) the translation, in mm.

    Raises:
        ValueError: fewer than 4 points, shape mismatch, negative weights, or coplanar /
            collinear reference points (rank-deficient fit).
    """
    X = np.asarray(X, dtype=float)
    x = np.asarray(x, dtype=float)
    if X.ndim != 2 or X.shape[1] != 3:
        raise ValueError(f"X must have shape (N, 3), got {X.shape}")
    if x.shape[-2:] != X.shape:
        raise ValueError(f"x must have shape {X.shape} or (..., {X.shape[0]}, 3), got {x.shape}")
    w = np.ones(X.shape[0]) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (X.shape[0],):
        raise ValueError(f"weights must have shape ({X.shape[0]},), got {w.shape}")
    if np.any(w < 0) or not np.all(np.isfinite(w)):
        raise ValueError("weights must be finite and non-negative")
    if np.count_nonzero(w) < 4:
        raise ValueError(
            f"least-squares gradient needs at least 4 points with positive weight, "
            f"got {np.count_nonzero(w)}"
        )
    w = w / w.sum()
    Xm = w @ X
    dX = X - Xm
    s = np.linalg.svd(np.sqrt(w)[:, None] * dX, compute_uv=False)
    if not s[-1] > rtol * s[0]:
        raise ValueError(
            "least-squares gradient: reference points are coplanar or collinear "
            f"(singular values {s}), the fit is rank-deficient"
        )
    M = dX.T @ (w[:, None] * dX)  # sum w dX (x) dX
    xm = np.einsum("n,...ni->...i", w, x)
    B = np.einsum("n,...ni,nj->...ij", w, x - xm[..., None, :], dX)  # sum w dx (x) dX
    F = np.linalg.solve(M, np.swapaxes(B, -1, -2))  # M F^T = B^T  (M symmetric)
    F = np.swapaxes(F, -1, -2)
    c = xm - np.einsum("...ij,j->...i", F, Xm)
    return F, c


def gradient_fit_noise_hd(X, residual_rms, h_v=0.0):
    """Root-mean-square deviatoric strain h_d (eq. 2.9) that the least-squares gradient
    (app. C.1) reads from the centroids' non-affine scatter alone, on a volumetric path.

    If the centroids scatter about an affine motion, x_a = F X_a + c + e_a with e_a independent
    and isotropic (variance s^2 per component), the fitted F is off by dF = sum_a e_a dX_a^T M^-1
    (M = sum_a dX_a dX_a^T, dX = X - mean X): each row of dF has covariance s^2 M^-1. To first
    order, with F = lambda I (lambda = exp(h_v / 3)), dh = sym(dF) / lambda and
    E[h_d^2] = 2/3 E[dev sym dF : dev sym dF] / lambda^2 = 10/9 s^2 tr(M^-1) / lambda^2.
    s^2 is read from the fit's own residuals: N rms^2 / (3 (N - 4)) (4 fitted parameters per
    component). A measured h_d of this size is the fit's noise, not a deviatoric strain of the
    volume; spatially correlated scatter makes the true noise larger than this estimate.

    Args:
        X: (N, 3) reference centroids (mm), N >= 5.
        residual_rms: rms distance (mm) of the current centroids from the fitted affine motion,
            sqrt(mean_a |x_a - F X_a - c|^2); a scalar or an array (e.g. one per output time).
        h_v: the fit's volumetric strain ln det F (< 0 in compaction), broadcast with residual_rms.

    Returns:
        the rms h_d of the noise (dimensionless), shaped like residual_rms.
    """
    X = np.asarray(X, dtype=float)
    if X.ndim != 2 or X.shape[1] != 3 or X.shape[0] < 5:
        raise ValueError(f"X must have shape (N, 3) with N >= 5, got {X.shape}")
    residual_rms = np.asarray(residual_rms, dtype=float)
    if np.any(residual_rms < 0):
        raise ValueError("residual_rms must be non-negative (a distance in mm)")
    n = X.shape[0]
    dX = X - X.mean(axis=0)
    trace_inverse = np.trace(np.linalg.inv(dX.T @ dX))
    variance = n * residual_rms**2 / (3.0 * (n - 4))
    stretch = np.exp(np.asarray(h_v, dtype=float) / 3.0)
    return np.sqrt(10.0 / 9.0 * variance * trace_inverse) / stretch


# -- Hencky strain and invariants ---------------------------------------------------------------
def hencky_strain(F) -> np.ndarray:
    """Left Hencky (logarithmic) strain h = 1/2 ln(F F^T) (thesis eq. 2.3; eq. 2.18 with
    F = I + grad u).

    Computed by the spectral decomposition of B = F F^T (thesis footnote 3 of §2.3): objective,
    h(Q F) = Q h(F) Q^T for any rotation Q, and h(F Q) = h(F). Dimensionless, natural sign
    (a stretch > 1 gives a positive principal strain).

    Args:
        F: (3, 3) or (..., 3, 3) deformation gradient(s), det F > 0.
    """
    F = _tensor(F, "F")
    B = F @ np.swapaxes(F, -1, -2)
    lam, V = np.linalg.eigh(B)
    if not np.all(lam > 0):
        raise ValueError("hencky_strain: F F^T is not positive definite (singular F)")
    return (V * (0.5 * np.log(lam))[..., None, :]) @ np.swapaxes(V, -1, -2)


def strain_invariants(h):
    """(h_v, h_d) of Hencky strain(s) h (thesis eq. 2.8-2.9 = 4.3).

    h_v = tr h (volumetric strain, ln det F; < 0 in compaction);
    h_d = sqrt(2/3 dev(h):dev(h)) with dev(h) = h - h_v/3 I (deviatoric strain, >= 0; for an
    axisymmetric strain h_d = 2/3 |h_axial - h_lateral| = |h~_d| of eq. 4.4).
    """
    h = _tensor(h, "h")
    dev = deviator(h)
    return _trace(h), np.sqrt(2.0 / 3.0 * np.einsum("...ij,...ij->...", dev, dev))


def rendulic_strain(h, axis=AXIAL):
    """(h_v, h~_d): signed strain coordinates in the Rendulic plane (thesis eq. 4.3-4.4).

    h~_d = 2/3 [h_I - (h_II + h_III)/2] with I the axial (loading) direction ``axis`` and II, III
    the two lateral ones. For any tensor this is computed as n . dev(h) . n (n the unit axial
    vector), which equals eq. 4.4 whenever h is diagonal in a frame containing n (axisymmetric
    or orthotropic paths, e.g. die compaction, isotropic unloading and the reload fan of eq.
    4.8-4.9) and otherwise is the projection of the deviator on the Rendulic direction.
    Natural sign: die compaction along the axis (h_I < 0, h_II = h_III = 0) gives h~_d < 0;
    |h~_d| = h_d for an axisymmetric tensor. Default axis: e3 (index 2).
    """
    h = _tensor(h, "h")
    n = axis_vector(axis)
    return _trace(h), np.einsum("i,...ij,j->...", n, deviator(h), n)


# -- density, volume, specific contact surface ---------------------------------------------------
def solid_volume(radii) -> float:
    """V_p = 4/3 pi sum r^3 (mm^3) of the VEP particles' *initial* radii (thesis eq. 2.5)."""
    r = np.asarray(radii, dtype=float)
    return float(4.0 / 3.0 * np.pi * np.sum(r**3))


def current_volume(volume_reference, F):
    """V = V0 det F (mm^3), the current volume of the periodic cell (thesis §2.3.2, eq. 4.13)."""
    return np.asarray(volume_reference, dtype=float) * np.linalg.det(_tensor(F, "F"))


def relative_density(solid_volume, cell_volume_reference, F):
    """rho = V_p / (V0 det F) (thesis eq. 2.4; eq. 2.17 for the simple cubic cell, pi / (6 det F)).

    Args:
        solid_volume: V_p (mm^3), e.g. :func:`solid_volume` of the initial radii (elastic volume
            change of the particles neglected, as in the thesis).
        cell_volume_reference: V0 = dx dy dz (mm^3), the reference periodic cell (VEP) volume.
        F: (3, 3) or (..., 3, 3) mesoscopic deformation gradient (least-squares fit).
    """
    return np.asarray(solid_volume, dtype=float) / current_volume(cell_volume_reference, F)


def specific_contact_surface(contact_area, volume_reference, F, weights=None):
    """Specific contact surface Gamma = S / V = S / (V0 det F) (mm^-1, thesis eq. 4.13).

    S is the total inter-particle contact area in the volume (thesis footnote 4 of §4.4.1: the
    sum of the areas of every contact of the model, one area per contacting pair, not one per
    side). ``contact_area`` is either S itself (scalar) or the (M,) areas of the individual
    contacts (mm^2), summed with optional ``weights`` (M,) -- e.g. :func:`contact_weights` to count
    each periodic contact of the VEP once.
    """
    a = np.asarray(contact_area, dtype=float)
    if a.ndim == 1:
        S = float(np.sum(a if weights is None else np.asarray(weights, dtype=float) * a))
    elif a.ndim == 0:
        if weights is not None:
            raise ValueError("weights need per-contact areas (M,)")
        S = float(a)
    else:
        raise ValueError(f"contact_area must be a scalar total or (M,) areas, got shape {a.shape}")
    return S / current_volume(volume_reference, F)


# -- reference cell and copies -----------------------------------------------------------------
def cell_vectors(cell) -> np.ndarray:
    """Reference cell vectors as rows c_i of a (3, 3) array, from edge lengths (3,) of a box
    (dx, dy, dz) or from a (3, 3) array already holding the cell vectors as rows (mm)."""
    c = np.asarray(cell, dtype=float)
    if c.shape == (3,):
        return np.diag(c)
    if c.shape == (3, 3):
        return c.copy()
    raise ValueError(f"cell must be edge lengths (3,) or cell vectors (3, 3), got {c.shape}")


def copy_centroids(x_original, shift, cell, F):
    """Centroids of duplicated particles: x_copy = x_orig + F (s . C) (mm).

    The thesis obtains copy centroids by translating the principal sphere by the cell vectors
    and their displacement from the auxiliary nodes (eq. 2.14), i.e. the periodic image shifted
    by the deformed lattice vector. ``shift`` (..., 3) integer lattice shifts s, ``cell`` edge
    lengths (3,) or cell vectors as rows (3, 3), F the gradient driving the images (the imposed
    F0 of the auxiliary nodes).
    """
    C = cell_vectors(cell)
    S = np.asarray(shift, dtype=float) @ C  # reference lattice vectors
    return np.asarray(x_original, dtype=float) + S @ _tensor(F, "F").T
