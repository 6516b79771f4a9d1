"""CLPS with and without the equal rotations of thesis eq. 2.16.

    python bench/clps_rotations.py --rotations on  --out results/clps_rotations   # one process
    python bench/clps_rotations.py --rotations off --out results/clps_rotations   # another
    python bench/clps_rotations.py --table-only --out results/clps_rotations

The flagship (24 particles, seed 1, isotropic to rho 0.92, explicit, smooth-ramps) under CLPS, its
copies' reference points coupled to their originals' in translation (eq. 2.15) and, with
``--rotations on``, in rotation too (eq. 2.16). Runs go to
``OUT/p<particles>_<loading>_rot<on|off>`` (finished ones are not repeated). The table gives
sigma_m at rho 0.80 / 0.85 / 0.90 (MPa, least-squares rho), the end state, h_d / h_v, the
non-affine rms / r, E_p of the volume and of the model (mJ), and the deviation of the run without
eq. 2.16 from the one with it.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from convergence import DENSITIES, sigma_at
from mpi4py import MPI

import mpfem_fenicsx  # noqa: F401  (mpi4py before dolfinx)
from mpfem_fenicsx.io.history import read_csv
from mpfem_fenicsx.workflows.compaction import CompactionCase, run_compaction


def summarize(h: dict) -> dict:
    """The run's table row: sigma_m (MPa, compression > 0) at DENSITIES and the end state."""
    ratio = h["h_d"][-1] / abs(h["h_v"][-1])
    return {
        **{f"sigma_m_{rho:.2f}": sigma_at(h, rho) for rho in DENSITIES},
        "sigma_m_end": float(h["sigma_m"][-1]),
        "rho_end": float(h["rho"][-1]),
        "hd_over_hv_end": float(ratio),
        "nonaffine_end": float(h["nonaffine"][-1]),
        "E_p_end": float(h["E_p"][-1]),
        "E_p_model_end": float(h["E_p_model"][-1]),
        "contacts_end": int(h["n_contacts"][-1]),
        "wall_s": float(h["wall_time"][-1]),
    }


def main(argv=None) -> list[dict]:
    """Run the missing eq. 2.16 on/off cases and print the table; return the rows."""
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--particles", type=int, default=24)
    p.add_argument("--loading", choices=("isotropic", "die"), default="isotropic")
    p.add_argument("--target-density", type=float, default=0.92)
    p.add_argument(
        "--d-bc",
        type=float,
        default=1.5,
        help="duplication distance / r_max (thesis: CLPS curves superpose from 1.5)",
    )
    p.add_argument("--increments", type=int, default=3000)
    p.add_argument("--rotations", nargs="+", choices=("on", "off"), default=["on", "off"])
    p.add_argument("--outputs", type=int, default=60)
    p.add_argument("--out", default="results/clps_rotations")
    p.add_argument("--table-only", action="store_true")
    args = p.parse_args(argv)
    if args.particles < 4 or args.increments < 10 or not 0 < args.d_bc <= 10:
        p.error("--particles must be >= 4, --increments >= 10 and --d-bc in (0, 10]")
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    rows = {}
    for rotations in (True, False):
        run_dir = (
            Path(args.out) / f"p{args.particles}_{args.loading}_rot{'on' if rotations else 'off'}"
        )
        if (
            not (run_dir / "done").exists()
            and not args.table_only
            and ("on" if rotations else "off") in args.rotations
        ):
            say(f"--- CLPS, equal rotations {'on' if rotations else 'off'} -> {run_dir}")
            start = time.perf_counter()
            case = CompactionCase.build(
                particles=args.particles,
                path=args.loading,
                condition="CLPS",
                d_bc=args.d_bc,
                target_density=args.target_density,
                equal_rotations=rotations,
                increments=args.increments,
                outputs=args.outputs,
                visual=False,
                checkpoint_every=0,
                directory=str(run_dir),
            )
            run_compaction(case, comm, log=lambda *a, **k: None)
            if comm.rank == 0:
                (run_dir / "done").write_text(f"{time.perf_counter() - start:.1f}\n")
        if (run_dir / "done").exists():
            rows[rotations] = summarize(read_csv(run_dir / "history.csv"))
    if comm.rank == 0 and rows:
        say(
            "| eq. 2.16 | sigma_m 0.80 / 0.85 / 0.90 (MPa) | end sigma_m / rho | h_d/h_v end | "
            "non-affine / r end "
            "| E_p volume / model (mJ) | contacts end | wall (s) |"
        )
        say("|---" * 8 + "|")
        for rotations, r in rows.items():
            say(
                f"| {'on' if rotations else 'off'} | {r['sigma_m_0.80']:.3f} / "
                f"{r['sigma_m_0.85']:.3f} / "
                f"{r['sigma_m_0.90']:.3f} | {r['sigma_m_end']:.3f} / {r['rho_end']:.4f} | "
                f"{r['hd_over_hv_end']:.4f} | "
                f"{r['nonaffine_end']:.4f} | {r['E_p_end']:.4f} / {r['E_p_model_end']:.4f} | "
                f"{r['contacts_end']} | "
                f"{r['wall_s']:.0f} |"
            )
        if len(rows) == 2:
            keys = [f"sigma_m_{rho:.2f}" for rho in DENSITIES] + [
                "sigma_m_end",
                "E_p_end",
                "hd_over_hv_end",
            ]
            say(
                "off vs on: "
                + ", ".join(
                    f"{k} {100 * (rows[False][k] / rows[True][k] - 1):+.2f} %" for k in keys
                )
            )
        sys.stdout.flush()
    return list(rows.values())


if __name__ == "__main__":
    main()
