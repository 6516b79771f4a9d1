"""Force-controlled rupture of an adhesive periodic volume of lead particles (the
thesis' perspective 4: rupture under force control, detected by the growth of the kinetic energy).

    python demos/force_rupture.py
        # flagship volume, gamma 1e-2, pulled along z
    python demos/force_rupture.py --final 0 0 -2 --gamma 1e-3

Pipeline (workflows.force_rupture): the flagship volume (24 particles, seed 1, CLP by periodic
images, explicit, adhesion --gamma) -> isotropic consolidation to --p-load by the servo on the
Schmidt stress, held -> unloaded to --p-probe, held (checkpoint) -> the three normal stresses
driven linearly from --p-probe to --final (MPa, compression > 0; default: the axial stress pulled
to -3 MPa, the lateral ones held at --p-probe) -> rupture where E_c / E_d (eq. 4.14) reaches
--phi-c and where Hill's W2 (eq. 4.15) turns <= 0, both recorded with the peak stress.

Outputs in --out (default results/force_rupture/): rupture.csv (one row per probe output: the
normal stresses, sigma_m, q, the stress along the path, the Hencky strains, E_c, E_d, E_c / E_d,
W2), rupture_points.csv, force_rupture.png, consolidate/ and probe/ with their histories.
"""

import argparse
import sys

from mpi4py import MPI

from mpfem_fenicsx.exits import RUN_FAILED, bad_input_exits, fail
from mpfem_fenicsx.options import add_case_option, add_parameter_option
from mpfem_fenicsx.workflows.compaction import CompactionCase, RunFailure
from mpfem_fenicsx.workflows.force_rupture import ForceRuptureCase, run_force_rupture


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_case_option(
        p, "packing", "particles"
    )  # type, default, range and help from the case declarations
    add_case_option(p, "packing", "seed")
    add_case_option(p, "contact", "gamma", default=1e-2, help="> 0 to carry tension")
    for name in (
        "p_load",
        "p_probe",
    ):  # meaning, unit, default and range from the case's declaration
        add_parameter_option(p, ForceRuptureCase, name)
    p.add_argument(
        "--final",
        type=float,
        nargs=3,
        default=[0.2, 0.2, -3.0],
        metavar=("S11", "S22", "S33"),
        help="normal stresses at the end of the probe (MPa, compression > 0)",
    )
    add_parameter_option(p, ForceRuptureCase, "phi_c")
    add_case_option(p, "solver", "increments", help="per 1e-3 s of loading")
    p.add_argument("--out", default="results/force_rupture")
    args = p.parse_args(argv)
    with bad_input_exits():
        base = CompactionCase.build(
            particles=args.particles,
            seed=args.seed,
            condition="CLP",
            gamma=args.gamma,
            increments=args.increments,
            visual=False,
        )
        case = ForceRuptureCase(
            base=base,
            p_load=args.p_load,
            p_probe=args.p_probe,
            final_stress=tuple(args.final),
            phi_c=args.phi_c,
            out_dir=args.out,
        )
    try:
        result = run_force_rupture(case, MPI.COMM_WORLD)
    except RunFailure as err:
        fail(RUN_FAILED, str(err))
    if MPI.COMM_WORLD.rank == 0:
        print(
            f"E_0 = {result['E_0']:.4g} mJ; E_c / E_d under the quasi-static part: "
            f"{result['phi_quasi_static']:.2g} (phi_c = {args.phi_c:g})"
        )
        for criterion, point in result["points"].items():
            print(
                f"  {criterion:5s}: t = {point['time'] * 1e3:.4f} ms, "
                f"sigma = ({point['sigma_11']:.3f}, "
                f"{point['sigma_22']:.3f}, {point['sigma_33']:.3f}) MPa, stress along the path "
                f"{point['path_stress']:.3f} MPa"
            )
        for criterion in ("phi", "w2"):
            if criterion not in result["points"]:
                print(f"  {criterion}: not met (no rupture along this path: extend --final)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
