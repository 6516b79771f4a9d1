"""mpfem-fenicsx: multi-particle finite element method for powder compaction on DOLFINx.

Units: mm, N, MPa, s, t/mm^3. Reported stresses and contact pressures: compression > 0.
"""

import dolfinx_solver  # noqa: F401  (orders mpi4py ahead of dolfinx / petsc4py)

__version__ = "0.1.0"
