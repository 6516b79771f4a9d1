"""Amplitudes a(t) in [0, 1] driving prescribed motions (time t in s)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SmoothStep:
    """Abaqus SMOOTH STEP between (t0, 0) and (t1, 1): a = 10 s^3 - 15 s^4 + 6 s^5, s = (t-t0)/(t1-t0).

    Zero velocity and acceleration at both knots, which keeps explicit runs quasi-static.
    """

    t1: float = 1.0
    t0: float = 0.0

    def __post_init__(self):
        if not self.t1 > self.t0:
            raise ValueError(f"SmoothStep needs t1 > t0, got t0={self.t0}, t1={self.t1}")

    def __call__(self, t: float) -> float:
        s = min(max((t - self.t0) / (self.t1 - self.t0), 0.0), 1.0)
        return s ** 3 * (10.0 - 15.0 * s + 6.0 * s * s)

    def rate(self, t: float) -> float:
        s = min(max((t - self.t0) / (self.t1 - self.t0), 0.0), 1.0)
        return 30.0 * s * s * (1.0 - s) ** 2 / (self.t1 - self.t0)


@dataclass(frozen=True)
class Ramp:
    """Linear ramp from 0 at t0 to 1 at t1."""

    t1: float = 1.0
    t0: float = 0.0

    def __call__(self, t: float) -> float:
        return min(max((t - self.t0) / (self.t1 - self.t0), 0.0), 1.0)

    def rate(self, t: float) -> float:
        return 1.0 / (self.t1 - self.t0) if self.t0 <= t <= self.t1 else 0.0
