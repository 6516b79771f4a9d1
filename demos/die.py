"""Die compaction ("matrice", uniaxial strain along z) of a periodic volume of lead particles.

    python demos/die.py                             # embedded default: 24 particles, CLP, rho -> 0.88
    python demos/die.py --particles 50 --target-density 0.95 --bc GDF

Same pipeline and outputs as demos/isotropic.py (see there), in results/die/ by default.

Known limit: with the default 4000 increments the explicit die run diverges near rho = 0.90
(kinetic energy builds up once the particles are strongly flattened along z); the default
stops at 0.88 until that is understood. More increments (--increments) slow the loading.
"""

from mpfem_fenicsx.cli.compaction import main

if __name__ == "__main__":
    main("die", __doc__)
