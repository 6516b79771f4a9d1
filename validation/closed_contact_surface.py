"""The specific contact surface of a finished fan counted two ways (table 4.2 and
thesis fig. 4.11-4.12): every loaded contact point (``Gamma``, adhesive points in tension
included) against the compressive, closed points only (``Gamma_closed``; Abaqus' CAREA counts
the closed part of a contact).

    python validation/closed_contact_surface.py fan_isotropic_0.79 /tmp/fan_closed [RUN_DIR]

Measures both at the end of the fan's loading and of its unload (the checkpoints in RUN_DIR,
default ``validation/runs/<fan>/``, where the fan ran: they are not versioned), then reruns the
fan's reloads from its unload in ``out`` (its load, unload and ``unloaded.json`` copied; a fan of
runs before the ``Gamma_closed`` column) and prints, per reload direction, the range of each
measure and the iso-``Gamma_closed`` points.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

sys.path.insert(
    0, str(Path(__file__).resolve().parents[1])
)  # the repository: the validation package

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402

from mpfem_fenicsx.homogenization.surfaces import iso_gamma_point  # noqa: E402
from mpfem_fenicsx.io import read_csv  # noqa: E402
from mpfem_fenicsx.workflows.compaction import CompactionRun  # noqa: E402
from mpfem_fenicsx.workflows.yield_surface import fan_rows, read_unloaded, run_yield_surface  # noqa: E402
from validation.cases import STAGES  # noqa: E402

RUNS = Path(__file__).resolve().parent / "runs"


def measured_at_checkpoints(fan, run_dir: Path) -> float:
    """Both measures at the end of the loading and of the unload; returns Gamma_closed unloaded."""
    base = fan.yield_surface_case(f"/tmp/closed_contact_surface_{fan.name}").base
    unloaded = read_unloaded(run_dir)
    hold = (10 * unloaded.dt, np.eye(3))  # one increment past the checkpoint, at a fixed gradient
    model, closed = None, np.nan
    for stage in ("load", "unload"):
        checkpoint = sorted((run_dir / stage / "checkpoints").iterdir())[-1]
        case = base.updated(
            directory=f"/tmp/closed_contact_surface_{fan.name}/{stage}",
            checkpoint_every=0,
            visual=False,
            segments_after=(*unloaded.segments, hold),
        )
        result = CompactionRun(
            case, MPI.COMM_SELF, log=lambda *a, **k: None, restart=checkpoint, model=model
        ).run(max_steps=1)
        model = result.model
        pairs = model.contact.pair_forces()  # CLP by images: every contact belongs to the volume
        volume = np.linalg.det(model.path(result.solver.t)) * np.prod(model.packing.cell)
        every, closed = pairs["area"].sum() / volume, pairs["area_closed"].sum() / volume
        print(f"end of the {stage}: Gamma {every:.3f}, Gamma_closed {closed:.3f} 1/mm")
    return float(closed)


def main(name: str, out: str, run_dir: str | None = None) -> None:
    """Rerun CLP fan ``name``'s reloads into ``out``; print Gamma_closed (1/mm) along them."""
    fan = {c.name: c for c in STAGES["fans"]}[name]
    case = fan.yield_surface_case(out)
    if case.base.bc != "CLP":
        raise SystemExit(
            "closed_contact_surface: CLP fans only (every contact point belongs to the volume)"
        )
    run_dir, out = Path(run_dir) if run_dir else RUNS / name, Path(out)
    closed0 = measured_at_checkpoints(fan, run_dir)
    out.mkdir(parents=True, exist_ok=True)
    for part in ("load", "unload"):
        if not (out / part).exists():
            shutil.copytree(run_dir / part, out / part)
    shutil.copy(run_dir / "unloaded.json", out / "unloaded.json")
    run_yield_surface(case, MPI.COMM_SELF, log=lambda *a: None, resume=True)
    unloaded = read_unloaded(out)
    fans = []
    for k, phi in enumerate(case.phis):
        history = out / f"reload_{k:03d}" / "history.csv"
        rows = fan_rows(history, float(phi), unloaded.t_unloaded)
        h = read_csv(history)
        closed = h["Gamma_closed"][h["time"] >= unloaded.t_unloaded * (1 - 1e-12)]
        closed[~np.isfinite(closed)] = (
            closed0  # the restart row: the unload's history had no such column
        )
        print(
            f"phi {np.degrees(phi):5.0f} deg: Gamma "
            f"{rows['Gamma'].min():.3f}-{rows['Gamma'].max():.3f}, "
            f"Gamma_closed {closed0:.3f} -> {closed.min():.3f}-{closed.max():.3f} "
            f"({closed.min() / closed0 - 1:+.0%} / {closed.max() / closed0 - 1:+.0%}); "
            f"sigma_m at the end {rows['sigma_m'][-1]:.2f} MPa"
        )
        fans.append({**rows, "Gamma": closed})
    for level in np.linspace(closed0, 0.3 * closed0, 8)[1:]:
        points = [iso_gamma_point(f, level) for f in fans]
        print(
            f"iso-Gamma_closed {level:.3f} 1/mm (sigma_m, sigma~_d MPa): "
            + " ".join("-" if p is None else f"({p[0]:.2f}, {p[1]:.2f})" for p in points)
        )


if __name__ == "__main__":
    main(*sys.argv[1:4])
