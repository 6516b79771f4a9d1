"""Hertz contact of two identical elastic spheres, frictionless, implicit.

    python demos/hertz.py [--size-min 0.005] [--steps 10] [--out results/hertz]
    python demos/hertz.py --solver explicit [--increments 8000]    # after the implicit run
    python demos/hertz.py --partner plane    # one sphere on a rigid plane (R = r)
    python demos/hertz.py --partner plane --size-min 0.003 --refine-radius 0.075

E = 200000 MPa, nu = 0.3, r = 1 mm; P1 tetrahedra refined around the contact point. Writes
<out>/force.csv (delta_mm, force_N, force_hertz_N) and <out>/force.png; prints the largest
relative deviation from F = 4/3 E* sqrt(R) delta^(3/2) for delta/r <= 0.005. On the plane,
also the deviation from Hertz's force at the measured contact radius, F = 4 E* a^3 / (3 R),
which the finite sphere's compliance between its driving core and the contact leaves alone.

``--solver explicit`` runs the same mesh with central differences (smooth-step approach over
--increments mass-scaled increments) into <out>/force_explicit.csv and, when the implicit
<out>/force.csv is there, prints the explicit force's largest deviation from the implicit curve
for delta/r >= 0.002 (within 5 % at slow loading).
"""

import argparse
from pathlib import Path

import numpy as np
from mpi4py import MPI

from mpfem_fenicsx.exits import bad_input_exits
from mpfem_fenicsx.options import add_parameter_option
from mpfem_fenicsx.solvers import solver_kind
from mpfem_fenicsx.workflows.hertz import HertzCase, run_hertz


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_parameter_option(parser, HertzCase, "size_min")
    add_parameter_option(parser, HertzCase, "refine_radius")
    add_parameter_option(parser, HertzCase, "steps")
    parser.add_argument("--out", default="results/hertz")
    add_parameter_option(parser, HertzCase, "solver")
    add_parameter_option(parser, HertzCase, "explicit_increments", flag="--increments")
    add_parameter_option(parser, HertzCase, "partner")
    args = parser.parse_args(argv)
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    with bad_input_exits():
        case = HertzCase(
            size_min=args.size_min,
            refine_radius=args.refine_radius,
            steps=args.steps,
            solver=args.solver,
            explicit_increments=args.increments,
            partner=args.partner,
        )
    stem = "force_plane" if case.partner == "plane" else "force"
    if not solver_kind(case.solver).static:  # a dynamic run compared with the static one
        res = run_hertz(case, args.out, comm, log=say)
        say(f"{res.num_dofs} dofs, {res.wall_time:.1f} s")
        implicit = Path(args.out) / f"{stem}.csv"
        if implicit.exists():
            ref = np.loadtxt(implicit, delimiter=",", skiprows=1)
            h = res.history
            delta, force = h.column("delta_mm"), h.column("force_N")
            loaded = delta >= 0.002 * case.radius
            f_imp = np.interp(delta[loaded], ref[:, 0], ref[:, 1])
            worst = np.abs(force[loaded] / f_imp - 1.0).max()
            say(f"explicit vs implicit for delta/r >= 0.002: largest deviation {100 * worst:.2f} %")
        return
    res = run_hertz(case, args.out, comm, log=say)
    h = res.history
    delta, force, ref = h.column("delta_mm"), h.column("force_N"), h.column("force_hertz_N")
    worst = np.abs(force / ref - 1.0).max()
    say(
        f"{res.num_dofs} dofs, {res.wall_time:.1f} s, "
        f"Newton iterations per step {res.newton_iterations}; "
        f"largest deviation from Hertz {100 * worst:.2f} %"
    )
    if case.partner == "plane":  # Hertz at the measured contact radius: local to the contact
        resolved = delta >= 1e-3 * case.radius
        local = np.abs(force / h.column("force_hertz_radius_N") - 1.0)[resolved].max()
        say(
            "largest deviation from Hertz at the contact radius (delta/r >= 0.001): "
            f"{100 * local:.2f} %"
        )
    if comm.rank == 0:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        d = np.linspace(0, delta.max(), 200)
        fig, ax = plt.subplots(figsize=(5.5, 4))
        ax.plot(d, case.hertz_force(d), "k-", label="Hertz")
        ax.plot(delta, force, "o", label="mpfem (P1, NTS penalty)")
        ax.set_xlabel("centre approach delta (mm)")
        ax.set_ylabel("force (N)")
        ax.legend()
        ax.grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(Path(args.out) / f"{stem}.png", dpi=120)
        say(f"wrote {args.out}/{stem}.csv and {stem}.png")


if __name__ == "__main__":
    main()
