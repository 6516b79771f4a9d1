r"""Convergence study of the explicit compaction curves: loading rate and particle mesh.

    python bench/convergence.py
        # flagship: N, 2N, 4N; chapter2 vs chapter4
    python bench/convergence.py --particles 50 --increments 6000 12000 --meshes chapter2
    python bench/convergence.py --profile smooth-step smooth-ramps --increments 4000 8000 \
        --meshes chapter2
    python bench/convergence.py --table-only                     # tabulate the runs already made
    python bench/convergence.py --particles 24 --loading die --bc CLPS --d-bc 1.5 --divisions 4 \
        --radius-factor 0.975 --target-density 0.85 --outputs 40 --meshes chapter2 \
        --increments 3000 6000 12000 --density rho_imposed --densities 0.75 0.80 0.84
        # the copies' conditions (validation CI subset)

Every run is the flagship case (``CompactionCase`` defaults: isotropic, CLP, rho -> 0.92, explicit)
with ``--particles``, a number of increments and a named particle mesh (and optionally another
loading, boundary condition, d_bc, particle divisions); its history goes to
``OUT/p<particles>[_<loading>_<bc>[_dbc<d_bc>][_div<divisions>]]_<mesh>_<profile>_n<increments>/
history.csv``
(a finished run is not repeated). The table (printed, and written to ``OUT/convergence.csv``) gives
per run: sigma_m (MPa, Love-Weber, compression > 0) at ``--densities`` (default rho = 0.80, 0.85,
0.90) of the loading branch, read on ``--density`` (rho: the centroids' fit; rho_imposed: the
cell's), its deviation from the run with
the most increments of the same mesh, sigma_m at the last row over its maximum (1: no end-of-load
hook), rho - rho_fe at the last row (the mesh's volume), the last row's unbalanced ratio and
E_c / E_int, and the wall time.
"""

from __future__ import annotations

import argparse
import csv
import itertools
import sys
import time
from pathlib import Path

import numpy as np
from mpfem_fenicsx.meshes.cubesphere import RESOLUTIONS
from mpi4py import MPI

from mpfem_fenicsx.io.history import read_csv
from mpfem_fenicsx.loading import PROFILES
from mpfem_fenicsx.solvers.constraint_mass import CONSTRAINT_MASSES
from mpfem_fenicsx.workflows.compaction import CompactionCase, run_compaction

DENSITIES = (0.80, 0.85, 0.90)


def sigma_at(history: dict, rho: float, column: str = "rho") -> float:
    """sigma_m (MPa) where the loading branch first reaches ``rho`` of ``column`` (linear
    interpolation; NaN if never)."""
    r, s = history[column], history["sigma_m"]
    above = np.flatnonzero(r >= rho)
    if above.size == 0 or above[0] == 0:
        return float("nan")
    k = above[0]
    return float(s[k - 1] + (s[k] - s[k - 1]) * (rho - r[k - 1]) / (r[k] - r[k - 1]))


def summarize(history: dict, densities=DENSITIES, column: str = "rho") -> dict:
    """The run's table row: sigma_m (MPa, compression > 0) at ``densities`` and the end state."""
    s = history["sigma_m"]
    return {
        **{f"sigma_m_{rho:.2f}": sigma_at(history, rho, column) for rho in densities},
        "rho_end": float(history["rho"][-1]),
        "sigma_m_end": float(s[-1]),
        "end_over_max": float(s[-1] / np.nanmax(s)),
        "rho_minus_rho_fe_rel": float(
            abs(history["rho"] - history["rho_fe"]).max() / history["rho"][-1]
        ),
        "unbalanced_end": float(history["unbalanced"][-1])
        if "unbalanced" in history
        else float("nan"),
        "E_c_over_E_int_end": float(history["E_c_over_E_int"][-1])
        if "E_c_over_E_int" in history
        else float("nan"),
        "wall_s": float(history["wall_time"][-1]),
    }


