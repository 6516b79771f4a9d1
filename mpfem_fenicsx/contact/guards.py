"""Guards of Newton's iterations on the adhesive contact law (thesis §3.3).

The adhesive law has a fold (softening steeper than a surface node's stiffness) and a kink at
gap = 0 for a virgin point: on a soft substrate Newton's iterates cycle between adhered and
separated, or between open and closed, at the rim of a contact. :class:`AdhesiveGuards` keeps
what the iterates of one increment did to each contact point (keyed as in
:class:`~mpfem_fenicsx.contact.model.ContactModel`) and makes those changes irreversible within
the increment: held softening slope, snap-off of a cycling point, snap-in. It is reset at the
start of every increment (and after a cut-back).
"""

from __future__ import annotations

import numpy as np

from .kernels import lookup
from .laws import ADHESIVE_LOADING, OVERLAP, SOFTENING, normal_branch


class AdhesiveGuards:
    """The adhesive points' bookkeeping over the iterates of an increment (arrays of keys)."""

    def __init__(self) -> None:
        #: whether a point cycling a third time snaps off (True) or is only recorded in
        #: :attr:`refused` (False: the caller cuts the increment back instead; a Newton solver
        #: allows the snap on short increments only)
        self.snap_allowed = True
        self.reset()

    def reset(self) -> None:
        """Forget the iterates: a new increment (or a cut-back) starts from the committed state."""
        #: keys of the points snapped off in the current increment (their softening cycled):
        #: their adhesive memory is erased for the rest of the increment
        self.separated = np.zeros(0, np.int64)
        #: keys of the points that cycled a third time while :attr:`snap_allowed` was False
        self.refused = np.zeros(0, np.int64)
        #: keys of the points that iterates of this increment moved from softening back to the
        #: adhesive loading line or into overlap at least once / at least twice, and the
        #: (sorted) keys / branch codes of the last evaluation
        self.returned = np.zeros(0, np.int64)
        self.returned_twice = np.zeros(0, np.int64)
        self.last = (np.zeros(0, np.int64), np.zeros(0, np.int64))
        #: snap-in: keys of virgin points that an iterate of this increment moved out of overlap,
        #: and the keys (sorted) / compressive tractions (MPa) of those armed on re-entering it
        self.left = np.zeros(0, np.int64)
        self.armed = (np.zeros(0, np.int64), np.zeros(0))

    def adjust_history(self, keys: np.ndarray, alpha_n: np.ndarray, smax_n: np.ndarray) -> None:
        """The committed history ``alpha_n``, ``smax_n`` of the points ``keys`` as this increment's
        iterates left it (in place): snapped-in points armed, erased memories erased."""
        if self.armed[0].size:  # snapped in by an earlier iterate of this increment
            pos, known = lookup(self.armed[0], keys)
            smax_n[known] = np.maximum(smax_n[known], self.armed[1][pos[known]])
        if self.separated.size:  # memory erased by an earlier iterate of this increment
            gone = np.isin(keys, self.separated)
            alpha_n[gone], smax_n[gone] = 0.0, 0.0

    def track(
        self, keys: np.ndarray, branch: np.ndarray, smax_n: np.ndarray, T1: np.ndarray
    ) -> np.ndarray:
        """After the law at an iterate (branch codes ``branch``, normal tractions ``T1``): snap-in,
        then peeling; returns the mask of the points whose softening slope the tangent holds at
        zero."""
        self.track_snap_in(keys, branch, smax_n, T1)
        return self.track_peeling(keys, branch)

    def remember(self, sorted_keys: np.ndarray, sorted_branch: np.ndarray) -> None:
        """The branch codes of this iterate, for the next one."""
        self.last = (sorted_keys, sorted_branch)

    def track_peeling(self, keys: np.ndarray, branch: np.ndarray) -> np.ndarray:
        """Snap bookkeeping of the adhesive points over the iterates of an increment; returns the
        mask of the points whose softening slope the tangent holds at zero."""
        held = np.zeros(keys.size, np.bool_)
        # An iterate that carries an adhered point beyond delta_max erases nothing by itself:
        # the law gives it zero traction there, and its memory is erased only if the converged
        # state leaves it there (ContactModel.begin_increment), so an overshooting iterate of a
        # tensile reload does not tear the adhesion off a whole contact.
        # A point that the last iterate put on the softening branch and this one sends back
        # (gap < delta_1) is cycling: the negative softening slope, steeper than the node's
        # own stiffness on the substrate, made Newton aim back into the contact, and the
        # penalty sends it out again. When it re-enters softening, its tangent is held at zero
        # slope for that update, so that it carries a point past the fold of its adhered
        # branch beyond delta_max (memory erased, see ContactModel.begin_increment). A third
        # return (the coupled update of a rim of such points can still cycle) snaps the
        # point if snap_allowed: its memory is erased for the rest of the increment, as a
        # dynamic snap-off would; otherwise it is recorded (refused) and the caller cuts the
        # increment back. A point whose softening is stable converges on it with the exact slope
        # (quadratic); after a kink overshoot it is held for one update only.
        last_keys, last_branch = self.last
        if last_keys.size:
            pos, known = lookup(last_keys, keys)
            was_softening = known & (normal_branch(last_branch[pos]) == SOFTENING)
            softening = normal_branch(branch) == SOFTENING
            # not on to separation
            back = keys[was_softening & (normal_branch(branch) <= ADHESIVE_LOADING)]
            if back.size:
                third = back[np.isin(back, self.returned_twice)]
                if self.snap_allowed:
                    self.separated = np.union1d(self.separated, third)
                else:
                    self.refused = np.union1d(self.refused, third)
                self.returned_twice = np.union1d(
                    self.returned_twice, back[np.isin(back, self.returned)]
                )
                self.returned = np.union1d(self.returned, back)
            # held for the one update after it re-enters softening: if it stays there, its
            # softening is stable and the exact slope returns (quadratic, not linear, rate)
            reentered = known & (normal_branch(last_branch[pos]) <= ADHESIVE_LOADING) & softening
            if reentered.any() and self.returned.size:
                held = reentered & np.isin(keys, self.returned)
        return held

    def track_snap_in(
        self, keys: np.ndarray, branch: np.ndarray, smax_n: np.ndarray, T1: np.ndarray
    ) -> None:
        """Snap-in of the adhesive law at the edge of a growing contact.

        A virgin point (no memory) at the edge of a contact that grows on a soft (plastic)
        substrate can sit at the kink gap = 0 of the unilateral law: in overlap, the penalty
        pushes it out; out, it has no stiffness and the next iterate drives it back in (measured:
        the wedge two-sphere loading cycled with period 3 at one ring until the increment was cut
        to a few 1e-4 of the load). With adhesion the law has no kink there once the point has
        touched: the adhesive loading line continues the penalty line through gap = 0. So a
        virgin point that an iterate moves out of overlap and a later one moves back in is armed
        for the rest of the increment with the compressive traction of that re-entry as its
        memory sigma_max (alpha from it, or the forced alpha): it is adhered as it would be one
        increment later, and the edge converges on a smooth law. Points whose memory an iterate
        erased (:attr:`separated`) are not re-armed."""
        last_keys, last_branch = self.last
        if not last_keys.size:
            return
        pos, known = lookup(last_keys, keys)
        was_closed = known & (normal_branch(last_branch[pos]) == OVERLAP)
        closed = normal_branch(branch) == OVERLAP
        virgin = smax_n == 0.0
        if self.separated.size:
            virgin &= ~np.isin(keys, self.separated)
        left = keys[was_closed & ~closed & virgin]
        if left.size:
            self.left = np.union1d(self.left, left)
        back = known & ~was_closed & closed & virgin & np.isin(keys, self.left)
        if back.any():
            armed_keys = np.concatenate([self.armed[0], keys[back]])
            armed_smax = np.concatenate([self.armed[1], T1[back]])
            order = np.argsort(armed_keys)
            self.armed = (armed_keys[order], armed_smax[order])
