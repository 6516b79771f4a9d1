"""Contact surface of every contact of the model against the volume's own, at a checkpoint of a
validation run (table 4.2: the thesis' footnote 4 of §4.4.1 sums S over "each contact
of the MPFEM model"; eq. 4.13 divides by the volume of the VEP).

    python validation/contact_surface.py die_GDF validation/runs/die_GDF/checkpoints/step0002100

Restarts the case from the checkpoint for one increment and prints S over the volume's
contacts (appendix-C weights), S over every contact of the model, their ratio, and both Gamma.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(
    0, str(Path(__file__).resolve().parents[1])
)  # the repository: the validation package

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

from mpfem_fenicsx.homogenization import contact_weights  # noqa: E402
from mpfem_fenicsx.workflows.compaction import CompactionRun  # noqa: E402
from validation.cases import STAGES  # noqa: E402


def main(name: str, checkpoint: str) -> None:
    """Print S (mm^2) of the volume's and of every contact, their ratio and both Gamma (1/mm)."""
    case = {c.name: c for cases in STAGES.values() for c in cases}[name].compaction_case(
        f"/tmp/contact_surface_{name}"
    )
    case.checkpoint_every = 0
    result = CompactionRun(case, MPI.COMM_WORLD, log=lambda *a, **k: None, restart=checkpoint).run(
        max_steps=1
    )
    model, solver = result.model, result.solver
    pf = model.contact.pair_forces()
    F0 = model.path(solver.t)
    cell = model.packing.cell
    image = np.rint(np.linalg.solve(F0, pf["shift"].T).T / cell).astype(np.int64)
    weights = contact_weights(
        pf["pairs"][:, 0], pf["pairs"][:, 1], model.original, model.shift, case.bc, image
    )
    volume = np.linalg.det(F0) * np.prod(cell)
    s_volume, s_model = float(np.sum(weights * pf["area"])), float(pf["area"].sum())
    if MPI.COMM_WORLD.rank == 0:
        print(
            f"{name} {Path(checkpoint).name}: t = {solver.t:.4g} s, S volume {s_volume:.5g} mm^2, "
            "S model "
            f"{s_model:.5g} mm^2, ratio {s_model / s_volume:.3f}; Gamma {s_volume / volume:.4g}, "
            "Gamma_model "
            f"{s_model / volume:.4g} mm^-1"
        )


if __name__ == "__main__":
    main(*sys.argv[1:3])
