"""The comoving carrier experiment: does carrying every particle with the
imposed homogeneous flow bias the explicit compaction?

    python bench/carrier.py
        # 50 particles, CLP and GDF, 4000 increments
    python bench/carrier.py --particles 24 --bcs CLP --increments 6000
    python bench/carrier.py --table-only                      # tabulate the runs already made

``GranularBoundaryConditions(comoving=True)`` (the default) writes every free node as
u = H (X_c - L/2) + w and integrates w: the particles of the volume are carried, without force,
by the flow at their centre, and the explicit solver's inertia and local damping see only w. With
``comoving=False`` only the constrained nodes (ties, couplings) follow F0 and a free particle
moves only when pushed. For a static solution the two are the same problem (a change of
variables); at a finite loading rate they are two dynamics. GDF's premise is that the particles of
the volume are free: the carrier must not decide where they go.

Each run is the flagship case (isotropic, rho -> 0.92, explicit, smooth-ramps) with ``--particles``,
``--bcs`` and the carrier on / off; histories go to ``OUT/p<particles>_<bc>_<carrier|free>_n<N>``
(finished runs are not repeated). The table gives, per run: sigma_m (MPa) at rho 0.80 / 0.85 / 0.90,
h_d / h_v at rho 0.85 and at the end (deviatoric over volumetric strain: 0 for an isotropic
affine motion), the rms non-affine displacement / r at the end, E_damp / E_d at the end (the local
damping's dissipation over the physical one), the end density and the deviation of each
carrier-free figure from the carried one.
"""

from __future__ import annotations

import argparse
import csv
import itertools
import sys
import time
from pathlib import Path

import numpy as np
from convergence import DENSITIES, sigma_at
from mpi4py import MPI

from mpfem_fenicsx.io.history import read_csv
from mpfem_fenicsx.workflows.compaction import CompactionCase, run_compaction


def value_at(history: dict, column: str, rho: float) -> float:
    """``column`` where the loading branch first reaches ``rho`` (linear interpolation; NaN if
    never)."""
    return sigma_at({"rho": history["rho"], "sigma_m": history[column]}, rho)


def summarize(history: dict) -> dict:
    """The run's table row: sigma_m (MPa, compression > 0) at DENSITIES, h_d/h_v, end values."""
    ratio = history["h_d"] / np.where(history["h_v"] != 0, np.abs(history["h_v"]), np.nan)
    return {
        **{f"sigma_m_{rho:.2f}": sigma_at(history, rho) for rho in DENSITIES},
        "hd_over_hv_0.85": value_at({**history, "ratio": ratio}, "ratio", 0.85),
        "hd_over_hv_end": float(ratio[-1]),
        "nonaffine_end": float(history["nonaffine"][-1]),
        "E_damp_over_E_d_end": float(history["E_damp"][-1] / history["E_d"][-1]),
        "rho_end": float(history["rho"][-1]),
        "wall_s": float(history["wall_time"][-1]),
    }


def main(argv=None) -> list[dict]:
    """Run the missing carrier on/off cases, write the CSV and print the table; return its rows."""
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--particles", type=int, default=50)
    p.add_argument(
        "--bcs", nargs="+", choices=("CLP", "GDF", "GDH", "CLPS"), default=["CLP", "GDF"]
    )
    p.add_argument("--increments", type=int, default=4000)
    p.add_argument(
        "--carrier",
        nargs="+",
        choices=("on", "off"),
        default=["on", "off"],
        help="runs to make (e.g. two processes, one each, never overlapping: they would share "
        "a run directory); the table takes every finished run",
    )
    p.add_argument("--outputs", type=int, default=100, help="history rows over the path")
    p.add_argument("--out", default="results/carrier")
    p.add_argument(
        "--table-only", action="store_true", help="tabulate the finished runs in --out, run nothing"
    )
    args = p.parse_args(argv)
    if args.particles < 4 or args.increments < 10:
        p.error("--particles must be >= 4 and --increments >= 10")
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    out = Path(args.out)
    rows = []
    for bc, comoving in itertools.product(args.bcs, (True, False)):
        run_dir = (
            out / f"p{args.particles}_{bc}_{'carrier' if comoving else 'free'}_n{args.increments}"
        )
        done = (run_dir / "done").exists()
        if not done and not args.table_only and ("on" if comoving else "off") in args.carrier:
            say(
                f"--- {args.particles} particles, {bc}, carrier {'on' if comoving else 'off'} -> "
                f"{run_dir}"
            )
            start = time.perf_counter()
            case = CompactionCase.build(
                particles=args.particles,
                condition=bc,
                comoving=comoving,
                increments=args.increments,
                outputs=args.outputs,
                visual=False,
                checkpoint_every=0,
                directory=str(run_dir),
            )
            run_compaction(case, comm, log=lambda *a, **k: None)
            if comm.rank == 0:
                (run_dir / "done").write_text(f"{time.perf_counter() - start:.1f}\n")
            done = True
        if done and comm.rank == 0:
            rows.append(
                {
                    "particles": args.particles,
                    "bc": bc,
                    "carrier": comoving,
                    **summarize(read_csv(run_dir / "history.csv")),
                }
            )
    if comm.rank == 0 and rows:
        for r in rows:  # each carrier-free run against the carried one
            ref = next((q for q in rows if q["bc"] == r["bc"] and q["carrier"]), None)
            r["max_dev_sigma_m"] = (
                max(
                    abs(r[f"sigma_m_{rho:.2f}"] / ref[f"sigma_m_{rho:.2f}"] - 1.0)
                    for rho in DENSITIES
                )
                if ref is not None
                else float("nan")
            )
        out.mkdir(parents=True, exist_ok=True)
        with open(out / "carrier.csv", "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        say(
            "| particles | bc | carrier | sigma_m 0.80 / 0.85 / 0.90 (MPa) | h_d/h_v 0.85 / end | "
            "non-affine rms / r "
            "(end) | E_damp / E_d (end) | rho (end) | max sigma_m dev. from carried | wall (s) |"
        )
        say("|---" * 10 + "|")
        for r in rows:
            say(
                f"| {r['particles']} | {r['bc']} | {'on' if r['carrier'] else 'off'} | "
                f"{r['sigma_m_0.80']:.3f} / {r['sigma_m_0.85']:.3f} / {r['sigma_m_0.90']:.3f} | "
                f"{r['hd_over_hv_0.85']:.4f} / {r['hd_over_hv_end']:.4f} | "
                f"{r['nonaffine_end']:.4f} | "
                f"{r['E_damp_over_E_d_end']:.4f} | {r['rho_end']:.4f} | "
                f"{100 * r['max_dev_sigma_m']:.2f} % | "
                f"{r['wall_s']:.0f} |"
            )
        sys.stdout.flush()
    return rows


if __name__ == "__main__":
    main()
