"""Fit a Drucker-Prager Cap surface to the yield points of a fan (thesis chapter 4).

Pure numpy / scipy. The points are (sigma_m, sigma~_d) in MPa, compression > 0, as
:func:`mpfem_fenicsx.homogenization.surfaces.surface_points` gives them (one per reload
direction). The fit minimizes, over d, beta, R, p_b (and K when the fan has points on the
extension side), the relative radial misfit of each point: its distance from the fan's centre
(the mean of the points) against the surface's distance along the same ray. alpha is fixed
(Abaqus needs a small one; 0.01 by default): the points do not resolve the transition arc.

Two figures judge the fit:

- ``radial_rms``: rms over the points of (|x - c| - r_surface) / |x - c|;
- ``deviatoric_rms``: the deviatoric stress at equal mean stress, rms over the points of
  (sigma~_d(surface at the point's sigma_m, on the point's side) - sigma~_d) divided by the rms
  of the points' sigma~_d (a point beyond the surface's range of sigma_m counts its whole
  sigma~_d).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, least_squares, minimize

from .cap import CapSurface
from .clay import ClaySurface


@dataclass(frozen=True)
class SurfaceFit:
    """A fitted surface and its figures (see the module)."""

    surface: CapSurface
    radial_rms: float
    deviatoric_rms: float
    #: per point: (|x - c| - r_surface) / |x - c| (> 0: the point lies outside the surface)
    radial_residuals: np.ndarray


def _points(sigma_m, sigma_tilde_d) -> np.ndarray:
    x = np.column_stack([np.ravel(sigma_m), np.ravel(sigma_tilde_d)]).astype(float)
    if len(x) < 4 or not np.all(np.isfinite(x)):
        raise ValueError(
            f"yield points: need >= 4 finite (sigma_m, sigma_tilde_d) pairs, got {len(x)}"
        )
    return x


def radial_residuals(surface: CapSurface, x: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """(|x - c| - r_surface) / |x - c| for the points ``x`` (N, 2) seen from ``centre``."""
    v = x - centre
    dist = np.linalg.norm(v, axis=1)
    return (dist - surface.radius(tuple(centre), v / dist[:, None])) / dist


def deviatoric_misfit(surface: CapSurface, sigma_m, sigma_tilde_d) -> float:
    """The rms of sigma~_d(surface) - sigma~_d at the points' mean stresses, over the rms of
    the points' sigma~_d (see the module)."""
    s = np.ravel(sigma_tilde_d).astype(float)
    fitted = np.nan_to_num(surface.sigma_tilde_d(np.ravel(sigma_m), np.sign(s)), nan=0.0)
    return float(np.sqrt(np.mean((fitted - s) ** 2) / np.mean(s**2)))


def _first_guess(x: np.ndarray) -> np.ndarray:
    """d, beta (deg), log R, p_b of a cap from the points' extent."""
    p, s = x[:, 0], x[:, 1]
    span = p.max() - p.min()
    p_b = p.max() + 0.02 * span
    apex = min(p.min(), 0.0) - 0.05 * span
    top = np.argmax(s)
    tan_b = max(s[top], 1e-6 * span) / max(p[top] - apex, 1e-6 * span)
    beta = min(max(math.degrees(math.atan(tan_b)), 5.0), 80.0)
    d = -apex * math.tan(math.radians(beta))
    R = min(max((p_b - p[top]) / max(s[top], 1e-9), 1e-3), 1e2)
    return np.array([d, beta, math.log(R), p_b])


