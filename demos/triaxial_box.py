"""A box of six independently driven rigid planes: hydrostatic or true-triaxial compaction.

    python demos/triaxial_box.py
        # embedded default: 12 lead particles, hydrostatic (ratios 1 1 1), density 0.4 -> 0.75
    python demos/triaxial_box.py --ratios 1 0.5 0.25 --target-density 0.7
    mpirun -n 2 python demos/triaxial_box.py

Pipeline: a seeded frictionless packing in a box at --fill (no sphere touches another or a
wall) -> one DOLFINx mesh of cube-sphere particles -> six rigid planes x0, x1, y0, y1, z0, z1 on
the box's faces, each moved along its normal by its own keyframe path: the side a shortens as
L_a0 exp(-c r_a s(t)) (r = --ratios, s a smooth step over the pressing time, c set by
--target-density), half on each of its planes -> explicit central differences, the particles
moved by contact only -> a hold.

Outputs in --out (default results/triaxial_box/): history.csv (rho, the box's lengths, the
wall stresses sigma_xx/yy/zz_walls = mean normal force of two opposite planes over the face
area, MPa, compression > 0, and every plane's translation, force and normal force), summary.json
(the end state, each plane's force, the quasi-static check) and box.png (von Mises).
"""

import argparse

from mpi4py import MPI

from mpfem_fenicsx.exits import bad_input_exits
from mpfem_fenicsx.options import add_parameter_option, run_exits
from mpfem_fenicsx.workflows.box import PLANES, BoxCase, run_box

OPTIONS = (
    "particles",
    "seed",
    "fill",
    "target_density",
    "wall_friction",
    "friction",
    "increments",
    "resolution",
    "outputs",
)


def main(argv=None) -> None:
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)

    # 1. The case: options are declared parameters of BoxCase (exit 2 with one line if refused)
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    for name in OPTIONS:
        add_parameter_option(parser, BoxCase, name)
    parser.add_argument(
        "--ratios",
        type=float,
        nargs=3,
        default=(1.0, 1.0, 1.0),
        metavar=("RX", "RY", "RZ"),
        help="relative shortening rates of the box's sides (>= 0, not all 0; default 1 1 1)",
    )
    parser.add_argument("--out", default="results/triaxial_box", help="results folder")
    parser.add_argument("--no-visual", action="store_true", help="no picture")
    args = parser.parse_args(argv)
    with bad_input_exits():
        case = BoxCase(
            **{n: getattr(args, n) for n in OPTIONS}, ratios=tuple(args.ratios), out_dir=args.out
        )

    # 2. Pack, press the six planes, hold (run_box)
    with run_exits():
        history, summary = run_box(case, comm, log=say, render=not args.no_visual)

    # 3. Each plane's force at the end and the wall stresses
    say(
        "planes' normal forces at the end (N): "
        + ", ".join(f"{name} {summary[f'{name}_N']:.4g}" for name, _, _ in PLANES)
    )
    say(
        f"rho {summary['rho']:.4f}; wall stresses xx / yy / zz = {summary['sigma_xx_walls']:.3f}"
        f" / {summary['sigma_yy_walls']:.3f} / {summary['sigma_zz_walls']:.3f} MPa"
    )
    verdict = "passed" if summary["quasi_static"] else "FAILED (run with more increments)"
    say(
        f"quasi-static check {verdict}: out of balance {summary['unbalanced_at_rest']:.2g} at "
        f"rest (limit 0.05); wall time {summary['wall_time_s']:.0f} s on {summary['ranks']} "
        f"rank(s), {summary['dofs']} dofs; outputs in {args.out}/"
    )


if __name__ == "__main__":
    main()
