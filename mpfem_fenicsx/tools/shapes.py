"""Shapes of rigid tools: where a point is with respect to the tool's surface.

Every shape answers one question, vectorized over points: for points ``x`` (n, 3) (mm, in the
tool's reference placement) the signed gap (mm, < 0 = inside the tool, the particle penetrates)
and the unit outward normal of the tool at the closest surface point (pointing towards the
particles' side). The rigid contact (:mod:`mpfem_fenicsx.contact.rigid`) uses them as the master
surface of a one-pass node-to-surface contact; a tool's motion is a translation applied outside
(the points are moved back by it before the query).

- :class:`Plane`: a half-space, its particles' side given by the normal;
- :class:`CylinderInside`: the inside of a circular cylinder (a die's wall), infinite along its
  axis;
- :class:`TriangulatedSurface`: any triangulated surface (an STL punch face, a cup), its
  triangles' right-hand normals pointing towards the particles.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree


def _unit(vector, name: str) -> np.ndarray:
    v = np.asarray(vector, dtype=float).reshape(3)
    norm = float(np.linalg.norm(v))
    if not np.isfinite(norm) or norm == 0.0:
        raise ValueError(f"{name} = {list(v)} must be a finite non-zero vector")
    return v / norm


@dataclass(frozen=True)
class Plane:
    """The half-space {x : (x - point) . normal < 0} is the tool; particles live on the side
    the unit ``normal`` points to. gap = (x - point) . normal."""

    point: tuple[float, float, float] = (0.0, 0.0, 0.0)
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self):
        if not np.all(np.isfinite(np.asarray(self.point, dtype=float))):
            raise ValueError(f"plane point = {self.point} must be finite")
        object.__setattr__(self, "normal", tuple(_unit(self.normal, "plane normal")))

    def gap_normal(self, x: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Points of ``x`` (n, 3) with gap < ``reach``: their indices, gaps (mm), normals."""
        n = np.asarray(self.normal)
        gap = (x - np.asarray(self.point)) @ n
        near = np.flatnonzero(gap < reach)
        return near, gap[near], np.broadcast_to(n, (near.size, 3)).copy()


@dataclass(frozen=True)
class CylinderInside:
    """The inside of a circular cylinder of ``radius`` (mm) about the axis through ``point``
    along ``axis``: particles live inside, the tool is everything beyond the radius (a die's
    wall). gap = radius - distance to the axis; the normal points to the axis. ``extent``
    (lo, hi): the wall spans lo <= (x - point) . axis <= hi only (mm; a die's wall ends at its
    top: an ejected compact leaves it); default: infinite."""

    radius: float = 1.0
    point: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    extent: tuple[float, float] = (-np.inf, np.inf)

    def __post_init__(self):
        if not (np.isfinite(self.radius) and self.radius > 0):
            raise ValueError(f"cylinder radius = {self.radius} is out of range: must be > 0 mm")
        if not np.all(np.isfinite(np.asarray(self.point, dtype=float))):
            raise ValueError(f"cylinder point = {self.point} must be finite")
        object.__setattr__(self, "axis", tuple(_unit(self.axis, "cylinder axis")))
        lo, hi = (float(v) for v in self.extent)
        if not lo < hi:
            raise ValueError(f"cylinder extent = {self.extent} must be (lo, hi) with lo < hi mm")

    def gap_normal(self, x: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Points of ``x`` (n, 3) with gap < ``reach``: their indices, gaps (mm), normals."""
        a = np.asarray(self.axis)
        d = x - np.asarray(self.point)
        along = d @ a
        radial = d - np.outer(along, a)
        rho = np.linalg.norm(radial, axis=1)
        gap = self.radius - rho
        lo, hi = self.extent
        near = np.flatnonzero((gap < reach) & (rho > 0.0) & (along >= lo) & (along <= hi))
        return near, gap[near], -radial[near] / rho[near, None]


def closest_points_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray):
    """Closest points (m, 3) to the points ``p`` (m, 3) on the triangles (a, b, c) (each (m, 3)),
    pairwise, by the Voronoi regions of the triangle (vertex, edge or face), and whether the
    closest point lies inside the face (m,)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = p - b
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = p - c
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v_face, w_face = vb / denom, vc / denom
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    out = a + v_face[:, None] * ab + w_face[:, None] * ac
    face = np.ones(len(p), dtype=bool)
    # the regions, from the last to be overridden to the first (Ericson's order reversed)
    regions = [
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), lambda: b + t_bc[:, None] * (c - b)),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), lambda: a + t_ac[:, None] * ac),
        ((d6 >= 0) & (d5 <= d6), lambda: c),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), lambda: a + t_ab[:, None] * ab),
        ((d3 >= 0) & (d4 <= d3), lambda: b),
        ((d1 <= 0) & (d2 <= 0), lambda: a),
    ]
    for mask, point in regions:
        if mask.any():
            out[mask] = point()[mask]
            face &= ~mask
    return out, face