def _fit(x: np.ndarray, build, guess, low, high, K: float | None) -> SurfaceFit:
    """The surface ``build(v, K)`` whose parameters v (within ``low``, ``high``, from
    ``guess``) minimize the points' radial misfit seen from their mean; K fixed when given,
    else fitted (its last parameter) if some points lie on the extension side, else 1."""
    centre = x.mean(axis=0)
    if K is None and np.any(x[:, 1] < 0):
        low, high, guess = [*low, 0.778], [*high, 1.0], [*guess, _K_guess(x)]

        def make(v):
            return build(v[:-1], float(v[-1]))
    else:

        def make(v):
            return build(v, 1.0 if K is None else float(K))

    def misfit(v) -> np.ndarray:
        try:
            trial = make(v)
        except ValueError:  # a trial outside the parameters' ranges
            return np.full(len(x), 10.0)
        if not trial.inside(*centre):
            return np.full(len(x), 10.0)
        return radial_residuals(trial, x, centre)

    guess = np.clip(guess, low, high)
    best = least_squares(misfit, guess, bounds=(low, high), x_scale="jac", xtol=1e-12)
    found = make(best.x)
    residuals = radial_residuals(found, x, centre)
    return SurfaceFit(
        surface=found,
        radial_rms=float(np.sqrt(np.mean(residuals**2))),
        deviatoric_rms=deviatoric_misfit(found, x[:, 0], x[:, 1]),
        radial_residuals=residuals,
    )


def _K_guess(x: np.ndarray) -> float:
    s = x[:, 1]
    return min(max(-s[s < 0].min() / max(s.max(), 1e-9), 0.778), 1.0)


def fit_cap(sigma_m, sigma_tilde_d, *, alpha: float = 0.01, K: float | None = None) -> SurfaceFit:
    """The Drucker-Prager Cap surface through the yield points (``sigma_m``, ``sigma_tilde_d``)
    (MPa, compression > 0); ``K`` fixed when given, else fitted if some points lie on the
    extension side (sigma~_d < 0), else 1."""
    x = _points(sigma_m, sigma_tilde_d)

    def build(v, K_value) -> CapSurface:
        d, beta, log_R, p_b = (float(c) for c in v)
        return CapSurface(d=d, beta=beta, R=math.exp(log_R), p_b=p_b, alpha=alpha, K=K_value)

    span = np.ptp(x[:, 0])
    low = [0.0, 0.5, math.log(1e-4), 1e-9 * span]
    high = [np.inf, 85.0, math.log(1e3), np.inf]
    return _fit(x, build, list(_first_guess(x)), low, high, K)


def fit_clay(sigma_m, sigma_tilde_d, *, K: float | None = None) -> SurfaceFit:
    """The critical-state ellipse (:class:`~.clay.ClaySurface`) through the yield points
    (``sigma_m``, ``sigma_tilde_d``) (MPa, compression > 0): M, beta, p_c, p_t and K (fixed
    when given, else fitted if some points lie on the extension side, else 1)."""
    x = _points(sigma_m, sigma_tilde_d)

    def build(v, K_value) -> ClaySurface:
        M, beta, p_c, p_t = (float(c) for c in v)
        return ClaySurface(M=M, beta=beta, p_c=p_c, p_t=p_t, K=K_value)

    p, s = x[:, 0], x[:, 1]
    span = np.ptp(p)
    p_c, p_t = p.max() + 0.02 * span, min(p.min() - 0.02 * span, 0.0)
    guess = [max(np.abs(s).max(), 1e-9) / (0.5 * (p_c - p_t)), 1.0, p_c, p_t]
    low = [1e-3, 0.05, 1e-9 * span, -np.inf]
    high = [1e2, 20.0, np.inf, 0.0]
    return _fit(x, build, guess, low, high, K)


def isotropic_hardening(density, sigma_m, density_0: float, bulk=None):
    """The hydrostatic yield stress against the plastic volumetric strain from an isotropic
    compaction curve: p_b = sigma_m (MPa) at each relative density, |eps_v^pl| =
    ln(rho / rho_0) - sigma_m / bulk (the elastic part removed when the bulk modulus ``bulk``
    (MPa, scalar or per point) is given). Returns (p_b, |eps_v^pl|) for
    :func:`~mpfem_fenicsx.calibration.abaqus.hardening_table`."""
    rho = np.ravel(density).astype(float)
    p = np.ravel(sigma_m).astype(float)
    if not 0.0 < density_0 < rho.min():
        raise ValueError(
            f"density_0 = {density_0!r} is out of range: must be > 0 and < the curve's densities"
        )
    eps = np.log(rho / density_0)
    if bulk is not None:
        eps = eps - p / np.asarray(bulk, dtype=float)
    return p, eps


