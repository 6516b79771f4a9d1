"""Relaxation damping of the explicit solver (towards the quasi-static path), on the peculiar
velocity w' = P v_red (the motion relative to the moving offsets g(t), e.g. the homogeneous flow
of a comoving granular cell):

- viscous: f_d = c M w' (``ExplicitSettings.damping`` = c, 1/s), node by node or on each body's
  mean (rigid) peculiar velocity;
- local non-viscous: -alpha |F| sign(w') (``ExplicitSettings.local_damping`` = alpha in [0, 1),
  the local damping of DEM codes, FLAC's static solution scheme), F the out-of-balance force,
  per body or per free reduced dof: it removes a share of every oscillation's energy and
  vanishes with the acceleration, so that a steady motion is not resisted.

Both dissipate into E_damp (:mod:`.energy`). Forces in N (driving-force convention of the
explicit solver's sum f_int + f_bv + f_cont + f_d, which the acceleration opposes), masses in t,
velocities in mm/s.
"""

from __future__ import annotations

from contextlib import nullcontext

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc


class RelaxationDamping:
    """The viscous (``viscous`` = c, 1/s) and local non-viscous (``local`` = alpha) damping of the
    constrained model ``constraint`` (``constraints.AffineConstraint``) over the ranks of
    ``comm``. ``bodies``: body id of every owned node, or None (node by node); id -1 a node left
    undamped (a body whose rigid motion is imposed). ``lifted``: a full-dof work vector (the
    problem's layout); ``timings``: a phase timer (the solver's), whose "constraints" phase
    gets the constraint products."""

    def __init__(
        self,
        viscous: float,
        local: float,
        constraint,
        comm: MPI.Comm,
        lifted: PETSc.Vec,
        bodies: np.ndarray | None = None,
        timings=None,
    ):
        self.viscous = viscous
        self.local = local
        self.constraint = constraint
        self.comm = comm
        self.bodies = None if bodies is None else np.asarray(bodies, dtype=np.int64)
        self._lifted = lifted
        self._timings = timings
        if self.bodies is not None:
            self._num_bodies = comm.allreduce(int(self.bodies.max(initial=-1)) + 1, op=MPI.MAX)
            # undamped nodes (-1) point past the last body: a bin dropped from the sums, a zero
            # row when lifted
            self._body_index = np.where(self.bodies >= 0, self.bodies, self._num_bodies)

    @property
    def active(self) -> bool:
        """Whether either damping acts."""
        return self.viscous > 0 or self.local > 0

    def _phase(self, name: str):
        return self._timings(name) if self._timings is not None else nullcontext()

    def viscous_force(self, mass: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """f_d = c M w' (N) on the owned dofs, for the nodal ``mass`` (t, one per owned node) and
        the peculiar ``velocity`` w' (owned dofs): node by node, or per body on its mean peculiar
        velocity less the mass-weighted mean of all bodies (momentum conserved, a rigid
        translation of the whole not resisted, the bodies' deformation not resisted)."""
        v = velocity.reshape(-1, 3)
        if self.bodies is not None:
            sums = self._body_sums(np.column_stack([mass, mass[:, None] * v]))
            body_mass = sums[:, 0]
            v_body = sums[:, 1:4] / np.where(body_mass > 0, body_mass, 1.0)[:, None]
            if body_mass.sum() > 0:
                v_body -= (body_mass @ v_body) / body_mass.sum()
            v = self._on_nodes(v_body)
        return (self.viscous * mass[:, None] * v).ravel()

    def local_force(
        self,
        force: np.ndarray,
        r_red: PETSc.Vec,
        v_red: PETSc.Vec,
        dof_mass: np.ndarray,
        mass_red: PETSc.Vec,
        velocity: np.ndarray,
        scratch: PETSc.Vec,
        reference: np.ndarray | None = None,
    ) -> np.ndarray:
        """The local non-viscous damping force (N, owned dofs, driving-force convention) for the
        sum of the other forces ``force`` (owned dofs) and its reduction ``r_red`` = P^T force;
        adds its reduction to ``r_red``. ``dof_mass``: lumped mass per owned dof (t), ``mass_red``
        the reduced one, ``velocity`` the peculiar velocity w' (owned dofs), ``v_red`` the
        reduced velocity, ``scratch`` a reduced work vector (overwritten).

        With bodies: per body b and direction, -alpha |F_b| sign(W_b) against the body's mean
        peculiar velocity W_b, F_b the body's out-of-balance force (sum of -force over its nodes,
        tied copy nodes included), spread over the nodes in proportion to their mass; the
        mass-weighted mean is removed (no net force on the volume). Without bodies: on every free
        reduced dof, d = alpha |r_red| sign(v_red - v_ref), lifted to the full dofs as M P (d /
        m_red); ``reference`` v_ref (reduced dofs, default 0): the velocity the damping does not
        resist (a tool-driven volume's homogeneous flow between its tools)."""
        alpha = self.local
        n = self.constraint.num_owned
        if self.bodies is not None:
            m = dof_mass.reshape(-1, 3)[:, 0]
            sums = self._body_sums(
                np.column_stack([m, -force.reshape(-1, 3), m[:, None] * velocity.reshape(-1, 3)])
            )
            mass, push, momentum = sums[:, 0], sums[:, 1:4], sums[:, 4:7]
            d_body = -alpha * np.abs(push) * np.sign(momentum)  # driving-force convention
            if mass.sum() > 0:  # none when every body's motion is imposed (GDH)
                d_body -= mass[:, None] * (d_body.sum(axis=0) / mass.sum())
            per_mass = d_body / np.where(mass > 0, mass, 1.0)[:, None]
            lifted = -(m[:, None] * self._on_nodes(per_mass)).ravel()  # force convention
            with self._phase("constraints"):
                self._lifted.array_w[:n] = lifted
                self.constraint.restrict(self._lifted, scratch)
        else:
            if reference is not None and reference.size != v_red.array_r.size:
                raise ValueError(
                    f"damping reference: {reference.size} values for {v_red.array_r.size} "
                    "reduced dofs (an unconstrained model's owned dofs)"
                )
            relative = v_red.array_r if reference is None else v_red.array_r - reference
            scratch.array_w[:] = alpha * np.abs(r_red.array_r) * np.sign(relative)
            scaled = scratch.duplicate()
            scaled.pointwiseDivide(scratch, mass_red)
            with self._phase("constraints"):
                self.constraint.P.mult(scaled, self._lifted)
            scaled.destroy()
            lifted = self._lifted.array_r[:n] * dof_mass
        r_red.axpy(1.0, scratch)
        return lifted

    def _body_sums(self, values: np.ndarray) -> np.ndarray:
        """(num_bodies, k) sums over the ranks of per-node ``values`` (owned nodes, (n_nodes, k))
        by damped body."""
        nb = self._num_bodies
        sums = np.stack(
            [
                np.bincount(self._body_index, weights=values[:, j], minlength=nb + 1)[:nb]
                for j in range(values.shape[1])
            ],
            axis=1,
        )
        return self.comm.allreduce(sums, op=MPI.SUM)

    def _on_nodes(self, per_body: np.ndarray) -> np.ndarray:
        """(n_nodes, k) rows of a per-body array at every owned node (zero on undamped nodes)."""
        return np.vstack([per_body, np.zeros((1, per_body.shape[1]))])[self._body_index]
