"""Rigid tools' motions: translations prescribed in time (mm, s).

A motion is a callable ``t -> (3,)`` translation of the tool from its reference placement.
:class:`KeyframePath` is the sequence of the field's set-ups (pressing, hold, unloading,
ejection): the tool stops at each keyframe and moves between consecutive ones by Abaqus' SMOOTH
STEP (zero velocity and acceleration at both ends), at a constant speed reached and left by
smooth ramps (``ramp``: a press's punch; the homogeneous flow it drives has no acceleration
between the ramps, so a volume moved by contact carries no inertia force there), or linearly.
Force-controlled tools are driven by a servo instead (:mod:`.servo`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..loading.amplitude import SmoothStep


@dataclass(frozen=True)
class KeyframePath:
    """The tool at ``positions[i]`` (mm, translation from its reference placement) at
    ``times[i]`` (s, increasing), moving between consecutive keyframes by a smooth step (or
    linearly with ``smooth=False``, or at a constant speed with ``ramp`` r in (0, 0.5]: the
    speed rises as (1 - cos(pi tau / r)) / 2 over the first r of the segment's time, stays, and
    falls likewise over the last r); before the first keyframe at its first position, after the
    last at its last."""

    times: tuple[float, ...]
    positions: tuple[tuple[float, float, float], ...]
    smooth: bool = True
    ramp: float | None = None

    def __post_init__(self):
        t = np.asarray(self.times, dtype=float)
        p = np.asarray(self.positions, dtype=float)
        if t.ndim != 1 or t.size == 0 or not np.all(np.isfinite(t)):
            raise ValueError(
                f"motion times = {list(self.times)} must be a non-empty list of numbers"
            )
        if np.any(np.diff(t) <= 0):
            raise ValueError(f"motion times = {list(t)} must increase strictly")
        if p.shape != (t.size, 3) or not np.all(np.isfinite(p)):
            raise ValueError(
                f"motion positions must be {t.size} finite (x, y, z) translations, one per time"
            )
        if self.ramp is not None and not 0.0 < self.ramp <= 0.5:
            raise ValueError(f"motion ramp = {self.ramp!r} is out of range: must be in (0, 0.5]")

    def __call__(self, t: float) -> np.ndarray:
        """Translation (3,) (mm) at time ``t`` (s)."""
        times = self.times
        p = np.asarray(self.positions, dtype=float)
        if t <= times[0]:
            return p[0].copy()
        if t >= times[-1]:
            return p[-1].copy()
        i = int(np.searchsorted(times, t, side="right")) - 1
        tau = (t - times[i]) / (times[i + 1] - times[i])
        if self.ramp is not None:
            a = ramped(tau, self.ramp)
        elif self.smooth:
            a = SmoothStep(times[i + 1], times[i])(t)
        else:
            a = tau
        return p[i] + a * (p[i + 1] - p[i])


def ramped(tau: float, r: float) -> float:
    """The travelled fraction at the time fraction ``tau`` in [0, 1] of a constant-speed move
    whose speed rises and falls over the fractions ``r`` at its ends by half cosines (the speed
    1 / (1 - r) between the ramps)."""

    def rising(x: float) -> float:  # the integral of (1 - cos(pi s / r)) / 2 from 0 to x
        return 0.5 * x - r / (2 * np.pi) * np.sin(np.pi * x / r)

    if tau <= r:
        s = rising(tau)
    elif tau <= 1.0 - r:
        s = 0.5 * r + (tau - r)
    else:
        s = (1.0 - r) - rising(1.0 - tau)
    return s / (1.0 - r)


def fixed(t: float) -> np.ndarray:
    """The motion of a tool that stays in place."""
    return np.zeros(3)