def reload_moduli(fan: dict[str, np.ndarray], share: float = 0.1) -> tuple[float, float]:
    """(bulk, shear) moduli (MPa) of the unloaded compact from the first ``share`` of the rows
    of two reloads of a fan (``workflows.yield_surface.fan_rows``: phi, h_v, h_tilde_d,
    sigma_m, sigma_tilde_d): the isotropic one (phi = 0), bulk = -d sigma_m / d h_v, and the
    deviatoric one (phi = 90 degrees), shear = -d sigma~_d / (3 d h~_d) (sigma~_d = sigma_a -
    sigma_r = -2 G (h_a - h_r) = -3 G h~_d for an isotropic elastic solid); slopes by least
    squares over at least 3 rows."""
    moduli = []
    for phi, strain, stress, factor in (
        (0.0, "h_v", "sigma_m", -1.0),
        (0.5 * math.pi, "h_tilde_d", "sigma_tilde_d", -1.0 / 3.0),
    ):
        rows = np.flatnonzero(np.isclose(fan["phi"], phi))
        if rows.size < 3:
            raise ValueError(f"fan: the reload phi = {math.degrees(phi):g} deg has < 3 rows")
        rows = rows[: max(3, int(share * rows.size))]
        h, s = fan[strain][rows], fan[stress][rows]
        moduli.append(factor * float(np.polyfit(h - h[0], s - s[0], 1)[0]))
    if min(moduli) <= 0:
        raise ValueError(f"fan: the reloads' first rows give moduli {moduli} (MPa): not > 0")
    return moduli[0], moduli[1]


def die_cap(shear: CapSurface, sigma_m: float, sigma_tilde_d: float) -> CapSurface:
    """The cap through a die compaction's stress (``sigma_m``, ``sigma_tilde_d``; MPa,
    compression > 0, axial the larger) on the shear line of ``shear`` (its d, beta, alpha, K
    kept): R and p_b such that the stress lies on the cap and the cap's normal gives a
    uniaxial plastic strain, d eps_q^p / d eps_v^p = 2/3 (the elastic increments neglected), as
    the die-test calibrations of powders set the cap. Raises ``ValueError`` when no cap does."""
    p, t = float(sigma_m), float(sigma_tilde_d)
    if not (p > 0.0 and t > 0.0):
        raise ValueError(f"die stress ({p:g}, {t:g}) MPa: needs sigma_m > 0 and sigma~_d > 0")
    c, tb, m = shear.cap_factor, shear.tan_beta, 2.0 / 3.0

    # with u = R^2: p - p_a = u t / (c^2 m) (the normal), then the point on the cap
    def on_cap(u):
        p_a = p - u * t / (c * c * m)
        return u * t * t / (c**4 * m * m) + t * t / (c * c) - (shear.d + p_a * tb) ** 2

    grid = np.geomspace(1e-8, 1e6, 400)
    values = np.array([on_cap(u) for u in grid])
    for k in np.flatnonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0):
        u = brentq(on_cap, grid[k], grid[k + 1], xtol=1e-14, rtol=1e-14)
        R, p_a = math.sqrt(u), p - u * t / (c * c * m)
        D = shear.d + p_a * tb
        if D > 0.0 and 1e-4 <= R <= 1e3:
            return CapSurface(
                d=shear.d, beta=shear.beta, R=R, p_b=p_a + R * D, alpha=shear.alpha, K=shear.K
            )
    raise ValueError(f"die stress ({p:g}, {t:g}) MPa: no cap on this shear line passes there")


