"""Rigid tools' motions: translations prescribed in time (mm, s).

A motion is a callable ``t -> (3,)`` translation of the tool from its reference placement.
:class:`KeyframePath` is the sequence of the field's set-ups (pressing, hold, unloading,
ejection): the tool stops at each keyframe and moves between consecutive ones by Abaqus' SMOOTH
STEP (zero velocity and acceleration at both ends, which keeps explicit runs quasi-static), or
linearly. Force-controlled tools are driven by a servo instead (:mod:`.servo`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..loading.amplitude import SmoothStep


@dataclass(frozen=True)
class KeyframePath:
    """The tool at ``positions[i]`` (mm, translation from its reference placement) at
    ``times[i]`` (s, increasing), moving between consecutive keyframes by a smooth step (or
    linearly with ``smooth=False``); before the first keyframe at its first position, after the
    last at its last."""

    times: tuple[float, ...]
    positions: tuple[tuple[float, float, float], ...]
    smooth: bool = True

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

    def __call__(self, t: float) -> np.ndarray:
        """Translation (3,) (mm) at time ``t`` (s)."""
        times = self.times
        p = np.asarray(self.positions, dtype=float)
        if t <= times[0]:
            return p[0].copy()
        if t >= times[-1]:
            return p[-1].copy()
        i = int(np.searchsorted(times, t, side="right")) - 1
        a = (
            SmoothStep(times[i + 1], times[i])(t)
            if self.smooth
            else (t - times[i]) / (times[i + 1] - times[i])
        )
        return p[i] + a * (p[i + 1] - p[i])


def fixed(t: float) -> np.ndarray:
    """The motion of a tool that stays in place."""
    return np.zeros(3)
