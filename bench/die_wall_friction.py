"""Die-wall friction and the height of a compact: the lower punch carries less than the upper one,
and less the taller the compact (Janssen); without wall friction both carry the same.

A column of n lead particles (radius r, the chapter-2 mesh) stacked in a die of radius 1.02 r
between two punches; the upper punch squeezes the column by ``squeeze`` of its height by a smooth
step, then holds. Printed and written (``--out``): per (n, wall friction) the forces on the upper
punch, the lower punch and the die along z at rest, their sum over the upper force (the balance),
and the transmission ratio lower / upper.

    python bench/die_wall_friction.py [--heights 1 3] [--frictions 0 0.3] [--increments 16000]

The particles are moved by contact only: the pressing must be slow enough that their
mass-scaled inertia is small against the forces (a coarse particle at 4000 increments overshoots
and ends touching neither punch).
"""

import argparse
import json
from pathlib import Path

import numpy as np
from mpi4py import MPI

from mpfem_fenicsx.contact import ContactLaw
from mpfem_fenicsx.material import LEAD
from mpfem_fenicsx.solvers.explicit import ExplicitSettings
from mpfem_fenicsx.tools import CylinderInside, KeyframePath, Plane, RigidTool
from mpfem_fenicsx.workflows.tooled import (
    build_tooled,
    mesh_radii,
    run_tooled,
    tool_law,
    tooled_solver,
)

R, T = 0.1, 1e-3  # mm, s


def column(n: int, friction: float, increments: int, squeeze: float, resolution: str) -> dict:
    """Press a column of n particles; the tools' forces along z at rest (N)."""
    law = ContactLaw(penalty=10 * LEAD.E / (R * np.pi / 12), friction=0.1)
    height = 2 * R * n
    press = KeyframePath((0.0, T), ((0, 0, 0), (0, 0, -squeeze * height)))
    tools = [
        RigidTool("upper", Plane((0, 0, height), (0, 0, -1)), tool_law(law, 0.1), press),
        RigidTool("lower", Plane((0, 0, 0), (0, 0, 1)), tool_law(law, 0.1)),
        RigidTool("die", CylinderInside(1.02 * R), tool_law(law, friction)),
    ]
    centres = [[0.0, 0.0, R * (2 * k + 1)] for k in range(n)]
    model = build_tooled(
        centres,
        mesh_radii([R] * n, "coarse"),
        tools,
        law,
        LEAD,
        MPI.COMM_WORLD,
        resolution="coarse",
    )
    solver = tooled_solver(
        model, ExplicitSettings(t_end=1.5 * T, target_dt=T / increments, local_damping=0.7)
    )
    run_tooled(model, solver, lambda s: None, outputs=2)
    upper, lower, die = model.tools.tool_forces()["force"][:, 2]
    return {
        "particles": n,
        "wall_friction": friction,
        "F_upper": float(upper),
        "F_lower": float(-lower),
        "F_die": float(die),
        "balance": float((upper + lower + die) / upper),
        "transmission": float(-lower / upper),
        "unbalanced": float(solver.unbalanced_ratio()),
    }


def main(argv=None):
    """Run the columns, print and write the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--heights", type=int, nargs="+", default=[1, 3])
    parser.add_argument("--frictions", type=float, nargs="+", default=[0.0, 0.3])
    parser.add_argument("--increments", type=int, default=16000)
    parser.add_argument("--resolution", default="chapter2", help="particle mesh")
    parser.add_argument("--squeeze", type=float, default=0.1, help="height reduction (-)")
    parser.add_argument("--out", default="bench/measured/die_wall_friction.json")
    args = parser.parse_args(argv)
    rows = []
    for n in args.heights:
        for mu in args.frictions:
            row = column(n, mu, args.increments, args.squeeze, args.resolution)
            rows.append(row)
            if MPI.COMM_WORLD.rank == 0:
                print(
                    f"n {n} wall friction {mu}: upper {row['F_upper']:.5f} N, lower "
                    f"{row['F_lower']:.5f} N, die {row['F_die']:+.5f} N; lower / upper "
                    f"{row['transmission']:.4f}; balance {row['balance']:.2e}; out of balance "
                    f"{row['unbalanced']:.1e}",
                    flush=True,
                )
    if MPI.COMM_WORLD.rank == 0:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
