"""The flagship compacted by Newton against its explicit default, row by row.

    python bench/implicit_vs_explicit.py                 # the table of the kept histories
    python bench/implicit_vs_explicit.py --run explicit  # (re)run one realization, then the table
    python bench/implicit_vs_explicit.py --run implicit --restart CHECKPOINT   # continue one
    python bench/implicit_vs_explicit.py --run implicit --held-regularization 5e-4
        # a variant of the held drag (here the earlier default), kept in implicit_held_5e-4/
        # (its table: the same --held-regularization without --run)
    python bench/implicit_vs_explicit.py --case die50 --run implicit
        # the 50-particle die CLP to rho 0.95 by Newton (resumes from its newest checkpoint)

Two realizations of one compaction (`demos/isotropic.py`'s default: 24 lead particles, CLP by
images, rho 0.59 -> 0.92): central differences with mass scaling and local damping at 6000
increments, and the quasi-static Newton path at 100 load steps (pseudo-time drag on the
particles' cores). The histories are kept in bench/measured/implicit_flagship/<solver>/; the
implicit run checkpoints every 5 steps there (resumable with ``--restart``). The table gives
sigma_m of both at the issue's densities (the explicit curve interpolated where the implicit one
has reached them), the implicit run's progress (rho, Newton iterations per step, cut-backs,
the drag's work over E_p, the drag's out-of-balance share) and both wall times.

``--case die50``: the validation campaign's 50-particle die CLP (the thesis' particle, seed 1, by
periodic images, rho 0.61 -> 0.95; its explicit run at 6000 increments is
validation/runs/die_CLP) by Newton at 100 nominal load steps, kept in
bench/measured/implicit_die50/; it checkpoints every 5 steps and a new ``--run`` resumes from the
newest checkpoint there.
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
KEPT = ROOT / "measured" / "implicit_flagship"
DENSITIES = (0.62, 0.65, 0.70, 0.75, 0.80, 0.85, 0.90)
#: the 50-particle die CLP: its Newton runs, its explicit run (the validation campaign's) and
#: the densities of its table
DIE50 = ROOT / "measured" / "implicit_die50"
DIE50_EXPLICIT = ROOT.parent / "validation" / "runs" / "die_CLP"
DIE50_DENSITIES = (0.65, 0.70, 0.75, 0.80, 0.85, 0.90, 0.95)


def read(path: Path) -> dict[str, np.ndarray]:
    """A history's columns as float arrays (empty cells NaN)."""
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) if r[k] else np.nan for r in rows]) for k in rows[0]}


def implicit_folder(held: float | None) -> str:
    """The kept implicit run: the default drag's, or that of another ``held`` drag."""
    if held is None:
        return "implicit"
    return "implicit_held_" + np.format_float_scientific(held, trim="-", exp_digits=1)


def run(solver: str, restart: str | None, held: float | None = None) -> None:
    """One realization through the flagship demo (the case's defaults but the solver and, for
    Newton, the held particles' drag)."""
    out = KEPT / (implicit_folder(held) if solver == "implicit" else solver)
    cmd = [sys.executable, str(ROOT.parent / "demos" / "isotropic.py"), "--no-visual"]
    cmd += ["--solver", solver, "--out", str(out)]
    if solver == "implicit":
        cmd += ["--checkpoint-every", "5"]
        if held is not None:
            cmd += ["--held-regularization", str(held)]
    if restart:
        cmd += ["--restart", restart]
    subprocess.run(cmd, check=True)


def run_die50(held: float | None) -> None:
    """The 50-particle die CLP by Newton: the validation campaign's case with the implicit
    solver (and the ``held`` drag), resumed from the newest checkpoint of its folder if any."""
    sys.path.insert(0, str(ROOT.parent))  # the repository: the validation package
    from mpi4py import MPI

    from mpfem_fenicsx.io.checkpoint import CheckpointError, resolve_checkpoint
    from mpfem_fenicsx.io.progress import Progress
    from mpfem_fenicsx.workflows.compaction import run_compaction
    from validation.cases import die_case

    out = DIE50 / implicit_folder(held)
    changes = dict(kind="implicit", checkpoint_every=5, visual=False)
    if held is not None:
        changes["held_regularization"] = held
    case = die_case("CLP").compaction_case(str(out)).updated(**changes)
    try:
        restart = resolve_checkpoint(out)
    except CheckpointError:
        restart = None
    run_compaction(case, MPI.COMM_WORLD, restart=restart, progress=Progress(MPI.COMM_WORLD))


def table(held: float | None = None, die50: bool = False) -> None:
    """The comparison of the kept histories (the implicit run of the ``held`` drag): the
    flagship's, or the 50-particle die CLP's."""
    if die50:
        explicit = read(DIE50_EXPLICIT / "history.csv")
        implicit = read(DIE50 / implicit_folder(held) / "history.csv")
        densities = DIE50_DENSITIES
    else:
        explicit, implicit = (
            read(KEPT / s / "history.csv") for s in ("explicit", implicit_folder(held))
        )
        densities = DENSITIES
    print("| rho | explicit sigma_m (MPa) | implicit sigma_m (MPa) | implicit / explicit - 1 |")
    print("|---|---|---|---|")
    for rho in densities:
        if rho > implicit["rho"].max():
            print(
                f"| {rho:.2f} | {np.interp(rho, explicit['rho'], explicit['sigma_m']):.4g} "
                "| not reached | |"
            )
            continue
        e = np.interp(rho, explicit["rho"], explicit["sigma_m"])
        i = np.interp(rho, implicit["rho"], implicit["sigma_m"])
        print(f"| {rho:.2f} | {e:.4g} | {i:.4g} | {i / e - 1:+.2%} |")
    its = implicit["newton_iterations"]
    end = -1
    print(
        f"\nimplicit: {its.size} steps to rho {implicit['rho'][end]:.4f}, Newton iterations per "
        f"step {np.nanmedian(its):.0f} (median, max {np.nanmax(its):.0f}), "
        f"{implicit['cutbacks'][end]:.0f} cut-backs, E_drag / E_p "
        f"{implicit['E_damp'][end] / implicit['E_p'][end]:.2%}, drag share of the forces "
        f"{implicit['unbalanced'][end]:.3f}; wall {implicit['wall_time'][end]:.0f} s "
        f"(explicit: {explicit['wall_time'][-1]:.0f} s to rho {explicit['rho'][-1]:.4f})"
    )


def main(argv=None) -> None:
    """Run what ``--run`` asks, then print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--case",
        choices=("flagship", "die50"),
        default="flagship",
        help="the flagship (isotropic, 24 particles) or the 50-particle die CLP to rho 0.95",
    )
    parser.add_argument("--run", choices=("explicit", "implicit"), default=None)
    parser.add_argument("--restart", default=None, help="implicit: continue from a checkpoint")
    parser.add_argument(
        "--held-regularization",
        type=float,
        default=None,
        help="implicit: another drag on the held particles than the case's (E V_p / h^2)",
    )
    args = parser.parse_args(argv)
    die50 = args.case == "die50"
    if die50 and args.run == "explicit":
        parser.error("--case die50: its explicit run is the validation campaign's (make validate)")
    if args.run and die50:
        run_die50(args.held_regularization)
    elif args.run:
        run(args.run, args.restart, args.held_regularization)
    table(args.held_regularization, die50)


if __name__ == "__main__":
    main()
