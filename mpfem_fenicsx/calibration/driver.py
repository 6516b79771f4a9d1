"""A material-point driver of the density-dependent continuum models (Abaqus' forms): the
Drucker-Prager Cap (:class:`~.cap.CapSurface`) or the critical-state ellipse
(:class:`~.clay.ClaySurface`).

Pure numpy / scipy, one material point, principal (diagonal) stresses and strains: the paths the
particle model runs (isotropic and die compaction, the triaxial test under a confining
pressure). Small strains, logarithmic strain increments; stresses in MPa, compression > 0 in
what the paths report.

The model, as Abaqus/Standard integrates it:

- isotropic elasticity of Young's modulus E and Poisson's ratio nu, interpolated in the relative
  density (held beyond the calibrated ones);
- the yield surface: its shape (cap: d, beta, R, alpha, K; ellipse: M, beta, K and p_t / p_c)
  interpolated in the density, its size (p_b, p_c) from the hardening table at the plastic
  volumetric strain eps_v^pl (compaction > 0);
- the surface's flow rule (``yield_and_flow``): for the cap, associated on the cap and Abaqus'
  non-associated potential on the shear line and the transition; for the ellipse, associated;
- the density rho = rho_0 exp(-tr eps) of the current strain (the field variable).

The return at each increment solves, for (p, t, dlambda), the trial state's p_tr, t_tr
(deviator scaled at fixed Lode angle): p = p_tr - K_b dlambda dG/dp,
t = t_tr - 3 G g^2 dlambda dG/dt (t = g q), F(p, t; p_b(eps_v^pl + dlambda dG/dp)) = 0.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.optimize import fsolve

from .abaqus import CalibratedDensity, hardening_table


@dataclass(frozen=True)
class ContinuumModel:
    """The calibrated model: surfaces and moduli at several densities, the hardening table
    (p_b against |eps_v^pl|) and the density rho_0 at zero strain."""

    rows: tuple[CalibratedDensity, ...]
    hardening: tuple[np.ndarray, np.ndarray]
    density_0: float

    def __post_init__(self) -> None:
        if not self.rows:
            raise ValueError("rows: need >= 1 calibrated density")
        object.__setattr__(self, "rows", tuple(sorted(self.rows, key=lambda r: r.density)))
        object.__setattr__(self, "hardening", hardening_table(*self.hardening))
        if not 0.0 < self.density_0 < 1.0:
            raise ValueError(f"density_0 = {self.density_0!r} is out of range: > 0 and < 1")

        kinds = {type(r.surface) for r in self.rows}
        if len(kinds) != 1:
            raise ValueError("rows: all the densities need the same kind of surface")

    def _interp(self, density: float, values) -> float:
        return float(np.interp(density, [r.density for r in self.rows], list(values)))

    def elastic(self, density: float) -> tuple[float, float]:
        """(bulk, shear) moduli (MPa) at ``density``."""
        E = self._interp(density, (r.young for r in self.rows))
        nu = self._interp(density, (r.poisson for r in self.rows))
        return E / (3.0 * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))

    def p_b(self, eps_v_pl: float) -> float:
        """The hydrostatic yield stress (MPa) at the plastic volumetric strain (compaction > 0);
        held at the table's ends."""
        p, e = self.hardening
        return float(np.interp(eps_v_pl, e, p))

    def surface(self, density: float, eps_v_pl: float):
        """The yield surface at ``density`` and ``eps_v_pl``: its shape interpolated in the
        density, its size from the hardening table."""
        kind = type(self.rows[0].surface)
        shape = {
            n: self._interp(density, (getattr(r.surface, n) for r in self.rows)) for n in kind.SHAPE
        }
        for n in self.rows[0].surface.size_ratios:
            shape[n] = self._interp(density, (r.surface.size_ratios[n] for r in self.rows))
        return kind.sized(self.p_b(eps_v_pl), **shape)


