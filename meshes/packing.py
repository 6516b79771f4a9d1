"""Sphere packings in a periodic cell: container, plain-text I/O, generator, duplicated particles.

Units: mm. The periodic cell is the box [0, dx] x [0, dy] x [0, dz] (origin at 0); a packing
holds N sphere centres in [0, d) per axis and their radii.

- :class:`Packing` with :meth:`Packing.validate` (overlap check over periodic images).
- :func:`write_packing` / :func:`read_packing`: the plain format a YADE or LIGGGHTS script
  exports: a header line ``dx dy dz``, then one ``x y z r`` line per sphere.
- :func:`generate_packing`: our own seeded, deterministic generator of a frictionless random
  packing (thesis §2.2.1): random centres in a dilute periodic cell, then the radii grow
  (equivalently the cell shrinks) in small increments, each followed by a frictionless energy
  minimisation (harmonic repulsion, FIRE) over a periodic neighbour list. It stops at a
  requested solid fraction, or when the packing jams (overlaps can no longer be relaxed).
- :func:`duplicate_particles`, :func:`assembly_particles`: the duplicated particles of thesis
  §2.2.1 (fig. 2.2) used to apply the boundary conditions, on all faces or, for the fully
  periodic CLP of thesis §2.5.4 (fig. 2.10a), on half of them.
"""

from __future__ import annotations

import itertools
import re
import time
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numba
import numpy as np
from scipy.spatial import cKDTree

__all__ = [
    "PACKING_FORMATS",
    "AssemblyParticles",
    "Duplicates",
    "Packing",
    "assembly_particles",
    "duplicate_particles",
    "generate_packing",
    "packing_format",
    "simple_cubic_packing",
    "sphere_rows",
    "periodic_pair_realizations",
    "read_packing",
    "write_packing",
]


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


# The 27 lattice vectors {-1, 0, 1}^3 (index 13 is the zero shift).
_SHIFTS = np.array(list(itertools.product((-1, 0, 1), repeat=3)), dtype=np.int64)


