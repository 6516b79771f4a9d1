"""Abaqus material fragments of the density-dependent continuum models, and their reader.

A fragment (units mm, N, MPa) defines one material with ``*ELASTIC, DEPENDENCIES=1`` (Young's
modulus and Poisson's ratio at each calibrated density) and either

- the Drucker-Prager Cap: ``*CAP PLASTICITY, DEPENDENCIES=1`` (d, beta, R, the initial cap
  position, alpha, K at each density) and ``*CAP HARDENING`` (p_b against the plastic
  volumetric strain); or
- the critical-state ellipse: ``*CLAY PLASTICITY, HARDENING=TABULAR, DEPENDENCIES=1`` (M, beta,
  K at each density) and ``*CLAY HARDENING`` in compression (p_c) and in tension (p_t).

Field variable 1 is the relative density (solid fraction): the model that reads the fragment
must set it, e.g. with a USDFLD subroutine that computes rho = rho_0 exp(|eps_v^pl|) from the
plastic volumetric strain, as density-dependent cap calibrations of powders do. Abaqus
interpolates the parameters linearly between the densities and holds them beyond the ends.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cap import CapSurface


@dataclass(frozen=True)
class CalibratedDensity:
    """The model at one relative density: its yield surface and isotropic elastic moduli."""

    density: float  #: relative density (solid fraction, -)
    surface: CapSurface
    young: float  #: Young's modulus (MPa)
    poisson: float  #: Poisson's ratio (-)

    def __post_init__(self) -> None:
        if not 0.0 < self.density < 1.0:
            raise ValueError(f"density = {self.density!r} is out of range: must be > 0 and < 1")
        if not self.young > 0.0:
            raise ValueError(f"young = {self.young!r} is out of range: must be > 0 (MPa)")
        if not -1.0 < self.poisson < 0.5:
            raise ValueError(f"poisson = {self.poisson!r} is out of range: must be > -1 and < 0.5")


def elastic_constants(bulk: float, shear: float) -> tuple[float, float]:
    """(E, nu) of an isotropic solid of bulk modulus ``bulk`` and shear modulus ``shear`` (MPa)."""
    if not (bulk > 0.0 and shear > 0.0):
        raise ValueError(f"bulk = {bulk!r}, shear = {shear!r}: both must be > 0 (MPa)")
    return 9.0 * bulk * shear / (3.0 * bulk + shear), (3.0 * bulk - 2.0 * shear) / (
        2.0 * (3.0 * bulk + shear)
    )


def hardening_table(p_b, eps_v_pl) -> tuple[np.ndarray, np.ndarray]:
    """The ``*CAP HARDENING`` table: p_b (MPa) against |eps_v^pl| (-), sorted by the strain, kept
    where p_b increases (Abaqus requires p_b > 0, increasing with the strain)."""
    p, e = np.ravel(p_b).astype(float), np.abs(np.ravel(eps_v_pl).astype(float))
    order = np.argsort(e, kind="stable")
    p, e = p[order], e[order]
    keep = (p > 0) & (p > np.maximum.accumulate(np.concatenate([[0.0], p[:-1]])))
    if keep.sum() < 2:
        raise ValueError("hardening: need >= 2 points with p_b > 0 increasing with eps_v^pl")
    return p[keep], e[keep]


def _line(values) -> str:
    return ", ".join("" if v is None else f"{v:.6g}" for v in values)


def _material(model: str, name: str, rows: list[CalibratedDensity]) -> list[str]:
    """The fragment's header, ``*MATERIAL`` and its ``*ELASTIC`` lines by density."""
    lines = [
        f"** {model} model fitted to multi-particle yield surfaces (mpfem-fenicsx)",
        "** units: mm, N, MPa; field variable 1: relative density (set it, e.g. by USDFLD)",
        f"*MATERIAL, NAME={name}",
        "*ELASTIC, DEPENDENCIES=1",
    ]
    return lines + [_line([r.young, r.poisson, None, r.density]) for r in rows]


