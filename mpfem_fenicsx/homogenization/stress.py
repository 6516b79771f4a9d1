"""Mesoscopic stress of a granular volume (thesis §2.3.3, §2.4.2, §2.6, ch. 4, appendix C.2).

Plain numpy arrays in and out (no dolfinx). Units: N, mm, MPa (N/mm^2), mJ (N mm).

Sign convention (one rule for the whole package):
- every stress TENSOR taken or returned here is a Cauchy (or first Piola) stress in the
  MECHANICS convention, tension > 0 -- what the finite-element model and the constraint
  reactions give (:func:`love_weber_stress`, :func:`schmidt_stress`, :func:`piola_to_cauchy`);
- every REPORTED scalar (sigma_m, sigma_d, sigma~_d) is in the soil-mechanics convention of the
  thesis, compression > 0 (:func:`stress_invariants`, :func:`rendulic_stress`);
  :func:`reported_stress` gives the whole tensor in that convention (-sigma);
- strains keep their natural sign (compaction: h_v < 0), see ``strain.py``.
"""

from __future__ import annotations

import numpy as np

from ..boundary import KINDS, boundary_kind
from .strain import AXIAL, _tensor, _trace, axis_vector, cell_vectors, deviator

BOUNDARY_CONDITIONS = KINDS  # the thesis' names (mpfem_fenicsx.boundary)


# -- invariants --------------------------------------------------------------------------------
def reported_stress(sigma) -> np.ndarray:
    """The stress tensor(s) in the reported (soil-mechanics) convention, compression > 0: -sigma."""
    return -_tensor(sigma, "sigma")


def stress_invariants(sigma):
    """(sigma_m, sigma_d) in MPa of Cauchy stress(es) given in the mechanics
    convention (tension > 0).

    sigma_m = -tr(sigma)/3: mean stress, thesis eq. 2.10 / 4.1 (sigma_m = tr/3 of the
    compression-positive tensor), > 0 in compaction.
    sigma_d = sqrt(3/2 s:s), s = dev(sigma): von Mises deviatoric stress, eq. 2.11, >= 0
    (unchanged by the sign convention). Uniaxial stress of magnitude q: sigma_d = |q|.
    """
    sigma = _tensor(sigma, "sigma")
    s = deviator(sigma)
    return -_trace(sigma) / 3.0, np.sqrt(1.5 * np.einsum("...ij,...ij->...", s, s))


def rendulic_stress(sigma, axis=AXIAL):
    """(sigma_m, sigma~_d) in MPa: signed coordinates in the Rendulic plane (thesis eq. 4.1-4.2).

    sigma~_d = sigma_I - (sigma_II + sigma_III)/2 of the compression-positive tensor, with I the
    axial (loading) direction ``axis`` (default e3, index 2) and II, III the lateral ones.
    ``sigma`` is the Cauchy stress in the mechanics convention (tension > 0); computed as
    sigma~_d = -3/2 n . dev(sigma) . n, equal to eq. 4.2 whenever sigma is diagonal in a frame
    containing n. Signs (compression > 0): die compaction along the axis (axial compression
    larger than the lateral one) gives sigma~_d > 0; uniaxial compression q > 0 along the axis
    gives sigma~_d = q = 3 sigma_m, uniaxial tension t > 0 gives sigma~_d = -t = 3 sigma_m
    (the line sigma~_d = 3 sigma_m of thesis §4.5); |sigma~_d| = sigma_d for an axisymmetric
    stress (thesis footnote 3 of §4.3.1).
    """
    sigma = _tensor(sigma, "sigma")
    n = axis_vector(axis)
    return -_trace(sigma) / 3.0, -1.5 * np.einsum("i,...ij,j->...", n, deviator(sigma), n)


# -- Love-Weber --------------------------------------------------------------------------------
def branch_vectors(x, pair_i, pair_j, offset=None) -> np.ndarray:
    """Branch vectors l = x_j (+ offset) - x_i (mm) of contacts (i, j) from centroids x (P, 3).

    ``offset`` (M, 3): translation of j's periodic image when the contact is with an image
    (e.g. the ``shift`` of ``ContactModel.pair_forces``, already in mm in the current cell).
    """
    x = np.asarray(x, dtype=float)
    lv = x[np.asarray(pair_j)] - x[np.asarray(pair_i)]
    if offset is not None:
        lv = lv + np.asarray(offset, dtype=float)
    return lv


