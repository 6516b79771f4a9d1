"""Are two runs' histories the same, bit for bit? The check of a refactoring that must not move
the numbers.

    python bench/same_history.py results/a/history.csv results/b/history.csv

Compares the two ``history.csv`` files column by column as written (the same text, so the same
bits), every column but ``wall_time``; prints the columns that differ with their largest
relative difference and exits 1 if any does (2 if the files do not have the same columns or
rows).
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
    args = p.parse_args(argv)
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


if __name__ == "__main__":
    sys.exit(main())
