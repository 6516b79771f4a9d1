"""How far a fan's yield points are from an ellipse, and whether turning the ellipse helps:
which family of continuum surface the computed fans call for.

    python validation/fan_ellipses.py fan_isotropic_0.79 fan_die_0.82_A3_n800

For each fan (``validation/runs/<fan>/surfaces.csv``, kind ``yield``) three ellipses in the
Rendulic plane (sigma_m, sigma~_d; MPa, compression > 0) are fitted by least squares on the
relative radial misfit seen from the points' mean (as ``mpfem_fenicsx.calibration.fit_cap``
does): centred on the hydrostatic axis with axes along it (the critical-state family), free
centre, and free centre and rotation (an anisotropic, rotated ellipse). It prints each fit's
rms misfit, centre, semi-axes and rotation, and where the ellipse, as an associated yield
surface, would be loaded by a die compaction: the point whose normal gives a uniaxial plastic
strain (d eps_q^p / d eps_v^p = 2/3) and its radial / axial stress ratio, to set beside the
die path's. Pure numpy / scipy; seconds.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

RUNS = Path(__file__).resolve().parent / "runs"


def yield_points(fan: Path) -> np.ndarray:
    """The fan's yield points, rows (sigma_m, sigma~_d)."""
    with open(fan / "surfaces.csv") as f:
        rows = [r for r in csv.DictReader(f) if r["kind"] == "yield"]
    return np.array([[float(r["sigma_m"]), float(r["sigma_tilde_d"])] for r in rows])


def ray_to_ellipse(origin, directions, centre, axes, angle) -> np.ndarray:
    """Distance from ``origin`` along each unit direction to the ellipse (semi-axes ``axes``
    along the directions ``angle`` and ``angle`` + 90 degrees, radians)."""
    turn = np.array([[np.cos(angle), np.sin(angle)], [-np.sin(angle), np.cos(angle)]])
    u0 = turn @ (origin - centre) / axes
    ue = directions @ turn.T / axes
    a, b, c = np.sum(ue**2, axis=1), 2.0 * ue @ u0, u0 @ u0 - 1.0
    return (-b + np.sqrt(np.maximum(b * b - 4.0 * a * c, 0.0))) / (2.0 * a)


def fit_ellipse(points: np.ndarray, shifted: bool, rotated: bool):
    """(rms radial misfit, centre, semi-axes (the long one first), the long axis's
    direction in degrees from the sigma_m axis) of the best ellipse."""
    mean = points.mean(axis=0)
    radius = np.linalg.norm(points - mean, axis=1)
    directions = (points - mean) / radius[:, None]

    def unpack(x):
        centre = np.array([x[0], x[1] if shifted else 0.0])
        return centre, np.abs(x[2:4]) + 1e-12, x[4] if rotated else 0.0

    def misfit(x):
        return (radius - ray_to_ellipse(mean, directions, *unpack(x))) / radius

    start = [mean[0], mean[1], np.ptp(points[:, 0]) / 2, np.ptp(points[:, 1]) / 2, 0.0]
    best = min(
        (least_squares(misfit, [*start[:4], a]) for a in np.radians([0.0, 30.0, 60.0, -30.0])),
        key=lambda s: s.cost,
    )
    centre, axes, angle = unpack(best.x)
    if axes[1] > axes[0]:  # the long axis first, its direction in (-90, 90] degrees
        axes, angle = axes[::-1], angle + 0.5 * np.pi
    angle = (np.degrees(angle) + 90.0) % 180.0 - 90.0
    return float(np.sqrt(np.mean(best.fun**2))), centre, axes, float(angle)


def die_point(centre, axes, angle_deg: float) -> tuple[float, float, float]:
    """(sigma_m, sigma~_d, radial / axial stress ratio) on the ellipse (``fit_ellipse``'s
    centre, semi-axes, long axis's direction) where its outward normal (d eps_v^p,
    d eps_q^p), with d eps_v^p > 0, gives a uniaxial plastic strain: d eps_q^p / d eps_v^p =
    2/3. With (u, v) = (a cos t, b sin t) along the axes, the normal is the turned
    (cos t / a, sin t / b), and the condition is linear in (cos t, sin t): of its two roots,
    t below is the one of compaction (its d eps_v^p is 1 / (a b) > 0 times a positive
    factor)."""
    (a, b), th = axes, np.radians(angle_deg)
    c, s = np.cos(th), np.sin(th)
    t = np.arctan2(-(s - 2.0 / 3.0 * c) / a, (c + 2.0 / 3.0 * s) / b)
    u, v = a * np.cos(t), b * np.sin(t)
    p, q = centre[0] + c * u - s * v, centre[1] + s * u + c * v
    return float(p), float(q), float((p - q / 3.0) / (p + 2.0 * q / 3.0))


def main(names: list[str]) -> None:
    """Print the three fits of each named fan."""
    for name in names:
        points = yield_points(RUNS / name)
        for label, shifted, rotated in (
            ("on the axis", False, False),
            ("free centre", True, False),
            ("free centre, rotated", True, True),
        ):
            rms, centre, axes, angle = fit_ellipse(points, shifted, rotated)
            print(
                f"{name} ({len(points)} points), ellipse {label}: misfit {100 * rms:.1f} %, "
                f"centre ({centre[0]:.2f}, {centre[1]:.2f}) MPa, semi-axes {axes[0]:.2f} / "
                f"{axes[1]:.2f} MPa, long axis at {angle:.1f} deg from the sigma_m axis; "
                "die point (sigma_m, sigma~_d) ({:.2f}, {:.2f}) MPa, radial / axial {:.3f}".format(
                    *die_point(centre, axes, angle)
                )
            )


if __name__ == "__main__":
    main(sys.argv[1:] or ["fan_isotropic_0.79", "fan_isotropic_0.87", "fan_die_0.82_A3_n800"])
