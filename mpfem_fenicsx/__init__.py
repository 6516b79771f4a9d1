"""mpfem-fenicsx: multi-particle finite element method for powder compaction on DOLFINx.

Units: mm, N, MPa, s, t/mm^3. Reported stresses and contact pressures: compression > 0.

Importing the package has no side effect: no MPI, no FE stack, no environment variable, no
thread setting. The thread rules of a run are :func:`mpfem_fenicsx.runtime.configure_runtime`,
which the command line and every solver apply.
"""