def _periodic_pairs(centres, radii, cell, cutoff):
    """Pairs (i < j, shift) with |c_i - (c_j + shift * cell)| < cutoff, over periodic images.

    Exact for any cell larger than ``cutoff`` (a pair may interact through several images, e.g.
    the 8-sphere simple cubic cell of side 4 r). Returns i, j, shift (M, 3), distance (M,).
    """
    n = radii.size
    images = (centres[None, :, :] + _SHIFTS[:, None, :] * cell).reshape(-1, 3)
    keep = np.flatnonzero(np.all((images > -cutoff) & (images < cell + cutoff), axis=1))
    found = cKDTree(centres).sparse_distance_matrix(
        cKDTree(images[keep]), cutoff, output_type="ndarray"
    )
    i, k = found["i"].astype(np.int64), keep[found["j"]]
    j, shift = k % n, _SHIFTS[k // n]
    mask = i < j  # drops self (and its images) and the mirrored copy (j, i, -shift)
    order = np.lexsort((k[mask], i[mask]))
    return i[mask][order], j[mask][order], shift[mask][order], found["v"][mask][order]


@dataclass(frozen=True, eq=False)
class Packing:
    """Spheres in the periodic cell [0, dx] x [0, dy] x [0, dz] (mm).

    ``cell`` (3,) cell sizes, ``centres`` (N, 3) in [0, d) per axis, ``radii`` (N,). Arrays are
    stored as read-only float64 copies. Construction checks shapes only; :meth:`validate` checks
    the geometry.
    """

    cell: np.ndarray
    centres: np.ndarray
    radii: np.ndarray

    def __post_init__(self):
        cell = np.array(self.cell, dtype=np.float64)
        centres = np.array(self.centres, dtype=np.float64)
        radii = np.array(self.radii, dtype=np.float64)
        if cell.shape != (3,):
            raise ValueError(f"cell must be 3 sizes (dx, dy, dz) in mm, got shape {cell.shape}")
        if centres.ndim != 2 or centres.shape[1] != 3 or centres.shape[0] < 1:
            raise ValueError(f"centres must have shape (N, 3) with N >= 1, got {centres.shape}")
        if radii.shape != (centres.shape[0],):
            raise ValueError(f"radii must have shape ({centres.shape[0]},), got {radii.shape}")
        object.__setattr__(self, "cell", _readonly(cell))
        object.__setattr__(self, "centres", _readonly(centres))
        object.__setattr__(self, "radii", _readonly(radii))

    @property
    def num_particles(self) -> int:
        """Number of particles."""
        return self.radii.size

    @property
    def solid_fraction(self) -> float:
        """Sum of the sphere volumes / cell volume."""
        return float(4.0 / 3.0 * np.pi * np.sum(self.radii**3) / np.prod(self.cell))

    def scaled(self, radius_factor: float) -> Packing:
        """Copy with radii multiplied by ``radius_factor`` (a run reduces them before meshing)."""
        if not (np.isfinite(radius_factor) and radius_factor > 0):
            raise ValueError(f"radius_factor must be > 0, got {radius_factor}")
        return Packing(self.cell, self.centres, self.radii * radius_factor)

    def pair_distances(self):
        """The periodic pairs whose centres are closer than 2 r_max: ``i``, ``j`` (i < j),
        ``shift`` (M, 3) the lattice vector of j's image, ``distance`` (M,) mm."""
        return _periodic_pairs(self.centres, self.radii, self.cell, 2.0 * self.radii.max())

    def _overlaps(self):
        """Periodic pairs within 2 r_max and their overlap relative to the smaller radius."""
        i, j, shift, dist = self.pair_distances()
        rel = (self.radii[i] + self.radii[j] - dist) / np.minimum(self.radii[i], self.radii[j])
        return i, j, shift, rel

    def contact_ratio(self) -> float:
        """Smallest d_ij / (r_i + r_j) over the periodic pairs (d the centre distance), capped
        at 1: below 1 the closest pair overlaps; the radii times this ratio overlap nowhere."""
        i, j, _, dist = self.pair_distances()
        return float(min(np.min(dist / (self.radii[i] + self.radii[j]), initial=1.0), 1.0))

    def max_overlap(self) -> float:
        """Largest overlap (r_i + r_j - distance) / min(r_i, r_j) over periodic pairs; 0 if none."""
        rel = self._overlaps()[3]
        return float(max(rel.max(initial=0.0), 0.0))

    def validate(self, overlap_tolerance: float = 1e-6, radius_factor: float = 1.0) -> Packing:
        """Raise ValueError on non-positive sizes, centres outside [0, d), or overlapping spheres.

        Overlaps are relative to the smaller radius of the pair and are checked over all periodic
        images with a cKDTree, on the radii times ``radius_factor`` (e.g. the assembly's 0.99
        reduction: a DEM packing left stable under a small confining stress carries contact
        overlaps of ~0.1 % of a radius, which that reduction removes). Returns ``self`` so that
        calls can be chained.
        """
        cell, c, r = self.cell, self.centres, self.radii
        if not np.all(np.isfinite(cell) & (cell > 0)):
            raise ValueError(f"cell sizes must be finite and > 0 mm, got {cell.tolist()}")
        bad = np.flatnonzero(~(np.isfinite(r) & (r > 0)))
        if bad.size:
            raise ValueError(f"radius must be > 0 mm; particle {bad[0]} has r={float(r[bad[0]])!r}")
        bad = np.flatnonzero(2.0 * r >= cell.min())
        if bad.size:
            raise ValueError(
                f"radius must be < min(cell)/2 = {cell.min() / 2:g} mm; particle {bad[0]} "
                f"has r={float(r[bad[0]])!r}"
            )
        outside = ~(np.isfinite(c) & (c >= 0.0) & (c < cell))
        if outside.any():
            p, ax = np.argwhere(outside)[0]
            raise ValueError(
                f"centre of particle {p} outside the cell: {'xyz'[ax]}={float(c[p, ax])!r} not in "
                f"[0, {float(cell[ax])!r}) mm"
            )
        if not 0.0 < radius_factor <= 1.0:
            raise ValueError(f"radius_factor must be in (0, 1], got {radius_factor}")
        i, j, shift, rel = (
            self if radius_factor == 1.0 else self.scaled(radius_factor)
        )._overlaps()
        if rel.size and rel.max() > overlap_tolerance:
            k = np.argmax(rel)
            after = (
                "" if radius_factor == 1.0 else f" after the radius reduction x{radius_factor:g}"
            )
            raise ValueError(
                f"overlap of particles {i[k]} and {j[k]} (image shift {shift[k].tolist()}): "
                f"{rel[k]:.3g} of the smaller radius{after} "
                f"> overlap_tolerance={overlap_tolerance:g}"
            )
        return self


def simple_cubic_packing(radius: float = 0.1) -> Packing:
    """The ordered cell of thesis §2.6: 8 touching spheres of radius r (mm) at r + 2 r {0, 1}^3 in
    a periodic cube of side 4 r (solid fraction pi / 6)."""
    _check_positive("radius", radius)
    grid = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=float)
    return Packing(
        cell=np.full(3, 4.0 * radius), centres=radius * (1.0 + 2.0 * grid), radii=np.full(8, radius)
    )


# --------------------------------------------------------------------------------------------
# Plain-text I/O
# --------------------------------------------------------------------------------------------


