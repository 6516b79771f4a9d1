"""The closed die's pressing curve against the number of increments (and the damping's frame).

    python bench/closed_die_rates.py --increments 8000 16000   # runs the missing ones, the table
    python bench/closed_die_rates.py --table                   # the table of the runs kept

Each run is `demos/closed_die.py`'s default case (12 lead particles poured into a die, single
action to a green density of 0.85, wall friction 0.1) at the given increments per pressing time,
kept in bench/measured/closed_die/<label>/ (history.csv, summary.json, density_bins.csv): a run
already there is not run again. The table compares, per run, the upper and lower punch pressures
at green densities 0.55 to 0.85 (interpolated along the pressing), the largest imbalance of the
tools' axial forces while the punch moves at constant speed (the particles' inertia over the
punch force), the end of the hold (pressures, out of balance), the springback and the ejection
force. A pressing curve converged in the increments no longer moves between two rows.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
KEPT = ROOT / "measured" / "closed_die"
DENSITIES = (0.55, 0.65, 0.75, 0.85)


def run(increments: int, frame: str) -> Path:
    """Run the default case at ``increments`` with the damping's ``frame`` (unless kept)."""
    from mpi4py import MPI

    from mpfem_fenicsx.workflows.closed_die import ClosedDieCase, run_closed_die

    label = f"n{increments}" + ("" if frame == "flow" else f"_{frame}")
    out = KEPT / label
    if (out / "summary.json").is_file():
        return out
    case = ClosedDieCase(increments=increments, damping_frame=frame, out_dir=str(out))
    result = run_closed_die(case, MPI.COMM_WORLD, render=False)
    for line in result.report():
        print(line)
    return out


def table(folders: list[Path]) -> str:
    """The comparison table (Markdown) of the kept runs."""
    from mpfem_fenicsx.io.history import read_csv
    from mpfem_fenicsx.workflows.closed_die import balanced_push

    head = " | ".join(f"p_up / p_low at {d}" for d in DENSITIES)
    lines = [
        f"| run | {head} | tools' imbalance at constant speed | end of hold p_up / p_low, "
        "out of balance | springback | ejection force: summary, balanced rows | wall time |",
        "|---" * (len(DENSITIES) + 6) + "|",
    ]
    for folder in folders:
        s = json.loads((folder / "summary.json").read_text())
        h = read_csv(folder / "history.csv")
        pressing = h["stage"] == 1
        rho = h["green_density"][pressing]
        cells = []
        for d in DENSITIES:
            if rho.max() < d - 1e-9:
                cells.append("-")
                continue
            up = np.interp(d, rho, h["upper_pressure"][pressing])
            low = np.interp(d, rho, h["lower_pressure"][pressing])
            cells.append(f"{up:.2f} / {low:.2f}")
        # the ejection force from the history's rows where the tools balance (the compact's
        # inertia left out; summaries before that measure kept every increment's)
        F = np.column_stack([h[f"{t}_Fz"] for t in ("upper", "lower", "die")])[h["stage"] == 4]
        pushes = [balanced_push(f) for f in F]
        eject = np.nanmax(pushes) if np.isfinite(pushes).any() else float("nan")
        lines.append(
            f"| {folder.name} | "
            + " | ".join(cells)
            + f" | {100 * s['tools_balance_pressing']:.1f} % | "
            f"{s['upper_pressure_pressed']:.3f} / {s['lower_pressure_pressed']:.3f} MPa, "
            f"{s['unbalanced_hold']:.1g} | {100 * s['springback']:.2f} % | "
            f"{s['ejection_force']:.3f} N, balanced rows {eject:.3f} N | "
            f"{s['wall_time_s']:.0f} s |"
        )
    return "\n".join(lines)


def main(argv=None) -> None:
    """Run the requested increments (unless kept), then print the table of every kept run."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--increments", type=int, nargs="*", default=[])
    parser.add_argument("--frame", choices=("flow", "rest"), default="flow")
    parser.add_argument("--table", action="store_true", help="only print the table")
    args = parser.parse_args(argv)
    if not args.table:
        for n in args.increments:
            run(n, args.frame)
    kept = sorted(p.parent for p in KEPT.glob("*/summary.json"))
    print(table(kept) if kept else "no run kept yet")


if __name__ == "__main__":
    main()
