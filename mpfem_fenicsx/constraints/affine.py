"""Affine constraints u_full = P u_reduced + g as an explicit PETSc matrix (dolfinx_mpc idea,
but as a layer *outside* assembly so that custom contact terms can be reduced the same way).

Reduced operators: K_red = P^T K P (``Mat.PtAP``), r_red = P^T r, lumped reduced mass
M_red = |P|^T (M |P| 1), the row sums of |P|^T M |P| (M lumped): the usual row-sum lumping for
injections and ties; for a distributing coupling, which hands the slave's stiffness to all its
masters, it hands them the slave's mass in proportion, which keeps the explicit stable increment
of the unconstrained mesh (a diagonal lumping does not: measured divergence). Prescribed (Dirichlet)
dofs are rows of P with no entry and their value in g; multipoint couplings (periodic ties,
distributing couplings, ``CouplingRows``) are rows with several entries: u_s = sum_k c_k u_k + g_s,
the masters k being free dofs on any rank.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx


@dataclass
class CouplingRows:
    """Slave rows u[slave] = sum_k coefficients[k] u[masters[k]] + g[slave] (CSR by slave).

    ``slaves``: local owned unrolled dofs; ``masters``: *global* unrolled dof indices (any rank);
    masters must be free (neither prescribed nor slaves): chains are not resolved.
    """

    slaves: np.ndarray
    indptr: np.ndarray
    masters: np.ndarray
    coefficients: np.ndarray

    @staticmethod
    def empty() -> CouplingRows:
        """No couplings."""
        return CouplingRows(
            np.zeros(0, np.int32), np.zeros(1, np.int64), np.zeros(0, np.int64), np.zeros(0)
        )


def _reduced_index_of(
    comm: MPI.Comm, cols: np.ndarray, size_global: int, dofs: np.ndarray
) -> np.ndarray:
    """Reduced index (-1: not free) of global unrolled ``dofs`` of any rank, given each rank's
    ``cols`` (reduced index of its owned dofs): a PETSc scatter fetches only the dofs asked for,
    from their owners (point to point; indices < 2^53 are exact as doubles)."""
    owned = PETSc.Vec().createMPI((cols.size, size_global), comm=comm)
    owned.array_w[:] = cols
    wanted = PETSc.Vec().createSeq(dofs.size, comm=MPI.COMM_SELF)
    index_set = PETSc.IS().createGeneral(dofs.astype(PETSc.IntType), comm=MPI.COMM_SELF)
    scatter = PETSc.Scatter().create(owned, index_set, wanted, None)
    scatter.scatter(owned, wanted, PETSc.InsertMode.INSERT_VALUES, PETSc.ScatterMode.FORWARD)
    out = np.rint(wanted.array_r).astype(np.int64)
    for obj in (scatter, index_set, wanted, owned):
        obj.destroy()
    return out


class AffineConstraint:
    """u = P u_red + g on the (blocked, unrolled) dofs of a vector space ``V``.

    Args:
        V: the displacement space.
        prescribed_dofs: local unrolled dof indices (block * bs + component) whose value is
            prescribed through :attr:`g`; ghosts are ignored (their owner constrains them).
        couplings: multipoint rows (owned slaves), see :class:`CouplingRows`.
    """

    def __init__(
        self,
        V: dolfinx.fem.FunctionSpace,
        prescribed_dofs: np.ndarray,
        couplings: CouplingRows | None = None,
    ):
        self.V = V
        comm = V.mesh.comm
        imap = V.dofmap.index_map
        bs = V.dofmap.index_map_bs
        self.num_owned = imap.size_local * bs
        dofs = np.unique(np.asarray(prescribed_dofs, dtype=np.int64))
        self.prescribed = dofs[dofs < self.num_owned].astype(np.int32)
        couplings = couplings or CouplingRows.empty()
        self.couplings = couplings
        self.slaves = np.asarray(couplings.slaves, dtype=np.int32)
        if self.slaves.size and (
            self.slaves.max() >= self.num_owned
            or np.intersect1d(self.slaves, dofs).size
            or np.unique(self.slaves).size != self.slaves.size
        ):
            raise ValueError("coupling slaves must be distinct owned dofs that are not prescribed")
        free = np.ones(self.num_owned, dtype=bool)
        free[self.prescribed] = False
        free[self.slaves] = False
        self.free = np.flatnonzero(free).astype(np.int32)
        n_red = self.free.size
        offset = comm.exscan(n_red) or 0
        self.num_reduced_global = comm.allreduce(n_red, op=MPI.SUM)
        self.reduced_range = (offset, offset + n_red)

        # one row per owned dof: free -> its reduced index; prescribed -> empty; slave -> masters
        counts = free.astype(np.int64)
        cols = np.full(self.num_owned, -1, np.int64)
        cols[self.free] = offset + np.arange(n_red)
        vals_free = np.ones(n_red)
        if comm.allreduce(self.slaves.size, op=MPI.SUM):
            master_cols = _reduced_index_of(
                comm, cols, (imap.size_global * bs), np.asarray(couplings.masters, np.int64)
            )
            if np.any(master_cols < 0):
                raise ValueError("a coupling master dof is prescribed or itself a slave")
            counts[self.slaves] = np.diff(couplings.indptr)
        indptr = np.zeros(self.num_owned + 1, dtype=np.int64)
        indptr[1:] = np.cumsum(counts)
        columns = np.empty(indptr[-1], dtype=np.int64)
        values = np.empty(indptr[-1])
        columns[indptr[self.free]] = cols[self.free]
        values[indptr[self.free]] = vals_free
        if self.slaves.size:
            row_of_entry = np.repeat(np.arange(self.slaves.size), np.diff(couplings.indptr))
            position = (
                indptr[self.slaves[row_of_entry]]
                + np.arange(row_of_entry.size)
                - np.asarray(couplings.indptr)[row_of_entry]
            )
            columns[position] = master_cols
            values[position] = couplings.coefficients
        sizes = ((self.num_owned, imap.size_global * bs), (n_red, self.num_reduced_global))
        csr = (indptr.astype(PETSc.IntType), columns.astype(PETSc.IntType))
        self.P = PETSc.Mat().createAIJ(sizes, csr=(*csr, values), comm=comm)
        self.P.assemble()
        #: |P|, for the lumped reduced mass
        self._P_abs = PETSc.Mat().createAIJ(sizes, csr=(*csr, np.abs(values)), comm=comm)
        self._P_abs.assemble()
        self.g = dolfinx.fem.Function(V, name="prescribed")

    # -- vectors ------------------------------------------------------------------------------
    def create_reduced_vector(self) -> PETSc.Vec:
        """A PETSc vector of the reduced (free) unknowns."""
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
        """Reduced coordinates of a Function that satisfies the constraint: its free dofs minus
        their offsets (g may carry free dofs too, e.g. a comoving homogeneous flow)."""
        out.array[:] = u.x.array[self.free] - self.g.x.array[self.free]

    def reduced_lumped_mass(self, mass: dolfinx.fem.Function) -> PETSc.Vec:
        """Row-sum lumped |P|^T M |P| for a lumped M (t): M_red = |P|^T (M * (|P| 1))."""
        ones = self.create_reduced_vector()
        ones.set(1.0)
        p1 = self._P_abs.createVecLeft()
        self._P_abs.mult(ones, p1)
        p1.pointwiseMult(p1, mass.x.petsc_vec)
        m_red = self.create_reduced_vector()
        self._P_abs.multTranspose(p1, m_red)
        ones.destroy()
        p1.destroy()
        return m_red

    def set_values(self, dofs: np.ndarray, values: np.ndarray) -> None:
        """Offsets g (mm) of any owned dofs (prescribed, slave rows, or free dofs carried by a
        moving frame: u_free = x + g), ghosts updated."""
        self.g.x.array[dofs] = values
        self.g.x.scatter_forward()

    def reduce_matrix(self, K: PETSc.Mat, result: PETSc.Mat | None = None) -> PETSc.Mat:
        """P^T K P (reusing ``result``'s nonzero pattern when given)."""
        if result is None:
            return K.PtAP(self.P)
        K.PtAP(self.P, result=result)
        return result
