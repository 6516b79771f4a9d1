"""The simple cubic cell between six frictionless walls against the periodic cell, row by row.

    python bench/walls_vs_periodic.py --periodic 16000 --walls 16000 32000   # missing runs, table
    python bench/walls_vs_periodic.py --walls 16000 --frame flow      # damped in the flow frame
    python bench/walls_vs_periodic.py --table                                # the kept runs

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
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
KEPT = ROOT / "measured" / "simple_cubic_walls"
#: walls' history columns and the periodic cell's (Love-Weber, compression > 0)
PAIRS = (
    ("sigma_zz_walls", "sigma33"),
    ("sigma_xx_walls", "sigma11"),
    ("sigma_yy_walls", "sigma22"),
)


def run_periodic(increments: int) -> Path:
    """The periodic cell's die compaction at ``increments`` (unless kept)."""
    from mpi4py import MPI

    from mpfem_fenicsx.workflows.compaction import run_compaction
    from mpfem_fenicsx.workflows.simple_cubic import simple_cubic_case

    out = KEPT / f"periodic_n{increments}"
    if not (out / "die" / "history.csv").is_file():
        case = simple_cubic_case("die", increments=increments, out_dir=str(out), visual=False)
        run_compaction(case, MPI.COMM_SELF, log=print)
        shutil.rmtree(out / "die" / "checkpoints", ignore_errors=True)  # 14 MB, not kept
    return out / "die"


def run_walls(increments: int, frame: str) -> Path:
    """The cell between walls at ``increments``, damped in ``frame`` (unless kept)."""
    from mpi4py import MPI

    from mpfem_fenicsx.workflows.simple_cubic import between_walls

    out = KEPT / (f"walls_n{increments}" if frame == "rest" else f"walls_{frame}_n{increments}")
    if not (out / "history.csv").is_file():
        between_walls(
            increments=increments, out_dir=str(out), comm=MPI.COMM_SELF, damping_frame=frame
        )
    return out


def table() -> str:
    """The comparison table (Markdown) of the kept walls runs against the slowest periodic."""
    from mpfem_fenicsx.io.history import read_csv

    def increments(folder: Path) -> int:
        return int(folder.name.split("_n")[1])

    def history_path(folder: Path) -> Path:  # the periodic runs write into their path's folder
        return folder / ("die" if folder.name.startswith("periodic") else "") / "history.csv"

    def done(folder: Path) -> bool:  # a run still going (or cut) has not reached 0.95
        path = history_path(folder)
        return path.is_file() and read_csv(path)["rho"][-1] >= 0.95 - 1e-6

    periodic = sorted(filter(done, KEPT.glob("periodic_n*")), key=increments)
    walls = sorted(filter(done, KEPT.glob("walls_*")), key=increments)
    if not periodic or not walls:
        return "(no runs kept)"
    ref = read_csv(history_path(periodic[-1]))
    lines = [
        f"reference: the periodic cell at {increments(periodic[-1])} increments, end "
        + " / ".join(f"{ref[c][-1]:.2f}" for _, c in PAIRS)
        + " MPa (sigma_zz / xx / yy)",
        "",
        "| run | end sigma_zz / xx / yy (MPa) | end vs periodic | largest row difference past "
        "5 % of the final stress (zz / xx / yy) | at rho |",
        "|---|---|---|---|---|",
    ]
    for folder in [*periodic[:-1], *walls]:
        h = read_csv(history_path(folder))
        cols = [c for c, _ in PAIRS] if folder.name.startswith("walls") else [c for _, c in PAIRS]
        ends, worst, where = [], [], []
        for col, (_, ref_col) in zip(cols, PAIRS, strict=True):
            ends.append(h[col][-1])
            past = ref[ref_col] >= 0.05 * ref[ref_col][-1]
            rho = ref["rho"][past]
            mine = np.interp(rho, h["rho"], h[col])
            diff = mine / ref[ref_col][past] - 1.0
            k = int(np.argmax(np.abs(diff)))
            worst.append(diff[k])
            where.append(rho[k])
        end_diff = [e / ref[c][-1] - 1.0 for e, (_, c) in zip(ends, PAIRS, strict=True)]
        lines.append(
            f"| {folder.name} | "
            + " / ".join(f"{e:.2f}" for e in ends)
            + " | "
            + " / ".join(f"{100 * d:+.2f} %" for d in end_diff)
            + " | "
            + " / ".join(f"{100 * w:+.1f} %" for w in worst)
            + " | "
            + " / ".join(f"{r:.3f}" for r in where)
            + " |"
        )
    return "\n".join(lines)


def main(argv=None) -> None:
    """Run the missing runs, print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--periodic", type=int, nargs="*", default=[], help="increments")
    parser.add_argument("--walls", type=int, nargs="*", default=[], help="increments")
    parser.add_argument("--frame", choices=("rest", "flow"), default="rest", help="damping's")
    parser.add_argument("--table", action="store_true", help="only the table of the kept runs")
    args = parser.parse_args(argv)
    if not args.table:
        for n in args.periodic:
            run_periodic(n)
        for n in args.walls:
            run_walls(n, args.frame)
    print(table())


if __name__ == "__main__":
    main()
