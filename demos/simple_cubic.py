"""Simple cubic cell: verification of the homogenization (thesis §2.6, fig. 2.17-2.20).

    python demos/simple_cubic.py                          # isotropic and die, rho -> 0.95
    python demos/simple_cubic.py --loading die --increments 2000

Eight lead spheres of radius r in a periodic cube of side 4 r (solid fraction pi / 6), CLP,
compacted isotropically and in a die (uniaxial strain along z) to rho = 0.95 with the explicit
solver. Every particle is an exact translate of the others (one mesh, one generic orientation
so that contact points fall inside facets, not on nodes), so the motion stays affine:
- rho = V_p / (V0 det F) = pi / (6 det F) (eq. 2.17), F the least-squares gradient (eq. 2.2);
- the least-squares Hencky strain equals the Hencky strain of the auxiliary-node gradient F0;
- the Love-Weber stress (contact forces x branch vectors, eq. 2.6) equals the Schmidt stress
  (auxiliary-node reactions, eq. 2.19) once the cell is at rest.

Copies: the thesis used the 12 face copies only (fig. 2.17: "the packing being ordered, no
particle was duplicated in the corners"). Beyond rho ~ 0.9 the flattened spheres also touch
their diagonal neighbours, and those contacts across the cell edges need the edge copies: by
default all 19 copies (faces, edges, corner) are meshed; --face-copies-only gives the thesis'
12 (then the die path loses the exact symmetry, h_lsq - h_aux ~ 1e-6, at the end).

Outputs in --out (default results/simple_cubic/): <loading>/history.csv (the compaction history,
the columns of the history), <loading>/checks.csv (time, rho, rho_pi6 = pi / (6 det F), the six
Hencky components of the least-squares and auxiliary-node gradients, sigma_m of Love-Weber and
Schmidt), simple_cubic.png (rho vs h_v, least-squares vs auxiliary Hencky strain, Love-Weber vs
Schmidt) and the printed figures of the three checks.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np
from mpi4py import MPI

from mpfem_fenicsx.exits import bad_input_exits
from mpfem_fenicsx.options import add_case_option
from mpfem_fenicsx.workflows.compaction import initial_packing, run_compaction
from mpfem_fenicsx.workflows.simple_cubic import COMPONENTS, checks, simple_cubic_case


def write_checks(data: dict[str, np.ndarray], path: Path) -> None:
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(list(data))
        writer.writerows(
            zip(*[[repr(float(v)) for v in col] for col in data.values()], strict=True)
        )


def plot(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4))
    for loading, (res, chk) in results.items():
        h = res.history
        hv = -h.column("h_v")  # compaction: plot -h_v > 0
        axes[0].plot(hv, chk["rho"], "-", label=f"{loading}: least squares")
        axes[0].plot(hv, chk["rho_pi6"], "k:", lw=1)
        for a, b in [(0, 0), (2, 2)]:
            name = f"{a + 1}{b + 1}"
            axes[1].plot(
                hv,
                -chk[f"h_aux_{name}"],
                "-",
                lw=3,
                alpha=0.35,
                label=f"{loading} h{name}: auxiliary nodes",
            )
            axes[1].plot(hv, -chk[f"h_lsq_{name}"], "--", label=f"{loading} h{name}: least squares")
        for k in (1, 3):
            axes[2].plot(
                hv, h.column(f"sigma{k}{k}"), "-", label=f"{loading} sigma{k}{k}: Love-Weber"
            )
            axes[2].plot(
                hv, h.column(f"sigma_schmidt_{k}{k}"), "--", label=f"{loading} sigma{k}{k}: Schmidt"
            )
    axes[0].set(xlabel="-h_v", ylabel="relative density rho", title="rho = pi / (6 det F) (dotted)")
    axes[1].set(xlabel="-h_v", ylabel="-h_ii (Hencky)", title="least squares vs auxiliary nodes")
    axes[2].set(
        xlabel="-h_v", ylabel="stress (MPa, compression > 0)", title="Love-Weber vs Schmidt"
    )
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("Simple cubic cell, 8 lead spheres, CLP (thesis §2.6)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--loading", choices=("isotropic", "die", "both"), default="both")
    p.add_argument(
        "--radius", type=float, default=0.1, help="sphere radius r (mm); the cell is 4 r"
    )
    add_case_option(p, "loading", "target_density", default=0.95)
    add_case_option(p, "solver", "increments", default=4000, help="per loading")
    p.add_argument(
        "--face-copies-only",
        action="store_true",
        help="the thesis' 12 face copies (no edge / corner copies)",
    )
    p.add_argument(
        "--no-visual", action="store_true", help="skip ParaView output and the particle PNG"
    )
    p.add_argument("--out", default="results/simple_cubic")
    args = p.parse_args(argv)
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    out = Path(args.out)
    results = {}
    for loading in ("isotropic", "die") if args.loading == "both" else (args.loading,):
        with bad_input_exits():  # the case and its packing, checked before any mesh
            case = simple_cubic_case(
                loading,
                args.radius,
                args.target_density,
                args.increments,
                str(out),
                visual=not args.no_visual,
                face_copies_only=args.face_copies_only,
            )
            initial_packing(case.packing, case.mesh, case.loading.target_density)
        res = run_compaction(case, comm, log=lambda *a: None)
        chk = checks(res)
        results[loading] = (res, chk)
        if comm.rank == 0:
            write_checks(chk, out / loading / "checks.csv")
        rho_err = np.max(np.abs(chk["rho"] - chk["rho_pi6"]) / chk["rho_pi6"])
        h_err = max(
            np.max(np.abs(chk[f"h_lsq_{a + 1}{b + 1}"] - chk[f"h_aux_{a + 1}{b + 1}"]))
            for a, b in COMPONENTS
        )
        lw, sm = chk["sigma_m_love_weber"][-1], chk["sigma_m_schmidt"][-1]
        say(
            f"{loading}: rho = {chk['rho'][-1]:.4f}, "
            f"max |rho - pi/(6 det F)| / rho = {rho_err:.2e}, "
            f"max |h_lsq - h_aux| = {h_err:.2e}, "
            f"sigma_m Love-Weber {lw:.3f} / Schmidt {sm:.3f} MPa "
            f"({100 * abs(lw - sm) / abs(lw):.2f} %), {res.num_dofs} dofs, "
            f"{res.increments} increments, "
            f"wall {res.wall_time:.0f} s"
        )
    if comm.rank == 0:
        plot(results, out / "simple_cubic.png")
        say(f"outputs in {out}/: <loading>/history.csv, <loading>/checks.csv, simple_cubic.png")


if __name__ == "__main__":
    main()
