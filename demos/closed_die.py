"""Closed-die compaction of a poured lead powder: pressing, hold, unloading, ejection.

    python demos/closed_die.py
        # embedded default: 12 particles, single action to a green density of 0.85
    python demos/closed_die.py --particles 30 --action double --wall-friction 0.3
    mpirun -n 2 python demos/closed_die.py

Pipeline: seeded spheres poured into a cylinder under a weak weight (every sphere rests on
others) -> one DOLFINx mesh of cube-sphere particles -> three rigid tools: the upper punch (a
plane on the poured column's top), the lower punch (z = 0) and the die's wall (the cylinder,
ending at the column's top) -> explicit central differences, mass scaling, local damping, the
particles moved by contact only -> four stages: pressing, hold, unloading (the upper punch
retreats), ejection (the lower punch pushes the compact out of the die).

Outputs in --out (default results/closed_die/): history.csv (per row: stage, green density =
the particles' volume over the volume between the punches, compact height from the particles,
punch pressures (MPa, compression > 0), die-wall normal and friction forces (N), each tool's
translation and force, energies, out-of-balance ratio), density_bins.csv (green density by
height and by radius at the end of the hold), summary.json (the figures printed at the end:
pressing, springback, ejection force, the quasi-static check, wall time), pressing_curve.png
(punch pressures against green density) and pressed.png / ejected.png (the compact coloured by
von Mises; pressed.vtu / ejected.vtu for ParaView).
"""

import argparse

from mpi4py import MPI

from mpfem_fenicsx.exits import bad_input_exits
from mpfem_fenicsx.options import add_parameter_option, run_exits
from mpfem_fenicsx.workflows.closed_die import ClosedDieCase, run_closed_die

#: the options of the demo: fields of ClosedDieCase (each checked against its range)
OPTIONS = (
    "particles",
    "seed",
    "target_density",
    "action",
    "wall_friction",
    "punch_friction",
    "friction",
    "increments",
    "resolution",
    "outputs",
)


def main(argv=None) -> None:
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)

    # 1. The case: each option is a declared parameter of ClosedDieCase, checked against its
    #    range (exit 2 with one line naming it)
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    for name in OPTIONS:
        add_parameter_option(parser, ClosedDieCase, name)
    parser.add_argument("--out", default="results/closed_die", help="results folder")
    parser.add_argument("--no-visual", action="store_true", help="no pictures")
    args = parser.parse_args(argv)
    with bad_input_exits():
        case = ClosedDieCase(**{n: getattr(args, n) for n in OPTIONS}, out_dir=args.out)

    # 2. Pour, press, hold, unload, eject (run_closed_die): a progress line per history row
    with run_exits():
        result = run_closed_die(case, comm, log=say, render=not args.no_visual)

    # 3. The figures: pressing, springback, ejection, density distribution, quasi-static check
    for line in result.report():
        say(line)
    say(f"outputs in {args.out}/")


if __name__ == "__main__":
    main()
