"""The committed history of contact points: one row per point identifier (a key)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kernels import lookup


@dataclass
class ContactState:
    """History of the contact points, sorted by key."""

    keys: np.ndarray
    alpha: np.ndarray
    smax: np.ndarray
    tt: np.ndarray
    work: np.ndarray  # frictional work W_f per point, mJ

    @staticmethod
    def empty() -> ContactState:
        """No contact points."""
        return ContactState(
            np.zeros(0, np.int64), np.zeros(0), np.zeros(0), np.zeros((0, 3)), np.zeros(0)
        )

    def history_of(self, keys: np.ndarray) -> tuple[np.ndarray, ...]:
        """alpha, sigma_max, tangential traction, frictional work of the points ``keys`` (n,);
        an empty history for keys not in the state (new points)."""
        n = keys.size
        alpha, smax, work, tt = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros((n, 3))
        if self.keys.size:
            pos, known = lookup(self.keys, keys)
            alpha[known], smax[known] = self.alpha[pos[known]], self.smax[pos[known]]
            tt[known], work[known] = self.tt[pos[known]], self.work[pos[known]]
        return alpha, smax, tt, work
