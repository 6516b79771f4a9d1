"""Force control of a rigid tool: a servo on its reaction (N, s, mm).

The tool moves along its pressing direction d (a plane's normal: towards the particles) at a
speed set from the error between the target pressing force and the measured one, like the stress
servo of the periodic volume:

    P = -F . d                          (F the particles' force on the tool; compression > 0)
    e = target(t) - P_filtered
    v = rate * clip((e + int e dt / integral_time) / band, -1, 1)     (along d)

The compact's force responds to the tool's displacement (an integrating plant): at a constant
target the error decays with the time constant band / (K rate), K the compact's stiffness (N/mm).
``filter_time`` low-passes the measured force (the explicit pseudo-dynamics make it ring).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np


@dataclass
class ForceServo:
    """Drive a tool along ``direction`` (unit, the pressing direction) so that the particles press
    on it with ``target(t)`` (N, compression > 0): speed at most ``rate`` (mm/s), proportional band
    ``band`` (N), optional integral time (s) and filter time (s) of the measured force."""

    target: Callable[[float], float]
    direction: tuple[float, float, float]
    rate: float
    band: float
    integral_time: float | None = None
    filter_time: float = 0.0
    #: the servo's state: filtered force (N, NaN before the first update) and error integral
    state: np.ndarray = field(default_factory=lambda: np.array([np.nan, 0.0]))

    def __post_init__(self):
        d = np.asarray(self.direction, dtype=float)
        if d.shape != (3,) or not np.isfinite(d).all() or np.linalg.norm(d) == 0:
            raise ValueError(f"servo direction = {self.direction} must be a non-zero vector")
        self.direction = tuple(d / np.linalg.norm(d))
        for name, low in (("rate", 0.0), ("band", 0.0)):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > low):
                raise ValueError(f"servo {name} = {value!r} is out of range: must be > 0")
        if self.integral_time is not None and not self.integral_time > 0:
            raise ValueError(f"servo integral_time = {self.integral_time!r} must be > 0 s")
        if not self.filter_time >= 0:
            raise ValueError(f"servo filter_time = {self.filter_time!r} must be >= 0 s")

    def step(self, t: float, dt: float, force: np.ndarray) -> np.ndarray:
        """The tool's displacement (3,) (mm) over the next increment ``dt`` (s) from the particles'
        force on it ``force`` (3,) (N) at time ``t`` (s)."""
        d = np.asarray(self.direction)
        pressing = -float(np.dot(force, d))
        filtered, integral = self.state
        if np.isnan(filtered) or self.filter_time == 0.0:
            filtered = pressing
        else:
            filtered += min(dt / self.filter_time, 1.0) * (pressing - filtered)
        error = self.target(t) - filtered
        drive = error + (integral / self.integral_time if self.integral_time else 0.0)
        command = float(np.clip(drive / self.band, -1.0, 1.0))
        if self.integral_time and abs(drive / self.band) < 1.0:  # anti-windup
            integral += error * dt
        self.state = np.array([filtered, integral])
        return self.rate * command * dt * d