def write_packing(packing: Packing, path) -> None:
    """Write ``dx dy dz`` then one ``x y z r`` line per sphere (mm), with round-trip floats."""
    with open(path, "w") as f:
        f.write(" ".join(f"{v:.17g}" for v in packing.cell) + "\n")
        np.savetxt(f, np.column_stack([packing.centres, packing.radii]), fmt="%.17g")


#: the packing file formats :func:`read_packing` recognizes
PACKING_FORMATS = ("plain", "yade", "lammps")

# a cell size in a comment header, e.g. YADE scripts' "# dx dy dz (mm) = 0.827 0.827 0.827 ; ..." or
# "# cell = 1 1 1"
_NUMBER = r"([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)"
_CELL_HEADER = re.compile(
    r"(?:dx\s*,?\s*dy\s*,?\s*dz|cell(?:[ _]?size)?|hsize)[^=:\n]*[=:]\s*"
    + r"[\s,;]+".join([_NUMBER] * 3),
    re.IGNORECASE,
)


def packing_format(path) -> str:
    """Which of :data:`PACKING_FORMATS` a packing file is: ``lammps`` (a LAMMPS / LIGGGHTS dump,
    ``ITEM: TIMESTEP`` ...), ``yade`` (a YADE ``export.text`` file: ``#format x_y_z_r`` or sphere
    lines ``x y z r`` without a cell line, the cell in a comment header or given by the caller),
    else ``plain`` (:func:`write_packing`: a line ``dx dy dz``, then ``x y z r`` lines)."""
    lines = Path(path).read_text().splitlines()
    for line in lines:
        if line.strip():
            if line.strip().upper().startswith("ITEM:"):
                return "lammps"
            break
    for line in lines:
        text = line.strip()
        if text.lower().startswith("#format"):
            return "yade"
        fields = text.split("#", 1)[0].split()
        if fields:
            return "yade" if len(fields) >= 4 else "plain"
    return "plain"


def read_packing(
    path,
    validate: bool = True,
    overlap_tolerance: float = 1e-6,
    cell=None,
    length_scale: float = 1.0,
) -> Packing:
    """Read a packing file as a DEM code left it (:func:`packing_format` tells which):

    - ``plain`` (:func:`write_packing`): a line ``dx dy dz``, then one ``x y z r`` line per sphere;
    - ``yade`` (YADE ``export.text``, ``#format x_y_z_r``; extra columns ignored): the cell from a
      comment header (``# dx dy dz (mm) = 0.827 0.827 0.827 ; ...``, ``# cell = ...``) or ``cell``;
    - ``lammps`` (LAMMPS / LIGGGHTS ``dump custom``): the last snapshot, its ``BOX BOUNDS`` (an
      orthogonal box; its lower corner becomes the origin) and the columns ``x y z`` (or ``xu``
      / ``xs`` ...) and ``radius`` (or ``diameter``).

    ``#`` comments and blank lines are allowed. The DEM formats' centres are wrapped into the
    periodic cell (DEM codes let them leave it). ``length_scale`` multiplies every length (e.g.
    1000 for a file in metres). Raises ValueError naming the file and line of a malformed line;
    with ``validate`` the packing is checked by :meth:`Packing.validate` (a DEM packing has small
    contact overlaps: raise ``overlap_tolerance``, or validate with the assembly's radius factor).
    """
    path = Path(path)
    if not (np.isfinite(length_scale) and length_scale > 0):
        raise ValueError(f"length_scale must be > 0, got {length_scale}")
    reader = {"plain": _read_plain, "yade": _read_yade, "lammps": _read_lammps}[
        packing_format(path)
    ]
    cell, centres, radii, wrap = reader(path, cell)
    cell, centres, radii = (
        np.asarray(a, dtype=float) * length_scale for a in (cell, centres, radii)
    )
    if wrap and cell.shape == (3,) and np.all(np.isfinite(cell) & (cell > 0)):
        centres = np.mod(centres, cell)
        centres[centres >= cell] = 0.0  # mod of a tiny negative value rounds up to the cell size
    packing = Packing(cell, centres, radii)
    return packing.validate(overlap_tolerance) if validate else packing


def sphere_rows(path) -> tuple[np.ndarray, np.ndarray]:
    """Centres (N, 3) and radii (N,) of a YADE export or a LAMMPS / LIGGGHTS dump's last
    snapshot as written: no cell, no wrapping (spheres between walls). A ``plain`` periodic
    packing file is refused: its first line is a cell."""
    path = Path(path)
    fmt = packing_format(path)
    if fmt == "plain":
        raise ValueError(
            f"{path}: a periodic packing file (its first line is a cell 'dx dy dz'); a list of "
            "spheres has 'x y z r' lines only"
        )
    reader = _read_lammps if fmt == "lammps" else _read_yade
    _, centres, radii, _ = reader(path, (1.0, 1.0, 1.0))
    return np.asarray(centres, dtype=float), np.asarray(radii, dtype=float)


