"""A lead particle squeezed between two prescribed caps to 30 % height reduction.

    python demos/sphere_squeeze.py --solver implicit|explicit [--reduction 0.3] [--out DIR]

Writes <out>/<solver>.csv (time, height_reduction, force_N, volume_mm3, volume_change). The
volume stays constant to well under 1 % (no volumetric locking with the SRI hexahedra).
"""

import argparse

from mpi4py import MPI

from mpfem_fenicsx.cli.exits import bad_input_exits
from mpfem_fenicsx.solvers import SOLVERS
from mpfem_fenicsx.workflows.foundation import check_sphere_squeeze, run_sphere_squeeze


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--solver", choices=SOLVERS, default="implicit")
    parser.add_argument("--reduction", type=float, default=0.3)
    parser.add_argument("--refinement", type=int, default=1)
    parser.add_argument("--explicit-steps", type=int, default=4000)
    parser.add_argument("--out", default="results/sphere_squeeze")
    args = parser.parse_args(argv)
    with bad_input_exits():
        check_sphere_squeeze(args.solver, args.reduction, args.refinement, explicit_steps=args.explicit_steps)
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    res = run_sphere_squeeze(args.solver, reduction=args.reduction, refinement=args.refinement,
                             out_dir=args.out, comm=comm, explicit_steps=args.explicit_steps, log=say)
    h = res.history
    say(f"{args.solver}: {res.num_dofs} dofs, {len(h.rows)} rows, force {h.column('force_N')[-1]:.4f} N at "
        f"{100 * h.column('height_reduction')[-1]:.1f} % height reduction, volume change "
        f"{100 * h.column('volume_change')[-1]:+.4f} %, wall {res.wall_time:.1f} s")


if __name__ == "__main__":
    main()