def _lode_factor(s: np.ndarray, q: float, K: float) -> float:
    """g = t / q from the principal deviator ``s`` (tension > 0): t = q/2 [1 + 1/K -
    (1 - 1/K)(r/q)^3], r^3 = 9/2 sum s^3."""
    if q <= 0.0:
        return 1.0
    r_over_q3 = float(np.clip(4.5 * np.sum(s**3) / q**3, -1.0, 1.0))
    return 0.5 * (1.0 + 1.0 / K - (1.0 - 1.0 / K) * r_over_q3)


class ReturnMappingError(RuntimeError):
    """The return of a trial stress to the yield surface found no solution."""


def return_map(model: ContinuumModel, strain: np.ndarray, sigma_trial: np.ndarray, eps_v_pl: float):
    """The stress (principal, tension > 0) and eps_v^pl after the return of ``sigma_trial`` at
    the total principal ``strain``; (sigma, eps_v_pl, plastic?)."""
    density = model.density_0 * math.exp(-float(np.sum(strain)))
    bulk, shear = model.elastic(density)
    p_tr = -float(np.mean(sigma_trial))
    s_tr = sigma_trial + p_tr
    q_tr = math.sqrt(1.5 * float(np.sum(s_tr**2)))
    surface = model.surface(density, eps_v_pl)
    g = _lode_factor(s_tr, q_tr, surface.K)
    t_tr = g * q_tr
    t_surface = surface.t(p_tr)
    if np.isfinite(t_surface) and t_tr <= t_surface:
        return sigma_trial, eps_v_pl, False

    def residual(x, region):
        p, t, dl, e = x
        trial = model.surface(density, e)
        F, (Gp, Gt) = trial.yield_and_flow(p, t, region)
        scale = max(trial.p_high, 1e-12)
        return [
            (p - p_tr + bulk * dl * Gp) / scale,
            (t - t_tr + 3.0 * shear * g * g * dl * Gt) / scale,
            F / scale,
            (e - eps_v_pl - dl * Gp) * bulk / scale,
        ]

    # first guess: the volumetric trial excess all plastic, on the hardened surface
    e0 = eps_v_pl + max(p_tr - surface.p_high, 0.0) / bulk
    p0 = min(p_tr, model.p_b(e0))
    t0 = float(np.nan_to_num(model.surface(density, e0).t(p0)))
    for region in surface.regions(p_tr):
        with warnings.catch_warnings():  # judged by the residual below
            warnings.simplefilter("ignore", RuntimeWarning)
            x = fsolve(
                residual,
                [p0, min(t_tr, t0), e0 - eps_v_pl, e0],
                args=(region,),
                xtol=1e-12,
            )
        p, t, dl, e = x
        solved = np.max(np.abs(residual(x, region))) < 1e-10
        if solved and dl >= 0.0 and t >= -1e-9 * surface.p_high:
            if model.surface(density, e).region_of(p) == region:
                break
    else:
        raise ReturnMappingError(
            f"return mapping failed at p_tr = {p_tr:.6g}, t_tr = {t_tr:.6g} MPa"
        )
    q = max(t, 0.0) / g
    s = s_tr * (q / q_tr) if q_tr > 0 else s_tr
    return s - p, e, True


@dataclass
class PointState:
    """The material point: principal strain (natural sign), principal stress (tension > 0),
    the plastic volumetric strain (compaction > 0)."""

    strain: np.ndarray
    stress: np.ndarray
    eps_v_pl: float = 0.0


def stress_update(model: ContinuumModel, state: PointState, strain: np.ndarray, depth: int = 0):
    """The stress and eps_v^pl at the total principal ``strain`` from ``state`` (not changed).
    A return that fails from a trial far outside the surface is retried in two halves of the
    increment (down to 1/256 of it)."""
    density = model.density_0 * math.exp(-float(np.sum(strain)))
    bulk, shear = model.elastic(density)
    de = strain - state.strain
    trial = state.stress + (bulk - 2.0 * shear / 3.0) * np.sum(de) + 2.0 * shear * de
    try:
        sigma, eps, _ = return_map(model, strain, trial, state.eps_v_pl)
    except ReturnMappingError:
        if depth >= 8:
            raise
        middle = 0.5 * (state.strain + strain)
        half = PointState(middle, *stress_update(model, state, middle, depth + 1))
        return stress_update(model, half, strain, depth + 1)
    return sigma, eps