def _numbers(path, lineno, line, what, expected) -> list[float]:
    fields = line.split("#", 1)[0].split()
    try:
        values = [float(v) for v in fields]
    except ValueError:
        raise ValueError(
            f"{path}: line {lineno}: {what} must hold {expected} numbers, got {line.strip()!r}"
        ) from None
    if len(values) != expected:
        raise ValueError(
            f"{path}: line {lineno}: {what} must hold {expected} numbers, got {len(values)}"
        )
    return values


def _read_plain(path, cell):
    rows, found = [], None
    for lineno, line in enumerate(path.read_text().splitlines(), start=1):
        if not line.split("#", 1)[0].split():
            continue
        if found is None:
            found = _numbers(path, lineno, line, "cell line 'dx dy dz'", 3)
        else:
            rows.append(_numbers(path, lineno, line, "sphere line 'x y z r'", 4))
    if found is None or not rows:
        raise ValueError(
            f"{path}: expected a cell line 'dx dy dz' and at least one sphere line 'x y z r'"
        )
    rows = np.array(rows)
    return (found if cell is None else cell), rows[:, :3], rows[:, 3], False


def _read_yade(path, cell):
    columns, header_cell, rows = ["x", "y", "z", "r"], None, []
    for lineno, line in enumerate(path.read_text().splitlines(), start=1):
        text = line.strip()
        if text.startswith("#"):
            if text.lower().startswith("#format"):
                columns = text[len("#format") :].strip().split("_")
            match = _CELL_HEADER.search(text)
            if match and header_cell is None:
                header_cell = [float(v) for v in match.groups()]
            continue
        if not text:
            continue
        rows.append(
            _numbers(path, lineno, line, f"sphere line '{' '.join(columns)}'", len(columns))
        )
    missing = [c for c in "xyzr" if c not in columns]
    if missing:
        raise ValueError(
            f"{path}: YADE #format needs the columns x, y, z, r; missing {', '.join(missing)}"
        )
    if not rows:
        raise ValueError(f"{path}: no sphere line 'x y z r'")
    cell = header_cell if cell is None else cell
    if cell is None:
        raise ValueError(
            f"{path}: a YADE export without its periodic cell: "
            f"give it (--cell dx dy dz) or add a header "
            f"line '# dx dy dz = ...'"
        )
    rows = np.array(rows)
    return cell, rows[:, [columns.index(c) for c in "xyz"]], rows[:, columns.index("r")], True


def _read_lammps(path, cell):
    lines = path.read_text().splitlines()
    starts = [
        k for k, line in enumerate(lines) if line.strip().upper().startswith("ITEM: TIMESTEP")
    ]
    if not starts:
        raise ValueError(f"{path}: a LAMMPS / LIGGGHTS dump must start with 'ITEM: TIMESTEP'")
    block, offset = lines[starts[-1] :], starts[-1]  # the last snapshot
    lo = hi = names = None
    count = None
    k = 0
    while k < len(block):
        head = block[k].strip().upper()
        if head.startswith("ITEM: NUMBER OF ATOMS"):
            count = int(block[k + 1].split()[0])
            k += 2
        elif head.startswith("ITEM: BOX BOUNDS"):
            if "XY" in head.split():
                raise ValueError(
                    f"{path}: line {offset + k + 1}: "
                    "a triclinic box is not supported (orthogonal only)"
                )
            bounds = [
                _numbers(path, offset + k + 2 + a, block[k + 1 + a], "box bounds line 'lo hi'", 2)
                for a in range(3)
            ]
            lo, hi = np.array(bounds)[:, 0], np.array(bounds)[:, 1]
            k += 4
        elif head.startswith("ITEM: ATOMS"):
            names = block[k].split()[2:]
            body = block[k + 1 : k + 1 + (count if count is not None else len(block))]
            atoms_line = offset + k + 2
            break
        else:
            k += 1
    if names is None or lo is None:
        raise ValueError(
            f"{path}: the dump's last snapshot needs 'ITEM: BOX BOUNDS' and 'ITEM: ATOMS' sections"
        )
    size = hi - lo
    axes = []
    for _a, axis in enumerate("xyz"):
        for name, scaled in (
            (axis, False),
            (axis + "u", False),
            (axis + "s", True),
            (axis + "su", True),
        ):
            if name in names:
                axes.append((names.index(name), scaled))
                break
        else:
            raise ValueError(
                f"{path}: line {atoms_line - 1}: "
                f"ATOMS columns need {axis} (or {axis}u, {axis}s); got "
                f"{' '.join(names)}"
            )
    if "radius" in names:
        radius_col, factor = names.index("radius"), 1.0
    elif "diameter" in names:
        radius_col, factor = names.index("diameter"), 0.5
    else:
        raise ValueError(
            f"{path}: line {atoms_line - 1}: ATOMS columns need radius (or diameter); "
            f"got {' '.join(names)}"
        )
    rows = np.array(
        [
            _numbers(path, atoms_line + i, line, "atom line", len(names))
            for i, line in enumerate(body)
            if line.strip()
        ]
    )
    if count is not None and rows.shape[0] != count:
        raise ValueError(
            f"{path}: the last snapshot holds {rows.shape[0]} atoms, its header says {count}"
        )
    centres = (
        np.column_stack(
            [
                lo[a] + rows[:, c] * size[a] if scaled else rows[:, c]
                for a, (c, scaled) in enumerate(axes)
            ]
        )
        - lo
    )
    return (size if cell is None else cell), centres, factor * rows[:, radius_col], True


