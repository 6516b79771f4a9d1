"""The process' thread rules for the numerical libraries, applied once by :func:`configure_runtime`.

Importing :mod:`mpfem_fenicsx` changes nothing in the process. The command line calls
:func:`configure_runtime` first thing, and every solver's constructor calls it (collectively
on the solver's communicator), so that demos and workflows get the same rules without a call:

- BLAS (OpenBLAS, which numpy, scipy and PETSc each load): one thread per process. The hot
  loops are numba kernels and PETSc; BLAS only sees vector dot products and norms, and its
  threads oversubscribe the cores of MPI ranks (a 300 000-entry dot took 12 ms with two BLAS
  threads on a busy 2-core node, 0.3 ms with one). A threaded dot also sums in another order,
  so the thread count shows in the last bits of the energies. OpenBLAS reads
  OPENBLAS_NUM_THREADS once, when it is loaded: the variable is set for the libraries not loaded
  yet (and for child processes), and the ones already loaded are told through their
  ``openblas_set_num_threads``. An exported OPENBLAS_NUM_THREADS is left as it is.
- numba's parallel kernels (material update, contact): the cores of this node shared between
  the MPI ranks of ``comm`` on it, max(1, min(NUMBA_NUM_THREADS, cores // ranks on the node)), so
  that 2 ranks on 2 cores do not run 2 threads each. An exported NUMBA_NUM_THREADS is left as it
  is. A stage that runs on one rank while the others sleep may raise it again
  (``numba.set_num_threads``).

Call it first with the widest communicator of the run: a workflow that splits its communicator
before it builds a solver calls ``configure_runtime(comm)`` itself beforehand, else the first
solver's (smaller) communicator decides the share.

The FE stack needs no import order from this package: dolfinx's and petsc4py's compiled modules
need the environment's libmpi.so.12, which mpi4py.MPI loads (``from mpi4py import MPI`` ahead of
them, or ``scripts/bootstrap.sh``'s start-up line, which loads it in any import order).
"""

from __future__ import annotations

import ctypes
import os
from dataclasses import dataclass
from pathlib import Path

#: names of the thread setter in the OpenBLAS builds in use (upstream, numpy's 64-bit-integer
#: build and scipy's build of it)
_BLAS_SETTERS = (
    "openblas_set_num_threads",
    "scipy_openblas_set_num_threads64_",
    "scipy_openblas_set_num_threads",
)


@dataclass(frozen=True)
class RuntimeThreads:
    """What :func:`configure_runtime` applied: the BLAS threads per process (None: an exported
    OPENBLAS_NUM_THREADS left to the libraries), the numba threads (None: an exported
    NUMBA_NUM_THREADS left to numba) and the OpenBLAS libraries told at run time."""

    blas: int | None
    numba: int | None
    blas_libraries: tuple[str, ...] = ()


_applied: RuntimeThreads | None = None


def configure_runtime(comm=None) -> RuntimeThreads:
    """Apply the thread rules of this module's docstring once per process (later calls return
    the first call's result and change nothing). Collective on ``comm`` (an mpi4py
    communicator; default MPI.COMM_WORLD) the first time, unless NUMBA_NUM_THREADS is exported."""
    global _applied
    if _applied is not None:
        return _applied
    blas, libraries = None, ()
    if "OPENBLAS_NUM_THREADS" not in os.environ:
        blas = 1
        os.environ["OPENBLAS_NUM_THREADS"] = str(blas)
        libraries = _limit_loaded_openblas(blas)
    numba_threads = None if "NUMBA_NUM_THREADS" in os.environ else _share_numba_threads(comm)
    _applied = RuntimeThreads(blas, numba_threads, libraries)
    return _applied


def _share_numba_threads(comm) -> int:
    """numba's threads: this node's cores shared between the ranks of ``comm`` on it."""
    import numba
    from mpi4py import MPI

    comm = MPI.COMM_WORLD if comm is None else comm
    node = comm.Split_type(MPI.COMM_TYPE_SHARED)
    try:
        cores = len(os.sched_getaffinity(0))
        threads = max(1, min(numba.config.NUMBA_NUM_THREADS, cores // node.size))
    finally:
        node.Free()
    numba.set_num_threads(threads)
    return threads


def _loaded_openblas() -> list[str]:
    """Paths of the OpenBLAS libraries mapped into this process (Linux; elsewhere none)."""
    maps = Path("/proc/self/maps")
    if not maps.exists():
        return []
    lines = maps.read_text().splitlines()
    paths = {line.split()[-1] for line in lines if "openblas" in line.rsplit("/", 1)[-1]}
    return sorted(p for p in paths if p.startswith("/") and ".so" in p)


def _limit_loaded_openblas(threads: int) -> tuple[str, ...]:
    """Tell every OpenBLAS already loaded to use ``threads`` threads; the libraries told."""
    told = []
    for path in _loaded_openblas():
        library = ctypes.CDLL(path)  # the loaded copy (the loader counts a reference)
        names = [name for name in _BLAS_SETTERS if hasattr(library, name)]
        setter = getattr(library, names[0]) if names else None
        if setter is not None:
            setter(ctypes.c_int(threads))
            told.append(path)
    return tuple(told)
