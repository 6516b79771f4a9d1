"""Two elastoplastic spheres with adhesion against Mesarovic-Johnson (thesis §3.4.2,
fig. 3.10-3.12).

    python demos/two_spheres.py                          # all ratios sigma_c / sigma_y (hours)
    python demos/two_spheres.py --ratios 0.8 1.0         # some of them
    python demos/two_spheres.py --replot
        # summary + figure from the histories in --out

Steel spheres (E = 200000 MPa, nu = 0.3, sigma_y = 200 MPa, H = 100 MPa), r = 1 mm, gamma =
1e-3 mJ/mm^2, alpha forced to 1, frictionless; compressed to a centre approach of 0.02 r, then
separated (implicit). Default model: the one-cell 2-degree wedge (axisymmetric by cyclic
symmetry) with quadrilaterals of 0.002 r on the contact cap (--size-min 0.004: the thesis used
0.00125 r), penalty 10 E / h = 1e9 N/mm^3 (the thesis' value), 40 load + 80 unload steps; 48 804
dofs, 30-60 min per ratio on one core (measured errors: README.md and bench/README.md, thesis:
< 5 % in [0.6, 1.6]). --model quarter runs the 3-D quarter model instead (hexahedra split from
gmsh tetrahedra; a resolved contact there costs ~10x more).

For each ratio (delta_max = 2 gamma / sigma_c) writes results/two_spheres/history_<ratio>.csv
(time, approach, force, contact radius, loaded points) and sigma_c_<ratio>.csv (a_over_a0,
force_N, force_mj_N on the unloading branch); then summary.csv (sigma_c_over_sigma_y, error_e:
thesis eq. 3.21 on a / a0 = 0.1 ... 0.9, grid_points, error_rms and error_samples over the
unloading samples, a0_mm, F0_N, samples, wall_s) and two_spheres.png. Under prescribed approach
the static unloading path ends where the last contact disc pulls off (logged); the branch is
compared with Mesarovic-Johnson up to there.
"""

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
from mpi4py import MPI

from mpfem_fenicsx.exits import bad_input_exits
from mpfem_fenicsx.io import History
from mpfem_fenicsx.options import add_parameter_option
from mpfem_fenicsx.workflows.two_spheres import TwoSphereCase, run_two_spheres, unloading_branch

RATIOS = (0.1, 0.3, 0.6, 0.8, 1.0, 1.2, 1.6, 2.0)


