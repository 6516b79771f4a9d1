"""Hexahedral "cube-sphere" (O-grid) mesh of a unit ball, in plain numpy.

Topology: an inner cube of ``divisions**3`` hexahedra surrounded by six mapped shell blocks of
``divisions**2 * layers`` hexahedra each, the outer surface lying on the sphere (thesis §2.1:
particles meshed in volume with C3D8R hexahedra, ~560 nodes each).

Default resolution (divisions=4, layers=4): 448 hexahedra, 517 nodes, 98 surface nodes.
``refinement=k`` multiplies both numbers of subdivisions by ``k``.

Geometry: the outer surface uses the equi-angular cube-to-sphere projection (nearly uniform
surface quads); the shell nodes are a linear blend, layer by layer, between the inner-cube face
(half size ``core_fraction``) and the sphere. Vertex order of each cell is DOLFINx's
(lexicographic) hexahedron ordering, with a positive Jacobian.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

#: DOLFINx hexahedron vertices in lexicographic (i, j, k) order
_HEX_CORNERS = np.array(
    [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1], [1, 1, 1]]
)


@dataclass(frozen=True)
class UnitBallMesh:
    """Nodes (n, 3) and hexahedra (m, 8) of the unit ball; ``surface_nodes`` on the sphere."""

    points: np.ndarray
    cells: np.ndarray
    surface_nodes: np.ndarray

    @property
    def num_nodes(self) -> int:
        return self.points.shape[0]

    @property
    def num_cells(self) -> int:
        return self.cells.shape[0]


def _lattice_cells(shape: tuple[int, int, int]) -> np.ndarray:
    """Hexahedra of a structured (ni+1, nj+1, nk+1) lattice, flat C-order node indices."""
    ni, nj, nk = shape
    i, j, k = np.meshgrid(np.arange(ni), np.arange(nj), np.arange(nk), indexing="ij")
    base = np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1)
    corners = base[:, None, :] + _HEX_CORNERS[None, :, :]
    return (corners[..., 0] * (nj + 1) + corners[..., 1]) * (nk + 1) + corners[..., 2]


def _orient_positive(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Mirror the cells whose Jacobian at the centre is negative (swap i <-> i+1 vertices)."""
    x = points[cells]
    d_i = (x[:, 1] + x[:, 3] + x[:, 5] + x[:, 7]) - (x[:, 0] + x[:, 2] + x[:, 4] + x[:, 6])
    d_j = (x[:, 2] + x[:, 3] + x[:, 6] + x[:, 7]) - (x[:, 0] + x[:, 1] + x[:, 4] + x[:, 5])
    d_k = (x[:, 4] + x[:, 5] + x[:, 6] + x[:, 7]) - (x[:, 0] + x[:, 1] + x[:, 2] + x[:, 3])
    det = np.einsum("ci,ci->c", d_i, np.cross(d_j, d_k))
    flipped = cells.copy()
    neg = det < 0
    flipped[neg] = cells[neg][:, [1, 0, 3, 2, 5, 4, 7, 6]]
    return flipped


@lru_cache(maxsize=16)
def unit_ball_hex(divisions: int = 4, layers: int = 4, refinement: int = 1,
                  core_fraction: float = 0.45) -> UnitBallMesh:
    """Cube-sphere hexahedral mesh of the ball of radius 1 centred at the origin.

    Args:
        divisions: hexahedra along an edge of the inner cube (>= 1).
        layers: hexahedra across the shell, from the inner cube to the sphere (>= 1).
        refinement: integer factor applied to ``divisions`` and ``layers`` (>= 1).
        core_fraction: half size of the inner cube relative to the radius, in (0, 1/sqrt(3)).
    """
    for name, value in (("divisions", divisions), ("layers", layers), ("refinement", refinement)):
        if int(value) != value or value < 1:
            raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    if not 0.0 < core_fraction < 1.0 / np.sqrt(3.0):
        raise ValueError(f"core_fraction must be in (0, {1/np.sqrt(3):.4f}), got {core_fraction}")
    n = int(divisions * refinement)
    m = int(layers * refinement)
    a = float(core_fraction)
    s = np.linspace(-1.0, 1.0, n + 1)

    blocks_x, blocks_c = [], []
    # inner cube
    X, Y, Z = np.meshgrid(s, s, s, indexing="ij")
    blocks_x.append(a * np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1))
    blocks_c.append(_lattice_cells((n, n, n)))
    # six shell blocks: face normal axis d, side sign; lattice (u, w, layer)
    U, W, T = np.meshgrid(s, s, np.linspace(0.0, 1.0, m + 1), indexing="ij")
    for d in range(3):
        others = [q for q in range(3) if q != d]
        for sign in (-1.0, 1.0):
            cube = np.empty(U.shape + (3,))
            cube[..., d] = sign
            cube[..., others[0]] = U
            cube[..., others[1]] = W
            sphere = np.empty_like(cube)
            sphere[..., d] = sign
            sphere[..., others[0]] = np.tan(0.25 * np.pi * U)
            sphere[..., others[1]] = np.tan(0.25 * np.pi * W)
            sphere /= np.linalg.norm(sphere, axis=-1, keepdims=True)
            pts = (1.0 - T[..., None]) * (a * cube) + T[..., None] * sphere
            blocks_x.append(pts.reshape(-1, 3))
            blocks_c.append(_lattice_cells((n, n, m)))

    offsets = np.cumsum([0] + [b.shape[0] for b in blocks_x[:-1]])
    all_x = np.concatenate(blocks_x)
    all_c = np.concatenate([c + o for c, o in zip(blocks_c, offsets)])
    # merge the nodes shared by adjacent blocks (computed identically up to round-off)
    key = np.round(all_x * 1e9).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)  # keep the order of first appearance: deterministic numbering
    renumber = np.empty_like(order)
    renumber[order] = np.arange(order.size)
    points = all_x[first[order]]
    cells = renumber[inverse.ravel()][all_c]
    cells = _orient_positive(points, cells)
    surface = np.flatnonzero(np.abs(np.linalg.norm(points, axis=1) - 1.0) < 1e-12)
    return UnitBallMesh(points=points, cells=cells.astype(np.int64), surface_nodes=surface)


def mobius_ball(points: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Conformal automorphism of the unit ball sending ``a`` (|a| < 1) to the origin.

    It maps the unit sphere onto itself and preserves angles, so a cube-sphere mesh keeps
    well-shaped elements while its nodes crowd towards the boundary point -a/|a| (element
    size scaled by (1 - |a|)/(1 + |a|) there, and by the inverse at the opposite pole): a local
    refinement for contact without changing the mesh topology.
    """
    a = np.asarray(a, dtype=float)
    if not np.linalg.norm(a) < 1.0:
        raise ValueError(f"mobius grading vector must have norm < 1, got {np.linalg.norm(a)}")
    aa = a @ a
    diff = points - a
    num = (1.0 - aa) * diff - np.einsum("ij,ij->i", diff, diff)[:, None] * a
    den = 1.0 - 2.0 * points @ a + np.einsum("ij,ij->i", points, points) * aa
    return num / den[:, None]