def love_weber_stress(
    forces, branches, volume, weights=None, symmetrize: bool = False
) -> np.ndarray:
    """Love-Weber mesoscopic Cauchy stress (MPa, MECHANICS convention, tension > 0).

        sigma = (1/V) sum_k w_k f^k (x) l^k,   sigma_ab = (1/V) sum_k w_k f^k_a l^k_b

    Thesis eq. 2.6, derived in appendix C.2 (eq. C.7-C.11) from the boundary average
    sigma_ab = (1/V) int x_b t_a dGamma (eq. C.7, mechanics sign) and the pair identity C.10.
    Convention of the arrays: contact k is between particles i and j,
      ``forces[k]`` = force exerted ON particle i BY particle j (N) (f^{beta->alpha}, alpha = i),
      ``branches[k]`` = x_j - x_i (mm), centroid of j minus centroid of i (see
      :func:`branch_vectors`; for a contact with a copy or periodic image, use that copy's
      centroid).
    Two particles pressed together: f on i points from j to i, l from i to j, f (x) l is
    negative (compressive) along the branch. The thesis writes eq. 2.6 with
    l^{beta->alpha} = x_alpha - x_beta (eq. C.10) and reports the result compression-positive: the
    thesis value is ``reported_stress`` of this one (-sigma).

    Each contact appears once (the force on i by j, not also the reaction on j by i). Only
    contacts of the VEP count and each periodic contact once: ``weights`` from
    :func:`contact_weights` (appendix C.2). Without symmetrize the tensor is eq. 2.6 as
    written; it is symmetric when the particles are in equilibrium (forces and moments).

    Args:
        forces: (M, 3) contact forces (N).
        branches: (M, 3) branch vectors (mm).
        volume: V = V0 det F (mm^3), the current volume of the periodic cell (VEP).
        weights: optional (M,) counting weights (default 1).
        symmetrize: return (sigma + sigma^T)/2.
    """
    f = np.asarray(forces, dtype=float).reshape(-1, 3)
    lv = np.asarray(branches, dtype=float).reshape(-1, 3)
    if f.shape != lv.shape:
        raise ValueError(
            f"forces {f.shape} and branches {lv.shape} must have the same shape (M, 3)"
        )
    if not np.ndim(volume) == 0 or not float(volume) > 0:
        raise ValueError(f"volume must be a positive scalar (mm^3), got {volume!r}")
    w = np.ones(f.shape[0]) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (f.shape[0],):
        raise ValueError(f"weights must have shape ({f.shape[0]},), got {w.shape}")
    sigma = np.einsum("k,ka,kb->ab", w, f, lv) / float(volume)
    return 0.5 * (sigma + sigma.T) if symmetrize else sigma


