"""Yield surface in the deviatoric plane by stress-controlled probes (beyond the
thesis, whose chapter-4 fans are strain-driven reloads in the (sigma_m, sigma~_d) plane).

Stages (data flow: consolidation -> unload -> checkpoint -> fan of Lode-angle probes -> surface):
1. **consolidate and unload** (``out/consolidate``, workflows.stress_probes): the three normal
   stresses servo-controlled up to the pressure ``p_load`` (ramp, hold), then down to the probes'
   mean stress ``p_probe`` < ``p_load`` (ramp, hold), ending with a checkpoint. The volume is then
   inside its yield surface: E_0 = E_d at the end;
2. **probes** (``out/probe_<deg>``): from that checkpoint, each probe keeps sigma_m = ``p_probe``
   and ramps the von Mises stress q along the Lode angle theta (loading.mixed.lode_shear_control),
   with the servo's state and the contact history carried over;
3. **surface**: the yield point of a probe is where E_d first reaches
E_0 (1 + ``dissipation_threshold``)
   (the iso-dissipation criterion of thesis §4.2.2), interpolated between history rows in the
   measured (Schmidt) stress. Angles 0-60 degrees cover the deviatoric plane of an isotropic
   state by symmetry (compression and extension differ, so the sector is [0, 60] and not less).

Outputs in ``out_dir``: ``fan.csv`` (theta_deg, time, sigma_m, q, lode_deg, E_d: the probes'
rows), ``surface.csv`` (theta_deg, sigma_m, q, lode_deg of each yield point),
``deviatoric_surface.png`` (the deviatoric plane, the points mirrored to the full circle, and the
principal-stress view). MPa, compression > 0; theta = 0 is triaxial compression along x, 60 degrees
triaxial extension along z (loading.mixed.lode_direction).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..homogenization import first_crossing, stress_invariants
from ..loading.mixed import lode_shear_control
from ..parameters import parameter
from .stress_probes import StressProbeCase, consolidate, run_probe

FAN_COLUMNS = ("theta_deg", "time", "sigma_m", "q", "lode_deg", "E_d")


@dataclass
class DeviatoricSurfaceCase(StressProbeCase):
    """A Lode-angle fan: the consolidated state of :class:`StressProbeCase` (base, p_load,
    p_probe, ramp, hold, unload, probe, the servo's settings), then one probe per angle."""

    q_max: float = parameter(
        3.0, "von Mises stress at the end of a probe (MPa)", low=0, high=1000, open_low=True
    )
    angles_deg: tuple = (0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0)
    dissipation_threshold: float = parameter(
        3e-3,
        "yield where E_d first exceeds E_0 (1 + this) (thesis §4.2.2: 0.3 %) (-)",
        low=0,
        high=1,
        open_low=True,
        open_high=True,
    )
    out_dir: str = "results/deviatoric_surface"

    def __post_init__(self):
        super().__post_init__()
        if len(self.angles_deg) < 1 or any(not -360 <= a <= 360 for a in self.angles_deg):
            raise ValueError(
                f"angles_deg must hold angles in [-360, 360] degrees, got {self.angles_deg}"
            )


def lode_angle(sigma: np.ndarray) -> float:
    """Lode angle (degrees, in [0, 360)) of a normal stress state (3,) (compression > 0) in the
    convention of loading.mixed.lode_direction: the angle of its deviator from the x direction."""
    s = np.asarray(sigma, dtype=float) - np.mean(sigma)
    # components on the deviatoric-plane axes e0 = direction(0), e90 = direction(90 deg)
    e0 = np.sqrt(2.0 / 3.0) * np.array([1.0, -0.5, -0.5])
    e90 = np.sqrt(2.0 / 3.0) * np.array([0.0, np.sqrt(3.0) / 2.0, -np.sqrt(3.0) / 2.0])
    angle = float(np.degrees(np.arctan2(s @ e90, s @ e0))) % 360.0
    return 0.0 if angle > 360.0 - 1e-9 else angle  # a rounding-level negative angle is 0, not 360


def probe_rows(history, theta_deg: float, t_start: float) -> dict[str, np.ndarray]:
    """fan.csv rows of one probe's history (rows after ``t_start``): Schmidt sigma_m, q, Lode
    angle."""
    t = history.column("time")
    keep = t > t_start * (1 + 1e-12)
    sigma = np.stack(
        [
            history.column(f"sigma_schmidt_{c}")[keep]
            for c in ("11", "12", "13", "21", "22", "23", "31", "32", "33")
        ],
        axis=-1,
    ).reshape(-1, 3, 3)
    mean, q = stress_invariants(-sigma)  # the invariants take tension > 0
    sigma = np.diagonal(sigma, axis1=1, axis2=2)
    return {
        "theta_deg": np.full(keep.sum(), theta_deg),
        "time": t[keep],
        "sigma_m": mean,
        "q": q,
        "lode_deg": np.array([lode_angle(s) for s in sigma]),
        "E_d": history.column("E_d")[keep],
    }


def yield_point(
    rows: dict[str, np.ndarray], E_0: float, threshold: float
) -> tuple[float, float, float] | None:
    """(sigma_m, q, lode_deg) where E_d first reaches E_0 (1 + threshold), or None."""
    _, m, q = first_crossing(
        rows["E_d"], E_0 * (1.0 + threshold), rows["sigma_m"], rows["q"], rising=True
    )
    if not np.isfinite(m):
        return None
    k = int(np.argmax(rows["E_d"] >= E_0 * (1.0 + threshold)))
    return float(m), float(q), float(rows["lode_deg"][k])


def run_deviatoric_surface(
    case: DeviatoricSurfaceCase, comm: MPI.Comm = MPI.COMM_WORLD, log=print
) -> dict:
    """Stages 1-3 (module docstring); returns {"E_0", "points": [(theta_deg, sigma_m, q, lode_deg)],
    "fan": fan rows}."""
    state = consolidate(case, comm, log=log)
    fan, points = [], []
    for theta in case.angles_deg:
        control = lode_shear_control(
            mean=case.p_probe,
            q_max=case.q_max,
            theta=np.radians(theta),
            duration=case.probe * case.base.loading.duration,
            t0=state.time,
            **case.servo(),
        )
        history = run_probe(case, state, control, f"probe_{theta:g}", comm, log=log)
        rows = probe_rows(history, theta, state.time)
        fan.append(rows)
        point = yield_point(rows, state.E_0, case.dissipation_threshold)
        if point is not None:
            points.append((theta, *point))
    if comm.rank == 0:
        write_outputs(Path(case.out_dir), fan, points, case)
    return {"E_0": state.E_0, "points": points, "fan": fan}


def write_outputs(
    out: Path, fan: list[dict], points: list[tuple], case: DeviatoricSurfaceCase
) -> None:
    """fan.csv, surface.csv and deviatoric_surface.png."""
    with open(out / "fan.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(FAN_COLUMNS)
        for rows in fan:
            for k in range(rows["time"].size):
                w.writerow([f"{rows[c][k]:.9g}" for c in FAN_COLUMNS])
    with open(out / "surface.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(("theta_deg", "sigma_m", "q", "lode_deg"))
        for p in points:
            w.writerow([f"{v:.9g}" for v in p])
    from ..io.plots import plot_deviatoric_surface

    plot_deviatoric_surface(
        points,
        out / "deviatoric_surface.png",
        mean=case.p_probe,
        title=f"yield in the deviatoric plane at sigma_m = {case.p_probe} MPa "
        f"(loaded to {case.p_load} MPa)",
    )
