"""Force-controlled rupture of a periodic volume (the thesis' perspective 4: rupture
"en pilotage en force", detected by the growth of the kinetic energy).

Stages (data flow: consolidation -> unload -> checkpoint -> stress probe -> rupture points):
1. **consolidate and unload** (workflows.stress_probes): the three normal stresses servo-controlled
   up to ``p_load``, then down to ``p_probe``, checkpoint; E_0 = E_d there;
2. **probe** (``out/probe``): from that checkpoint the three normal stresses are driven linearly
   from p_probe to ``final_stress`` (e.g. (0, 0, -5): uniaxial tension along z with free lateral
   faces; tension needs adhesion, ``base.contact.gamma`` > 0) over ``probe`` durations, then
   held. Past the volume's strength the servo can no longer raise the stress: it strains the cell
   at its largest rate and the particles, no longer held, accelerate;
3. **rupture**, by two independent criteria, both recorded: (a) the kinetic / dissipated
   energy ratio phi = E_c / E_d (thesis eq. 4.14; Abdelmoula's criterion, thesis §4.5.1:
   "particulièrement adapté à un pilotage en effort") first reaching ``phi_c``. Under a
   quasi-static stress path phi stays at the level of the servo's residual vibrations
   (``phi_quasi_static``: its median over the probe's first half); (b) Hill's second-order work
   W2 = dsigma : dh (eq. 4.15; Cauchy stress tension > 0, Hencky strain) first becoming <= 0,
   with the increments as Savitzky-Golay derivatives over ``w2_window`` rows (as
   workflows.yield_surface). On a stress path it marks the peak. The strength along the path
   is the largest stress reached along its direction (``path_stress``: the projection of
   sigma - sigma_start on final_stress - sigma_start).

Outputs in ``out_dir``: ``rupture.csv`` (one row per probe output: RUPTURE_COLUMNS),
``rupture_points.csv`` (criterion phi | w2 | peak, time, the three normal stresses, sigma_m, q,
path_stress) and ``force_rupture.png``. MPa (compression > 0, as the histories), mJ, s.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..homogenization import (
    first_crossing,
    hencky_strain,
    row_increments,
    second_order_work,
    stress_invariants,
)
from ..io.history import tensor_from_columns
from ..loading.mixed import normal_stress_path
from ..parameters import parameter, parameter_of
from .stress_probes import StressProbeCase, consolidate, run_probe

RUPTURE_COLUMNS = (
    "time",
    "sigma_11",
    "sigma_22",
    "sigma_33",
    "sigma_m",
    "q",
    "path_stress",
    "h_11",
    "h_22",
    "h_33",
    "E_c",
    "E_d",
    "phi",
    "W2",
)
POINT_COLUMNS = (
    "criterion",
    "time",
    "sigma_11",
    "sigma_22",
    "sigma_33",
    "sigma_m",
    "q",
    "path_stress",
)


@dataclass
class ForceRuptureCase(StressProbeCase):
    """A stress probe to rupture from the consolidated state of :class:`StressProbeCase`."""

    # the probe starts lightly loaded
    p_probe: float = parameter_of(StressProbeCase, "p_probe", default=0.2)
    final_stress: tuple = (0.0, 0.0, -5.0)  # MPa (compression > 0): uniaxial tension along z
    phi_c: float = parameter(
        1e-3,
        "rupture threshold on E_c / E_d (eq. 4.14) (-)",
        low=0,
        high=1,
        open_low=True,
        open_high=True,
    )
    w2_window: int = parameter(
        5,
        "rows of the Savitzky-Golay derivatives of W2 (0: raw differences; else odd)",
        low=0,
        high=1001,
    )
    rows_per_probe: int = parameter_of(StressProbeCase, "rows_per_probe", default=40)
    out_dir: str = "results/force_rupture"

    def __post_init__(self):
        super().__post_init__()
        final = np.asarray(self.final_stress, dtype=float)
        if final.shape != (3,) or not np.all(np.isfinite(final)):
            raise ValueError(
                f"final_stress must hold 3 finite normal stresses (MPa), got {self.final_stress}"
            )
        if np.linalg.norm(final - self.p_probe) == 0:
            raise ValueError("final_stress must differ from the starting state p_probe I")
        if np.any(final < 0) and not self.base.contact.gamma > 0:
            raise ValueError(
                f"final_stress is tensile but base.contact.gamma = {self.base.contact.gamma}: "
                f"without adhesion the volume carries no tension (set gamma > 0 mJ/mm^2)"
            )
        if self.w2_window != 0 and not (self.w2_window >= 3 and self.w2_window % 2 == 1):
            raise ValueError(
                f"w2_window must be 0 or an odd number >= 3 of rows, got {self.w2_window}"
            )


def rupture_rows(
    history, t_start: float, start: np.ndarray, final: np.ndarray, w2_window: int = 5
) -> dict:
    """RUPTURE_COLUMNS of the probe's rows (after ``t_start``) of a history; ``start`` and
    ``final`` (3,) the path's end stresses (MPa, compression > 0)."""
    t = history.column("time")
    keep = t > t_start * (1 + 1e-12)
    sigma, F = (
        tensor_from_columns(history, "sigma_schmidt_")[keep],
        tensor_from_columns(history, "F")[keep],
    )
    h = hencky_strain(F)
    mean, q = stress_invariants(-sigma)  # the invariants and W2 take tension > 0
    normal = np.diagonal(sigma, axis1=1, axis2=2)
    direction = (final - start) / np.linalg.norm(final - start)
    E_c, E_d = history.column("E_c")[keep], history.column("E_d")[keep]
    rows = {
        "time": t[keep],
        "sigma_m": mean,
        "q": q,
        "path_stress": (normal - start) @ direction,
        "E_c": E_c,
        "E_d": E_d,
        "phi": np.divide(E_c, E_d, out=np.full_like(E_c, np.nan), where=E_d > 0),
        "W2": second_order_work(row_increments(-sigma, w2_window), row_increments(h, w2_window)),
    }
    for i in range(3):
        rows[f"sigma_{i + 1}{i + 1}"] = normal[:, i]
        rows[f"h_{i + 1}{i + 1}"] = h[:, i, i]
    return rows


