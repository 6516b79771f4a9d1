"""The simple cubic cell between six frictionless walls against the periodic cell, row by row.

    python bench/walls_vs_periodic.py --periodic 16000 --walls 16000 32000   # missing runs, table
    python bench/walls_vs_periodic.py --walls 16000 --frame flow      # damped in the flow frame
    python bench/walls_vs_periodic.py --newton 80     # both realizations by Newton, 80 steps
    python bench/walls_vs_periodic.py --table                                # the kept runs
    python bench/walls_vs_periodic.py --mirrored --newton 80   # mirrored meshes (kept apart)
    python bench/walls_vs_periodic.py --refinement 2 --newton 80   # the refined particle
    python bench/walls_vs_periodic.py --newton 80 --drag 5e-5      # a weaker drag, both

Two realizations of one die compaction (rho pi / 6 -> 0.95): the thesis' periodic cell (CLP by
copies, `simple_cubic_case("die")`) and its eight spheres in a box of rigid planes on the cell's
contact planes, the top plane following the periodic path's F0_zz(t)
(`simple_cubic.between_walls`). The walls are the cell's symmetry planes: the stresses must
agree at every row once both runs are quasi-static. Runs are kept in
bench/measured/simple_cubic_walls/<label>/history.csv (a run already there is not run again; one
process per run, `MPI.COMM_SELF`; the periodic runs' checkpoints are deleted after the run).
The table interpolates every walls run at the periodic
reference's densities (the slowest periodic run kept) and reports, past 5 % of the final
stress, the largest relative difference of sigma_zz, sigma_xx, sigma_yy, and the end values.

By Newton (``--newton STEPS``), both realizations follow the static path (no inertia, no
damping): the periodic cell by images (equal to the copies to 1e-11), the walls by
`between_walls(solver="implicit")`, both with the pseudo-time drag on the particles' cores at
5e-4 E V_p / h^2 relative to the homogeneous flow (kept as periodic_newton_s<STEPS> and
walls_newton_s<STEPS>, compared with each other).

``--mirrored``: the same runs with the particle meshes mirror images of each other across the
contact planes (`simple_cubic.mirrored_rotations`), so that the walls are symmetry planes of the
discrete problem too, kept in bench/measured/simple_cubic_walls/mirrored/.

``--refinement N``: both realizations on the chapter-2 particle refined N times (its
subdivisions times N: h / N, the facets' sag inside the sphere / N^2), kept in
bench/measured/simple_cubic_walls/refined<N>/.

``--drag D``: both Newton realizations with the drag D E V_p / h^2 instead of 5e-4 (kept as
periodic_newton_s<STEPS>_drag<D>, walls_newton_s<STEPS>_drag<D>): the drag carries a share of
the load and regularizes the static path, so two drags show how far each path depends on it.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
KEPT = ROOT / "measured" / "simple_cubic_walls"


def kept(mirrored: bool, refinement: int = 1) -> Path:
    """The runs' folder: the generic orientation's, or the mirrored meshes' (``--mirrored``),
    on the chapter-2 particle or refined (``--refinement``)."""
    root = KEPT / "mirrored" if mirrored else KEPT
    return root / f"refined{refinement}" if refinement > 1 else root


#: walls' history columns and the periodic cell's (Love-Weber, compression > 0)
PAIRS = (
    ("sigma_zz_walls", "sigma33"),
    ("sigma_xx_walls", "sigma11"),
    ("sigma_yy_walls", "sigma22"),
)


def run_periodic(increments: int, mirrored: bool = False, refinement: int = 1) -> Path:
    """The periodic cell's die compaction at ``increments`` (unless kept)."""
    from mpi4py import MPI

    from mpfem_fenicsx.workflows.compaction import run_compaction
    from mpfem_fenicsx.workflows.simple_cubic import simple_cubic_case

    out = kept(mirrored, refinement) / f"periodic_n{increments}"
    if not (out / "die" / "history.csv").is_file():
        case = simple_cubic_case(
            "die",
            increments=increments,
            out_dir=str(out),
            visual=False,
            mirrored=mirrored,
            refinement=refinement,
        )
        run_compaction(case, MPI.COMM_SELF, log=print)
        shutil.rmtree(out / "die" / "checkpoints", ignore_errors=True)  # 14 MB, not kept
    return out / "die"


#: the drag of both Newton realizations (E V_p / h^2): weak whatever the contacts, since the
#: die's two axial contacts do not hold a particle laterally
NEWTON_DRAG = 5e-4


def finished(folder: Path) -> bool:
    """A run that ended (marked ``done``; or, kept before the marker, a history without
    checkpoints left): not run again. A killed run has its checkpoints and continues."""
    history = folder / "history.csv"
    return (folder / "done").is_file() or (
        history.is_file() and not (folder / "checkpoints").exists()
    )