def die_point(surface: CapSurface) -> tuple[float, float]:
    """The stress (sigma_m, sigma~_d; MPa) on the cap of ``surface`` whose normal gives a
    uniaxial plastic strain, d eps_q^p / d eps_v^p = 2/3: where a die compaction loads the cap
    when the elastic increments are neglected. Raises ``ValueError`` when the cap has none."""
    c = surface.cap_factor
    p_a, p_b, k = surface.p_a, surface.p_b, (surface.R / c) ** 2

    def flow(p):  # d eps_q / d eps_v - 2/3 along the cap: from +inf at p_a to -2/3 at p_b
        return k * float(surface.t(p)) / (p - p_a) - 2.0 / 3.0

    span = p_b - p_a
    low, high = p_a + 1e-12 * span, p_b - 1e-12 * span
    if not (span > 0.0 and flow(low) > 0.0 > flow(high)):
        raise ValueError(f"the cap of {surface} has no point of uniaxial plastic strain")
    p = brentq(flow, low, high, xtol=1e-14 * span, rtol=1e-14)
    return p, float(surface.t(p))


def die_ratio(sigma_m, sigma_tilde_d):
    """Radial / axial stress of a die compaction from its (sigma_m, sigma~_d), axial the larger:
    (sigma_m - sigma~_d / 3) / (sigma_m + 2 sigma~_d / 3)."""
    return (sigma_m - sigma_tilde_d / 3.0) / (sigma_m + 2.0 * sigma_tilde_d / 3.0)


def paths_cap(shear: CapSurface, p_iso: float, sigma_m: float, sigma_tilde_d: float):
    """The cap on the shear line of ``shear`` (d, beta, alpha, K kept) calibrated on the two
    compaction curves at one density: its hydrostatic yield p_b against the isotropic curve's
    sigma_m ``p_iso``, and its die stress (:func:`die_point`) against the die curve's
    (``sigma_m``, ``sigma_tilde_d``) in mean stress and in radial / axial ratio. R and p_b
    minimize the largest of these three relative errors (elastic increments neglected).
    Returns the surface and the errors {"isotropic", "die_sigma_m", "die_ratio"} (model /
    particles - 1)."""
    if not (p_iso > 0.0 and sigma_m > 0.0 and sigma_tilde_d > 0.0):
        raise ValueError(
            f"paths_cap: p_iso = {p_iso:g}, die ({sigma_m:g}, {sigma_tilde_d:g}) MPa: "
            "all must be > 0"
        )
    ratio = die_ratio(sigma_m, sigma_tilde_d)

    def errors(x):
        surface = CapSurface(
            d=shear.d,
            beta=shear.beta,
            R=math.exp(x[0]),
            p_b=p_iso * math.exp(x[1]),
            alpha=shear.alpha,
            K=shear.K,
        )
        p, t = die_point(surface)
        return surface, {
            "isotropic": surface.p_b / p_iso - 1.0,
            "die_sigma_m": p / sigma_m - 1.0,
            "die_ratio": die_ratio(p, t) / ratio - 1.0,
        }

    def worst(x):
        try:
            return max(abs(e) for e in errors(x)[1].values())
        except ValueError:  # no cap (R, p_b) of that size on this shear line
            return 1e3

    start = die_cap(shear, sigma_m, sigma_tilde_d)  # the die exact, the isotropic curve not
    # the minimax over (ln R, ln p_b): a grid in R (each R's best p_b scale by bisection on the
    # balance of the isotropic and die errors is not monotone enough), then the simplex
    best = min(
        ([math.log(r), s] for r in start.R * np.geomspace(0.5, 3.0, 25) for s in (0.0, 0.05, 0.1)),
        key=worst,
    )
    result = minimize(worst, best, method="Nelder-Mead", options={"xatol": 1e-8, "fatol": 1e-10})
    return errors(result.x)
