"""Admission of a packing for a run: the one rule that ``mpfem pack --input``, ``mpfem run
--check`` and the run itself apply, so that whatever a run refuses is refused first by the
checks, with the same one-line message.

Units mm. Overlaps are relative to the smaller radius of a pair (a DEM packing left stable under
a small confining stress carries contact overlaps of ~0.1 % of a radius).

The run meshes each sphere of radius r as a cube-sphere of radius ``radius_factor * r``; a
volume-exact cube-sphere puts its surface nodes at ``node_scale`` times that radius (1.0100 for
the default 6x6 particle, :attr:`meshes.cubesphere.UnitBallMesh.radius_scale`). The spheres
through those nodes must not overlap at the start, else the penalty contact releases the
overlap's energy in the first increments, a bang that deforms the particles before any loading.
Hence the rule of :func:`admit_packing`:

1. the packing's geometry: cell, radii and centres (:meth:`Packing.validate`);
2. the start spheres, radii x ``radius_factor * node_scale``, overlap nowhere (relative
   tolerance :data:`START_OVERLAP_TOLERANCE`);
3. if they do and the factor is the default (``automatic``) and the packing itself overlaps (a DEM
   export), the reduction is lowered to the largest 4-decimal factor that leaves a gap of
   :data:`START_GAP` between the closest start spheres, provided the packing's largest overlap
   is a contact's (at most :data:`MAX_DEM_OVERLAP`); a packing without overlap keeps the factor
   (generated packings run bit for bit as before);
4. the initial relative density rho0 = V_p / V0 with the reduced radii (thesis eq. 2.5) lies
   below the target density.

A refusal is a ValueError of one line that names the fix; what was decided is reported in
:attr:`Admission.notes`, with a warning when the lengths look like metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .packing import Packing

__all__ = [
    "MAX_DEM_OVERLAP",
    "START_GAP",
    "START_OVERLAP_TOLERANCE",
    "Admission",
    "admit_packing",
    "metres_warning",
]

#: largest overlap (fraction of the smaller radius) of the spheres through the particle meshes'
#: nodes at the start: round-off of touching spheres, not an interpenetration
START_OVERLAP_TOLERANCE = 1e-6
#: relative gap d / (r_i + r_j) - 1 left between the closest start spheres by an automatic radius
#: reduction (a generated packing at the default 0.99 with the 6x6 particle leaves 6e-5)
START_GAP = 1e-4
#: largest packing overlap (fraction of the smaller radius) the automatic reduction takes: beyond
#: it the packing is not a DEM packing at rest under a small stress, or its lengths are off
MAX_DEM_OVERLAP = 0.02
#: below these (mm) a packing's lengths look like metres: a radius under a micrometre, a cell
#: under 10 micrometres
METRES_RADIUS, METRES_CELL = 1e-3, 1e-2


@dataclass(frozen=True)
class Admission:
    """A packing admitted for a run and what the run will do with it."""

    packing: Packing  # as given (radii not reduced), mm
    radius_factor: float  # the reduction applied to the radii before meshing (-)
    rho0: float  # initial relative density V_p / V0 with the reduced radii (thesis eq. 2.5)
    overlap: float  # the packing's largest overlap / smaller radius (0 if none)
    node_scale: float  # the particle mesh's surface nodes / its meshed radius
    automatic: bool  # True when the default factor was lowered for the packing's overlaps
    notes: tuple[str, ...] = ()  # one line each, for the log: the decision, warnings


def _floor4(x: float) -> float:
    """``x`` rounded down to 4 decimals (a factor a user can type and that still works)."""
    return math.floor(x * 1e4) / 1e4


def _percent(fraction: float) -> str:
    return f"{100 * fraction:.2g} %"


def metres_warning(packing: Packing) -> str | None:
    """One line when the packing's lengths look like metres read as millimetres (largest radius
    below :data:`METRES_RADIUS` or largest cell side below :data:`METRES_CELL`), else None."""
    r_max, cell = float(packing.radii.max()), packing.cell
    if r_max >= METRES_RADIUS and float(cell.max()) >= METRES_CELL:
        return None
    sides = " x ".join(f"{d:.3g}" for d in cell)
    return (
        f"WARNING: the packing's lengths look like metres (largest radius {r_max:.3g} mm, "
        f"cell {sides} mm): convert the file with "
        f"'mpfem pack --input FILE --length-scale 1000 --out FILE.txt'"
    )


def _worst_pair(packing: Packing, scale: float) -> tuple[int, int, list[int], float]:
    """The pair of the largest overlap of the spheres of radii ``scale * r``: i, j, the lattice
    shift of j's image and the overlap over the smaller scaled radius."""
    i, j, shift, dist = packing.pair_distances()
    r_i, r_j = scale * packing.radii[i], scale * packing.radii[j]
    rel = (r_i + r_j - dist) / np.minimum(r_i, r_j)
    k = int(np.argmax(rel))
    return int(i[k]), int(j[k]), shift[k].tolist(), float(rel[k])


