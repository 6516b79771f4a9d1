"""Amplitudes a(t) in [0, 1] driving prescribed motions (time t in s)."""

from __future__ import annotations

from dataclasses import dataclass


def _quintic_ramp(u: float) -> float:
    """Smooth step 10 u^3 - 15 u^4 + 6 u^5 on [0, 1]: zero slope and curvature at both ends."""
    return u**3 * (10.0 - 15.0 * u + 6.0 * u * u)


@dataclass(frozen=True)
class SmoothStep:
    """Abaqus SMOOTH STEP between (t0, 0) and (t1, 1): a = 10 s^3 - 15 s^4 + 6 s^5,
    s = (t-t0)/(t1-t0).

    Zero velocity and acceleration at both knots, which keeps explicit runs quasi-static.
    """

    t1: float = 1.0
    t0: float = 0.0

    def __post_init__(self):
        if not self.t1 > self.t0:
            raise ValueError(f"SmoothStep needs t1 > t0, got t0={self.t0}, t1={self.t1}")

    def __call__(self, t: float) -> float:
        """Amplitude in [0, 1] at time ``t`` (s)."""
        s = min(max((t - self.t0) / (self.t1 - self.t0), 0.0), 1.0)
        return _quintic_ramp(s)

    def rate(self, t: float) -> float:
        """d amplitude / dt (1/s) at time ``t`` (s)."""
        s = min(max((t - self.t0) / (self.t1 - self.t0), 0.0), 1.0)
        return 30.0 * s * s * (1.0 - s) ** 2 / (self.t1 - self.t0)


def _quintic_ramp_integral(u: float) -> float:
    """Integral from 0 to u of :func:`_quintic_ramp` (1/2 at u = 1)."""
    return u**4 * (2.5 - 3.0 * u + u * u)


@dataclass(frozen=True)
class SmoothRamps:
    """Constant rate between smooth ramps: the rate rises from 0 over the first ``rise`` fraction
    of [t0, t1], stays at its plateau, and falls back to 0 over the last ``fall`` fraction.

    The ramps are quintic in the rate (zero rate, acceleration and jerk at t0 and t1, like
    SmoothStep), so the plateau is 1 / (1 - (rise + fall) / 2) times the mean rate, against 1.875
    for SmoothStep. Explicit compactions: the packing is loaded at a uniform rate through the
    rearrangement range instead of at the smooth step's peak, and the long fall lets it settle
    (loading-rate study in bench/README.md).
    """

    t1: float = 1.0
    t0: float = 0.0
    rise: float = 0.1
    fall: float = 0.3

    def __post_init__(self):
        if not self.t1 > self.t0:
            raise ValueError(f"SmoothRamps needs t1 > t0, got t0={self.t0}, t1={self.t1}")
        if not (0.0 < self.rise and 0.0 < self.fall and self.rise + self.fall <= 1.0):
            raise ValueError(
                f"SmoothRamps needs rise > 0, fall > 0 and rise + fall <= 1, got rise={self.rise}, "
                f"fall={self.fall}"
            )

    @property
    def plateau(self) -> float:
        """Rate on the plateau in units of the mean rate 1 / (t1 - t0)."""
        return 1.0 / (1.0 - 0.5 * (self.rise + self.fall))

    def __call__(self, t: float) -> float:
        """Amplitude in [0, 1] at time ``t`` (s)."""
        s = min(max((t - self.t0) / (self.t1 - self.t0), 0.0), 1.0)
        v = self.plateau
        if s < self.rise:
            return v * self.rise * _quintic_ramp_integral(s / self.rise)
        if s > 1.0 - self.fall:
            return 1.0 - v * self.fall * _quintic_ramp_integral((1.0 - s) / self.fall)
        return v * (0.5 * self.rise + s - self.rise)

    def rate(self, t: float) -> float:
        """d amplitude / dt (1/s) at time ``t`` (s)."""
        s = min(max((t - self.t0) / (self.t1 - self.t0), 0.0), 1.0)
        u = min(s / self.rise, (1.0 - s) / self.fall, 1.0)
        return self.plateau * _quintic_ramp(u) / (self.t1 - self.t0)


#: amplitude shapes of a macroscopic path segment, by name (GradientPath.profiles)
PROFILES = {"smooth-step": SmoothStep, "smooth-ramps": SmoothRamps}


@dataclass(frozen=True)
class Ramp:
    """Linear ramp from 0 at t0 to 1 at t1."""

    t1: float = 1.0
    t0: float = 0.0

    def __call__(self, t: float) -> float:
        """Amplitude in [0, 1] at time ``t`` (s)."""
        return min(max((t - self.t0) / (self.t1 - self.t0), 0.0), 1.0)

    def rate(self, t: float) -> float:
        """d amplitude / dt (1/s) at time ``t`` (s)."""
        return 1.0 / (self.t1 - self.t0) if self.t0 <= t <= self.t1 else 0.0
