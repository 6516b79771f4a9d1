"""Sphere packings in a container (a die's cylinder or a box): no periodic cell.

Units: mm. The containers stand on z = 0:

- :class:`CylinderContainer`: radius R about the z axis, 0 <= z <= height (a die between its
  punches);
- :class:`BoxContainer`: [0, Lx] x [0, Ly] x [0, Lz] (a box of six walls).

:func:`generate_container_packing` is the seeded generator of a frictionless random packing in
one (the periodic generator's method, thesis §2.2.1: random centres in a dilute container, then
the radii grow in small increments of solid fraction, each followed by a FIRE minimisation of a
harmonic repulsion between spheres and from the walls); :func:`read_spheres` reads a list of
spheres as a DEM code with walls leaves it (``x y z r`` lines, YADE export, LAMMPS dump), without
a cell.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
from scipy.spatial import cKDTree

from .packing import sphere_rows


@dataclass(frozen=True)
class CylinderContainer:
    """The inside of the cylinder of ``radius`` (mm) about the z axis, 0 <= z <= ``height``."""

    radius: float
    height: float

    def __post_init__(self):
        for name in ("radius", "height"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"container {name} = {value!r} is out of range: must be > 0 mm")

    @property
    def volume(self) -> float:
        """mm^3."""
        return float(np.pi * self.radius**2 * self.height)

    def wall_gaps(self, x: np.ndarray, r: np.ndarray) -> np.ndarray:
        """(n, 3) distances from each sphere's surface to the lateral wall, the bottom, the top
        (mm, < 0: the sphere crosses that wall)."""
        rho = np.hypot(x[:, 0], x[:, 1])
        return np.column_stack([self.radius - rho - r, x[:, 2] - r, self.height - x[:, 2] - r])

    def scaled(self, factor: float) -> CylinderContainer:
        """The container with every length times ``factor``."""
        return CylinderContainer(self.radius * factor, self.height * factor)


@dataclass(frozen=True)
class BoxContainer:
    """The box [0, Lx] x [0, Ly] x [0, Lz] (mm)."""

    lengths: tuple[float, float, float]

    def __post_init__(self):
        lengths = np.asarray(self.lengths, dtype=float)
        if lengths.shape != (3,) or not np.all(np.isfinite(lengths) & (lengths > 0)):
            raise ValueError(f"container lengths = {self.lengths!r} must be 3 numbers > 0 mm")
        object.__setattr__(self, "lengths", tuple(float(v) for v in lengths))

    @property
    def volume(self) -> float:
        """mm^3."""
        return float(np.prod(self.lengths))

    def wall_gaps(self, x: np.ndarray, r: np.ndarray) -> np.ndarray:
        """(n, 6) distances from each sphere's surface to the walls x = 0, x = Lx, y = 0, ...
        (mm, < 0: the sphere crosses that wall)."""
        L = np.asarray(self.lengths)
        return np.column_stack([g for a in range(3) for g in (x[:, a] - r, L[a] - x[:, a] - r)])

    def scaled(self, factor: float) -> BoxContainer:
        """The container with every length times ``factor``."""
        return BoxContainer(tuple(v * factor for v in self.lengths))


@dataclass(frozen=True, eq=False)
class Spheres:
    """Spheres without a periodic cell: ``centres`` (N, 3) and ``radii`` (N,) (mm), and the
    ``container`` they were generated in (or None)."""

    centres: np.ndarray
    radii: np.ndarray
    container: CylinderContainer | BoxContainer | None = None

    def __post_init__(self):
        c = np.array(self.centres, dtype=float)
        r = np.array(self.radii, dtype=float)
        if c.ndim != 2 or c.shape[1] != 3 or c.shape[0] < 1:
            raise ValueError(f"centres must have shape (N, 3) with N >= 1, got {c.shape}")
        if r.shape != (c.shape[0],):
            raise ValueError(f"radii must have shape ({c.shape[0]},), got {r.shape}")
        bad = np.flatnonzero(~(np.isfinite(r) & (r > 0)))
        if bad.size:
            raise ValueError(f"radius must be > 0 mm; sphere {bad[0]} has r={float(r[bad[0]])!r}")
        if not np.all(np.isfinite(c)):
            raise ValueError("centres must be finite")
        object.__setattr__(self, "centres", c)
        object.__setattr__(self, "radii", r)

    @property
    def num_particles(self) -> int:
        """Number of spheres."""
        return self.radii.size

    @property
    def solid_volume(self) -> float:
        """Sum of the sphere volumes (mm^3)."""
        return float(4.0 / 3.0 * np.pi * np.sum(self.radii**3))

    @property
    def solid_fraction(self) -> float:
        """Solid volume over the container's volume (NaN without a container)."""
        return self.solid_volume / self.container.volume if self.container else float("nan")

    def max_overlap(self) -> float:
        """Largest overlap (r_i + r_j - distance) / min(r_i, r_j) between two spheres, or of a
        sphere across a wall of the container (relative to its radius); 0 if none."""
        r = self.radii
        pairs = cKDTree(self.centres).query_pairs(2.0 * r.max(), output_type="ndarray")
        worst = 0.0
        if len(pairs):
            i, j = pairs[:, 0], pairs[:, 1]
            d = np.linalg.norm(self.centres[i] - self.centres[j], axis=1)
            worst = max(worst, float(((r[i] + r[j] - d) / np.minimum(r[i], r[j])).max()))
        if self.container is not None:
            gaps = self.container.wall_gaps(self.centres, r)
            worst = max(worst, float((-gaps / r[:, None]).max()))
        return max(worst, 0.0)

    def scaled(self, radius_factor: float) -> Spheres:
        """Copy with the radii times ``radius_factor`` (same centres and container)."""
        return Spheres(self.centres, self.radii * radius_factor, self.container)