def _start_refusal(packing: Packing, factor: float, node_scale: float, dem: bool) -> str:
    """The message for a factor whose start spheres overlap, with the largest factor that works
    (``dem``: the packing overlaps, and the default factor would be lowered)."""
    i, j, shift, start = _worst_pair(packing, factor * node_scale)
    fit = _floor4(packing.contact_ratio() / node_scale)
    default = " (or leave the default: it is lowered for a DEM packing's overlaps)" if dem else ""
    return (
        f"radius_factor {factor:g}: the particle mesh's nodes lie at {node_scale:.4f} x the "
        f"meshed radius, so particles {i} and {j} (image shift {shift}) would start "
        f"interpenetrating by up to {_percent(start)} of the smaller radius; use radius_factor "
        f"<= {fit:.4f}{default}, more divisions or exact_volume = false"
    )


def _dem_refusal(packing: Packing, node_scale: float) -> str:
    """The message for a packing whose overlaps are beyond a DEM contact's."""
    i, j, shift, overlap = _worst_pair(packing, 1.0)
    fit = _floor4(packing.contact_ratio() / node_scale)
    accept = f", or set radius_factor <= {fit:.4f} to take it as it is" if fit >= 0.5 else ""
    return (
        f"overlap of particles {i} and {j} (image shift {shift}): {_percent(overlap)} of the "
        f"smaller radius, beyond the {_percent(MAX_DEM_OVERLAP)} of a DEM contact that the "
        f"automatic radius reduction takes; relax the packing in the DEM code or check its "
        f"lengths{accept}"
    )


def _choose_factor(
    packing: Packing, radius_factor: float, node_scale: float, automatic: bool, tolerance: float
) -> tuple[float, float, bool]:
    """(factor, the packing's largest overlap, lowered automatically?) or ValueError."""
    overlap = packing.max_overlap()
    start = packing.scaled(radius_factor * node_scale).max_overlap()
    if start <= tolerance:
        return radius_factor, overlap, False
    if not (automatic and overlap > tolerance):
        raise ValueError(_start_refusal(packing, radius_factor, node_scale, overlap > tolerance))
    if overlap > MAX_DEM_OVERLAP:
        raise ValueError(_dem_refusal(packing, node_scale))
    return _floor4((1.0 - START_GAP) * packing.contact_ratio() / node_scale), overlap, True


def admit_packing(
    packing: Packing,
    radius_factor: float,
    node_scale: float,
    *,
    target_density: float | None = None,
    automatic: bool = False,
    tolerance: float = START_OVERLAP_TOLERANCE,
) -> Admission:
    """Admit ``packing`` for a run whose particles are meshed at ``radius_factor`` times the
    packing's radii with their surface nodes at ``node_scale`` times that (the module's rule).

    ``automatic``: ``radius_factor`` is the default, which may be lowered for a DEM packing's
    overlaps (reported in the notes); otherwise a factor too large is refused, naming the largest
    one that works. ``target_density``: the run's, which must exceed rho0. Raises ValueError of
    one line naming the particle, field or file setting to change.
    """
    if not (math.isfinite(radius_factor) and 0.0 < radius_factor <= 1.0):
        raise ValueError(f"radius_factor must be in (0, 1], got {radius_factor!r}")
    if not (math.isfinite(node_scale) and node_scale > 0.0):
        raise ValueError(f"node_scale must be > 0, got {node_scale!r}")
    packing.validate(overlap_tolerance=np.inf)  # sizes and centres; the overlaps are ruled here
    factor, overlap, lowered = _choose_factor(
        packing, radius_factor, node_scale, automatic, tolerance
    )
    solid = float(4.0 / 3.0 * np.pi * np.sum((packing.radii * factor) ** 3))  # thesis eq. 2.5
    rho0 = solid / float(np.prod(packing.cell))
    if target_density is not None and not rho0 < target_density < 1.0:
        raise ValueError(
            f"loading.target_density = {target_density} is out of range: must be in "
            f"({rho0:.4f}, 1), above the packing's initial relative density "
            f"V_p / V0 = {rho0:.4f}"
        )
    notes = []
    if lowered:
        notes.append(
            f"radius reduction x{factor:.4f} (instead of x{radius_factor:g}) for the "
            f"packing's {_percent(overlap)} overlaps and the particle's nodes at "
            f"{node_scale:.4f} x its radius"
        )
    elif overlap > tolerance:  # a DEM packing's contacts (not the round-off of touching spheres)
        notes.append(
            f"largest overlap {_percent(overlap)} of the smaller radius, removed by the "
            f"radius reduction x{factor:g} (the particle's nodes at {node_scale:.4f} x "
            f"its radius)"
        )
    warning = metres_warning(packing)
    if warning is not None:
        notes.append(warning)
    return Admission(packing, factor, rho0, overlap, node_scale, lowered, tuple(notes))