def drive(
    model: ContinuumModel,
    strain_end,
    stress_held=(None, None, None),
    increments: int = 200,
    state: PointState | None = None,
):
    """Load the point from ``state`` (default: unstrained, unstressed) along a straight
    principal strain path to ``strain_end`` (natural sign: compaction < 0), with the
    components whose ``stress_held`` is a number held at that stress instead (MPa, compression
    > 0; their strains are found by Newton). Returns the reported rows {density, sigma_m,
    sigma_tilde_d (axis 3), sigma_1, sigma_2, sigma_3 (compression > 0), eps_v_pl} and the end
    state."""
    state = state or PointState(np.zeros(3), np.zeros(3))
    held = np.array([h is not None for h in stress_held])
    target = np.array([0.0 if h is None else -float(h) for h in stress_held])
    start = state.strain.copy()
    rows = []
    for k in range(1, increments + 1):
        strain = start + (np.asarray(strain_end, float) - start) * k / increments
        strain[held] = state.strain[held]
        strain, sigma, eps = _hold_stresses(model, state, strain, held, target)
        state = PointState(strain, sigma, eps)
        rows.append(_report(model, state))
    return {k: np.array([r[k] for r in rows]) for k in rows[0]}, state


def _hold_stresses(model, state, strain, held, target):
    """The strains of the ``held`` components that bring their stresses to ``target`` (tension
    > 0): Newton on a finite-difference tangent, with a backtracking line search and the
    elastic stiffness as the fallback direction (on a perfectly plastic shear line the
    consistent tangent is nearly singular)."""
    sigma, eps = stress_update(model, state, strain)
    if not held.any():
        return strain, sigma, eps
    idx = np.flatnonzero(held)
    bulk, shear = model.elastic(model.density_0 * math.exp(-float(np.sum(strain))))
    elastic = (bulk - 2.0 * shear / 3.0) * np.ones((3, 3)) + 2.0 * shear * np.eye(3)
    scale = max(1.0, float(np.max(np.abs(sigma))))
    for _ in range(100):
        miss = sigma[idx] - target[idx]
        if np.max(np.abs(miss)) < 1e-10 * scale:
            return strain, sigma, eps
        J = np.empty((idx.size, idx.size))
        for j, comp in enumerate(idx):
            probe = strain.copy()
            probe[comp] += 1e-9
            J[:, j] = (stress_update(model, state, probe)[0][idx] - sigma[idx]) / 1e-9
        for matrix in (J, elastic[np.ix_(idx, idx)]):
            step, better = np.linalg.solve(matrix, miss), None
            for _ in range(30):
                trial = strain.copy()
                trial[idx] -= step
                got = stress_update(model, state, trial)
                if np.linalg.norm(got[0][idx] - target[idx]) < np.linalg.norm(miss):
                    better = (trial, *got)
                    break
                step = 0.5 * step
            if better is not None:
                strain, sigma, eps = better
                break
        else:
            break
    raise RuntimeError(f"held stresses not reached: {sigma[idx]} against {target[idx]} MPa")


def _report(model: ContinuumModel, state: PointState) -> dict[str, float]:
    c = -state.stress
    return {
        "density": model.density_0 * math.exp(-float(np.sum(state.strain))),
        "sigma_m": float(np.mean(c)),
        "sigma_tilde_d": float(c[2] - 0.5 * (c[0] + c[1])),
        "sigma_1": float(c[0]),
        "sigma_2": float(c[1]),
        "sigma_3": float(c[2]),
        "eps_v_pl": state.eps_v_pl,
    }
