"""Affine constraints u_full = P u_reduced + g as an explicit PETSc matrix (dolfinx_mpc idea,
but as a layer *outside* assembly so that custom contact terms can be reduced the same way).

Reduced operators: K_red = P^T K P (``Mat.PtAP``), r_red = P^T r, lumped reduced mass
M_red = P^T (M * (P 1)) (row-sum lumping of P^T M P). Prescribed (Dirichlet) dofs are rows of P
with no entry and their value in g; multipoint couplings (periodic ties, distributing couplings)
are rows with several entries and arrive with the granular-volume capability.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx


class AffineConstraint:
    """u = P u_red + g on the (blocked, unrolled) dofs of a vector space ``V``.

    Args:
        V: the displacement space.
        prescribed_dofs: local unrolled dof indices (block * bs + component) whose value is
            prescribed through :attr:`g`; ghosts are ignored (their owner constrains them).
    """

    def __init__(self, V: dolfinx.fem.FunctionSpace, prescribed_dofs: np.ndarray):
        self.V = V
        comm = V.mesh.comm
        imap = V.dofmap.index_map
        bs = V.dofmap.index_map_bs
        self.num_owned = imap.size_local * bs
        dofs = np.unique(np.asarray(prescribed_dofs, dtype=np.int64))
        self.prescribed = dofs[dofs < self.num_owned].astype(np.int32)
        free = np.ones(self.num_owned, dtype=bool)
        free[self.prescribed] = False
        self.free = np.flatnonzero(free).astype(np.int32)
        n_red = self.free.size
        offset = comm.exscan(n_red) or 0
        self.num_reduced_global = comm.allreduce(n_red, op=MPI.SUM)
        self.reduced_range = (offset, offset + n_red)
        global_offset = imap.local_range[0] * bs

        indptr = np.zeros(self.num_owned + 1, dtype=PETSc.IntType)
        indptr[1:] = np.cumsum(free)
        cols = (offset + np.arange(n_red)).astype(PETSc.IntType)
        self.P = PETSc.Mat().createAIJ(
            ((self.num_owned, imap.size_global * bs), (n_red, self.num_reduced_global)),
            csr=(indptr, cols, np.ones(n_red)), comm=comm)
        self.P.assemble()
        self._global_offset = global_offset
        self.g = dolfinx.fem.Function(V, name="prescribed")

    # -- vectors ------------------------------------------------------------------------------
    def create_reduced_vector(self) -> PETSc.Vec:
        return self.P.createVecRight()

    def set_prescribed(self, values: np.ndarray) -> None:
        """Values (mm) of the prescribed dofs, in the order of :attr:`prescribed`."""
        self.g.x.array[self.prescribed] = values
        self.g.x.scatter_forward()

    def expand(self, x_red: PETSc.Vec, out: dolfinx.fem.Function, with_offset: bool = True) -> None:
        """out = P x_red (+ g), ghosts updated."""
        self.P.mult(x_red, out.x.petsc_vec)
        if with_offset:
            out.x.array[: self.num_owned] += self.g.x.array[: self.num_owned]
        out.x.scatter_forward()

    def restrict(self, full: PETSc.Vec, out: PETSc.Vec) -> None:
        """out = P^T full (full must be assembled: ghost contributions already added)."""
        self.P.multTranspose(full, out)

    def reduce_values(self, u: dolfinx.fem.Function, out: PETSc.Vec) -> None:
        """Reduced coordinates of a Function that satisfies the constraint (injection P^T u)."""
        self.P.multTranspose(u.x.petsc_vec, out)

    def reduced_lumped_mass(self, mass: dolfinx.fem.Function) -> PETSc.Vec:
        """Row-sum lumped P^T M P: M_red = P^T (M * (P 1))."""
        ones = self.create_reduced_vector()
        ones.set(1.0)
        p1 = self.P.createVecLeft()
        self.P.mult(ones, p1)
        p1.pointwiseMult(p1, mass.x.petsc_vec)
        m_red = self.create_reduced_vector()
        self.P.multTranspose(p1, m_red)
        ones.destroy()
        p1.destroy()
        return m_red

    def reduce_matrix(self, K: PETSc.Mat, result: PETSc.Mat | None = None) -> PETSc.Mat:
        """P^T K P (reusing ``result``'s nonzero pattern when given)."""
        if result is None:
            return K.PtAP(self.P)
        K.PtAP(self.P, result=result)
        return result
