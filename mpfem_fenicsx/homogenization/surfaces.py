"""Threshold surfaces of a fan of reloads (thesis chapter 4, §4.2-4.5), from the fan's plain
arrays (``workflows.yield_surface.fan_rows``: phi, sigma_m, sigma_tilde_d, E_d, Gamma, W2, ...):
the yield point by iso-dissipation, iso-Gamma points, Hill's W2 <= 0, the limit specific contact
surface Gamma_l, default iso-Gamma levels. Stresses in MPa (compression > 0), Gamma in 1/mm."""

from __future__ import annotations

import math

import numpy as np

from .stress import first_crossing


def default_gamma_levels(gamma_unloaded: float, gamma_fan: np.ndarray) -> tuple[float, ...]:
    """Iso-Gamma levels when none are given (1/mm): two between the unloaded value and the fan's
    smallest Gamma (loss of contact surface, damage) and two towards its largest (contacts
    growing), at 1/3 and 2/3 of the way. The thesis picked absolute levels per density; the
    reloads' Gamma range depends on the amplitude A, so levels are taken inside it."""
    lo, hi = float(np.nanmin(gamma_fan)), float(np.nanmax(gamma_fan))
    levels = [gamma_unloaded + f * (lo - gamma_unloaded) for f in (2 / 3, 1 / 3)] + [
        gamma_unloaded + f * (hi - gamma_unloaded) for f in (1 / 3, 2 / 3)
    ]
    return tuple(
        sorted(
            {
                float(f"{g:.5g}")
                for g in levels
                if g > 0 and abs(g - gamma_unloaded) > 1e-9 * gamma_unloaded
            }
        )
    )


def surface_points(
    fan: dict[str, np.ndarray], E_0: float, dissipation_threshold: float, gamma_thresholds
) -> dict[str, tuple[float, float]]:
    """Threshold points of one reload: {kind: (sigma_m, sigma_tilde_d)} for kind in yield,
    gamma_<value>, w2 (absent when not crossed). W2 is only read where the strain increment is
    at least 20 % of the reload's largest (the smooth-step amplitude stops the loading at both
    ends, where dsigma : dh is round-off, thesis §4.5)."""
    sm, sd = fan["sigma_m"], fan["sigma_tilde_d"]
    points = {}
    _, m, d = first_crossing(fan["E_d"], E_0 * (1.0 + dissipation_threshold), sm, sd, rising=True)
    if np.isfinite(m):
        points["yield"] = (float(m), float(d))
    for level in gamma_thresholds:
        p = iso_gamma_point(fan, level)
        if p is not None:
            points[f"gamma_{level:.4g}"] = p
    sel = moving_rows(fan)
    _, m, d = first_crossing(fan["W2"][sel], 0.0, sm[sel], sd[sel], rising=False)
    if np.isfinite(m):
        points["w2"] = (float(m), float(d))
    return points


def moving_rows(fan: dict[str, np.ndarray]) -> slice:
    """Rows where the strain increment is >= 20 % of the reload's largest (W2 is read there)."""
    moving = np.flatnonzero(fan["_dh"] >= 0.2 * np.nanmax(fan["_dh"]))
    return slice(moving[0], moving[-1] + 1) if moving.size >= 2 else slice(0, 0)


def iso_gamma_point(fan: dict[str, np.ndarray], level: float) -> tuple[float, float] | None:
    """(sigma_m, sigma~_d) where a reload's specific contact surface crosses ``level`` (1/mm) for
    the last time, either way (thesis §4.3, "le seuil le plus tardif"); None if it never does."""
    best = (-1.0, np.nan, np.nan)
    for rising in (True, False):
        pos, m, d = first_crossing(
            fan["Gamma"], level, fan["sigma_m"], fan["sigma_tilde_d"], rising=rising, last=True
        )
        if np.isfinite(pos) and pos > best[0]:
            best = (pos, m, d)
    return (float(best[1]), float(best[2])) if np.isfinite(best[1]) else None


#: a collapse of the contacts loses at least this fraction of the unloaded Gamma (-)
MIN_GAMMA_COLLAPSE = 0.05


def limit_specific_surface(
    fans: list[dict],
    gamma_unloaded: float,
    scale: float,
    tolerance: float = 0.02,
    levels: int = 24,
    min_directions: int = 3,
    min_collapse: float = MIN_GAMMA_COLLAPSE,
) -> float:
    """Limit specific contact surface Gamma_l (1/mm, thesis §4.3 and table 4.2): the threshold
    below which the iso-Gamma curves superpose (the contacts collapse at the stress peak, so
    every lower threshold is crossed at almost the same stress; the thesis reads it off the
    curves and takes the limit curve as the rupture surface). Operationally: ``levels`` levels
    from the unloaded value down to the lowest one still crossed by ``min_directions`` reloads;
    consecutive curves, compared on the directions crossing both, superpose when no point
    moves by more than ``tolerance`` x ``scale`` (MPa, e.g. the yield surface's largest
    stress); Gamma_l is the highest level from which every lower pair superposes. Crossings
    within 10 % of ``scale`` of the unloaded state are not counted (levels just below the
    unloaded value are crossed at the start of every reload, trivially together). NaN when
    the curves never superpose (reloads too short to break the contacts), and when no
    ``min_directions`` reloads lose at least ``min_collapse`` of the unloaded Gamma: the lowest
    levels of a fan whose contacts hold are crossed where the reloads stop, together but
    without any collapse."""
    minima = np.sort([float(np.nanmin(f["Gamma"])) for f in fans])
    if (
        minima.size < min_directions
        or not minima[min_directions - 1] <= (1.0 - min_collapse) * gamma_unloaded
    ):
        return float("nan")
    grid = np.linspace(gamma_unloaded, minima[min_directions - 1], levels + 1)[1:]

    def away(fan, p):
        start = (fan["sigma_m"][0], fan["sigma_tilde_d"][0])
        return p if p is not None and math.dist(p, start) > 0.1 * scale else None

    curves = [{k: away(f, iso_gamma_point(f, g)) for k, f in enumerate(fans)} for g in grid]
    superposed = []
    for upper, lower in zip(curves[:-1], curves[1:], strict=True):
        common = [k for k in upper if upper[k] is not None and lower[k] is not None]
        moved = max((math.dist(upper[k], lower[k]) for k in common), default=np.inf)
        superposed.append(len(common) >= min_directions and moved <= tolerance * scale)
    j = len(superposed)
    while j > 0 and superposed[j - 1]:
        j -= 1
    return float(grid[j]) if j < len(superposed) else float("nan")


def w2_sign_changes(fan: dict[str, np.ndarray]) -> int:
    """Sign changes of the raw (unfiltered) W2 of a reload where it is read (:func:`_moving`): a
    quasi-static reload has at most one (W2 > 0, then <= 0 at rupture); dynamic noise many."""
    w = fan["_W2_raw"][moving_rows(fan)]
    signs = np.sign(w[np.isfinite(w) & (w != 0)])
    return int(np.count_nonzero(signs[1:] != signs[:-1]))