def rupture_points(rows: dict, phi_c: float) -> dict[str, dict]:
    """{criterion: {POINT_COLUMNS but criterion}} for phi (E_c / E_d first reaching phi_c), w2
    (W2 first <= 0, after the first row where it is > 0) and peak (the largest path stress);
    a criterion never met is absent. Values interpolated linearly between rows."""
    series = [rows[c] for c in POINT_COLUMNS[1:]]
    points = {}
    position, *values = first_crossing(rows["phi"], phi_c, *series, rising=True)
    if np.isfinite(position):
        points["phi"] = dict(zip(POINT_COLUMNS[1:], map(float, values), strict=True))
    positive = np.flatnonzero(rows["W2"] > 0)
    if positive.size:
        k0 = positive[0]
        position, *values = first_crossing(
            rows["W2"][k0:], 0.0, *(s[k0:] for s in series), rising=False
        )
        if np.isfinite(position):
            points["w2"] = dict(zip(POINT_COLUMNS[1:], map(float, values), strict=True))
    k = int(np.nanargmax(rows["path_stress"]))
    points["peak"] = {c: float(rows[c][k]) for c in POINT_COLUMNS[1:]}
    return points


def phi_quasi_static(rows: dict) -> float:
    """The level of E_c / E_d under the quasi-static part of the probe (median over its first
    half)."""
    return float(np.nanmedian(rows["phi"][: max(1, rows["phi"].size // 2)]))


def run_force_rupture(case: ForceRuptureCase, comm: MPI.Comm = MPI.COMM_WORLD, log=print) -> dict:
    """Stages 1-3 (module docstring); returns {"E_0", "rows", "points", "phi_quasi_static"}."""
    state = consolidate(case, comm, log=log)
    T = case.base.loading.duration
    start = np.full(3, case.p_probe)
    final = np.asarray(case.final_stress, dtype=float)
    control = normal_stress_path(
        [state.time, state.time + case.probe * T], [start, final], **case.servo()
    )
    history = run_probe(case, state, control, "probe", comm, log=log)
    rows = rupture_rows(history, state.time, start, final, case.w2_window)
    points = rupture_points(rows, case.phi_c)
    result = {
        "E_0": state.E_0,
        "rows": rows,
        "points": points,
        "phi_quasi_static": phi_quasi_static(rows),
    }
    if comm.rank == 0:
        write_outputs(Path(case.out_dir), rows, points, case)
    return result


def write_outputs(out: Path, rows: dict, points: dict, case: ForceRuptureCase) -> None:
    """rupture.csv, rupture_points.csv and force_rupture.png."""
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "rupture.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(RUPTURE_COLUMNS)
        for k in range(rows["time"].size):
            w.writerow([f"{rows[c][k]:.9g}" for c in RUPTURE_COLUMNS])
    with open(out / "rupture_points.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(POINT_COLUMNS)
        for criterion, point in points.items():
            w.writerow([criterion] + [f"{point[c]:.9g}" for c in POINT_COLUMNS[1:]])
    from ..io.plots import plot_force_rupture

    plot_force_rupture(
        rows,
        points,
        case.phi_c,
        out / "force_rupture.png",
        title=f"stress probe {case.p_probe:g} I -> diag{tuple(case.final_stress)} MPa "
        f"(gamma {case.base.contact.gamma:g} mJ/mm^2)",
    )
