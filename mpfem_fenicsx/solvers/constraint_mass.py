"""The consistent reduced mass of a constrained model, P^T M P, and its solve (explicit solver).

With u = P x + g (``constraints.AffineConstraint``) and the lumped nodal masses M (diagonal, t),
the reduced equations of motion are P^T M P a = r. Row-sum lumping (the explicit solver's
default) replaces P^T M P by the diagonal |P|^T M |P|, which hands each eliminated node's mass to
every one of its masters. The consistent matrix keeps the particles' own inertia. P's rows are the
free dofs (one entry 1) and the slaves (their masters' coefficients C), so
    P^T M P = D + C^T M_s C        (D: the free dofs' masses, M_s: the slaves')
and, by the Woodbury identity, over the slaves that carry mass,
    (P^T M P)^-1 = D^-1 - D^-1 C^T S^-1 C D^-1,   S = M_s^-1 + C D^-1 C^T,
where S has one row per massive slave and couples only the slaves that share masters (a CLPS
copy's pivots with those of the other copies of its original): a small matrix, factorized once
per mass change (MUMPS' Cholesky, distributed under MPI); a solve costs two products with C.
"""

from __future__ import annotations

import numpy as np
from petsc4py import PETSc

#: the explicit solver's reduced masses of a constrained model
#: (``ExplicitSettings.constraint_mass``)
CONSTRAINT_MASSES = ("lumped", "consistent")


class ConsistentReducedMass:
    """Solves P^T M P a = r (:meth:`solve`) for the constraint's P (``AffineConstraint``) and the
    nodal masses ``mass`` (t, the owned unrolled dofs, a dolfinx Function's array)."""

    def __init__(self, constraint, mass: np.ndarray):
        P = constraint.P
        comm = P.getComm()
        mass = np.asarray(mass)[: constraint.num_owned]
        self._inverse_free = constraint.create_reduced_vector()  # D^-1
        self._inverse_free.array_w[:] = 1.0 / mass[constraint.free]
        massive = np.sort(constraint.slaves[mass[constraint.slaves] > 0.0])
        self.num_slaves = comm.tompi4py().allreduce(massive.size)
        self._ksp = None
        if not self.num_slaves:
            return
        row_start = P.getOwnershipRange()[0]
        rows = PETSc.IS().createGeneral((row_start + massive).astype(PETSc.IntType), comm=comm)
        lo, hi = constraint.reduced_range
        columns = PETSc.IS().createStride(hi - lo, first=lo, step=1, comm=comm)
        self._C = P.createSubMatrix(rows, columns)
        scaled = self._C.copy()
        scaled.diagonalScale(R=self._inverse_free)
        self._S = scaled.matTransposeMult(self._C)  # C D^-1 C^T
        scaled.destroy()
        inverse_slave = self._S.createVecLeft()
        inverse_slave.array_w[:] = 1.0 / mass[massive]
        self._S.setDiagonal(self._S.getDiagonal() + inverse_slave)
        rows.destroy()
        columns.destroy()
        ksp = PETSc.KSP().create(comm)
        ksp.setOperators(self._S)
        ksp.setType(PETSc.KSP.Type.PREONLY)
        pc = ksp.getPC()
        pc.setType(PETSc.PC.Type.CHOLESKY)
        pc.setFactorSolverType("mumps")
        ksp.setUp()
        self._ksp = ksp
        self._y, self._z = self._S.createVecs()
        self._w = self._inverse_free.duplicate()

    def solve(self, r: PETSc.Vec, a: PETSc.Vec) -> None:
        """a = (P^T M P)^-1 r (reduced vectors)."""
        a.pointwiseMult(r, self._inverse_free)
        if self._ksp is None:
            return
        self._C.mult(a, self._y)
        self._ksp.solve(self._y, self._z)
        if self._ksp.getConvergedReason() <= 0:
            raise RuntimeError(
                f"consistent reduced mass: the Cholesky solve failed "
                f"(KSP reason {self._ksp.getConvergedReason()})"
            )
        self._C.multTranspose(self._z, self._w)
        self._w.pointwiseMult(self._w, self._inverse_free)
        a.axpy(-1.0, self._w)

    def destroy(self) -> None:
        """Free the PETSc objects (solver, matrices, work vectors) this mass holds."""
        for name in ("_ksp", "_S", "_C", "_y", "_z", "_w", "_inverse_free"):
            obj = getattr(self, name, None)
            if obj is not None:
                obj.destroy()
