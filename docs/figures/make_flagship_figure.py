"""Draw the README's flagship figure from the results folder of ``make demo``.

Left: the compaction curve, mean stress sigma_m (MPa, compression > 0, Love-Weber) against the
relative density rho (thesis eq. 2.4-2.5), read from ``history.csv``. Right: the deformed
particles coloured by von Mises stress, the run's own ``particles.png``.

Usage (from the repository root, after ``make demo``)::

    .venv/bin/python docs/figures/make_flagship_figure.py [RESULTS] [--out PNG]

RESULTS defaults to ``results/isotropic``; PNG to ``docs/figures/flagship.png``.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402

HERE = Path(__file__).resolve().parent
SIZE_INCHES = (16.0, 7.0)  # with DPI: the 1600 x 700 px of the README
DPI = 100


def read_curve(history_csv: Path) -> tuple[list[float], list[float]]:
    """The (rho, sigma_m) columns of a compaction history, rows in time order."""
    with history_csv.open(newline="") as stream:
        rows = list(csv.DictReader(stream))
    if not rows or "rho" not in rows[0] or "sigma_m" not in rows[0]:
        raise ValueError(f"{history_csv}: needs rows with the columns rho and sigma_m")
    rho = [float(row["rho"]) for row in rows]
    sigma_m = [float(row["sigma_m"]) for row in rows]
    return rho, sigma_m


def draw(results: Path, out: Path) -> Path:
    """Write the two-panel figure of the run in ``results`` to ``out``."""
    rho, sigma_m = read_curve(results / "history.csv")
    particles = mpimg.imread(results / "particles.png")

    figure, (curve, picture) = plt.subplots(
        1, 2, figsize=SIZE_INCHES, gridspec_kw={"width_ratios": [1.0, 1.15]}
    )
    # the compaction curve, its end point named with its figures
    curve.plot(rho, sigma_m, "o-", color="tab:blue", markersize=3.5, linewidth=1.6)
    curve.annotate(
        f"rho {rho[-1]:.4f}\nsigma_m {sigma_m[-1]:.3f} MPa",
        xy=(rho[-1], sigma_m[-1]),
        xytext=(-150, -10),
        textcoords="offset points",
        fontsize=12,
        arrowprops={"arrowstyle": "->", "color": "0.3"},
    )
    curve.set_xlabel("relative density rho (-)", fontsize=13)
    curve.set_ylabel("mean stress sigma_m (MPa, compression > 0)", fontsize=13)
    curve.set_title("Isotropic compaction, 24 lead particles, CLP", fontsize=14)
    curve.tick_params(labelsize=11)
    curve.grid(alpha=0.3)
    # the deformed particles as the run rendered them
    picture.imshow(particles)
    picture.set_axis_off()
    picture.set_title("Deformed particles, von Mises stress (MPa)", fontsize=14)

    figure.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(out, dpi=DPI)
    plt.close(figure)
    return out


def main(argv: list[str] | None = None) -> int:
    """Command line: the results folder and the output PNG."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "results",
        nargs="?",
        type=Path,
        default=Path("results/isotropic"),
        help="results folder holding history.csv and particles.png (default: results/isotropic)",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=HERE / "flagship.png",
        help="PNG to write (default: docs/figures/flagship.png)",
    )
    args = parser.parse_args(argv)
    for name in ("history.csv", "particles.png"):
        if not (args.results / name).is_file():
            parser.error(f"results: {args.results / name} is missing (run `make demo` first)")
    print(draw(args.results, args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
