"""Every demo runs end to end at a smoke size: each ``demos/*.py`` in a subprocess with tiny
options, into a temporary folder; it must exit 0, write its main outputs, and the numbers of
its CSV files must be finite.

The demos are found by a glob: a new demo without an entry in :data:`SMOKE` fails
``test_demo_runs_at_smoke_size`` until it gets one. Smoke sizes check that a demo runs, not
its physics (the physics has its own tests): some demos' own checks do not pass at these sizes.
"""

from __future__ import annotations

import csv
import math
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest
from mpfem_fenicsx.meshes.packing import simple_cubic_packing, write_packing

ROOT = Path(__file__).resolve().parents[1]
DEMOS = sorted(p.stem for p in (ROOT / "demos").glob("*.py"))


@dataclass(frozen=True)
class Smoke:
    """A demo's smoke run: its options (``--out`` is added) and the files it must write into the
    output folder; the numbers of those that are CSV tables must be finite, except in the
    ``nan_ok`` columns, which may be empty or NaN where their value is not defined."""

    options: tuple[str, ...]
    outputs: tuple[str, ...]
    nan_ok: tuple[str, ...] = ()

    def csv_files(self) -> tuple[str, ...]:
        return tuple(name for name in self.outputs if name.endswith(".csv"))


#: demo -> its smoke run. Granular demos: 8 spheres on a simple cubic lattice where the demo
#: reads a packing file ({packing}: written by the test), else the generator's smallest periodic
#: volume (24 particles); a hundred or so increments; visual output off where there is a switch
#: history columns left empty where undefined (kinetic over internal energy while E_int <= 0)
#: NaN where undefined: a ratio at rest; the Newton columns of explicit rows
UNDEFINED = ("E_c_over_E_int", "newton_iterations", "linear_iterations", "cutbacks")
SMOKE: dict[str, Smoke] = {
    "closed_die": Smoke(
        (
            "--particles",
            "3",
            "--increments",
            "2000",
            "--target-density",
            "0.6",
            "--outputs",
            "8",
            "--no-visual",
        ),
        ("history.csv", "density_bins.csv", "summary.json"),
    ),
    "cubic_cell": Smoke(
        ("--increments", "200", "--target-density", "0.56"), ("history.csv", "stresses.png")
    ),
    "deviatoric_surface": Smoke(
        ("--particles", "24", "--increments", "100", "--angles", "0"),
        ("fan.csv", "surface.csv", "deviatoric_surface.png"),
    ),
    "die": Smoke(
        (
            "--packing",
            "{packing}",
            "--mesh",
            "coarse",
            "--increments",
            "100",
            "--target-density",
            "0.6",
            "--outputs",
            "5",
            "--checkpoint-every",
            "0",
            "--no-visual",
        ),
        ("history.csv", "packing.txt"),
        nan_ok=UNDEFINED,
    ),
    "flat_contact": Smoke((), ("normal.csv", "tangential.csv", "flat_contact.png")),
    "force_rupture": Smoke(
        ("--particles", "24", "--increments", "100"),
        ("rupture.csv", "rupture_points.csv", "force_rupture.png"),
    ),
    "hertz": Smoke(("--size-min", "0.05", "--steps", "3"), ("force.csv", "force.png")),
    "isotropic": Smoke(
        (
            "--packing",
            "{packing}",
            "--mesh",
            "coarse",
            "--increments",
            "100",
            "--target-density",
            "0.6",
            "--outputs",
            "5",
            "--checkpoint-every",
            "0",
            "--no-visual",
        ),
        ("history.csv", "packing.txt"),
        nan_ok=UNDEFINED,
    ),
    "simple_cubic": Smoke(
        ("--loading", "isotropic", "--increments", "100", "--target-density", "0.6", "--no-visual"),
        ("isotropic/history.csv", "isotropic/checks.csv", "simple_cubic.png"),
        nan_ok=UNDEFINED,
    ),
    "sphere_squeeze": Smoke(("--reduction", "0.05"), ("implicit.csv",)),
    "triaxial": Smoke(
        ("--particles", "24", "--increments", "100", "--outputs", "5"),
        ("history.csv", "loading_path.png"),
        nan_ok=UNDEFINED,
    ),
    "triaxial_box": Smoke(
        (
            "--increments",
            "2000",
            "--particles",
            "4",
            "--fill",
            "0.3",
            "--target-density",
            "0.45",
            "--outputs",
            "4",
            "--no-visual",
        ),
        ("history.csv", "summary.json"),
    ),
    "two_spheres": Smoke(
        ("--ratios", "1.0", "--size-min", "0.1", "--load-steps", "2", "--unload-steps", "2"),
        ("summary.csv", "two_spheres.png"),
        nan_ok=("error_e", "pull_off_mm"),
    ),  # too few unloading samples
    "uniaxial": Smoke(("--log-strain", "0.05"), ("stress_strain.csv",)),
    "yield_surface": Smoke(
        (
            "--packing",
            "{packing}",
            "--mesh",
            "coarse",
            "--increments",
            "40",
            "--target-density",
            "0.6",
            "--nphi",
            "3",
            "--reload-steps",
            "10",
            "--outputs",
            "5",
            "--checkpoint-every",
            "0",
        ),
        ("fan.csv", "surfaces.csv", "uniaxial.csv", "yield_surface.png"),
        nan_ok=("compressive_MPa", "tensile_MPa"),
    ),
}