#: the full demo: the wedge at the thesis' contact resolution
DEMO_CASE = TwoSphereCase(
    model="wedge", size_min=0.004, refine_radius=0.2, grading=0.3, load_steps=40, unload_steps=80
)


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    d = DEMO_CASE
    parser.add_argument(
        "--ratios", type=float, nargs="+", default=RATIOS, help="sigma_c / sigma_y values"
    )
    parser.add_argument("--gamma", type=float, default=d.gamma, help="adhesion energy, mJ/mm^2")
    for name in (
        "size_min",
        "grading",
        "refine_radius",
        "model",
        "wedge_angle",
        "load_steps",
        "unload_steps",
    ):
        add_parameter_option(
            parser, TwoSphereCase, name, default=getattr(d, name)
        )  # the demo's own defaults
    parser.add_argument("--out", default="results/two_spheres")
    parser.add_argument(
        "--replot",
        action="store_true",
        help="no simulation: summary, curves and figure from the history_<ratio>.csv in --out",
    )
    args = parser.parse_args(argv)
    with bad_input_exits():  # every ratio's case before the first run
        cases = {
            ratio: replace(
                d,
                ratio=ratio,
                gamma=args.gamma,
                size_min=args.size_min,
                grading=args.grading,
                refine_radius=args.refine_radius,
                model=args.model,
                wedge_angle=args.wedge_angle,
                load_steps=args.load_steps,
                unload_steps=args.unload_steps,
            )
            for ratio in args.ratios
        }
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    out = Path(args.out)
    summary = History(
        out / "summary.csv",
        [
            "sigma_c_over_sigma_y",
            "error_e",
            "grid_points",
            "error_rms",
            "error_samples",
            "a0_mm",
            "F0_N",
            "samples",
            "pull_off_mm",
            "wall_s",
        ],
        comm,
    )
    curves = {}
    for ratio in args.ratios:
        case = cases[ratio]
        if args.replot:
            path = out / f"history_{ratio:g}.csv"
            if not path.exists():
                say(f"sigma_c / sigma_y = {ratio:g}: no {path}, skipped")
                continue
            branch = unloading_branch(case, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2))
            pull_off, wall = float("nan"), float("nan")
        else:
            say(
                f"sigma_c / sigma_y = {ratio:g}: sigma_c = {case.sigma_c:g} MPa, "
                f"delta_max = {case.delta_max:.3g} mm"
            )
            res = run_two_spheres(case, out, comm, log=say)
            branch = res.branch
            pull_off = float("nan") if res.pull_off is None else res.pull_off
            wall = res.wall_time
            say(f"  {res.num_dofs} dofs, {wall:.0f} s")
        curve = History(
            out / f"sigma_c_{ratio:g}.csv", ["a_over_a0", "force_N", "force_mj_N"], comm
        )
        for a, f, f_mj in zip(branch.a, branch.F, branch.F_mj, strict=True):
            curve.append(a_over_a0=a / branch.a0, force_N=f, force_mj_N=f_mj)
        curve.write()
        curves[ratio] = (branch.a / branch.a0, branch.F / branch.F0, branch.a0, branch.F0, case)
        summary.append(
            sigma_c_over_sigma_y=ratio,
            error_e=branch.error,
            grid_points=branch.grid_points,
            error_rms=branch.error_rms,
            error_samples=branch.error_samples,
            a0_mm=branch.a0,
            F0_N=branch.F0,
            samples=branch.a.size,
            pull_off_mm=pull_off,
            wall_s=wall,
        )
        summary.write()
        say(
            f"  sigma_c / sigma_y = {ratio:g}: a0 = {branch.a0:.4f} mm, "
            f"F0 = {branch.F0:.3f} N, e = "
            f"{100 * branch.error:.2f} % "
            f"(eq. 3.21 on {branch.grid_points} radii a / a0 = 0.1..0.9); "
            f"{branch.a.size} unloading samples: {100 * branch.error_rms:.2f} % rms"
        )
    if not curves:
        say(f"no results in {out}")
        return
    if comm.rank == 0:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
        s = np.linspace(0, 1, 200)
        for k, (ratio, (x, f, a0, F0, case)) in enumerate(curves.items()):
            colour = f"C{k}"
            ax[0].plot(x, f, "o", ms=3, color=colour, label=f"sigma_c/sigma_y = {ratio:g}")
            ax[0].plot(s, case.mesarovic_johnson(s * a0, a0, F0) / F0, "-", color=colour, lw=1)
        ax[0].set_xlabel("a / a0")
        ax[0].set_ylabel("F / (pi a0^2 p0)")
        ax[0].set_title("unloading: mpfem (points) vs Mesarovic-Johnson (lines)")
        ax[0].legend(fontsize=7)
        ax[0].grid(alpha=0.3)
        rows = summary.array()
        ax[1].plot(rows[:, 0], 100 * rows[:, 1], "o-", label="e, eq. 3.21 (a / a0 = 0.1 ... 0.9)")
        ax[1].plot(
            rows[:, 0], 100 * rows[:, 3], "s--", ms=4, label="rms over the unloading samples"
        )
        ax[1].legend(fontsize=7)
        ax[1].axhline(5.0, color="k", ls="--", lw=1)
        ax[1].set_ylim(bottom=0.0)
        ax[1].set_xlabel("sigma_c / sigma_y")
        ax[1].set_ylabel("deviation from Mesarovic-Johnson (% of F0)")
        ax[1].grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(out / "two_spheres.png", dpi=120)
        say(f"wrote {out}/summary.csv, sigma_c_<ratio>.csv and two_spheres.png")


if __name__ == "__main__":
    main()