def cap_fragment(
    rows: list[CalibratedDensity],
    hardening: tuple[np.ndarray, np.ndarray],
    name: str = "POWDER",
) -> str:
    """The Abaqus fragment (see the module) of the calibrated densities ``rows`` and the
    hardening table (p_b, |eps_v^pl|) of :func:`hardening_table`. The initial cap position of
    each density is the plastic volumetric strain at which the table reaches its p_b."""
    if not rows:
        raise ValueError("rows: need >= 1 calibrated density")
    rows = sorted(rows, key=lambda r: r.density)
    p_b, eps = hardening_table(*hardening)
    lines = _material("Drucker-Prager Cap", name, rows)
    lines.append("*CAP PLASTICITY, DEPENDENCIES=1")
    for r in rows:
        s = r.surface
        eps0 = float(np.interp(s.p_b, p_b, eps))
        lines.append(_line([s.d, s.beta, s.R, eps0, s.alpha, s.K, None, r.density]))
    lines.append("*CAP HARDENING")
    lines += [_line([p, e]) for p, e in zip(p_b, eps, strict=True)]
    return "\n".join(lines) + "\n"


def clay_fragment(
    rows: list[CalibratedDensity],
    hardening: tuple[np.ndarray, np.ndarray],
    density_0: float,
    name: str = "POWDER",
) -> str:
    """The Abaqus fragment of the critical-state ellipse (:class:`~.clay.ClaySurface`) at the
    calibrated densities ``rows``: ``*ELASTIC`` and ``*CLAY PLASTICITY, HARDENING=TABULAR``
    (M, beta, K) with field variable 1 = relative density, ``*CLAY HARDENING`` TYPE=COMPRESSION
    (p_c against |eps_v^pl|, the table of :func:`hardening_table` from a strain of 0) and
    TYPE=TENSION (p_t = (p_t / p_c)(rho) p_c, rho = ``density_0`` exp(eps_v^pl), the ratio
    interpolated between the calibrated densities and held beyond them)."""
    if not rows:
        raise ValueError("rows: need >= 1 calibrated density")
    rows = sorted(rows, key=lambda r: r.density)
    p_c, eps = hardening_table(*hardening)
    if eps[0] > 0.0:  # Abaqus' tables start at zero plastic strain
        p_c, eps = np.concatenate([[1e-3 * p_c[0]], p_c]), np.concatenate([[0.0], eps])
    ratio = np.interp(
        density_0 * np.exp(eps),
        [r.density for r in rows],
        [r.surface.p_t / r.surface.p_c for r in rows],
    )
    p_t = np.minimum.accumulate(ratio * p_c)  # must not increase with the strain
    lines = _material("critical-state (Cam-clay)", name, rows)
    lines.append("*CLAY PLASTICITY, HARDENING=TABULAR, DEPENDENCIES=1")
    for r in rows:
        s = r.surface
        lines.append(_line([None, s.M, None, s.beta, s.K, None, r.density]))
    lines.append("*CLAY HARDENING, TYPE=COMPRESSION")
    lines += [_line([p, e]) for p, e in zip(p_c, eps, strict=True)]
    lines.append("*CLAY HARDENING, TYPE=TENSION")
    lines += [_line([p, e]) for p, e in zip(p_t, eps, strict=True)]
    return "\n".join(lines) + "\n"


def read_keywords(text: str) -> list[tuple[str, dict[str, str], list[list[float | None]]]]:
    """The keyword blocks of an Abaqus input text: (KEYWORD, {PARAMETER: value}, data lines),
    comments (``**``) skipped, empty fields as None, keywords and parameters upper case."""
    blocks = []
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line.startswith("**"):
            continue
        if line.startswith("*"):
            head, *params = [part.strip() for part in line[1:].split(",")]
            options = {}
            for param in params:
                key, _, value = param.partition("=")
                options[key.strip().upper()] = value.strip()
            blocks.append((head.upper(), options, []))
        else:
            if not blocks:
                raise ValueError(f"data line before any keyword: {line!r}")
            fields = [f.strip() for f in line.split(",")]
            blocks[-1][2].append([float(f) if f else None for f in fields])
    return blocks


def surfaces_from_fragment(text: str) -> dict[float, CapSurface]:
    """The cap surfaces written by :func:`cap_fragment`, by density, read back (p_b from the
    hardening table at each density's initial cap position)."""
    blocks = {key: (options, data) for key, options, data in read_keywords(text)}
    _, hardening = blocks["CAP HARDENING"]
    p_b = np.array([row[0] for row in hardening])
    eps = np.array([row[1] for row in hardening])
    surfaces = {}
    for row in blocks["CAP PLASTICITY"][1]:
        d, beta, R, eps0, alpha, K, _, density = row
        surfaces[density] = CapSurface(
            d=d, beta=beta, R=R, p_b=float(np.interp(eps0, eps, p_b)), alpha=alpha, K=K
        )
    return surfaces
