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
    alpha_forced: float | None = None  # force the degree of contact (e.g. 1.0), else PW law

    def __post_init__(self):
        checks = [
            ("penalty", self.penalty, self.penalty > 0, "> 0 N/mm^3"),
            ("friction", self.friction, self.friction >= 0, ">= 0"),
            ("gamma", self.gamma, self.gamma >= 0, ">= 0 mJ/mm^2"),
            ("delta_max", self.delta_max, self.delta_max > 0, "> 0 mm"),
            ("asperity_yield", self.asperity_yield, self.asperity_yield > 0, "> 0 MPa"),
        ]
        if self.tangential_penalty is not None:
            checks.append(("tangential_penalty", self.tangential_penalty, self.tangential_penalty > 0, "> 0 N/mm^3"))
        if self.alpha_forced is not None:
            checks.append(("alpha_forced", self.alpha_forced, 0 <= self.alpha_forced <= 1, "in [0, 1]"))
        for name, value, ok, allowed in checks:
            if not ok:
                raise ValueError(f"contact.{name} = {value!r} is out of range: must be {allowed}")

    @property
    def p0(self) -> float:
        """Pullen-Williamson pressure scale p0 = 3 sigma_y(asperity), MPa."""
        return 3.0 * self.asperity_yield

    @property
    def sigma_c(self) -> float:
        """Adhesive strength sigma_c = 2 gamma / delta_max, MPa."""
        return 2.0 * self.gamma / self.delta_max

    def kernel_parameters(self):
        kt = self.penalty if self.tangential_penalty is None else self.tangential_penalty
        forced = -1.0 if self.alpha_forced is None else float(self.alpha_forced)
        return (self.penalty, kt, self.friction, self.sigma_c, self.delta_max, self.p0, forced)


@numba.njit(parallel=True, cache=True)
def evaluate_law(gap, slip, normal, alpha_n, smax_n, tt_n, k, kt, mu, sigma_c, delta_max, p0,
                 alpha_forced, T1, Tt, alpha, smax, dT1, dTt_dslip, dTt_dgap, dissipation):
    """Tractions, updated history and consistent tangents at every contact point.

    Inputs: gap (n,), slip (n, 3) tangential relative displacement increment of the slave
    (mm), normal (n, 3), history alpha_n, smax_n (MPa), tt_n (n, 3) (MPa).
    Outputs: T1, Tt (n, 3), alpha, smax; dT1 = dT1/d gap (MPa/mm); dTt_dslip (n, 3, 3) and
    dTt_dgap (n, 3) derivatives of Tt; dissipation (n,) frictional work per area (mJ/mm^2).
    """
    n = gap.shape[0]
    for i in numba.prange(n):
        d = gap[i]
        a = alpha_n[i]
        sm = smax_n[i]
        if d < 0.0:
            t1 = -k * d
            dt1 = -k
            if t1 > sm:
                sm = t1
        elif d < delta_max:
            if alpha_forced >= 0.0:
                a_eff = alpha_forced
            else:
                a_eff = sm / (p0 + sm) if sm > 0.0 else 0.0
            peak = a_eff * sigma_c
            d1 = peak / k
            if d <= d1:
                t1 = -k * d
                dt1 = -k
            else:
                t1 = -peak * (delta_max - d) / (delta_max - d1)
                dt1 = peak / (delta_max - d1)
        else:
            t1 = 0.0
            dt1 = 0.0
            sm = 0.0  # memory erased beyond delta_max
        if alpha_forced >= 0.0:
            a = alpha_forced
        else:
            a = sm / (p0 + sm) if sm > 0.0 else 0.0
        T1[i] = t1
        dT1[i] = dt1
        alpha[i] = a
        smax[i] = sm

        # tangential: previous traction rotated into the current tangent plane
        nx, ny, nz = normal[i, 0], normal[i, 1], normal[i, 2]
        tp0, tp1, tp2 = tt_n[i, 0], tt_n[i, 1], tt_n[i, 2]
        dot = tp0 * nx + tp1 * ny + tp2 * nz
        tp0 -= dot * nx
        tp1 -= dot * ny
        tp2 -= dot * nz
        s0, s1, s2 = slip[i, 0], slip[i, 1], slip[i, 2]
        dot = s0 * nx + s1 * ny + s2 * nz
        s0 -= dot * nx
        s1 -= dot * ny
        s2 -= dot * nz
        for p in range(3):
            dTt_dgap[i, p] = 0.0
            for q in range(3):
                dTt_dslip[i, p, q] = 0.0
        dissipation[i] = 0.0
        if t1 <= 0.0 or mu == 0.0:
            Tt[i, 0] = 0.0
            Tt[i, 1] = 0.0
            Tt[i, 2] = 0.0
            continue
        tr0 = tp0 - kt * s0
        tr1 = tp1 - kt * s1
        tr2 = tp2 - kt * s2
        norm = np.sqrt(tr0 * tr0 + tr1 * tr1 + tr2 * tr2)
        limit = mu * t1
        nv = (nx, ny, nz)
        if norm <= limit:
            Tt[i, 0] = tr0
            Tt[i, 1] = tr1
            Tt[i, 2] = tr2
            for p in range(3):
                for q in range(3):
                    dTt_dslip[i, p, q] = -kt * ((1.0 if p == q else 0.0) - nv[p] * nv[q])
        else:
            t0, t1v, t2 = tr0 / norm, tr1 / norm, tr2 / norm
            tv = (t0, t1v, t2)
            Tt[i, 0] = limit * t0
            Tt[i, 1] = limit * t1v
            Tt[i, 2] = limit * t2
            ratio = limit / norm
            for p in range(3):
                dTt_dgap[i, p] = mu * dt1 * tv[p]
                for q in range(3):
                    dTt_dslip[i, p, q] = -kt * ratio * ((1.0 if p == q else 0.0) - nv[p] * nv[q]
                                                         - tv[p] * tv[q])
            # slip part of the increment and its dissipation
            e0 = s0 + (Tt[i, 0] - tp0) / kt
            e1 = s1 + (Tt[i, 1] - tp1) / kt
            e2 = s2 + (Tt[i, 2] - tp2) / kt
            dissipation[i] = -(Tt[i, 0] * e0 + Tt[i, 1] * e1 + Tt[i, 2] * e2)
