"""Die compaction ("matrice", uniaxial strain along z) of a periodic volume of lead particles.

    python demos/die.py                             # embedded default: 24 particles, CLP, rho -> 0.92
    python demos/die.py --particles 50 --target-density 0.95 --bc GDF

Same pipeline and outputs as demos/isotropic.py (see there), in results/die/ by default.
"""

from mpfem_fenicsx.cli.compaction import main

if __name__ == "__main__":
    main("die", __doc__)
