"""The flagship compacted by Newton against its explicit default, row by row.

    python bench/implicit_vs_explicit.py                 # the table of the kept histories
    python bench/implicit_vs_explicit.py --run explicit  # (re)run one realization, then the table
    python bench/implicit_vs_explicit.py --run implicit --restart CHECKPOINT   # continue one
    python bench/implicit_vs_explicit.py --run implicit --held-regularization 5e-4
        # a variant of the held drag (here the earlier default), kept in implicit_held_5e-4/
        # (its table: the same --held-regularization without --run)
    python bench/implicit_vs_explicit.py --case die50 --run implicit
        # the 50-particle die CLP to rho 0.95 by Newton (resumes from its newest checkpoint)
    python bench/implicit_vs_explicit.py --case random16 --run explicit --increments 48000
    python bench/implicit_vs_explicit.py --case random16 --run implicit --held-regularization 1e-3
        # the heavy test's random volume: one realization of it (explicit at a loading rate,
        # Newton at a held drag); without --run, the table of all those kept

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

``--case random16``: the heavy test's random volume (16 generated lead particles, radii
0.09-0.11 mm, seed 1, the coarse particle, CLP by images, rho 0.556 -> 0.66) by central
differences at several loading rates (``--increments``, kept in explicit_n<N>/) and by Newton
at several held drags (implicit_held_<drag>/), kept in bench/measured/implicit_random16/; the
table compares every kept run with the slowest explicit one.
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
#: the heavy test's random volume: its runs and the densities of its table
RANDOM16 = ROOT / "measured" / "implicit_random16"
RANDOM16_DENSITIES = (0.625, 0.63, 0.635, 0.64, 0.645, 0.65)


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


def run_die50(held: float | None, restart: str | None = None, steps: int | None = None) -> None:
    """The 50-particle die CLP by Newton: the validation campaign's case with the implicit
    solver (and the ``held`` drag), resumed from ``restart`` or else the newest checkpoint of
    its folder if any; ``steps``: another nominal number of load steps than the case's (a
    restart is exact: the same step sequence stalls where it stalled, another one takes other
    states past it; the drag's viscosity, c = k dt0, moves with dt0 by as much)."""
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
    if steps is not None:
        changes["steps"] = steps
    case = die_case("CLP").compaction_case(str(out)).updated(**changes)
    try:
        restart = restart or resolve_checkpoint(out)
    except CheckpointError:
        restart = None
    run_compaction(case, MPI.COMM_WORLD, restart=restart, progress=Progress(MPI.COMM_WORLD))


def run_random16(solver: str, increments: int, held: float | None) -> None:
    """The heavy test's random volume by ``solver``: explicit at ``increments``, or Newton at
    30 nominal steps and the ``held`` drag (the solver section's default if None)."""
    from mpi4py import MPI

    from mpfem_fenicsx.io.progress import Progress
    from mpfem_fenicsx.workflows.compaction import CompactionCase, run_compaction

    if solver == "explicit":
        out, count = RANDOM16 / f"explicit_n{increments}", {"increments": increments}
    else:
        out, count = RANDOM16 / implicit_folder(held), {"steps": 30}
        if held is not None:
            count["held_regularization"] = held
    case = CompactionCase.build(
        particles=16, r_min=0.09, r_max=0.11, seed=1, resolution="coarse", exact_volume=False,
        condition="CLP", images=True, target_density=0.66, outputs=40, visual=False,
        directory=str(out), kind=solver, **count,
    )  # fmt: skip
    run_compaction(case, MPI.COMM_WORLD, progress=Progress(MPI.COMM_WORLD))


def table_random16() -> None:
    """Every kept realization of the random volume against its slowest explicit run: sigma_m
    at the table's densities (relative difference), the largest difference past the first
    contacts (Z > 6) before rho 0.650 and past rho 0.638 (the heavy test's rows)."""
    runs = {p.parent.name: read(p) for p in sorted(RANDOM16.glob("*/history.csv"))}
    done = [
        k for k in runs if k.startswith("explicit_n") and runs[k]["rho_imposed"][-1] > 0.66 - 1e-9
    ]
    slowest = max(done, key=lambda k: int(k[10:]))  # of the explicit runs that reached 0.66
    ref = runs[slowest]
    print(f"sigma_m (MPa) and its difference from {slowest}")
    head = " | ".join(f"{r:.3f}" for r in RANDOM16_DENSITIES)
    print(f"| run | {head} | max Z>6 | max >0.638 |")
    print("|---" * (len(RANDOM16_DENSITIES) + 3) + "|")
    for name, h in runs.items():
        if name.startswith("explicit_n") and name not in done:
            print(f"| {name} | (under way: at rho {h['rho'][-1]:.4f}) |")
            continue
        cells = []
        for rho in RANDOM16_DENSITIES:
            e = np.interp(rho, ref["rho"], ref["sigma_m"])
            v = np.interp(rho, h["rho"], h["sigma_m"])
            cells.append(f"{v:.3f} ({v / e - 1:+.1%})")
        rows = (h["Z"] > 6.0) & (h["rho"] < 0.650)
        d = h["sigma_m"][rows] / np.interp(h["rho"][rows], ref["rho"], ref["sigma_m"]) - 1
        late = d[h["rho"][rows] > 0.638]
        print(
            f"| {name} | " + " | ".join(cells)
            + f" | {np.abs(d).max():.1%} | {np.abs(late).max() if late.size else np.nan:.1%} |"
        )  # fmt: skip


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
    # the work that each run's regularization dissipates, over E_p: the explicit run's damping
    # (local and bulk viscous), the implicit run's drag
    print(
        "| rho | explicit sigma_m (MPa) | implicit sigma_m (MPa) | implicit / explicit - 1 "
        "| explicit (E_damp + E_visc) / E_p | implicit E_drag / E_p |"
    )
    print("|---|---|---|---|---|---|")

    def at(h, rho, *keys):
        return sum(np.interp(rho, h["rho"], np.nan_to_num(h[k])) for k in keys)

    for rho in densities:
        e = at(explicit, rho, "sigma_m")
        damping = at(explicit, rho, "E_damp", "E_visc") / at(explicit, rho, "E_p")
        if rho > implicit["rho"].max():
            print(f"| {rho:.2f} | {e:.4g} | not reached | | {damping:.2%} | |")
            continue
        i = at(implicit, rho, "sigma_m")
        drag = at(implicit, rho, "E_damp") / at(implicit, rho, "E_p")
        print(f"| {rho:.2f} | {e:.4g} | {i:.4g} | {i / e - 1:+.2%} | {damping:.2%} | {drag:.2%} |")
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
        choices=("flagship", "die50", "random16"),
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
    parser.add_argument(
        "--steps", type=int, default=None, help="die50, implicit: nominal load steps (default 100)"
    )
    parser.add_argument(
        "--increments", type=int, default=24000, help="random16, explicit: its loading rate"
    )
    args = parser.parse_args(argv)
    if args.case == "random16":
        if args.run:
            run_random16(args.run, args.increments, args.held_regularization)
        table_random16()
        return
    die50 = args.case == "die50"
    if die50 and args.run == "explicit":
        parser.error("--case die50: its explicit run is the validation campaign's (make validate)")
    if args.run and die50:
        run_die50(args.held_regularization, args.restart, args.steps)
    elif args.run:
        run(args.run, args.restart, args.held_regularization)
    table(args.held_regularization, die50)


if __name__ == "__main__":
    main()
