"""The extended (modified) Cam-clay yield surface with a tensile intercept, on the meridian plane.

Pure numpy. Stresses in MPa, compression > 0, as in :mod:`.cap`. The surface is Abaqus'
critical-state ellipse (``*CLAY PLASTICITY`` with ``*CLAY HARDENING``, TYPE=COMPRESSION and
TYPE=TENSION) in the p-t plane:

    F = (1 / b^2) ((p - p_cs) / a)^2 + (t / (M a))^2 - 1 = 0,
    a = (p_c - p_t) / (1 + beta),  p_cs = p_t + a,

b = 1 on the dry side (p < p_cs) and b = beta on the wet side: it meets the pressure axis at
the hydrostatic tensile yield stress p_t (<= 0 for a compact with cohesion) and at the
hydrostatic compressive yield stress p_c, and its top, t = M a, is the critical state p_cs. The
deviatoric measure t and the flow stress ratio K are those of :mod:`.cap` (sigma~_d = t in
triaxial compression, -K t in extension). Flow is associated.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..parameters import check_parameters, parameter
from .meridian import MeridianSurface


@dataclass(frozen=True)
class ClaySurface(MeridianSurface):
    """One critical-state ellipse (see the module). Checked on creation: a ``ValueError`` names
    the field and its allowed range."""

    M: float = parameter(1.0, "stress ratio at critical state M (-)", low=0.0, open_low=True)
    beta: float = parameter(
        1.0, "wet-side ellipse ratio beta (-)", low=0.0, high=100.0, open_low=True
    )
    p_c: float = parameter(
        10.0, "hydrostatic compressive yield stress p_c (MPa)", low=0.0, open_low=True
    )
    p_t: float = parameter(
        0.0, "hydrostatic tensile yield stress p_t, <= 0 (MPa)", high=0.0, low=-1e9
    )
    K: float = parameter(
        1.0, "flow stress ratio K, triaxial extension over compression (-)", low=0.778, high=1.0
    )

    #: the parameters interpolated in the density (the size p_c comes from the hardening)
    SHAPE: ClassVar[tuple[str, ...]] = ("M", "beta", "K")

    def __post_init__(self) -> None:
        check_parameters(self)
        if self.p_t >= self.p_c:
            raise ValueError(f"p_t = {self.p_t:g} is out of range: must be < p_c = {self.p_c:g}")

    @property
    def a(self) -> float:
        """The dry-side semi-axis (MPa)."""
        return (self.p_c - self.p_t) / (1.0 + self.beta)

    @property
    def p_cs(self) -> float:
        """The critical state's mean stress (MPa): the top of the ellipse."""
        return self.p_t + self.a

    @property
    def p_low(self) -> float:
        """The tensile end on the pressure axis (MPa): p_t."""
        return self.p_t

    @property
    def p_high(self) -> float:
        """The compressive end on the pressure axis (MPa): p_c."""
        return self.p_c

    @property
    def t_max(self) -> float:
        """The largest t (MPa), at the critical state: M a."""
        return self.M * self.a

    def t(self, p) -> np.ndarray:
        """t on the surface at mean stresses ``p`` (MPa); NaN outside [p_t, p_c]."""
        p = np.asarray(p, dtype=float)
        semi = np.where(p > self.p_cs, self.beta * self.a, self.a)
        x = (p - self.p_cs) / semi
        inside = np.abs(x) <= 1.0 + 1e-12
        return np.where(inside, self.t_max * np.sqrt(np.clip(1.0 - x**2, 0.0, None)), np.nan)

    def yield_and_flow(self, p: float, t: float, region=None):
        """F (stress units: a (sqrt(1 + F_dimensionless) - 1)) and the associated flow
        direction (dF/dp, dF/dt) at (p, t); ``region`` is unused (one smooth surface)."""
        a = self.a
        b = self.beta if p > self.p_cs else 1.0
        u, v = (p - self.p_cs) / (b * a), t / (self.M * a)
        r = max(float(np.hypot(u, v)), 1e-300)
        return a * (r - 1.0), (u / (b * r), v / (self.M * r))

    @property
    def size_ratios(self) -> dict[str, float]:
        """Quantities interpolated in the density that scale with the size: p_t / p_c."""
        return {"tension_ratio": self.p_t / self.p_c}

    @classmethod
    def sized(cls, p_high: float, tension_ratio: float = 0.0, **shape) -> ClaySurface:
        """The ellipse of the given shape, p_c = ``p_high`` and p_t = ``tension_ratio`` p_c."""
        return cls(**shape, p_c=p_high, p_t=tension_ratio * p_high)

    def regions(self, p_trial: float):
        """The regions a return may end in, most likely first: one."""
        return (None,)

    def region_of(self, p: float):
        """The region of a stress on the surface at mean stress ``p``: one."""
        return None
