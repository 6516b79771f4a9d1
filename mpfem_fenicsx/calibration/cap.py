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
from typing import ClassVar

import numpy as np

from ..parameters import check_parameters, parameter
from .meridian import MeridianSurface


@dataclass(frozen=True)
class CapSurface(MeridianSurface):
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

    #: the parameters interpolated in the density (the size p_b comes from the hardening)
    SHAPE: ClassVar[tuple[str, ...]] = ("d", "beta", "R", "alpha", "K")

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
    def p_low(self) -> float:
        """The surface's tensile end on the pressure axis (MPa): the apex."""
        return self.apex

    @property
    def p_high(self) -> float:
        """The surface's compressive end on the pressure axis (MPa): p_b."""
        return self.p_b

    @property
    def t_max(self) -> float:
        """The largest t of the surface (MPa), at the top of the cap."""
        return self._cap_height

    @property
    def _D(self) -> float:
        return self.d + self.p_a * self.tan_beta

    @property
    def cap_factor(self) -> float:
        """c = 1 + alpha - alpha / cos(beta) (-): the cap's height over the shear line's t at
        p_a, the factor of t in the cap and shear flow potentials."""
        return 1.0 + self.alpha - self.alpha / math.cos(math.radians(self.beta))

    @property
    def _cap_height(self) -> float:
        """t at the top of the cap (p = p_a): c D (``cap_factor``)."""
        return self.cap_factor * self._D

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

    # -- the interface of the material-point driver ------------------------------------------
    @property
    def size_ratios(self) -> dict[str, float]:
        """Quantities interpolated in the density that scale with the size: none."""
        return {}

    @classmethod
    def sized(cls, p_high: float, **shape_and_ratios) -> CapSurface:
        """The surface of the given shape and hydrostatic yield stress ``p_high`` (p_b)."""
        return cls(**shape_and_ratios, p_b=p_high)

    def regions(self, p_trial: float) -> tuple[str, str]:
        """The regions a return from a trial at mean stress ``p_trial`` may end in, the likely
        one first: the cap right of p_a, the shear line (with the transition) left of it."""
        return ("cap", "shear") if p_trial > self.p_a else ("shear", "cap")

    def region_of(self, p: float) -> str:
        """The region of a stress on the surface at mean stress ``p``."""
        return "cap" if p > self.p_a else "shear"

    def yield_and_flow(self, p: float, t: float, region: str):
        """F of the ``region`` (the cap, or the shear line with the transition arc; MPa) and
        the flow direction (dG/dp, dG/dt) of Abaqus' potentials: associated on the cap,
        G_c = sqrt((p - p_a)^2 + (R t / c)^2); elsewhere G_s = sqrt(((p_a - p) tan(beta))^2 +
        (t / c)^2), c = 1 + alpha - alpha / cos(beta)."""
        b, c = math.radians(self.beta), self.cap_factor
        p_a, tb, a = self.p_a, self.tan_beta, self.alpha
        D = self.d + p_a * tb
        if region == "cap":
            G = max(math.hypot(p - p_a, self.R * t / c), 1e-300)
            return G - self.R * D, ((p - p_a) / G, (self.R / c) ** 2 * t / G)
        if a > 0.0 and p > p_a - a * D * math.sin(b):  # transition arc
            F = math.hypot(p - p_a, t - (1.0 - a / math.cos(b)) * D) - a * D
        else:
            F = t - p * tb - self.d
        G = max(math.hypot((p_a - p) * tb, t / c), 1e-300)
        return F, (-(p_a - p) * tb**2 / G, t / c**2 / G)
