"""mpfem-fenicsx: multi-particle finite element method for powder compaction on DOLFINx.

Units: mm, N, MPa, s, t/mm^3. Reported stresses and contact pressures: compression > 0.
"""

import os

# One OpenBLAS thread per process, set before numpy loads it: the hot loops are numba kernels
# and PETSc, BLAS only sees vector dot products, and its threads oversubscribe the cores of
# MPI ranks (a 300k-entry dot took 6 ms instead of 0.1 ms with 2 ranks on 2 cores). Override by
# exporting OPENBLAS_NUM_THREADS.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import dolfinx_solver  # noqa: E402, F401  (orders mpi4py ahead of dolfinx / petsc4py)
from mpi4py import MPI  # noqa: E402

# The numba kernels (material update, contact) run parallel loops: share the cores between the
# MPI ranks of this node instead of letting every rank use one thread per core (2 ranks x 2
# threads on 2 cores oversubscribe, and idle worker threads spin). A stage that runs on one rank
# while the others sleep may raise it again (numba.set_num_threads, up to NUMBA_NUM_THREADS).
import numba  # noqa: E402

if "NUMBA_NUM_THREADS" not in os.environ:
    _node = MPI.COMM_WORLD.Split_type(MPI.COMM_TYPE_SHARED)
    numba.set_num_threads(max(1, min(numba.config.NUMBA_NUM_THREADS, len(os.sched_getaffinity(0)) // _node.size)))
    _node.Free()