def _run(demo: str, smoke: Smoke, out: Path) -> subprocess.CompletedProcess:
    """The demo in a subprocess of this interpreter, from the output folder's parent."""
    packing = out.parent / "simple_cubic_packing.txt"
    # radii x0.95: the coarse volume-exact particles' nodes lie 2.3 % outside their spheres
    write_packing(simple_cubic_packing(0.1).scaled(0.95), packing)
    options = [option.replace("{packing}", str(packing)) for option in smoke.options]
    command = [sys.executable, str(ROOT / "demos" / f"{demo}.py"), *options, "--out", str(out)]
    return subprocess.run(
        command, capture_output=True, text=True, timeout=600, check=False, cwd=out.parent
    )


def _number(cell: str) -> float | None:
    """The cell's number (NaN for an empty cell: a value not defined), None for text."""
    if not cell.strip():
        return math.nan
    try:
        return float(cell)
    except ValueError:
        return None


def _non_finite(path: Path, nan_ok: tuple[str, ...]) -> list[str]:
    """Cells of a CSV table that are not finite numbers (empty cells included), as
    "column row value" strings; text columns (a non-empty cell that is not a number) are
    skipped."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    bad = []
    for k, name in enumerate(header):
        values = [_number(row[k] if k < len(row) else "") for row in body]
        if any(value is None for value in values):
            continue  # a text column (names, kinds)
        bad += [
            f"{name} row {r + 1}: {value}"
            for r, value in enumerate(values)
            if not math.isfinite(value) and not (name in nan_ok and math.isnan(value))
        ]
    return bad


def test_every_demo_has_a_smoke_entry():
    """The table names the demos of the folder, no more and no fewer."""
    missing, stale = sorted(set(DEMOS) - set(SMOKE)), sorted(set(SMOKE) - set(DEMOS))
    assert not missing and not stale, f"demos without an entry: {missing}; without a demo: {stale}"


@pytest.mark.parametrize("demo", DEMOS)
def test_demo_runs_at_smoke_size(demo, tmp_path):
    smoke = SMOKE.get(demo)
    assert smoke is not None, f"demos/{demo}.py has no entry in SMOKE (tests/test_demos.py)"
    out = tmp_path / "out"
    start = time.perf_counter()
    proc = _run(demo, smoke, out)
    wall = time.perf_counter() - start
    assert proc.returncode == 0, f"{demo}: exit {proc.returncode}\n{proc.stderr[-3000:]}"
    missing = [name for name in smoke.outputs if not (out / name).is_file()]
    written = sorted(str(p.relative_to(out)) for p in out.rglob("*"))
    assert not missing, f"{demo} did not write {missing}; it wrote {written}"
    for name in smoke.csv_files():
        bad = _non_finite(out / name, smoke.nan_ok)
        assert not bad, f"{demo}: {name} has non-finite numbers: {bad[:10]}"
    print(f"{demo}: {wall:.1f} s")
