"""Homogeneous uniaxial tension of a lead block to log strain 0.5.

    python demos/uniaxial.py --solver implicit|explicit [--out results/uniaxial]

Writes <out>/stress_strain.csv (log_strain, true_stress_MPa, eps_p; one row per increment for
the implicit solver, per output increment for the explicit one) and, for the explicit solver,
<out>/energy.csv (W_ext, E_int, E_p, E_el, E_kin, E_visc in mJ). Prints the largest deviation
from the hardening law sigma_0 + K eps_p^n (thesis eq. 2.1).
"""

import argparse

import numpy as np
from mpi4py import MPI

from mpfem_fenicsx.exits import bad_input_exits
from mpfem_fenicsx.material import LEAD
from mpfem_fenicsx.options import add_parameter_option
from mpfem_fenicsx.workflows.foundation import UniaxialCase, run_uniaxial


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    for name in (
        "solver",
        "log_strain",
        "cells",
    ):  # meaning, unit, default and range from UniaxialCase
        add_parameter_option(parser, UniaxialCase, name)
    parser.add_argument("--out", default="results/uniaxial")
    args = parser.parse_args(argv)
    with bad_input_exits():
        case = UniaxialCase(
            solver=args.solver, log_strain=args.log_strain, cells=args.cells, material=LEAD
        )
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    res = run_uniaxial(case, args.out, comm, log=say)
    plastic = res.eps_p > 1e-3
    dev = np.abs(res.true_stress[plastic] / LEAD.yield_stress(res.eps_p[plastic]) - 1.0).max()
    say(
        f"{args.solver}: {len(res.log_strain)} rows, final log strain {res.log_strain[-1]:.4f}, "
        f"true stress {res.true_stress[-1]:.4f} MPa, eps_p {res.eps_p[-1]:.4f}; "
        f"max deviation from sigma_0 + K eps_p^n: {100 * dev:.3f} %; wall {res.wall_time:.1f} s"
    )
    say(f"wrote {res.csv}")


if __name__ == "__main__":
    main()
