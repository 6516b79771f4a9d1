"""A lead particle squeezed between two prescribed caps to 30 % height reduction.

    python demos/sphere_squeeze.py --solver implicit|explicit [--reduction 0.3] [--out DIR]

Writes <out>/<solver>.csv (time, height_reduction, force_N, volume_mm3, volume_change). The
volume stays constant to well under 1 % (no volumetric locking with the SRI hexahedra).
"""

import argparse

from mpi4py import MPI

from mpfem_fenicsx.exits import bad_input_exits
from mpfem_fenicsx.options import add_parameter_option
from mpfem_fenicsx.workflows.foundation import SqueezeCase, run_sphere_squeeze


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    for name in ("solver", "reduction", "refinement", "explicit_steps"):  # declared in SqueezeCase
        add_parameter_option(parser, SqueezeCase, name)
    parser.add_argument("--out", default="results/sphere_squeeze")
    args = parser.parse_args(argv)
    with bad_input_exits():
        case = SqueezeCase(
            solver=args.solver,
            reduction=args.reduction,
            refinement=args.refinement,
            explicit_steps=args.explicit_steps,
        )
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    res = run_sphere_squeeze(case, out_dir=args.out, comm=comm, log=say)
    h = res.history
    say(
        f"{args.solver}: {res.num_dofs} dofs, {len(h.rows)} rows, "
        f"force {h.column('force_N')[-1]:.4f} N at "
        f"{100 * h.column('height_reduction')[-1]:.1f} % height reduction, volume change "
        f"{100 * h.column('volume_change')[-1]:+.4f} %, wall {res.wall_time:.1f} s"
    )


if __name__ == "__main__":
    main()