def mark_done(folder: Path) -> None:
    """Mark a run ended and drop its checkpoints (not kept in the repository once it ended)."""
    shutil.rmtree(folder / "checkpoints", ignore_errors=True)
    (folder / "done").write_text("ended\n")


def run_newton(
    steps: int,
    mirrored: bool = False,
    refinement: int = 1,
    only: str | None = None,
    drag: float = NEWTON_DRAG,
) -> tuple[Path, Path]:
    """Both realizations by Newton in ``steps`` load steps at the core ``drag`` (unless kept;
    ``only``: one of them), each checkpointed every 5 steps and continued from its newest
    checkpoint when killed."""
    from mpi4py import MPI

    from mpfem_fenicsx.io.checkpoint import CheckpointError, resolve_checkpoint
    from mpfem_fenicsx.workflows.compaction import RunFailure, run_compaction
    from mpfem_fenicsx.workflows.simple_cubic import between_walls, simple_cubic_case

    root = kept(mirrored, refinement)
    label = f"newton_s{steps}" + ("" if drag == NEWTON_DRAG else f"_drag{drag:g}")
    periodic, walls = root / f"periodic_{label}", root / f"walls_{label}"
    if only != "walls" and not finished(periodic / "die"):
        case = simple_cubic_case(
            "die", out_dir=str(periodic), visual=False, mirrored=mirrored, refinement=refinement
        ).updated(
            kind="implicit",
            steps=steps,
            images=True,
            regularization=drag,
            held_regularization=drag,
            checkpoint_every=5,
            outputs=steps,
        )
        try:
            restart = resolve_checkpoint(periodic / "die")
        except CheckpointError:
            restart = None
        try:
            run_compaction(case, MPI.COMM_SELF, log=print, restart=restart)
        except RunFailure as err:  # Newton below its minimum increment: compared up to there
            print(err)
        mark_done(periodic / "die")
    if only != "periodic" and not finished(walls):
        between_walls(
            out_dir=str(walls),
            comm=MPI.COMM_SELF,
            solver="implicit",
            steps=steps,
            outputs=steps,
            regularization=drag,
            mirrored=mirrored,
            refinement=refinement,
            checkpoint_every=5,
        )
        mark_done(walls)
    return periodic / "die", walls


def run_walls(increments: int, frame: str, mirrored: bool = False, refinement: int = 1) -> Path:
    """The cell between walls at ``increments``, damped in ``frame`` (unless kept)."""
    from mpi4py import MPI

    from mpfem_fenicsx.workflows.simple_cubic import between_walls

    name = f"walls_n{increments}" if frame == "rest" else f"walls_{frame}_n{increments}"
    out = kept(mirrored, refinement) / name
    if not (out / "history.csv").is_file():
        between_walls(
            increments=increments,
            out_dir=str(out),
            comm=MPI.COMM_SELF,
            damping_frame=frame,
            mirrored=mirrored,
            refinement=refinement,
        )
    return out


def table(mirrored: bool = False, refinement: int = 1) -> str:
    """The comparison tables (Markdown) of the kept runs: the explicit walls runs against the
    slowest explicit periodic run, each Newton walls run against the Newton periodic run of
    its step count."""
    from mpfem_fenicsx.io.history import read_csv

    def increments(folder: Path) -> int:
        return int(folder.name.split("_n")[1])

    def history_path(folder: Path) -> Path:  # the periodic runs write into their path's folder
        return folder / ("die" if folder.name.startswith("periodic") else "") / "history.csv"

    def done(folder: Path) -> bool:  # a run still going (or cut) has not reached 0.95
        path = history_path(folder)
        return path.is_file() and read_csv(path)["rho"][-1] >= 0.95 - 1e-6

    root = kept(mirrored, refinement)
    explicit = [f for f in root.glob("*_n*") if "newton" not in f.name and done(f)]
    periodic = sorted((f for f in explicit if f.name.startswith("periodic")), key=increments)
    walls = sorted((f for f in explicit if f.name.startswith("walls")), key=increments)
    out = []
    if periodic and walls:
        ref = read_csv(history_path(periodic[-1]))
        out += [
            f"reference: the periodic cell at {increments(periodic[-1])} increments, end "
            + " / ".join(f"{ref[c][-1]:.2f}" for _, c in PAIRS)
            + " MPa (sigma_zz / xx / yy)",
            "",
            *_compare(ref, [(f.name, read_csv(history_path(f))) for f in periodic[:-1] + walls]),
        ]
    for folder in sorted(root.glob("walls_newton_s*")):
        ref_folder = root / folder.name.replace("walls", "periodic")
        if not (history_path(folder).is_file() and history_path(ref_folder).is_file()):
            continue
        # the periodic run by Newton may stop short of 0.95 (Newton below its minimum
        # increment), and a run under way has not reached it: both compared up to the
        # shorter one's last row
        ref, mine = read_csv(history_path(ref_folder)), read_csv(history_path(folder))
        last = min(ref["rho"][-1], mine["rho"][-1])
        ref = {k: v[ref["rho"] <= last + 1e-12] for k, v in ref.items()}
        partial = not (done(folder) and finished(ref_folder / "die"))
        # past 5 % of the final stress: a partial comparison takes the final stresses of
        # the chapter-2 particle's periodic run by Newton (its ends agree within 1 %)
        final = None
        if partial and history_path(KEPT / ref_folder.name).is_file():
            coarse = read_csv(history_path(KEPT / ref_folder.name))
            final = {c: coarse[c][-1] for _, c in PAIRS}
        out += [
            "",
            f"by Newton: reference {ref_folder.name}, compared up to rho {last:.4f}"
            + (" (runs under way)" if partial else "")
            + ": "
            + " / ".join(f"{ref[c][-1]:.2f}" for _, c in PAIRS)
            + " MPa (sigma_zz / xx / yy; 'end' below: at that rho)",
            "",
            *_compare(ref, [(folder.name, mine)], final),
        ]
    return "\n".join(out) if out else "(no runs kept)"


