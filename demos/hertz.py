"""Hertz contact of two identical elastic spheres (SPEC §9 case 2), frictionless, implicit.

    python demos/hertz.py [--size-min 0.005] [--steps 10] [--out results/hertz]

E = 200000 MPa, nu = 0.3, r = 1 mm; P1 tetrahedra refined around the contact point. Writes
<out>/force.csv (delta_mm, force_N, force_hertz_N) and <out>/force.png; prints the largest
relative deviation from F = 4/3 E* sqrt(R) delta^(3/2) for delta/r <= 0.005.
"""

import argparse
from pathlib import Path

import numpy as np
from mpi4py import MPI

from mpfem_fenicsx.workflows.hertz import HertzCase, run_hertz


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size-min", type=float, default=0.005, help="element size at the contact / r")
    parser.add_argument("--steps", type=int, default=10)
    parser.add_argument("--out", default="results/hertz")
    args = parser.parse_args(argv)
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    res = run_hertz(HertzCase(size_min=args.size_min, steps=args.steps), args.out, comm, log=say)
    h = res.history
    delta, force, ref = h.column("delta_mm"), h.column("force_N"), h.column("force_hertz_N")
    worst = np.abs(force / ref - 1.0).max()
    say(f"{res.num_dofs} dofs, {res.wall_time:.1f} s, Newton iterations per step {res.newton_iterations}; "
        f"largest deviation from Hertz {100 * worst:.2f} %")
    if comm.rank == 0:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        d = np.linspace(0, delta.max(), 200)
        fig, ax = plt.subplots(figsize=(5.5, 4))
        ax.plot(d, HertzCase().hertz_force(d), "k-", label="Hertz")
        ax.plot(delta, force, "o", label="mpfem (P1, NTS penalty)")
        ax.set_xlabel("centre approach delta (mm)")
        ax.set_ylabel("force (N)")
        ax.legend()
        ax.grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(Path(args.out) / "force.png", dpi=120)
        say(f"wrote {args.out}/force.csv and force.png")


if __name__ == "__main__":
    main()
