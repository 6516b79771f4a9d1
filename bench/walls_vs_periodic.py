"""The simple cubic cell between six frictionless walls against the periodic cell, row by row.

    python bench/walls_vs_periodic.py --periodic 16000 --walls 16000 32000   # missing runs, table
    python bench/walls_vs_periodic.py --walls 16000 --frame flow      # damped in the flow frame
    python bench/walls_vs_periodic.py --newton 80     # both realizations by Newton, 80 steps
    python bench/walls_vs_periodic.py --table                                # the kept runs
    python bench/walls_vs_periodic.py --mirrored --newton 80   # mirrored meshes (kept apart)

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
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
KEPT = ROOT / "measured" / "simple_cubic_walls"


def kept(mirrored: bool) -> Path:
    """The runs' folder: the generic orientation's, or the mirrored meshes' (``--mirrored``)."""
    return KEPT / "mirrored" if mirrored else KEPT


#: walls' history columns and the periodic cell's (Love-Weber, compression > 0)
PAIRS = (
    ("sigma_zz_walls", "sigma33"),
    ("sigma_xx_walls", "sigma11"),
    ("sigma_yy_walls", "sigma22"),
)


def run_periodic(increments: int, mirrored: bool = False) -> Path:
    """The periodic cell's die compaction at ``increments`` (unless kept)."""
    from mpi4py import MPI

    from mpfem_fenicsx.workflows.compaction import run_compaction
    from mpfem_fenicsx.workflows.simple_cubic import simple_cubic_case

    out = kept(mirrored) / f"periodic_n{increments}"
    if not (out / "die" / "history.csv").is_file():
        case = simple_cubic_case(
            "die", increments=increments, out_dir=str(out), visual=False, mirrored=mirrored
        )
        run_compaction(case, MPI.COMM_SELF, log=print)
        shutil.rmtree(out / "die" / "checkpoints", ignore_errors=True)  # 14 MB, not kept
    return out / "die"


#: the drag of both Newton realizations (E V_p / h^2): weak whatever the contacts, since the
#: die's two axial contacts do not hold a particle laterally
NEWTON_DRAG = 5e-4


def run_newton(steps: int, mirrored: bool = False) -> tuple[Path, Path]:
    """Both realizations by Newton in ``steps`` load steps (unless kept)."""
    from mpi4py import MPI

    from mpfem_fenicsx.workflows.compaction import run_compaction
    from mpfem_fenicsx.workflows.simple_cubic import between_walls, simple_cubic_case

    root = kept(mirrored)
    periodic, walls = root / f"periodic_newton_s{steps}", root / f"walls_newton_s{steps}"
    if not (periodic / "die" / "history.csv").is_file():
        case = simple_cubic_case(
            "die", out_dir=str(periodic), visual=False, mirrored=mirrored
        ).updated(
            kind="implicit",
            steps=steps,
            images=True,
            regularization=NEWTON_DRAG,
            held_regularization=NEWTON_DRAG,
            checkpoint_every=0,
            outputs=steps,
        )
        run_compaction(case, MPI.COMM_SELF, log=print)
    if not (walls / "history.csv").is_file():
        between_walls(
            out_dir=str(walls),
            comm=MPI.COMM_SELF,
            solver="implicit",
            steps=steps,
            outputs=steps,
            regularization=NEWTON_DRAG,
            mirrored=mirrored,
        )
    return periodic / "die", walls


def run_walls(increments: int, frame: str, mirrored: bool = False) -> Path:
    """The cell between walls at ``increments``, damped in ``frame`` (unless kept)."""
    from mpi4py import MPI

    from mpfem_fenicsx.workflows.simple_cubic import between_walls

    name = f"walls_n{increments}" if frame == "rest" else f"walls_{frame}_n{increments}"
    out = kept(mirrored) / name
    if not (out / "history.csv").is_file():
        between_walls(
            increments=increments,
            out_dir=str(out),
            comm=MPI.COMM_SELF,
            damping_frame=frame,
            mirrored=mirrored,
        )
    return out


def table(mirrored: bool = False) -> str:
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

    root = kept(mirrored)
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
        if done(folder) and history_path(ref_folder).is_file():
            # the periodic run by Newton may stop short of 0.95 (Newton below its minimum
            # increment): both compared up to its last row
            ref = read_csv(history_path(ref_folder))
            out += [
                "",
                f"by Newton: reference {ref_folder.name}, last row at rho {ref['rho'][-1]:.4f}: "
                + " / ".join(f"{ref[c][-1]:.2f}" for _, c in PAIRS)
                + " MPa (sigma_zz / xx / yy; 'end' below: at that rho)",
                "",
                *_compare(ref, [(folder.name, read_csv(history_path(folder)))]),
            ]
    return "\n".join(out) if out else "(no runs kept)"


def _compare(ref: dict, runs: list) -> list[str]:
    """Table lines: each of ``runs`` ((label, history)) against the periodic ``ref`` at its
    densities past 5 % of its final stresses (a walls run by its wall columns)."""
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
            past = ref[ref_col] >= 0.05 * ref[ref_col][-1]
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
    parser.add_argument("--table", action="store_true", help="only the table of the kept runs")
    parser.add_argument(
        "--mirrored", action="store_true", help="particle meshes mirrored across the contact planes"
    )
    args = parser.parse_args(argv)
    if not args.table:
        for n in args.periodic:
            run_periodic(n, args.mirrored)
        for n in args.walls:
            run_walls(n, args.frame, args.mirrored)
        for n in args.newton:
            run_newton(n, args.mirrored)
    print(table(args.mirrored))


if __name__ == "__main__":
    main()
