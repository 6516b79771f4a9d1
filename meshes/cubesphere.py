"""Hexahedral "cube-sphere" (O-grid) mesh of a unit ball, in plain numpy.

Topology: an inner cube of ``divisions**3`` hexahedra surrounded by six mapped shell blocks of
``divisions**2 * layers`` hexahedra each, the outer surface lying on the sphere (thesis §2.1:
particles meshed in volume with C3D8R hexahedra).

Named resolutions (:data:`RESOLUTIONS`, ``(divisions, layers)``):
- ``"chapter2"`` (default): the thesis' appendix-A particle, an inner cube of 6^3 and one shell
  layer of 6x6 quadrilaterals per cube face: 432 hexahedra, 561 nodes, 218 surface nodes;
- ``"chapter4"``: the 10x10 O-grid of the thesis' chapter 4: 1 600 hexahedra, 1 933 nodes, 602
  surface nodes;
- ``"coarse"``: the earlier default (4^3 core, 4 shell layers): 448 hexahedra, 517 nodes, 98
  surface nodes.
``refinement=k`` multiplies both numbers of subdivisions by ``k``.

Geometry: the outer surface uses the equi-angular cube-to-sphere projection (nearly uniform
surface quads); the shell nodes are a linear blend, layer by layer, between the inner-cube face
(half size ``core_fraction``) and the sphere. A faceted ball holds less than its sphere (the flat
quadrilaterals cut the caps off: 2.95 % at 6x6 per face, 6.5 % at 4x4), so by default every node is
scaled by ``s = (4/3 pi / V_h)^(1/3)``, V_h the trilinear volume: the mesh then holds exactly the
volume of the unit ball (its surface nodes lie at radius s, e.g. 1.0100 at 6x6, its facet centres
inside), the volume the thesis' relative density counts (eq. 2.4-2.5). Vertex order of each cell
is DOLFINx's (lexicographic) hexahedron ordering, with a positive Jacobian.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

#: DOLFINx hexahedron vertices in lexicographic (i, j, k) order
_HEX_CORNERS = np.array(
    [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1], [1, 1, 1]]
)


#: named cube-sphere resolutions: (inner-cube divisions, shell layers)
RESOLUTIONS = {"chapter2": (6, 1), "chapter4": (10, 1), "coarse": (4, 4)}
DEFAULT_RESOLUTION = "chapter2"


def resolution(name: str) -> tuple[int, int]:
    """(divisions, layers) of a named resolution (:data:`RESOLUTIONS`)."""
    if name not in RESOLUTIONS:
        raise ValueError(f"mesh resolution must be one of {', '.join(RESOLUTIONS)}, got {name!r}")
    return RESOLUTIONS[name]


@dataclass(frozen=True)
class UnitBallMesh:
    """Nodes (n, 3) and hexahedra (m, 8) of the unit ball; ``surface_nodes`` on the outer surface
    (at radius ``radius_scale``: 1 for the inscribed mesh, > 1 for the volume-exact one)."""

    points: np.ndarray
    cells: np.ndarray
    surface_nodes: np.ndarray
    radius_scale: float = 1.0

    @property
    def num_nodes(self) -> int:
        """Number of nodes."""
        return self.points.shape[0]

    @property
    def num_cells(self) -> int:
        """Number of hexahedra."""
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


def hexahedra_volume(points: np.ndarray, cells: np.ndarray) -> float:
    """Volume of trilinear hexahedra (DOLFINx vertex order), 2x2x2 Gauss points (exact: det J is
    of degree 2 per direction)."""
    x = points[cells]  # (m, 8, 3)
    c = _HEX_CORNERS.astype(float)
    volume = 0.0
    for q in (
        np.array(
            np.meshgrid(*[[0.5 - 0.5 / np.sqrt(3.0), 0.5 + 0.5 / np.sqrt(3.0)]] * 3, indexing="ij")
        )
        .reshape(3, -1)
        .T
    ):
        # d N_a / d q_d of the trilinear shape functions at q
        factors = np.where(c == 1, q, 1.0 - q)  # (8, 3)
        signs = np.where(c == 1, 1.0, -1.0)
        dN = np.stack(
            [signs[:, d] * np.prod(np.delete(factors, d, axis=1), axis=1) for d in range(3)], axis=1
        )
        volume += np.linalg.det(np.einsum("mai,ad->mid", x, dN)).sum() / 8.0
    return float(volume)


@lru_cache(maxsize=16)
def unit_ball_hex(
    divisions: int | None = None,
    layers: int | None = None,
    refinement: int = 1,
    core_fraction: float = 0.5,
    exact_volume: bool = True,
) -> UnitBallMesh:
    """Cube-sphere hexahedral mesh of the ball of radius 1 centred at the origin.

    Args:
        divisions: hexahedra along an edge of the inner cube (>= 1; None: the default resolution's).
        layers: hexahedra across the shell, from the inner cube to the sphere (>= 1; None:
            likewise).
        refinement: integer factor applied to ``divisions`` and ``layers`` (>= 1).
        core_fraction: half size of the inner cube relative to the radius, in (0, 1/sqrt(3)).
            0.5 keeps the smallest edge of a one-layer shell near its largest (the stable explicit
            increment: smallest edge 0.134 at 6x6, against 0.055 for the 4-layer ``coarse`` mesh).
        exact_volume: scale the nodes so that the hexahedra hold the unit ball's volume 4/3 pi
            (False: surface nodes on the unit sphere, the mesh inscribed in it).
    """
    d_div, d_lay = RESOLUTIONS[DEFAULT_RESOLUTION]
    divisions = d_div if divisions is None else divisions
    layers = d_lay if layers is None else layers
    for name, value in (("divisions", divisions), ("layers", layers), ("refinement", refinement)):
        if int(value) != value or value < 1:
            raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    if not 0.0 < core_fraction < 1.0 / np.sqrt(3.0):
        raise ValueError(f"core_fraction must be in (0, {1 / np.sqrt(3):.4f}), got {core_fraction}")
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
    all_c = np.concatenate([c + o for c, o in zip(blocks_c, offsets, strict=True)])
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
    scale = 1.0
    if exact_volume:
        scale = float(np.cbrt(4.0 / 3.0 * np.pi / hexahedra_volume(points, cells)))
        points = scale * points
    return UnitBallMesh(
        points=points, cells=cells.astype(np.int64), surface_nodes=surface, radius_scale=scale
    )


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
