"""Flagship demo: isotropic compaction of a granular volume (SPEC §8, thesis chapters 2-4).

    python demos/isotropic.py [--out results/isotropic]

Status: the granular isotropic compaction needs particle contact (issue 3) and periodic
volumes with multipoint constraints (issue 4), which are not built yet. Until they land this
script runs, on its embedded default, the foundation's end-to-end case with the same pipeline
(cube-sphere hexahedral particle -> Hencky/von Mises return mapping -> implicit Newton on the
constrained system -> history, ParaView series and a rendered PNG): one lead particle (thesis
table 2.1) squeezed between two prescribed caps to 30 % height reduction.

Outputs in <out>/: implicit.csv (time, height_reduction, force_N, volume_mm3, volume_change),
implicit.xdmf (open in ParaView: displacement, von_mises_MPa, eps_p, particle), implicit.png.
"""

import argparse

from mpi4py import MPI

from mpfem_fenicsx.workflows.foundation import SOLVERS, run_sphere_squeeze


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--solver", choices=SOLVERS, default="implicit")
    parser.add_argument("--out", default="results/isotropic")
    args = parser.parse_args(argv)
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    say("NOTE: granular isotropic compaction arrives with contact (issue 3) and periodic volumes "
        "(issue 4); running the foundation case: a lead particle squeezed to 30 % height reduction.")
    res = run_sphere_squeeze(args.solver, out_dir=args.out, comm=comm, visual=True, log=say)
    h = res.history
    say(f"{args.solver}: {res.num_dofs} dofs, force {h.column('force_N')[-1]:.3f} N at "
        f"{100 * h.column('height_reduction')[-1]:.0f} % height reduction, volume change "
        f"{100 * h.column('volume_change')[-1]:+.3f} %, wall {res.wall_time:.1f} s")
    say(f"outputs in {args.out}/: {args.solver}.csv, {args.solver}.xdmf (ParaView), {args.solver}.png")


if __name__ == "__main__":
    main()
