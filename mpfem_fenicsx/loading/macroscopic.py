"""Macroscopic loading paths F0(t) of a granular volume (thesis §2.5 and §4.2).

Compaction keeps the solid volume (plastic flow is isochoric, elastic change is small), so a
target relative density rho_f reached from rho_0 needs det F0 = rho_0 / rho_f:
- isotropic:  F0 = (rho_0 / rho_f)^(1/3) I,
- die ("matrice", uniaxial strain along e3): F0 = diag(1, 1, rho_0 / rho_f).
A path is a sequence of segments F = F_n ... F_2 F_1 (e.g. F_r F_d F_c: compaction, unloading,
reload), each applied with an amplitude a_k(t) on its logarithm, F_k(t) = exp(a_k(t) log G_k), so
that the Hencky strain rate is proportional to the amplitude's rate (zero at the knots): the smooth
step, or a constant rate between smooth ramps (loading.amplitude.PROFILES).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm, logm

from .amplitude import PROFILES

PATHS = ("isotropic", "die")


def compaction_gradient(path: str, rho_initial: float, rho_target: float) -> np.ndarray:
    """F0 (3, 3) taking the relative density from ``rho_initial`` to ``rho_target``."""
    if path not in PATHS:
        raise ValueError(f"loading must be one of {', '.join(PATHS)}, got {path!r}")
    if not 0.0 < rho_initial < 1.0:
        raise ValueError(f"initial relative density must be in (0, 1), got {rho_initial:.4f}")
    if not rho_initial < rho_target < 1.0:
        raise ValueError(
            f"target_density must be in ({rho_initial:.4f}, 1) (above the packing's "
            f"density, below full density), got {rho_target}"
        )
    ratio = rho_initial / rho_target
    if path == "isotropic":
        return ratio ** (1.0 / 3.0) * np.eye(3)
    return np.diag([1.0, 1.0, ratio])


def unload_gradient(h_v: float) -> np.ndarray:
    """Isotropic increment gradient F^d = exp(h_v / 3) I of volumetric Hencky strain ``h_v``
    (natural sign: h_v > 0 unloads a compact by expansion). The thesis writes it
    1 + zeta (1 - tr F^c) with zeta found by trial (eq. 4.7); the yield-surface workflow instead
    finds h_v for a prescribed residual mean stress."""
    return np.exp(h_v / 3.0) * np.eye(3)


def reload_gradient(phi: float, amplitude: float, axis: int = 2) -> np.ndarray:
    """Reload increment gradient F^r = diag(exp h^r) of thesis eq. 4.8-4.9 in direction ``phi``
    (rad) of the Rendulic strain plane, axis I = ``axis`` (default z, the die axis):
    h_I = -A (cos phi / 3 + sin phi), h_II = h_III = -A (cos phi / 3 - sin phi / 2), so that the
    compression-positive volumetric and signed deviatoric strains are A cos phi and A sin phi
    (h_v = -A cos phi, h~_d = -A sin phi in the natural sign of the histories): phi = 0 is
    isotropic compression, pi isotropic expansion, pi / 2 axial compression at constant volume."""
    if not amplitude > 0:
        raise ValueError(f"reload amplitude A must be > 0, got {amplitude}")
    if axis not in (0, 1, 2):
        raise ValueError(f"axis must be 0, 1 or 2, got {axis}")
    h = np.full(3, -amplitude * (np.cos(phi) / 3.0 - np.sin(phi) / 2.0))
    h[axis] = -amplitude * (np.cos(phi) / 3.0 + np.sin(phi))
    return np.diag(np.exp(h))


@dataclass
class GradientPath:
    """Piecewise smooth path of the macroscopic gradient, F0(0) = I (or ``start``).

    ``segments``: list of (duration s, increment gradient G_k (3, 3)); the gradient at the end
    of segment k is G_k ... G_1 start. ``profiles``: amplitude shape of each segment by name
    (loading.amplitude.PROFILES); segments beyond it use "smooth-step".
    """

    segments: list[tuple[float, np.ndarray]]
    start: np.ndarray = field(default_factory=lambda: np.eye(3))
    profiles: tuple[str, ...] = ()

    def __post_init__(self):
        for name in self.profiles:
            if name not in PROFILES:
                raise ValueError(f"profile must be one of {', '.join(PROFILES)}, got {name!r}")
        if len(self.profiles) > len(self.segments):
            raise ValueError(f"{len(self.profiles)} profiles for {len(self.segments)} segments")
        self._knots = [0.0]
        self._amplitudes = []
        self._logs = []
        self._ends = [np.asarray(self.start, dtype=float)]
        for k, (duration, G) in enumerate(self.segments):
            G = np.asarray(G, dtype=float)
            if not duration > 0:
                raise ValueError(f"segment {k}: duration must be > 0 s, got {duration}")
            if G.shape != (3, 3) or not np.linalg.det(G) > 0:
                raise ValueError(
                    f"segment {k}: increment gradient must be a 3x3 matrix with det > 0"
                )
            self._knots.append(self._knots[-1] + duration)
            shape = PROFILES[self.profiles[k] if k < len(self.profiles) else "smooth-step"]
            self._amplitudes.append(shape(self._knots[-1], self._knots[-2]))
            self._logs.append(np.real(logm(G)))
            self._ends.append(G @ self._ends[-1])

    @property
    def duration(self) -> float:
        """End time of the last segment (s)."""
        return self._knots[-1]

    @property
    def knots(self) -> list[float]:
        """Start and end times (s) of the segments: [0, t_1, ..., duration]."""
        return list(self._knots)

    def __call__(self, t: float) -> np.ndarray:
        """F0 (3, 3) at time ``t`` (s); held at the last segment's end after it."""
        k = int(np.searchsorted(self._knots, t, side="right")) - 1
        if k >= len(self.segments):
            return self._ends[-1].copy()
        k = max(k, 0)
        a = self._amplitudes[k](t)
        return expm(a * self._logs[k]) @ self._ends[k]