# --------------------------------------------------------------------------------------------
# Generator: grow radii + FIRE relaxation of a harmonic repulsion (frictionless)
# --------------------------------------------------------------------------------------------

# FIRE 2.0 parameters (Guénolé et al. 2020), in units of unit mass and unit contact stiffness.
_DT0, _DT_MAX, _DT_MIN = 0.05, 0.3, 1e-3
_N_DELAY, _F_INC, _F_DEC, _ALPHA0, _F_ALPHA = 5, 1.1, 0.5, 0.1, 0.99

# Return codes of _fire
_RELAXED, _JAMMED, _REBUILD, _BUDGET = 0, 1, 2, 3


@numba.njit(cache=True)
def _fire(
    x, v, xref, pi, pj, rad, cell, state, max_steps, tol, ftol, half_skin
):  # pragma: no cover
    """FIRE minimisation of U = 1/2 sum_(i,j) max(r_i + r_j - |x_i - x_j|, 0)^2 (min. image).

    Stops with _RELAXED when every overlap < tol, _JAMMED when every net force < ftol while
    overlaps remain, _REBUILD when a particle moved more than half_skin since the neighbour list
    was built, or _BUDGET after max_steps. ``state`` = [dt, alpha, n_positive, steps] (updated).
    """
    n = x.shape[0]
    f = np.empty_like(x)
    dt, alpha, npos = state[0], state[1], int(state[2])
    code = _BUDGET
    for _ in range(max_steps):
        state[3] += 1
        f[:] = 0.0
        omax = 0.0
        for k in range(pi.shape[0]):
            i, j = pi[k], pj[k]
            d0 = x[i, 0] - x[j, 0]
            d1 = x[i, 1] - x[j, 1]
            d2 = x[i, 2] - x[j, 2]
            d0 -= cell[0] * np.rint(d0 / cell[0])
            d1 -= cell[1] * np.rint(d1 / cell[1])
            d2 -= cell[2] * np.rint(d2 / cell[2])
            s = rad[i] + rad[j]
            r2 = d0 * d0 + d1 * d1 + d2 * d2
            if r2 < s * s:
                r = np.sqrt(r2)
                ov = s - r
                omax = max(omax, ov)
                if r > 0.0:
                    c = ov / r
                else:  # coincident centres: push apart along x
                    c, d0 = 1.0, ov
                f[i, 0] += c * d0
                f[i, 1] += c * d1
                f[i, 2] += c * d2
                f[j, 0] -= c * d0
                f[j, 1] -= c * d1
                f[j, 2] -= c * d2
        power, vv, ff, fmax2 = 0.0, 0.0, 0.0, 0.0
        for i in range(n):
            fi2 = f[i, 0] ** 2 + f[i, 1] ** 2 + f[i, 2] ** 2
            fmax2 = max(fmax2, fi2)
            ff += fi2
            for a in range(3):
                power += f[i, a] * v[i, a]
                vv += v[i, a] ** 2
        if omax < tol:
            code = _RELAXED
            break
        if fmax2 < ftol * ftol:
            code = _JAMMED
            break
        if power > 0.0:
            npos += 1
            if npos > _N_DELAY:
                dt = min(dt * _F_INC, _DT_MAX)
                alpha *= _F_ALPHA
        else:
            npos = 0
            dt = max(dt * _F_DEC, _DT_MIN)
            alpha = _ALPHA0
            x -= 0.5 * dt * v
            v[:] = 0.0
            vv = 0.0
        # semi-implicit Euler with FIRE velocity mixing
        v += dt * f
        vn = np.sqrt(np.sum(v * v))
        fn = np.sqrt(ff)
        if fn > 0.0:
            v *= 1.0 - alpha
            v += (alpha * vn / fn) * f
        x += dt * v
        dmax2 = 0.0
        for i in range(n):
            dmax2 = max(
                dmax2,
                (x[i, 0] - xref[i, 0]) ** 2
                + (x[i, 1] - xref[i, 1]) ** 2
                + (x[i, 2] - xref[i, 2]) ** 2,
            )
        if dmax2 > half_skin * half_skin:
            code = _REBUILD
            break
    state[0], state[1], state[2] = dt, alpha, npos
    return code