@numba.njit(cache=True)
def _forces(x, rad, pi, pj, walls, kind, gravity, f):  # pragma: no cover
    """Harmonic repulsion forces f (n, 3) and the largest overlap: spheres pairs (pi, pj) and the
    walls (kind 0: cylinder, walls = [R, H]; kind 1: box, walls = [Lx, Ly, Lz]); a weight
    ``gravity`` r^3 along -z on each sphere."""
    f[:] = 0.0
    for i in range(x.shape[0]):
        f[i, 2] = -gravity * rad[i] ** 3
    omax = 0.0
    for k in range(pi.shape[0]):
        i, j = pi[k], pj[k]
        d = x[i] - x[j]
        r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
        s = rad[i] + rad[j]
        if r2 < s * s:
            r = np.sqrt(r2)
            ov = s - r
            omax = max(omax, ov)
            c = ov / r if r > 0.0 else 1.0
            for a in range(3):
                f[i, a] += c * d[a]
                f[j, a] -= c * d[a]
    for i in range(x.shape[0]):
        if kind == 0:
            rho = np.sqrt(x[i, 0] ** 2 + x[i, 1] ** 2)
            ov = rho + rad[i] - walls[0]
            if ov > 0.0 and rho > 0.0:
                omax = max(omax, ov)
                f[i, 0] -= ov * x[i, 0] / rho
                f[i, 1] -= ov * x[i, 1] / rho
            lo, hi = 2, 3
        else:
            lo, hi = 0, 3
        for a in range(lo, hi):
            length = walls[1] if kind == 0 else walls[a]
            ov = rad[i] - x[i, a]
            if ov > 0.0:
                omax = max(omax, ov)
                f[i, a] += ov
            ov = x[i, a] + rad[i] - length
            if ov > 0.0:
                omax = max(omax, ov)
                f[i, a] -= ov
    return omax


@numba.njit(cache=True)
def _fire_walls(
    x, v, rad, pi, pj, walls, kind, gravity, xref, state, max_steps, tol, ftol, half_skin
):  # pragma: no cover
    """FIRE minimisation of the harmonic repulsion (:func:`_forces`); return codes 0 relaxed,
    1 jammed, 2 rebuild the neighbour list, 3 budget spent (the periodic generator's)."""
    f = np.empty_like(x)
    dt, alpha, npos = state[0], state[1], int(state[2])
    code = 3
    for _ in range(max_steps):
        state[3] += 1
        omax = _forces(x, rad, pi, pj, walls, kind, gravity, f)
        power = np.sum(f * v)
        ff = np.sum(f * f)
        fmax2 = 0.0
        for i in range(x.shape[0]):
            fmax2 = max(fmax2, f[i, 0] ** 2 + f[i, 1] ** 2 + f[i, 2] ** 2)
        if omax < tol:
            code = 0
            break
        if fmax2 < ftol * ftol:
            code = 1
            break
        if power > 0.0:
            npos += 1
            if npos > 5:
                dt = min(dt * 1.1, 0.3)
                alpha *= 0.99
        else:
            npos = 0
            dt = max(dt * 0.5, 1e-3)
            alpha = 0.1
            x -= 0.5 * dt * v
            v[:] = 0.0
        v += dt * f
        vn = np.sqrt(np.sum(v * v))
        fn = np.sqrt(ff)
        if fn > 0.0:
            v *= 1.0 - alpha
            v += (alpha * vn / fn) * f
        x += dt * v
        dmax2 = 0.0
        for i in range(x.shape[0]):
            dmax2 = max(dmax2, np.sum((x[i] - xref[i]) ** 2))
        if dmax2 > half_skin * half_skin:
            code = 2
            break
    state[0], state[1], state[2] = dt, alpha, npos
    return code


