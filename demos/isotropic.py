"""Flagship demo: isotropic compaction of a periodic volume of lead particles (thesis chapter 2).

    python demos/isotropic.py                       # embedded default: 24 particles, CLP, rho -> 0.92
    python demos/isotropic.py --particles 50 --target-density 0.95 --bc CLP
    mpirun -n 2 python demos/isotropic.py --bc GDF

Pipeline: seeded frictionless packing (or --packing FILE) -> duplicated particles (d_bc rule,
thesis §2.2.1) -> one DOLFINx mesh of hexahedral cube-sphere particles -> Hencky/von Mises
bulk + penalty/Coulomb/adhesive contact -> GDH/GDF/CLPS/CLP as PETSc multipoint constraints
-> explicit central differences with mass scaling -> history and pictures.

Outputs in --out (default results/isotropic/): history.csv (time, rho, h_v, h_d, sigma_m,
sigma_d with compression > 0, F11..F33 from the least-squares fit, n_contacts, energies),
packing.txt (the packing used), particles.xdmf (ParaView: displacement, von Mises, eps_p,
particle id) and particles.png (deformed particles coloured by von Mises stress).
"""

from mpfem_fenicsx.cli.compaction import main

if __name__ == "__main__":
    main("isotropic", __doc__)