def main(argv=None) -> list[dict]:
    """Run the missing rate and mesh cases, write the CSV and print the table; return its rows."""
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    d = CompactionCase()
    p.add_argument("--particles", type=int, default=d.packing.particles)
    p.add_argument(
        "--increments",
        type=int,
        nargs="+",
        default=[d.solver.increments, 2 * d.solver.increments, 4 * d.solver.increments],
    )
    p.add_argument(
        "--meshes", nargs="+", choices=tuple(RESOLUTIONS), default=["chapter2", "chapter4"]
    )
    p.add_argument(
        "--profile",
        nargs="+",
        choices=tuple(PROFILES),
        default=[d.loading.profile],
        help="amplitude of the compaction in time ([loading] profile)",
    )
    p.add_argument("--target-density", type=float, default=d.loading.target_density)
    p.add_argument("--outputs", type=int, default=100, help="history rows over the path")
    p.add_argument("--loading", default=d.loading.path, help="[loading] path (isotropic, die)")
    p.add_argument(
        "--bc", default=d.boundary.condition, help="[boundary] condition: CLP, CLPS, GDF or GDH"
    )
    p.add_argument(
        "--d-bc", type=float, default=None, help="duplication distance / r_max (default: table 2.3)"
    )
    p.add_argument(
        "--divisions", type=int, default=None, help="hexahedra per inner-cube edge of the particle"
    )
    p.add_argument(
        "--radius-factor",
        type=float,
        default=d.mesh.radius_factor,
        help="[mesh] radius_factor (a coarse volume-exact particle needs less than 0.99: "
        "4 divisions <= 0.9778)",
    )
    p.add_argument(
        "--constraint-mass",
        choices=CONSTRAINT_MASSES,
        default=d.solver.constraint_mass,
        help="explicit reduced mass of the constrained model ([solver] constraint_mass)",
    )
    p.add_argument(
        "--densities",
        type=float,
        nargs="+",
        default=list(DENSITIES),
        help="densities where sigma_m is read",
    )
    p.add_argument(
        "--density",
        choices=("rho", "rho_imposed"),
        default="rho",
        help="the density column the sigma_m are read on",
    )
    p.add_argument("--out", default="results/convergence")
    p.add_argument(
        "--table-only", action="store_true", help="tabulate the finished runs in --out, run nothing"
    )
    args = p.parse_args(argv)
    if args.particles < 2 or min(args.increments) < 10:
        p.error("--particles must be >= 2 and --increments >= 10")
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    out = Path(args.out)
    options = dict(
        path=args.loading,
        condition=args.bc,
        d_bc=args.d_bc,
        divisions=args.divisions,
        radius_factor=args.radius_factor,
        constraint_mass=args.constraint_mass,
    )
    variant = (
        ""
        if (args.loading, args.bc, args.d_bc, args.divisions)
        == (d.loading.path, d.boundary.condition, None, None)
        else (
            f"_{args.loading}_{args.bc}"
            + (f"_dbc{args.d_bc:g}" if args.d_bc is not None else "")
            + (f"_div{args.divisions}" if args.divisions is not None else "")
        )
    )
    if args.radius_factor != d.mesh.radius_factor:
        variant += f"_rf{args.radius_factor:g}"
    if args.constraint_mass != d.solver.constraint_mass:
        variant += f"_{args.constraint_mass}_mass"
    densities = tuple(args.densities)
    columns = [f"sigma_m_{rho:.2f}" for rho in densities]
    rows = []
    for mesh, profile in itertools.product(args.meshes, args.profile):
        for n in sorted(args.increments):
            run_dir = out / f"p{args.particles}{variant}_{mesh}_{profile}_n{n}"
            done = (run_dir / "done").exists()
            if not done and not args.table_only:
                say(
                    f"--- {args.particles} particles, mesh {mesh}, {profile}, {n} increments -> "
                    f"{run_dir}"
                )
                start = time.perf_counter()
                case = CompactionCase.build(
                    particles=args.particles,
                    resolution=mesh,
                    profile=profile,
                    increments=n,
                    target_density=args.target_density,
                    outputs=args.outputs,
                    visual=False,
                    checkpoint_every=0,
                    directory=str(run_dir),
                    **options,
                )
                run_compaction(case, comm, log=lambda *a, **k: None)
                if comm.rank == 0:
                    (run_dir / "done").write_text(f"{time.perf_counter() - start:.1f}\n")
                done = True
            if done and comm.rank == 0:
                rows.append(
                    {
                        "particles": args.particles,
                        "variant": variant.lstrip("_") or "-",
                        "mesh": mesh,
                        "profile": profile,
                        "increments": n,
                        **summarize(read_csv(run_dir / "history.csv"), densities, args.density),
                    }
                )
    if comm.rank == 0 and rows:
        for mesh, profile in itertools.product(
            args.meshes, args.profile
        ):  # vs the finest rate, same mesh and profile
            same = [r for r in rows if r["mesh"] == mesh and r["profile"] == profile]
            if not same:
                continue
            ref = max(same, key=lambda r: r["increments"])
            for r in same:
                r["max_dev_from_finest"] = max(abs(r[c] / ref[c] - 1.0) for c in columns)
        out.mkdir(parents=True, exist_ok=True)
        with open(out / "convergence.csv", "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        read_on = " / ".join(f"{rho:.2f}" for rho in densities)
        header = (
            f"| particles | variant | mesh | profile | N | sigma_m at {args.density} {read_on} "
            "(MPa) | max dev. "
            "from finest N | end / max | max abs(rho - rho_fe) / rho | unbalanced (end) | "
            "E_c/E_int (end) | "
            "wall (s) |"
        )
        say(header)
        say("|---" * 12 + "|")
        for r in rows:
            say(
                f"| {r['particles']} | {r['variant']} | {r['mesh']} | {r['profile']} | "
                f"{r['increments']} | " + " / ".join(f"{r[c]:.3f}" for c in columns) + " | "
                f"{100 * r['max_dev_from_finest']:.2f} % | {r['end_over_max']:.4f} | "
                f"{r['rho_minus_rho_fe_rel']:.2e} | "
                f"{r['unbalanced_end']:.2e} | {r['E_c_over_E_int_end']:.2e} | {r['wall_s']:.0f} |"
            )
        sys.stdout.flush()
    return rows


if __name__ == "__main__":
    main()