def _relax(x, rad, walls, kind, tol, skin, deadline, max_steps=200_000, gravity=0.0) -> bool:
    """Relax x in place with a Verlet list; True when every overlap < tol (with ``gravity``:
    until the forces balance, tol < 0)."""
    v = np.zeros_like(x)
    state = np.array([0.05, 0.1, 0.0, 0.0])
    while True:
        pairs = cKDTree(x).query_pairs(2.0 * rad.max() + skin, output_type="ndarray")
        pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))] if len(pairs) else pairs
        pi = np.ascontiguousarray(pairs[:, 0]) if len(pairs) else np.zeros(0, np.int64)
        pj = np.ascontiguousarray(pairs[:, 1]) if len(pairs) else np.zeros(0, np.int64)
        chunk = int(min(20000, max_steps - state[3]))
        code = _fire_walls(
            x,
            v,
            rad,
            pi,
            pj,
            walls,
            kind,
            gravity,
            x.copy(),
            state,
            chunk,
            tol,
            1e-2 * abs(tol),
            0.5 * skin,
        )
        if code in (0, 1):
            return code == 0 or gravity > 0.0
        if state[3] >= max_steps:
            return False
        if time.perf_counter() > deadline:
            raise RuntimeError(
                "generate_container_packing: max_time_s exceeded; raise it or use fewer spheres"
            )