def _wrap(x: np.ndarray, cell: np.ndarray) -> np.ndarray:
    """Periodic wrap into [0, d) per axis (np.mod may round up to d itself)."""
    y = np.mod(x, cell)
    return np.where(y >= cell, 0.0, y)


class _Relaxer:
    """FIRE relaxation of spheres of radii ``rad`` in the fixed periodic ``cell`` (Verlet list)."""

    def __init__(self, cell, rad, skin, deadline):
        self.cell, self.rad, self.skin, self.deadline = cell, rad, skin, deadline
        self.steps = 0

    def relax(self, x, tol, ftol, max_steps) -> int:
        """Relax x in place; returns _RELAXED or _JAMMED (an exhausted budget counts as jammed)."""
        v = np.zeros_like(x)
        state = np.array([_DT0, _ALPHA0, 0.0, 0.0])
        code = _REBUILD
        while True:
            if code == _REBUILD:
                x[:] = _wrap(x, self.cell)
                cutoff = 2.0 * self.rad.max() + self.skin
                pairs = cKDTree(x, boxsize=self.cell).query_pairs(cutoff, output_type="ndarray")
                pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
                pi, pj, xref = pairs[:, 0].copy(), pairs[:, 1].copy(), x.copy()
            chunk = int(min(20000, max_steps - state[3]))
            code = _fire(
                x, v, xref, pi, pj, self.rad, self.cell, state, chunk, tol, ftol, 0.5 * self.skin
            )
            if code in (_RELAXED, _JAMMED):
                break
            if state[3] >= max_steps:
                code = _JAMMED
                break
            if time.perf_counter() > self.deadline:
                raise RuntimeError(
                    "generate_packing: max_time_s exceeded; increase max_time_s or reduce n"
                )
        self.steps += int(state[3])
        x[:] = _wrap(x, self.cell)
        return code


def _check_positive(name, value, unit="mm"):
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be > 0 {unit}, got {value!r}")


