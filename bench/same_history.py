"""Are two runs' histories the same, bit for bit? The check of a refactoring that must not move
the numbers.

    python bench/same_history.py results/a/history.csv results/b/history.csv
    python bench/same_history.py serial/history.csv np2/history.csv --within 1e-3
        # the same run on another number of ranks: the same contact count in every row, and
        # rho and sigma_m within 1e-3 of their largest value

Compares the two ``history.csv`` files column by column as written (the same text, so the same
bits), every column but ``wall_time``; prints the columns that differ with their largest
relative difference and exits 1 if any does (2 if the files do not have the same columns or
rows). With ``--within TOL`` the verdict is the one of two runs that may differ by round-off
(another number of ranks, another summation order): the ``n_contacts`` column equal in every row
and ``rho`` and ``sigma_m`` within TOL of the column's largest magnitude (the largest relative
difference of every differing column is printed).
"""

import argparse
import sys

import numpy as np


def read(path: str) -> tuple[list[str], list[list[str]]]:
    """The header and the rows of a history file, as text."""
    lines = open(path).read().splitlines()
    return lines[0].split(","), [line.split(",") for line in lines[1:]]


def differing_columns(a: str, b: str) -> list[str]:
    """The columns (wall_time aside) whose text differs, with their largest relative difference."""
    head_a, rows_a = read(a)
    head_b, rows_b = read(b)
    if head_a != head_b or len(rows_a) != len(rows_b):
        sys.exit(f"{a} and {b} differ in their columns or their number of rows")
    out = []
    for j, column in enumerate(head_a):
        if column == "wall_time" or all(x[j] == y[j] for x, y in zip(rows_a, rows_b, strict=True)):
            continue
        x = np.array([float(r[j] or "nan") for r in rows_a])
        y = np.array([float(r[j] or "nan") for r in rows_b])
        out.append(f"{column} ({np.nanmax(np.abs(x - y) / np.maximum(np.abs(x), 1e-300)):.2g})")
    return out


def main(argv=None) -> int:
    """Print the verdict; 0 when the histories are the same."""
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("a")
    p.add_argument("b")
    p.add_argument("--within", type=float, help="round-off verdict (see above)")
    args = p.parse_args(argv)
    if args.within is not None:
        return _within(args.a, args.b, args.within)
    rows = len(read(args.a)[1])
    diff = differing_columns(args.a, args.b)
    print(
        f"{rows} rows: "
        + (
            "the same, bit for bit (wall_time aside)"
            if not diff
            else "differ in " + ", ".join(diff)
        )
    )
    return 1 if diff else 0


def _within(a: str, b: str, tol: float) -> int:
    """The round-off verdict: 0 when the contact counts agree and rho, sigma_m are within tol."""
    head_a, rows_a = read(a)
    head_b, rows_b = read(b)
    if head_a != head_b or len(rows_a) != len(rows_b):
        sys.exit(f"{a} and {b} differ in their columns or their number of rows")
    failed = False
    for j, column in enumerate(head_a):
        if column == "wall_time":
            continue
        x = np.array([float(r[j] or "nan") for r in rows_a])
        y = np.array([float(r[j] or "nan") for r in rows_b])
        finite = np.isfinite(x) & np.isfinite(y)
        if not finite.any():
            continue
        scale = max(float(np.abs(x[finite]).max()), 1e-300)
        rel = float(np.abs(x - y)[finite].max()) / scale
        bad = (column == "n_contacts" and rel > 0) or (column in ("rho", "sigma_m") and rel > tol)
        failed |= bad
        if rel > 0 or column in ("n_contacts", "rho", "sigma_m"):
            print(f"{column}: {rel:.2g} of its largest value{'  <-- fails' if bad else ''}")
    print(f"{len(rows_a)} rows: " + ("differ beyond round-off" if failed else "the same history"))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