def generate_container_packing(
    n: int,
    r_min: float,
    r_max: float,
    seed: int,
    target_fraction: float | None,
    shape: str = "cylinder",
    aspect: float | tuple[float, float, float] = 1.0,
    max_time_s: float = 600.0,
) -> Spheres:
    """Seeded frictionless random packing of ``n`` spheres (radii uniform in [r_min, r_max] mm)
    in a container at solid fraction ``target_fraction`` (sphere volume / container volume, in
    (0, 0.6]: walls keep a random packing looser than a periodic one; the spheres do not touch),
    or, with None, poured: the spheres settle under a weak weight (a sphere alone on the floor
    would overlap it by 1e-6 r_min) until the forces balance, and the container's top is put on
    the highest sphere: every sphere rests on others or the walls (a die filled by pouring; its
    fraction and height / width follow from the settling, the width from ``aspect`` at an
    assumed fraction of 0.55):

    - ``shape="cylinder"``: a :class:`CylinderContainer` of height / diameter ``aspect``;
    - ``shape="box"``: a :class:`BoxContainer` of side ratios ``aspect`` (3 numbers).

    Every sphere lies inside the container without overlapping another (up to 1e-6 of a radius,
    removed by a final uniform scaling of the centres). Same arguments -> the same packing.
    Raises ValueError if the packing jams before the target."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be an integer >= 1, got {n!r}")
    if not (np.isfinite(r_min) and r_min > 0):
        raise ValueError(f"r_min must be > 0 mm, got {r_min!r}")
    if not (np.isfinite(r_max) and r_max >= r_min):
        raise ValueError(f"r_max must be >= r_min = {r_min!r} mm, got {r_max!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    if target_fraction is not None and not (0.0 < target_fraction <= 0.6):
        raise ValueError(f"target_fraction = {target_fraction!r} is out of range: (0, 0.6]")
    if shape not in ("cylinder", "box"):
        raise ValueError(f"shape = {shape!r} must be 'cylinder' or 'box'")
    ratios = np.broadcast_to(np.asarray(aspect, dtype=float), (3,) if shape == "box" else ())
    if not np.all(np.isfinite(ratios) & (ratios > 0)):
        raise ValueError(f"aspect = {aspect!r} must be > 0")
    deadline = time.perf_counter() + max_time_s
    rng = np.random.default_rng(seed)
    radii = rng.uniform(r_min, r_max, n)
    solid = 4.0 / 3.0 * np.pi * np.sum(radii**3)
    # the container at the dilute fraction phi0 for radius factor 1; radii grow as g = (phi /
    # phi0)^(1/3)
    if target_fraction is None:
        return _poured(radii, rng, shape, ratios, r_min, deadline)
    phi0 = min(0.25, target_fraction)
    volume = solid / phi0
    if shape == "cylinder":
        # pi R^2 (2 R aspect) = volume
        R = (volume / (2.0 * np.pi * float(ratios))) ** (1.0 / 3.0)
        container = CylinderContainer(float(R), float(2.0 * R * ratios))
        walls, kind = np.array([container.radius, container.height]), 0
        rho = R * np.sqrt(rng.random(n))
        theta = 2.0 * np.pi * rng.random(n)
        x = np.column_stack(
            [rho * np.cos(theta), rho * np.sin(theta), container.height * rng.random(n)]
        )
    else:
        side = (volume / np.prod(ratios)) ** (1.0 / 3.0)
        container = BoxContainer(tuple(side * ratios))
        walls, kind = np.asarray(container.lengths), 1
        x = rng.random((n, 3)) * walls
    tol = 1e-4 * r_min
    skin = 0.3 * r_min
    phi_ok, dphi = phi0, 0.02

    def relax(phi, trial, tolerance):
        g = (phi / phi0) ** (1.0 / 3.0)
        return _relax(trial, g * radii, walls, kind, g * tolerance, g * skin, deadline)

    if not relax(phi_ok, x, tol):
        raise ValueError(f"target_fraction={target_fraction} unreachable: jammed at {phi_ok:.4f}")
    while phi_ok < target_fraction and dphi >= 1e-4:
        phi = min(phi_ok + dphi, target_fraction)
        trial = x.copy()
        if relax(phi, trial, tol):
            x, phi_ok = trial, phi
        else:
            dphi *= 0.5
    if phi_ok < target_fraction:
        raise ValueError(f"target_fraction={target_fraction} unreachable: jammed at {phi_ok:.4f}")
    polished = x.copy()
    if relax(phi_ok, polished, 1e-9 * r_min):
        x = polished
    g = (phi_ok / phi0) ** (1.0 / 3.0)
    # final lengths: the radii are the drawn ones; the container and centres scale by 1 / g
    return _without_overlap(Spheres(x / g, radii, container.scaled(1.0 / g)))


def _without_overlap(spheres: Spheres) -> Spheres:
    """The spheres with centres and container grown by the tiny factor that removes their
    remaining overlaps (radii unchanged)."""
    overlap = spheres.max_overlap()
    if overlap == 0.0:
        return spheres
    grow = 1.0 + 2.0 * overlap + 1e-12
    return Spheres(spheres.centres * grow, spheres.radii, spheres.container.scaled(grow))


#: poured packings: the weight of the smallest sphere over the contact stiffness, / r_min (-)
POURED_WEIGHT = 1e-6


def _poured(radii, rng, shape, ratios, r_min, deadline) -> Spheres:
    """Spheres settled under a weak weight in a container whose width follows from ``ratios``
    at an assumed fraction of 0.55 (:func:`generate_container_packing`)."""
    n = radii.size
    solid = 4.0 / 3.0 * np.pi * np.sum(radii**3)
    volume = solid / 0.55
    if shape == "cylinder":
        R = float((volume / (2.0 * np.pi * float(ratios))) ** (1.0 / 3.0))
        tall = solid / (0.2 * np.pi * R**2)
        walls, kind = np.array([R, tall]), 0
        rho = (R - radii) * np.sqrt(rng.random(n))
        theta = 2.0 * np.pi * rng.random(n)
        x = np.column_stack([rho * np.cos(theta), rho * np.sin(theta), tall * rng.random(n)])
    else:
        side = (volume / np.prod(ratios)) ** (1.0 / 3.0)
        lengths = side * np.asarray(ratios)
        lengths[2] = solid / (0.2 * lengths[0] * lengths[1])
        walls, kind = lengths, 1
        x = rng.random((n, 3)) * lengths
    skin = 0.3 * r_min
    if not _relax(x, radii, walls, kind, 1e-4 * r_min, skin, deadline):
        raise ValueError("poured packing: the spheres could not be placed in the container")
    weight = POURED_WEIGHT * r_min  # the smallest sphere's weight, stiffness x length
    _relax(x, radii, walls, kind, -0.1 * weight, skin, deadline, 2_000_000, weight / r_min**3)
    top = float(np.max(x[:, 2] + radii))
    if shape == "cylinder":
        container = CylinderContainer(float(walls[0]), top)
    else:
        container = BoxContainer((float(walls[0]), float(walls[1]), top))
    return _without_overlap(Spheres(x, radii, container))


def write_spheres(spheres: Spheres, path) -> None:
    """Write one ``x y z r`` line per sphere (mm), round-trip floats, with a ``#format x_y_z_r``
    header (the YADE export format: read back by :func:`read_spheres`)."""
    with open(path, "w") as f:
        f.write("#format x_y_z_r\n")
        np.savetxt(f, np.column_stack([spheres.centres, spheres.radii]), fmt="%.17g")


def read_spheres(path, length_scale: float = 1.0) -> Spheres:
    """Read a list of spheres without a periodic cell: ``x y z r`` lines (with an optional
    ``#format x_y_z_r`` header: a YADE export) or a LAMMPS / LIGGGHTS dump's last snapshot
    (centres as written, not wrapped). ``length_scale`` multiplies every length."""
    path = Path(path)
    if not (np.isfinite(length_scale) and length_scale > 0):
        raise ValueError(f"length_scale must be > 0, got {length_scale}")
    centres, radii = sphere_rows(path)
    return Spheres(centres * length_scale, radii * length_scale)
