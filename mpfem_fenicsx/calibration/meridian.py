"""What every yield surface of the calibration shares on the meridian (Rendulic) plane.

A surface is described by its deviatoric measure t(p) on [p_low, p_high] (MPa, compression
> 0) and its flow stress ratio K: in triaxial compression (sigma~_d > 0) the surface lies at
sigma~_d = t, in triaxial extension at sigma~_d = -K t (Abaqus' t = q / 2 [1 + 1/K - (1 - 1/K)
(r/q)^3]). The elastic domain is convex.
"""

from __future__ import annotations

import math

import numpy as np


class MeridianSurface:
    """Mixin of the surfaces: needs ``t(p)``, ``K``, ``p_low``, ``p_high`` and ``t_max``."""

    def sigma_tilde_d(self, p, side) -> np.ndarray:
        """sigma~_d (MPa) on the surface at ``p``: ``side`` > 0 the triaxial-compression side
        (t), < 0 the extension side (-K t); NaN outside [p_low, p_high]."""
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
        compression side from p_low to p_high, then the extension side back. The points are
        denser near both ends, where the surface turns."""
        u = 0.5 - 0.5 * np.cos(np.linspace(0.0, math.pi, n))
        p = self.p_low + u * (self.p_high - self.p_low)
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
        hi = np.full(len(e), 2.0 * (self.p_high - self.p_low + self.t_max) + 1.0)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            x = c + mid[:, None] * e
            inner = self.inside(x[:, 0], x[:, 1])
            lo, hi = np.where(inner, mid, lo), np.where(inner, hi, mid)
        return 0.5 * (lo + hi)
