"""Yield surface of a periodic volume of lead particles in the deviatoric plane, by
stress-controlled probes at constant mean stress over Lode angles (beyond the thesis, whose
chapter-4 fans are strain-driven reloads in the (sigma_m, sigma~_d) plane).

    python demos/deviatoric_surface.py
        # flagship volume, 7 probes over 0-60 deg
    python demos/deviatoric_surface.py --angles 0 15 30 45 60 --p-load 4 --p-probe 2

Pipeline (workflows.deviatoric_surface): the flagship volume (24 particles, seed 1, CLP by
periodic images, explicit) -> isotropic consolidation to --p-load by the servo on the Schmidt
stress, held -> unloaded to --p-probe, held (checkpoint) -> one probe per Lode angle from that
checkpoint: sigma_m held at --p-probe, the von Mises stress q ramped to --q-max along the angle
-> yield where E_d first exceeds E_0 (1 + 0.3 %), E_0 at the end of the unload (thesis §4.2.2).

Outputs in --out (default results/deviatoric_surface/): fan.csv, surface.csv,
deviatoric_surface.png (the deviatoric plane, points mirrored by the symmetry of an isotropic
state, and principal-stress space), consolidate/ and probe_<deg>/ with their histories.
"""

import argparse
import sys

from mpi4py import MPI

from mpfem_fenicsx.exits import RUN_FAILED, bad_input_exits, fail
from mpfem_fenicsx.options import add_case_option, add_parameter_option
from mpfem_fenicsx.workflows.compaction import CompactionCase, RunFailure
from mpfem_fenicsx.workflows.deviatoric_surface import DeviatoricSurfaceCase, run_deviatoric_surface


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_case_option(
        p, "packing", "particles"
    )  # type, default, range and help from the case declarations
    add_case_option(p, "packing", "seed")
    for name in (
        "p_load",
        "p_probe",
        "q_max",
    ):  # meaning, unit, default and range from the case's declaration
        add_parameter_option(p, DeviatoricSurfaceCase, name)
    p.add_argument(
        "--angles",
        type=float,
        nargs="+",
        default=[0, 10, 20, 30, 40, 50, 60],
        help="Lode angles of the probes "
        "(deg; 0 triaxial compression along x, 60 extension along z)",
    )
    add_case_option(p, "solver", "increments", help="per 1e-3 s of loading")
    p.add_argument("--out", default="results/deviatoric_surface")
    args = p.parse_args(argv)
    with bad_input_exits():
        base = CompactionCase.build(
            particles=args.particles,
            seed=args.seed,
            condition="CLP",
            increments=args.increments,
            visual=False,
        )
        case = DeviatoricSurfaceCase(
            base=base,
            p_load=args.p_load,
            p_probe=args.p_probe,
            q_max=args.q_max,
            angles_deg=tuple(args.angles),
            out_dir=args.out,
        )
    try:
        result = run_deviatoric_surface(case, MPI.COMM_WORLD)
    except RunFailure as err:
        fail(RUN_FAILED, str(err))
    if MPI.COMM_WORLD.rank == 0:
        print(
            f"E_0 = {result['E_0']:.4g} mJ; "
            "yield points (theta deg: sigma_m, q MPa, measured Lode angle deg):"
        )
        for theta, sigma_m, q, lode in result["points"]:
            print(f"  {theta:5.1f}: {sigma_m:.3f}, {q:.3f}, {lode:.1f}")
        missing = len(args.angles) - len(result["points"])
        if missing:
            print(f"{missing} probe(s) did not yield below q = {args.q_max} MPa (raise --q-max)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