def contact_weights(pair_i, pair_j, original, shift, bc: str, pair_shift=None) -> np.ndarray:
    """Counting weights (M,) of the contacts in the Love-Weber sum (thesis appendix C.2).

    Particles are described per body p of the model: ``original[p]`` the index of the VEP
    particle it duplicates (p itself for a VEP particle), ``shift[p]`` (3,) its integer lattice
    shift (zero for a VEP particle, so copy <=> shift != 0). A contact k = (pair_i[k],
    pair_j[k]) -- optionally with j's periodic image shifted by the integer ``pair_shift[k]``
    (contact with images) -- is the physical contact between VEP particles original[i] and
    original[j] across the relative lattice shift shift[j] + pair_shift - shift[i]; that triple
    (unordered) identifies the physical contact.

    Rules (appendix C.2):
    - ``"CLP"`` (full periodicity, Schmidt: copies are stiffless shells tied node by node):
      every contact of the model counts, weight 1, including copy-copy (shell-shell) contacts.
      The coupling equations spread the force of one physical periodic contact over all its
      modelled images ((alpha+, beta+) and (alpha-, beta-), ...), the shells do no deformation
      work, so the physical contact is the SUM of its images: all must be summed.
    - ``"GDH"``, ``"GDF"``, ``"CLPS"`` (solid copies with their own deformation work): a contact
      counts only if at least one of its particles belongs to the VEP (copy-copy forces feed the
      deformation of particles outside the VEP: weight 0); a contact between a VEP particle and
      a copy stands for the periodic contact with the copy's original and counts; when the
      same physical contact is modelled more than once (alpha+ with beta+ AND alpha- with beta-)
      it must be counted once only: its n counted realisations get weight 1/n each (their mean;
      equal realisations in an exactly periodic state).
    Each modelled contact must be listed once (force on i by j), as ``ContactModel.pair_forces``
    does; with the solid rule a contact listed as both (i, j) and (j, i) is also merged.

    Returns:
        (M,) float weights for :func:`love_weber_stress` (and :func:`specific_contact_surface`).
    """
    kind = boundary_kind(bc)
    i = np.asarray(pair_i, dtype=np.int64).ravel()
    j = np.asarray(pair_j, dtype=np.int64).ravel()
    if i.shape != j.shape:
        raise ValueError("pair_i and pair_j must have the same length")
    m = i.size
    if kind.tied_nodes or m == 0:
        return np.ones(m)
    original = np.asarray(original, dtype=np.int64)
    shift = np.rint(np.asarray(shift, dtype=float)).astype(np.int64).reshape(-1, 3)
    if shift.shape[0] != original.size:
        raise ValueError("original and shift must describe the same bodies")
    is_copy = np.any(shift != 0, axis=1)
    sj = shift[j]
    if pair_shift is not None:
        sj = sj + np.rint(np.asarray(pair_shift, dtype=float)).astype(np.int64).reshape(m, 3)
    oa, ob = original[i], original[j]
    d = sj - shift[i]
    copy_i = is_copy[i]
    copy_j = is_copy[j] | np.any(sj != shift[j], axis=1)  # an image is not a VEP particle
    # canonical key of the physical contact: (lower original, higher original, shift from the
    # first to the second); a particle touching its own image: the shift whose first non-zero
    # component is positive
    same = oa == ob
    if np.any(same & ~np.any(d, axis=1)):
        raise ValueError("a contact links a particle to itself (same original, no lattice shift)")
    first_nz = d[np.arange(m), np.argmax(d != 0, axis=1)]
    flip = (oa > ob) | (same & (first_nz < 0))
    key = np.column_stack(
        [np.where(flip, ob, oa), np.where(flip, oa, ob), np.where(flip[:, None], -d, d)]
    )
    counted = ~(copy_i & copy_j)
    w = np.zeros(m)
    if np.any(counted):
        _, inverse, counts = np.unique(
            key[counted], axis=0, return_inverse=True, return_counts=True
        )
        w[counted] = 1.0 / counts[inverse.ravel()]
    return w


def coordination(pair_i, pair_j, original, weights, num_particles: int, rattler_below: int = 4):
    """Force-carrying contacts of the periodic volume and its mean coordination number.

    ``pair_i``, ``pair_j`` (M,) bodies of the contacts that carry force (compression or adhesive
    tension), ``original`` (bodies,) the volume particle each body stands for, ``weights`` (M,) the
    counting weights of :func:`contact_weights`. Each counted contact gives one contact to both of
    its particles (a particle touching its own periodic image gets two).

    Returns (contacts, Z, rattlers): the weighted number of contacts, the mean coordination number
    Z = 2 contacts / N over the ``num_particles`` particles of the volume, and the number of
    particles with fewer than ``rattler_below`` contacts (4 = d + 1 in 3-D: fewer cannot hold a
    particle in force equilibrium without friction; they are counted in Z, not removed).
    """
    original = np.asarray(original, dtype=np.int64)
    w = np.asarray(weights, dtype=float).ravel()
    per_particle = np.bincount(
        original[np.asarray(pair_i, dtype=np.int64)], weights=w, minlength=num_particles
    ) + np.bincount(
        original[np.asarray(pair_j, dtype=np.int64)], weights=w, minlength=num_particles
    )
    per_particle = per_particle[:num_particles]
    contacts = float(w.sum())
    return (
        contacts,
        2.0 * contacts / num_particles,
        int(np.count_nonzero(per_particle < rattler_below - 1e-9)),
    )