@dataclass(frozen=True, eq=False)
class TriangulatedSurface:
    """A rigid triangulated surface: ``vertices`` (m, 3) mm, ``triangles`` (k, 3) vertex indices,
    each triangle's right-hand normal (b - a) x (c - a) pointing towards the particles. The gap
    of a point is its distance to the closest triangle, negative on the tool's side of it; the
    normal is the face normal when the closest point is inside a face, else the unit vector from
    the closest point (on an edge or vertex) to the point, signed likewise."""

    vertices: np.ndarray
    triangles: np.ndarray
    _tree: cKDTree = field(init=False, repr=False)
    _radius: float = field(init=False, repr=False)

    def __post_init__(self):
        v = np.asarray(self.vertices, dtype=float)
        t = np.asarray(self.triangles, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3 or not np.all(np.isfinite(v)):
            raise ValueError("triangulated surface: vertices must be finite, shape (m, 3)")
        if t.ndim != 2 or t.shape[1] != 3 or t.shape[0] == 0:
            raise ValueError("triangulated surface: triangles must have shape (k, 3), k > 0")
        if t.min() < 0 or t.max() >= len(v):
            raise ValueError(f"triangulated surface: vertex index out of range [0, {len(v)})")
        normal = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
        if np.any(np.linalg.norm(normal, axis=1) == 0.0):
            raise ValueError("triangulated surface: degenerate (zero-area) triangles")
        centroid = v[t].mean(axis=1)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "triangles", t)
        object.__setattr__(self, "_tree", cKDTree(centroid))
        radius = np.linalg.norm(v[t] - centroid[:, None, :], axis=2).max()
        object.__setattr__(self, "_radius", float(radius))

    @staticmethod
    def from_stl(path: str | Path) -> TriangulatedSurface:
        """Read an ASCII or binary STL file (mm); its facets' vertex order gives the normals
        (the normals written in the file are ignored); shared vertices are merged."""
        corners = read_stl(path)
        vertices, inverse = np.unique(corners.reshape(-1, 3), axis=0, return_inverse=True)
        return TriangulatedSurface(vertices, inverse.reshape(-1, 3))

    @property
    def face_normals(self) -> np.ndarray:
        """(k, 3) unit right-hand normals of the triangles."""
        v, t = self.vertices, self.triangles
        n = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
        return n / np.linalg.norm(n, axis=1)[:, None]

    def gap_normal(self, x: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Points of ``x`` (n, 3) within ``reach`` of the surface (|gap| < reach, or any gap < 0
        of a point whose closest triangle is within reach): indices, gaps (mm), normals."""
        lists = self._tree.query_ball_point(x, r=abs(reach) + self._radius)
        count = np.fromiter((len(c) for c in lists), dtype=np.int64, count=len(lists))
        if count.sum() == 0:
            return np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 3))
        point = np.repeat(np.arange(len(x)), count)
        tri = np.fromiter((i for c in lists for i in c), dtype=np.int64, count=int(count.sum()))
        v, t = self.vertices, self.triangles
        p = x[point]
        cp, inside = closest_points_on_triangles(p, v[t[tri, 0]], v[t[tri, 1]], v[t[tri, 2]])
        distance = np.linalg.norm(p - cp, axis=1)
        # the closest triangle of every point
        order = np.lexsort((distance, point))
        first = order[np.r_[True, point[order][1:] != point[order][:-1]]]
        point, tri, cp, inside, distance = (
            point[first],
            tri[first],
            cp[first],
            inside[first],
            distance[first],
        )
        face = self.face_normals[tri]
        d = x[point] - cp
        side = np.where(np.einsum("ij,ij->i", d, face) < 0.0, -1.0, 1.0)
        gap = side * distance
        with np.errstate(divide="ignore", invalid="ignore"):
            radial = side[:, None] * d / distance[:, None]
        normal = np.where((inside | (distance == 0.0))[:, None], face, radial)
        near = gap < reach
        return point[near], gap[near], normal[near]


def read_stl(path: str | Path) -> np.ndarray:
    """The triangles of an STL file as their corners (k, 3, 3), ASCII or binary."""
    data = Path(path).read_bytes()
    if len(data) >= 84:
        (count,) = struct.unpack("<I", data[80:84])
        if len(data) == 84 + 50 * count:
            records = np.frombuffer(
                data[84:], dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
            )
            return records["v"].astype(float)
    text = data.decode("ascii", errors="replace")
    if not text.lstrip().startswith("solid"):
        raise ValueError(f"{path}: not an STL file (neither binary nor ASCII 'solid')")
    corners = [
        [float(w) for w in line.split()[1:4]]
        for line in text.splitlines()
        if line.strip().startswith("vertex")
    ]
    if not corners or len(corners) % 3:
        raise ValueError(f"{path}: ASCII STL without whole triangles ({len(corners)} vertices)")
    return np.asarray(corners).reshape(-1, 3, 3)


def write_stl(path: str | Path, corners: np.ndarray, name: str = "tool") -> None:
    """Write triangles' corners (k, 3, 3) (mm) as an ASCII STL file."""
    corners = np.asarray(corners, dtype=float)
    lines = [f"solid {name}"]
    for tri in corners:
        n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
        n = n / (np.linalg.norm(n) or 1.0)
        lines.append(f"  facet normal {n[0]:.9e} {n[1]:.9e} {n[2]:.9e}")
        lines.append("    outer loop")
        lines += [f"      vertex {c[0]:.9e} {c[1]:.9e} {c[2]:.9e}" for c in tri]
        lines += ["    endloop", "  endfacet"]
    lines.append(f"endsolid {name}")
    Path(path).write_text("\n".join(lines) + "\n")