def generate_packing(
    n: int,
    r_min: float,
    r_max: float,
    seed: int,
    target_fraction: float | None = None,
    cell_aspect=(1.0, 1.0, 1.0),
    max_time_s: float = 600.0,
) -> Packing:
    """Seeded frictionless random packing of ``n`` spheres in a periodic cell (thesis §2.2.1).

    Radii are uniform in [r_min, r_max] (mm; thesis 0.082-0.147, r_max/r_min ~ 1.8). Centres are
    drawn at random in a dilute cell of aspect ``cell_aspect``; the radii then grow in small
    increments of solid fraction (equivalent to shrinking the cell, as the thesis did in YADE),
    each increment followed by a FIRE minimisation of a harmonic repulsion over a periodic
    cKDTree neighbour list until every overlap is below 1e-4 r_min:

    - ``target_fraction`` given: stop at that solid fraction (e.g. 0.55, a loose packing);
      raise ValueError if the packing jams before it.
    - ``target_fraction=None``: compress until jammed, i.e. until the overlaps can no longer be
      relaxed (force balance with residual overlaps); the increment is bisected down to 1e-4
      and the last relaxed (unjammed) state is returned (~0.62-0.65 for frictionless spheres).

    The final state is relaxed further, then the cell is expanded by the tiny factor that makes
    it exactly overlap-free, and rescaled so that the radii are the drawn ones. Same arguments ->
    bit-identical result. ``max_time_s`` bounds the wall time (RuntimeError beyond).
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
        raise ValueError(f"n must be an integer >= 2, got {n!r}")
    _check_positive("r_min", r_min)
    if not (np.isfinite(r_max) and r_max >= r_min):
        raise ValueError(f"r_max must be >= r_min = {r_min!r} mm, got {r_max!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    if target_fraction is not None and not (0.0 < target_fraction <= 0.74):
        raise ValueError(f"target_fraction must be in (0, 0.74] or None, got {target_fraction!r}")
    aspect = np.array(cell_aspect, dtype=np.float64)
    if aspect.shape != (3,) or not np.all(np.isfinite(aspect) & (aspect > 0)):
        raise ValueError(f"cell_aspect must be 3 numbers > 0, got {cell_aspect!r}")
    _check_positive("max_time_s", max_time_s, "s")
    deadline = time.perf_counter() + max_time_s

    rng = np.random.default_rng(seed)
    radii = rng.uniform(r_min, r_max, n)
    volume = 4.0 / 3.0 * np.pi * np.sum(radii**3)

    # Fixed internal cell at solid fraction phi0 for radius factor 1; radii rad = g * radii with
    # phi = phi0 * g^3.
    phi0 = 0.35 if target_fraction is None else min(0.35, target_fraction)
    cell = aspect * (volume / (phi0 * np.prod(aspect))) ** (1.0 / 3.0)
    x = rng.random((n, 3)) * cell
    # nearest-image forces need cell > 2 * cutoff up to the densest state (phi = 0.74)
    g_max = (0.74 / phi0) ** (1.0 / 3.0)
    room = cell.min() / 2.0 - 2.0 * g_max * r_max
    if room <= 0.0:
        raise ValueError(
            f"n={n} too small for a periodic cell: the smallest side must exceed 4 r_max "
            f"(use more particles or a cubic cell_aspect)"
        )
    skin = min(0.3 * r_min, 0.9 * room)
    tol = 1e-4 * r_min  # overlap tolerance during compression, final radii units

    def relax(phi, x, tol, max_steps=200_000):
        g = (phi / phi0) ** (1.0 / 3.0)
        relaxer = _Relaxer(cell, g * radii, g * skin, deadline)
        return relaxer.relax(x, g * tol, 1e-2 * g * tol, max_steps)

    phi_ok = phi0
    if relax(phi_ok, x, tol) != _RELAXED:
        raise ValueError(f"target_fraction={target_fraction} unreachable: jammed at {phi_ok:.4f}")
    dphi, dphi_min = 0.02, 1e-4
    phi_end = target_fraction if target_fraction is not None else 1.0
    while phi_ok < phi_end and dphi >= dphi_min:
        phi = min(phi_ok + dphi, phi_end)
        trial = x.copy()
        if relax(phi, trial, tol) == _RELAXED:
            x, phi_ok = trial, phi
        else:
            dphi *= 0.5
    if target_fraction is not None and phi_ok < target_fraction:
        raise ValueError(f"target_fraction={target_fraction} unreachable: jammed at {phi_ok:.4f}")

    # polish (capped, kept if it succeeds), then expand the cell to remove residual overlaps exactly
    polished = x.copy()
    if relax(phi_ok, polished, 1e-9 * r_min, max_steps=50_000) == _RELAXED:
        x = polished
    g = (phi_ok / phi0) ** (1.0 / 3.0)
    rad = g * radii
    i, j, _, dist = _periodic_pairs(x, rad, cell, 2.0 * rad.max())
    expand = max(1.0, np.max((rad[i] + rad[j]) / dist, initial=1.0)) * (1.0 + 1e-12)
    scale = expand / g  # internal -> final lengths (radii become the drawn ones)
    final_cell = cell * scale
    return Packing(final_cell, _wrap(x * scale, final_cell), radii)


# --------------------------------------------------------------------------------------------
# Duplicated particles (thesis §2.2.1, fig. 2.2; CLP variant §2.5.4, fig. 2.10a)
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Duplicates:
    """Copies of packing particles: copy k is particle ``original[k]`` translated by
    ``shift[k] * cell``.

    ``original`` (M,) int, ``shift`` (M, 3) int in {-1, 0, 1}, ``centres`` (M, 3) mm, ``radii``
    (M,) mm.
    """

    original: np.ndarray
    shift: np.ndarray
    centres: np.ndarray
    radii: np.ndarray

    @property
    def num_copies(self) -> int:
        """Number of copies (M)."""
        return self.original.size


def duplicate_particles(
    packing: Packing, d_bc: float, faces: str = "all", corners: bool = True
) -> Duplicates:
    """Duplicated particles for the boundary conditions (thesis §2.2.1).

    A particle whose centre is closer than ``d_bc`` (mm) to the plane x = x_min is copied to
    x + dx (beyond x_max); one closer than ``d_bc`` to x = x_max is copied to x - dx. x_min and
    x_max are the x coordinates of the most eccentric centres (not the cell faces). The same rule
    is then applied in y to all particles including the x copies, then in z to everything, so
    corners and edges get copies. ``faces="half"`` (fully periodic CLP, thesis §2.5.4, fig. 2.10a)
    makes only the + side copies (particles near x_min, y_min, z_min). ``corners=False`` applies
    each axis to the original particles only (face copies only, as for the simple cubic cell of
    thesis §2.6 with its 12 copies).
    """
    if faces not in ("all", "half"):
        raise ValueError(f"faces must be 'all' or 'half', got {faces!r}")
    _check_positive("d_bc", d_bc)
    c, cell = packing.centres, packing.cell
    lo, hi = c.min(axis=0), c.max(axis=0)
    n = packing.num_particles
    original, shift = np.arange(n), np.zeros((n, 3), dtype=np.int64)
    for ax in range(3):
        candidates = original if corners else np.arange(n)
        cand_shift = shift if corners else np.zeros((n, 3), dtype=np.int64)
        xa = c[candidates, ax]  # copies along other axes keep this coordinate
        sides = [(xa - lo[ax] < d_bc, +1)] + ([(hi[ax] - xa < d_bc, -1)] if faces == "all" else [])
        new_orig, new_shift = [original], [shift]
        for near, sign in sides:
            s = cand_shift[near].copy()
            s[:, ax] = sign
            new_orig.append(candidates[near])
            new_shift.append(s)
        original, shift = np.concatenate(new_orig), np.concatenate(new_shift)
    original, shift = original[n:], shift[n:]
    return Duplicates(
        _readonly(original),
        _readonly(shift),
        _readonly(c[original] + shift * cell),
        _readonly(packing.radii[original].copy()),
    )


class AssemblyParticles(NamedTuple):
    """Particles of the FE assembly: originals first, then copies (what a mesher needs)."""

    centres: np.ndarray  # (N + M, 3) mm
    radii: np.ndarray  # (N + M,) mm
    original: np.ndarray  # (N + M,) index of the packing particle (identity for the originals)
    shift: np.ndarray  # (N + M, 3) lattice vector, zeros for the originals


def assembly_particles(packing: Packing, duplicates: Duplicates) -> AssemblyParticles:
    """Concatenate the packing particles and their ``duplicates`` (originals first)."""
    n = packing.num_particles
    if duplicates.original.size and (
        duplicates.original.min() < 0 or duplicates.original.max() >= n
    ):
        raise ValueError(f"duplicates.original must index the packing particles in [0, {n})")
    return AssemblyParticles(
        np.concatenate([packing.centres, duplicates.centres]),
        np.concatenate([packing.radii, duplicates.radii]),
        np.concatenate([np.arange(n), duplicates.original]),
        np.concatenate([np.zeros((n, 3), dtype=np.int64), duplicates.shift]),
    )


def periodic_pair_realizations(original: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """Which pairs of assembly bodies may touch so that every periodic pair is realized once (CLP).

    Body p is particle ``original[p]`` of the periodic volume translated by the lattice vector
    ``shift[p]`` (zero for the volume's own particles). The pair of bodies (p, q) stands for the
    periodic pair (original[p], original[q], shift[q] - shift[p]); with CLP's tied copies (thesis
    eq. 2.14) every body pair that stands for the same periodic pair is the same contact, so
    exactly one of them must be searched. Preferred: a pair with a body of the volume (its force
    acts on the volume directly); else the first copy-copy pair. A copy-copy pair is the only
    realization of a periodic pair whose lattice shift has mixed signs, e.g. (-1, 0, +1), since
    copies sit on the + faces only (``duplicate_particles(faces="half")``).

    Returns the (n, n) symmetric boolean matrix (False on the diagonal) for
    ``ContactModel(allowed=)``.
    """
    original = np.asarray(original, dtype=np.int64)
    shift = np.asarray(shift, dtype=np.int64)
    n = original.size
    if shift.shape != (n, 3):
        raise ValueError(f"shift must have shape ({n}, 3), got {shift.shape}")
    p, q = np.triu_indices(n, k=1)
    a, b, rel = original[p], original[q], shift[q] - shift[p]
    # canonical orientation of the unordered periodic pair: (i, j, s) == (j, i, -s)
    first_nonzero = np.where(rel != 0, rel, 0)[np.arange(rel.shape[0]), np.argmax(rel != 0, axis=1)]
    flip = (a > b) | ((a == b) & (first_nonzero < 0))
    i, j = np.where(flip, b, a), np.where(flip, a, b)
    s = np.where(flip[:, None], -rel, rel)
    key = np.column_stack([i, j, s])
    is_copy = np.any(shift != 0, axis=1)
    copy_copy = is_copy[p] & is_copy[q]
    order = np.lexsort((np.arange(p.size), copy_copy, *key.T[::-1]))  # by key, then preference
    sorted_key = key[order]
    new_key = np.ones(order.size, dtype=bool)
    new_key[1:] = np.any(sorted_key[1:] != sorted_key[:-1], axis=1)
    chosen = order[new_key]
    allowed = np.zeros((n, n), dtype=bool)
    allowed[p[chosen], q[chosen]] = True
    return allowed | allowed.T
