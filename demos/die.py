"""Die compaction ("matrice", uniaxial strain along z) of a periodic volume of lead particles.

    python demos/die.py
        # embedded default: 24 particles, CLP, rho -> 0.92
    python demos/die.py --particles 50 --target-density 0.95 --bc GDF

Same pipeline, options and outputs as demos/isotropic.py (see there), in results/die/ by default.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the demos folder: isotropic.py's steps

from isotropic import main  # noqa: E402

if __name__ == "__main__":
    main(loading="die", doc=__doc__)