# -- Schmidt stress from the auxiliary nodes ---------------------------------------------------
def schmidt_piola(aux_reactions, cell) -> np.ndarray:
    """Mesoscopic first Piola stress from the auxiliary-node reactions (MPa, tension > 0).

    Thesis §2.6 (after Schmidt [99]): P_ab = F_a^b / A_b, F_a^b the a-th component of the
    reaction at auxiliary node b, A_b the reference area of the cell face of normal x_b. Derived
    from eq. 2.14: the "displacement" of auxiliary node b is the change of the b-th cell vector,
    u_aux_b = (F - I) c_b, so the external virtual work is
        dW = sum_b R_b . dF c_b = dF : (sum_b R_b (x) c_b) = V0 P : dF,
    i.e. P = (1/V0) sum_b R_b (x) c_b (V0 = det C), which for a box (c_b = L_b e_b, A_b =
    V0 / L_b) is the thesis' P_ab = R_b,a / A_b. The same holds for a sheared (parallelepiped)
    cell: R_b = P (c_c x c_d) is the force on face b.

    Args:
        aux_reactions: (3, 3), row b = reaction R_b (N) of auxiliary node b (the force the
            driving constraint exerts on the cell through node b; outwards in tension), or a
            stack (..., 3, 3).
        cell: reference cell edge lengths (3,) or cell vectors as rows c_b (3, 3) (mm).
    """
    R = _tensor(aux_reactions, "aux_reactions")
    C = cell_vectors(cell)
    V0 = abs(np.linalg.det(C))
    if not V0 > 0:
        raise ValueError("cell: degenerate reference cell")
    return np.einsum("...ba,bc->...ac", R, C) / V0


def piola_to_cauchy(P, F) -> np.ndarray:
    """Cauchy stress sigma = P F^T / det F (thesis eq. 2.19), same sign convention as P."""
    P = _tensor(P, "P")
    F = _tensor(F, "F")
    return P @ np.swapaxes(F, -1, -2) / np.linalg.det(F)[..., None, None]


def schmidt_stress(aux_reactions, F, cell) -> np.ndarray:
    """Mesoscopic Cauchy stress from the auxiliary-node reactions (MPa, MECHANICS convention):
    sigma = P F^T / det F with P = :func:`schmidt_piola` (thesis §2.6, eq. 2.19).

    F is the gradient of the periodic cell (the imposed F0 of the auxiliary nodes). Valid for
    full periodicity (CLP); with solid copies the reactions include the copies' contacts (thesis
    §2.6). If the reactions are already the generalized force R conjugate to H = F0 - I
    (``GranularBoundaryConditions.macroscopic_force``, dW = R : dH), P = R / V0 instead.
    """
    return piola_to_cauchy(schmidt_piola(aux_reactions, cell), F)


# -- chapter 4 indicators ----------------------------------------------------------------------
def second_order_work(dsigma, dh):
    """Hill's second-order work W2 = dsigma : dh (MPa, thesis eq. 4.15).

    ``dsigma`` (..., 3, 3): Cauchy stress increments in the MECHANICS convention (tension > 0,
    e.g. ``np.diff(sigma, axis=0)`` of a history), ``dh`` (..., 3, 3): Hencky strain increments
    (natural sign). With consistent signs W2 > 0 on a stable path (elastic loading or hardening
    compaction) and W2 <= 0 signals Hill's instability (thesis §4.5: rupture threshold slightly
    negative). Stresses in the reported (compression > 0) convention must be negated first.
    """
    dsigma = _tensor(dsigma, "dsigma")
    dh = _tensor(dh, "dh")
    return np.einsum("...ij,...ij->...", dsigma, dh)


def dissipated_energy(plastic, frictional):
    """E_d = E_p + E_f (mJ, thesis eq. 4.10): plastic dissipation (eq. 4.11) plus frictional
    dissipation (eq. 4.12)."""
    return np.asarray(plastic, dtype=float) + np.asarray(frictional, dtype=float)