def _compare(ref: dict, runs: list, final: dict | None = None) -> list[str]:
    """Table lines: each of ``runs`` ((label, history)) against the periodic ``ref`` at its
    densities past 5 % of its final stresses (``final``: these instead of ``ref``'s last row;
    a walls run by its wall columns)."""
    lines = [
        "| run | end sigma_zz / xx / yy (MPa) | end vs periodic | largest row difference past "
        "5 % of the final stress (zz / xx / yy) | at rho |",
        "|---|---|---|---|---|",
    ]
    for label, h in runs:
        cols = [c for c, _ in PAIRS] if label.startswith("walls") else [c for _, c in PAIRS]
        ends, worst, where = [], [], []
        for col, (_, ref_col) in zip(cols, PAIRS, strict=True):
            ends.append(np.interp(ref["rho"][-1], h["rho"], h[col]))
            end = ref[ref_col][-1] if final is None else final[ref_col]
            past = ref[ref_col] >= 0.05 * end
            rho = ref["rho"][past]
            mine = np.interp(rho, h["rho"], h[col])
            diff = mine / ref[ref_col][past] - 1.0
            k = int(np.argmax(np.abs(diff)))
            worst.append(diff[k])
            where.append(rho[k])
        end_diff = [e / ref[c][-1] - 1.0 for e, (_, c) in zip(ends, PAIRS, strict=True)]
        lines.append(
            f"| {label} | "
            + " / ".join(f"{e:.2f}" for e in ends)
            + " | "
            + " / ".join(f"{100 * d:+.2f} %" for d in end_diff)
            + " | "
            + " / ".join(f"{100 * w:+.1f} %" for w in worst)
            + " | "
            + " / ".join(f"{r:.3f}" for r in where)
            + " |"
        )
    return lines


def main(argv=None) -> None:
    """Run the missing runs, print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--periodic", type=int, nargs="*", default=[], help="increments")
    parser.add_argument("--walls", type=int, nargs="*", default=[], help="increments")
    parser.add_argument("--frame", choices=("rest", "flow"), default="rest", help="damping's")
    parser.add_argument("--newton", type=int, nargs="*", default=[], help="load steps")
    parser.add_argument(
        "--only",
        choices=("periodic", "walls"),
        default=None,
        help="--newton: run only this realization (the two side by side in two processes)",
    )
    parser.add_argument(
        "--drag", type=float, default=NEWTON_DRAG, help="--newton: the core drag (E V_p / h^2)"
    )
    parser.add_argument("--table", action="store_true", help="only the table of the kept runs")
    parser.add_argument(
        "--mirrored", action="store_true", help="particle meshes mirrored across the contact planes"
    )
    parser.add_argument(
        "--refinement", type=int, default=1, help="the chapter-2 particle refined (1-4)"
    )
    args = parser.parse_args(argv)
    if not 1 <= args.refinement <= 4:
        parser.error(f"--refinement {args.refinement} must be in [1, 4]")
    if not 0 < args.drag <= 1:
        parser.error(f"--drag {args.drag} must be in (0, 1]")
    m, r = args.mirrored, args.refinement
    if not args.table:
        for n in args.periodic:
            run_periodic(n, m, r)
        for n in args.walls:
            run_walls(n, args.frame, m, r)
        for n in args.newton:
            run_newton(n, m, r, args.only, args.drag)
    print(table(m, r))


if __name__ == "__main__":
    main()
