"""The Drucker-Prager Cap yield surface in Abaqus' form, on the meridian plane of a compact.

Pure numpy. Stresses in MPa, compression > 0 (the reported convention of
:mod:`mpfem_fenicsx.homogenization`): the equivalent pressure p is the mean stress sigma_m, and
a point of a yield fan is (sigma_m, sigma~_d) with sigma~_d > 0 on the triaxial-compression side
(axial stress the larger compression, as in die pressing) and < 0 on the triaxial-extension
side (thesis eq. 4.1-4.2).

The surface, with D = d + p_a tan(beta) and p_a = (p_b - R d) / (1 + R tan(beta)):

- shear failure   F_s = t - p tan(beta) - d = 0, from the tensile apex p = -d / tan(beta);
- transition      F_t = sqrt((p - p_a)^2 + (t - (1 - alpha / cos(beta)) D)^2) - alpha D = 0;
- cap             F_c = sqrt((p - p_a)^2 + (R t / (1 + alpha - alpha / cos(beta)))^2) - R D = 0,
  which meets the pressure axis at the hydrostatic yield stress p_b = p_a + R D;

where t = q / 2 [1 + 1/K - (1 - 1/K)(r/q)^3] is the deviatoric measure: t = q in triaxial
compression (r / q = -1) and t = q / K in triaxial extension (r / q = 1), so that on the
extension side the surface lies at sigma~_d = -K t. The parameters are those of Abaqus'
``*CAP PLASTICITY`` (d, beta in degrees, R, alpha, K) and ``*CAP HARDENING`` (p_b).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..parameters import check_parameters, parameter


@dataclass(frozen=True)
class CapSurface:
    """One Drucker-Prager Cap yield surface (Abaqus' form, see the module). Checked on creation:
    a ``ValueError`` names the field and its allowed range."""

    d: float = parameter(1.0, "cohesion d in the p-t plane (MPa)", low=0.0)
    beta: float = parameter(
        30.0,
        "friction angle beta in the p-t plane (degrees)",
        low=0.0,
        high=90.0,
        open_low=True,
        open_high=True,
    )
    R: float = parameter(0.5, "cap eccentricity R (-)", low=1e-4, high=1e3)
    p_b: float = parameter(10.0, "hydrostatic yield stress p_b (MPa)", low=0.0, open_low=True)
    alpha: float = parameter(
        0.01, "transition surface radius parameter alpha (-)", low=0.0, high=0.5
    )
    K: float = parameter(
        1.0, "flow stress ratio K, triaxial extension over compression (-)", low=0.778, high=1.0
    )

    def __post_init__(self) -> None:
        check_parameters(self)
        b = math.radians(self.beta)
        if self.alpha * math.sin(b) * math.tan(b) >= 1.0 or self.alpha * (1 / math.cos(b) - 1) >= 1:
            raise ValueError(
                f"alpha = {self.alpha:g} is out of range: must be < 1 / (sin(beta) tan(beta)) and "
                f"< 1 / (1 / cos(beta) - 1) at beta = {self.beta:g} degrees (the transition "
                "surface inside the shear line and the cap)"
            )

    # -- the surface's landmarks ------------------------------------------------------------
    @property
    def tan_beta(self) -> float:
        """tan(beta) (-)."""
        return math.tan(math.radians(self.beta))

    @property
    def p_a(self) -> float:
        """The cap's centre on the pressure axis (MPa): the evolution parameter of Abaqus."""
        return (self.p_b - self.R * self.d) / (1.0 + self.R * self.tan_beta)

    @property
    def apex(self) -> float:
        """The shear line's tensile apex, p = -d / tan(beta) (MPa): the most negative mean
        stress (hydrostatic tension) the surface admits."""
        return -self.d / self.tan_beta

    @property
    def _D(self) -> float:
        return self.d + self.p_a * self.tan_beta

    @property
    def _cap_height(self) -> float:
        """t at the top of the cap (p = p_a): (1 + alpha - alpha / cos(beta)) D."""
        return (1.0 + self.alpha - self.alpha / math.cos(math.radians(self.beta))) * self._D

    # -- the surface in the meridian plane ----------------------------------------------------
    def t(self, p) -> np.ndarray:
        """The deviatoric measure t on the surface at mean stresses ``p`` (MPa); NaN outside
        [apex, p_b]."""
        p = np.asarray(p, dtype=float)
        D, a, tb = self._D, self.alpha, self.tan_beta
        cos_b = math.cos(math.radians(self.beta))
        p_t = self.p_a - a * D * math.sin(math.radians(self.beta))  # shear line meets transition
        out = np.full(p.shape, np.nan)
        shear = (p >= self.apex) & (p <= p_t)
        out[shear] = self.d + p[shear] * tb
        trans = (p > p_t) & (p <= self.p_a)
        out[trans] = (1.0 - a / cos_b) * D + np.sqrt(
            np.maximum((a * D) ** 2 - (p[trans] - self.p_a) ** 2, 0.0)
        )
        cap = (p > self.p_a) & (p <= self.p_b)
        out[cap] = (self._cap_height / (self.R * D)) * np.sqrt(
            np.maximum((self.R * D) ** 2 - (p[cap] - self.p_a) ** 2, 0.0)
        )
        return out

    def sigma_tilde_d(self, p, side) -> np.ndarray:
        """sigma~_d (MPa) on the surface at ``p``: ``side`` > 0 the triaxial-compression side
        (t), < 0 the extension side (-K t); NaN outside [apex, p_b]."""
        t = self.t(p)
        return np.where(np.asarray(side) >= 0, t, -self.K * t)

    def inside(self, sigma_m, sigma_tilde_d) -> np.ndarray:
        """True where (sigma_m, sigma~_d) lies strictly inside the elastic domain."""
        s = np.asarray(sigma_tilde_d, dtype=float)
        t_point = np.where(s >= 0, s, -s / self.K)
        t_surface = self.t(sigma_m)
        return np.isfinite(t_surface) & (t_point < t_surface)

    def boundary(self, n: int = 361) -> tuple[np.ndarray, np.ndarray]:
        """The closed surface as a polygon (sigma_m, sigma~_d) of 2 ``n`` - 1 vertices: the
        compression side from the apex to p_b, then the extension side back to the apex. The
        points are denser near both ends, where the surface turns."""
        u = 0.5 - 0.5 * np.cos(np.linspace(0.0, math.pi, n))
        p = self.apex + u * (self.p_b - self.apex)
        upper = self.sigma_tilde_d(p, 1)
        lower = self.sigma_tilde_d(p[::-1][1:], -1)
        return np.concatenate([p, p[::-1][1:]]), np.concatenate([upper, lower])

    def radius(self, centre: tuple[float, float], direction) -> np.ndarray:
        """Distance (MPa) from ``centre`` (sigma_m, sigma~_d), a point inside the surface, to the
        surface along the unit vectors ``direction`` (N, 2) of the meridian plane (bisection on
        :meth:`inside`; the elastic domain is convex)."""
        c = np.asarray(centre, dtype=float)
        if not self.inside(c[0], c[1]):
            raise ValueError(f"centre = {tuple(c)} is not inside the surface")
        e = np.asarray(direction, dtype=float).reshape(-1, 2)
        lo = np.zeros(len(e))
        hi = np.full(len(e), 2.0 * (self.p_b - self.apex + self._cap_height) + 1.0)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            x = c + mid[:, None] * e
            inner = self.inside(x[:, 0], x[:, 1])
            lo, hi = np.where(inner, mid, lo), np.where(inner, hi, mid)
        return 0.5 * (lo + hi)
