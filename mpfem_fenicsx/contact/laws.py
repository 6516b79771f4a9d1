"""Contact laws per contact point (thesis §3.3): penalty normal contact with the adhesive
Pullen-Williamson law, and penalty-regularized Coulomb friction.

Sign conventions: delta = normal gap (mm, < 0 = overlap); T1 = normal traction on the slave,
compression > 0 (MPa); T_t = tangential traction on the slave (MPa, vector in the tangent plane).

Normal law (thesis fig. 3.4, eq. 3.11-3.12), with k the penalty (N/mm^3):
- overlap (delta < 0): T1 = -k delta; sigma_max = max(sigma_max, T1);
  degree of contact alpha = sigma_max / (p0 + sigma_max) (only grows; or forced to a value);
- opening (0 <= delta < delta_max), adhesion sigma_c = 2 gamma / delta_max:
  T1 = -k delta down to -alpha sigma_c (delta_1 = alpha sigma_c / k), then linear softening
  T1 = -alpha sigma_c (delta_max - delta) / (delta_max - delta_1) to 0 at delta_max; the work of
  separation is alpha gamma. Reloading before delta_max follows the same curve;
- delta >= delta_max: T1 = 0 and the memory is erased (alpha = sigma_max = 0).
Tangential law (eq. 3.14-3.19), only while T1 > 0 (zero shear in tension):
  trial T_t = T_t,n - k_t delta_t; stick if |T_t| <= mu T1, else slip T_t = mu T1 T_t / |T_t|;
  slip increment delta_slip = delta_t + (T_t - T_t,n) / k_t; dissipation dW_f = -T_t . delta_slip
  (mJ/mm^2 per unit area, >= 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np


@dataclass(frozen=True)
class ContactLaw:
    """Parameters of the contact law (units: N/mm^3, MPa, mJ/mm^2 = N/mm, mm)."""

    penalty: float = 1e9  # normal penalty k, N/mm^3
    tangential_penalty: float | None = None  # k_t (default: = penalty)
    friction: float = 0.1  # Coulomb coefficient mu
    gamma: float = 0.0  # Dupre adhesion energy, mJ/mm^2
    delta_max: float = 5e-4  # separation at which adhesion vanishes, mm (0.5 um)
    asperity_yield: float = 5.0  # asperity yield stress sigma_y, MPa; p0 = 3 sigma_y
    #: force the degree of contact (e.g. 1.0) at the points where contact has been established
    #: (sigma_max > 0); never-touched points carry no adhesion (no snap-in ahead of the contact)
    alpha_forced: float | None = None

    def __post_init__(self):
        checks = [
            ("penalty", self.penalty, self.penalty > 0, "> 0 N/mm^3"),
            ("friction", self.friction, self.friction >= 0, ">= 0"),
            ("gamma", self.gamma, self.gamma >= 0, ">= 0 mJ/mm^2"),
            ("delta_max", self.delta_max, self.delta_max > 0, "> 0 mm"),
            ("asperity_yield", self.asperity_yield, self.asperity_yield > 0, "> 0 MPa"),
        ]
        if self.tangential_penalty is not None:
            checks.append(
                (
                    "tangential_penalty",
                    self.tangential_penalty,
                    self.tangential_penalty > 0,
                    "> 0 N/mm^3",
                )
            )
        if self.alpha_forced is not None:
            checks.append(
                ("alpha_forced", self.alpha_forced, 0 <= self.alpha_forced <= 1, "in [0, 1]")
            )
        for name, value, ok, allowed in checks:
            if not ok:
                raise ValueError(f"contact.{name} = {value!r} is out of range: must be {allowed}")

    def require_softening_branch(self) -> None:
        """Raise ValueError unless the adhesive peak alpha sigma_c is reached at an opening
        delta_1 = alpha sigma_c / k below delta_max (alpha <= 1, or alpha_forced): otherwise the
        softening branch T1 = -peak (delta_max - delta) / (delta_max - delta_1) degenerates and the
        law holds k delta_max^2 / 2 instead of gamma. Granular cases call it on their input; the
        single-contact elastic checks use such a law on purpose (adhesion off: sigma_0 = 1e6)."""
        alpha = 1.0 if self.alpha_forced is None else self.alpha_forced
        if alpha * self.sigma_c / self.penalty >= self.delta_max:
            raise ValueError(
                f"contact.gamma = {self.gamma!r} with contact.delta_max = {self.delta_max!r} and "
                "penalty "
                f"{self.penalty:.4g} N/mm^3: the adhesive peak opening alpha sigma_c / k = "
                f"{alpha * self.sigma_c / self.penalty:.3g} mm must be < delta_max (gamma < "
                f"k delta_max^2 / 2 = {self.penalty * self.delta_max**2 / 2:.3g} mJ/mm^2)"
            )

    @property
    def p0(self) -> float:
        """Pullen-Williamson pressure scale p0 = 3 sigma_y(asperity), MPa."""
        return 3.0 * self.asperity_yield

    @property
    def sigma_c(self) -> float:
        """Adhesive strength sigma_c = 2 gamma / delta_max, MPa."""
        return 2.0 * self.gamma / self.delta_max

    def kernel_parameters(self):
        """The law's numbers as the compiled kernels take them (normal and tangential penalty,
        friction, sigma_c, delta_max, p0, forced alpha or -1)."""
        kt = self.penalty if self.tangential_penalty is None else self.tangential_penalty
        forced = -1.0 if self.alpha_forced is None else float(self.alpha_forced)
        return (self.penalty, kt, self.friction, self.sigma_c, self.delta_max, self.p0, forced)


def default_penalty(E: float, length: float, factor: float = 10.0) -> float:
    """Penalty from element stiffness: k = factor * E / h (N/mm^3), h = contact element size (mm).

    With factor 10 the penalty overlap stays ~1 % of the elastic approach of the surfaces (the
    Hertz case reaches the analytic force within 5 %), while Newton keeps converging; the thesis'
    1e9 N/mm^3 suits its coarse Abaqus meshes and explicit dynamics.
    """
    if not (E > 0 and length > 0 and factor > 0):
        raise ValueError(
            f"default_penalty needs E, length, factor > 0, got {E}, {length}, {factor}"
        )
    return factor * E / length


#: normal branches of the law (``branch code % 4``, see :func:`law_point`)
OVERLAP, ADHESIVE_LOADING, SOFTENING, SEPARATED = 0, 1, 2, 3
#: tangential branches (``branch code // 4``)
NO_TANGENT, STICK, SLIP = 0, 1, 2


def normal_branch(code):
    """The normal branch (OVERLAP, ADHESIVE_LOADING, SOFTENING or SEPARATED) of branch codes."""
    return code % 4


@numba.njit(cache=True)
def law_point(
    d,
    sx,
    sy,
    sz,
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
    out,
):
    """Contact law at one point (module docstring).

    Inputs: gap d (mm); slip increment (sx, sy, sz) (mm); unit normal (nx, ny, nz); history
    alpha_n, smax_n (MPa) and previous tangential traction (tpx, tpy, tpz) (MPa); ``branch``:
    -1 to select the branches from the state, or the code returned in out[8] to stay on given
    branches (used to differentiate across the kinks of the law for the tangent); ``t1_held``:
    NaN, or a traction (MPa) that the softening branch returns unchanged (zero slope: the
    tangent of a peeling point, see ``contact.model._point_tangents``).
    out = [T1, Ttx, Tty, Ttz, alpha, smax, dT1/d gap, dissipation per area, branch code].
    Branch code = 4 * tangential (0 none, 1 stick, 2 slip) + normal (0 overlap, 1 adhesive
    loading line, 2 softening, 3 separated).
    """
    sm = smax_n
    a_mem = sm / (p0 + sm) if sm > 0.0 else 0.0
    # a forced degree of contact applies where contact was established (sigma_max > 0)
    a_eff = alpha_forced if (alpha_forced >= 0.0 and sm > 0.0) else a_mem
    peak = a_eff * sigma_c
    d1 = peak / k
    if branch < 0:
        if d < 0.0:
            nb = OVERLAP
        elif d < delta_max:
            nb = ADHESIVE_LOADING if d <= d1 else SOFTENING
        else:
            nb = SEPARATED
    else:
        nb = branch % 4
    if nb == OVERLAP:
        t1 = -k * d
        dt1 = -k
        if t1 > sm:
            sm = t1
    elif nb == ADHESIVE_LOADING:
        t1 = -k * d
        dt1 = -k
    elif nb == SOFTENING:
        if np.isnan(t1_held):
            t1 = -peak * (delta_max - d) / (delta_max - d1)
            dt1 = peak / (delta_max - d1)
        else:
            t1 = t1_held
            dt1 = 0.0
    else:
        t1 = 0.0
        dt1 = 0.0
        sm = 0.0  # memory erased beyond delta_max
    if alpha_forced >= 0.0 and sm > 0.0:
        a = alpha_forced
    else:
        a = sm / (p0 + sm) if sm > 0.0 else 0.0
    out[0] = t1
    out[4] = a
    out[5] = sm
    out[6] = dt1
    out[7] = 0.0
    # previous tangential traction rotated into the current tangent plane: projected, then
    # rescaled to its stored magnitude (a projection alone shrinks it by cos theta when the
    # normal turns by theta and releases stored shear without slip; the direction is that of the
    # exact rotation up to O(theta^2) per increment); then the tangential slip
    before = np.sqrt(tpx * tpx + tpy * tpy + tpz * tpz)
    dot = tpx * nx + tpy * ny + tpz * nz
    tpx -= dot * nx
    tpy -= dot * ny
    tpz -= dot * nz
    after = np.sqrt(tpx * tpx + tpy * tpy + tpz * tpz)
    if after > 1e-12 * before:
        tpx *= before / after
        tpy *= before / after
        tpz *= before / after
    dot = sx * nx + sy * ny + sz * nz
    sx -= dot * nx
    sy -= dot * ny
    sz -= dot * nz
    tb = NO_TANGENT
    if branch < 0:
        if t1 > 0.0 and mu > 0.0:
            trx = tpx - kt * sx
            try_ = tpy - kt * sy
            trz = tpz - kt * sz
            tb = STICK if np.sqrt(trx * trx + try_ * try_ + trz * trz) <= mu * t1 else SLIP
    else:
        tb = branch // 4
    out[8] = 4 * tb + nb
    if tb == NO_TANGENT:
        out[1] = 0.0
        out[2] = 0.0
        out[3] = 0.0
        return
    trx = tpx - kt * sx
    try_ = tpy - kt * sy
    trz = tpz - kt * sz
    if tb == STICK:
        out[1] = trx
        out[2] = try_
        out[3] = trz
        return
    norm = np.sqrt(trx * trx + try_ * try_ + trz * trz)
    limit = mu * t1
    out[1] = limit * trx / norm
    out[2] = limit * try_ / norm
    out[3] = limit * trz / norm
    # slip part of the increment and its dissipation
    e0 = sx + (out[1] - tpx) / kt
    e1 = sy + (out[2] - tpy) / kt
    e2 = sz + (out[3] - tpz) / kt
    out[7] = -(out[1] * e0 + out[2] * e1 + out[3] * e2)


@numba.njit(parallel=True, cache=True)
def evaluate_law(
    gap,
    slip,
    normal,
    alpha_n,
    smax_n,
    tt_n,
    k,
    kt,
    mu,
    sigma_c,
    delta_max,
    p0,
    alpha_forced,
    T1,
    Tt,
    alpha,
    smax,
    dissipation,
    branch,
):
    """Tractions, updated history and branch codes at every contact point (:func:`law_point`)."""
    n = gap.shape[0]
    for i in numba.prange(n):
        out = np.empty(9)
        law_point(
            gap[i],
            slip[i, 0],
            slip[i, 1],
            slip[i, 2],
            normal[i, 0],
            normal[i, 1],
            normal[i, 2],
            alpha_n[i],
            smax_n[i],
            tt_n[i, 0],
            tt_n[i, 1],
            tt_n[i, 2],
            k,
            kt,
            mu,
            sigma_c,
            delta_max,
            p0,
            alpha_forced,
            -1,
            np.nan,
            out,
        )
        branch[i] = int(out[8])
        T1[i] = out[0]
        Tt[i, 0] = out[1]
        Tt[i, 1] = out[2]
        Tt[i, 2] = out[3]
        alpha[i] = out[4]
        smax[i] = out[5]
        dissipation[i] = out[7]