def row_increments(series, window: int = 0) -> np.ndarray:
    """Per-row increments of a history series (T, ...): Savitzky-Golay first derivatives
    (quadratic fits over ``window`` rows, odd >= 3) that keep an explicit run's small oscillations
    from flipping the sign of W2 (the thesis low-pass filtered its explicit W2, §4.5); with
    ``window`` < 3 or fewer rows than it, raw differences with NaN in the first row."""
    series = np.asarray(series, dtype=float)
    if window >= 3 and series.shape[0] >= window:
        from scipy.signal import savgol_filter

        return savgol_filter(series, window, 2, deriv=1, axis=0)
    return np.concatenate([np.full((1,) + series.shape[1:], np.nan), np.diff(series, axis=0)])


def first_crossing(indicator, level, *series, rising: bool = True, last: bool = False):
    """First crossing of ``level`` by ``indicator`` (T,) and the series linearly interpolated there
    (``last``: the latest crossing instead, e.g. an iso-Gamma threshold on a non-monotonic Gamma,
    thesis §4.3: "le seuil le plus tardif").

    Used for the thesis ch. 4 thresholds: yield (iso-dissipation, E_d reaching E_0 (1 + 0.3 %),
    §4.2.2, rising), damage (iso-Gamma, falling) and Hill's rupture (W2 <= threshold, falling).
    A crossing is a step k -> k+1 with indicator[k] < level <= indicator[k+1] (rising) or
    indicator[k] > level >= indicator[k+1] (falling).

    Returns:
        (position, *values): fractional index k + theta of the crossing and each series (T, ...)
        interpolated there; NaN (of the series' trailing shape) if there is no crossing.
    """
    g = np.asarray(indicator, dtype=float).ravel() - float(level)
    if not rising:
        g = -g
    hits = np.flatnonzero((g[:-1] < 0) & (g[1:] >= 0))
    arrays = [np.asarray(s, dtype=float) for s in series]
    for s in arrays:
        if s.shape[:1] != g.shape:
            raise ValueError(
                f"series of length {s.shape[:1]} do not match the indicator ({g.size})"
            )
    if hits.size == 0:
        return (np.nan, *[np.full(s.shape[1:], np.nan) for s in arrays])
    k = int(hits[-1] if last else hits[0])
    theta = -g[k] / (g[k + 1] - g[k])
    return (k + theta, *[(1 - theta) * s[k] + theta * s[k + 1] for s in arrays])


def uniaxial_strengths(sigma_m, sigma_tilde_d):
    """Uniaxial compressive and tensile strengths (MPa, > 0) of a closed surface in the Rendulic
    plane: its intersections with the uniaxial line sigma~_d = 3 sigma_m (thesis §4.4-4.5; a
    uniaxial stress s along axis I gives sigma_m = s / 3, sigma~_d = s).

    ``sigma_m``, ``sigma_tilde_d`` (N,): the polygon's vertices in order (reported convention,
    compression > 0), closed implicitly (last -> first). Returns (compressive, tensile): the
    value |sigma~_d| at the intersection with sigma_m > 0 farthest from the origin, and at the one
    with sigma_m < 0; NaN where the line does not cross the polygon on that side.
    """
    p = np.asarray(sigma_m, dtype=float).ravel()
    q = np.asarray(sigma_tilde_d, dtype=float).ravel()
    if p.shape != q.shape or p.size < 3:
        raise ValueError(
            f"a closed surface needs >= 3 vertices of (sigma_m, sigma_tilde_d), got {p.size}"
        )
    g = q - 3.0 * p  # signed distance (up to a factor) to the uniaxial line
    g1, p1, q1 = np.roll(g, -1), np.roll(p, -1), np.roll(q, -1)
    cross = (g == 0) | (g * g1 < 0)
    theta = np.where(g1 != g, g / np.where(g1 != g, g - g1, 1.0), 0.0)
    ps = p + theta * (p1 - p)
    qs = q + theta * (q1 - q)
    ps, qs = ps[cross], qs[cross]
    compressive = float(np.max(qs[ps > 0])) if np.any(ps > 0) else np.nan
    tensile = float(-np.min(qs[ps < 0])) if np.any(ps < 0) else np.nan
    return compressive, tensile
