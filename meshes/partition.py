"""A partition that suits particles: whole particles on one rank, ranks as compact regions.

DOLFINx's graph partitioner sees the particles' mesh as a graph of cells; particles are
disconnected components, so it balances cells but places the components anywhere: a rank's
particles are scattered through the volume and touch every other rank's. For contact the halo
of a rank (the surface it must receive from the others) is the surface of the particles that
touch its own, so a rank should own a compact region of whole particles.

:func:`coordinate_bisection` splits the particles' centres recursively along the longest extent
of each group, in proportion to the number of ranks on each side and balanced by weight (the
work of a particle: its number of cells; a stiffless copy or a rigid carrier weighs little).
:func:`particle_partitioner` turns that into a DOLFINx cell partitioner for meshes whose cells
are numbered particle by particle (``particle_mesh``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from dolfinx.cpp.graph import AdjacencyList_int32


def coordinate_bisection(points: np.ndarray, weights: np.ndarray, nparts: int) -> np.ndarray:
    """Part (0 .. nparts-1) of every point: recursive coordinate bisection balanced by weight.

    Args:
        points: (n, 3) positions (mm), e.g. the particles' centres.
        weights: (n,) work of each point (> 0).
        nparts: number of parts (>= 1).

    Each group of points and of parts is split along the axis of its largest extent, at the
    weighted quantile that gives each half its share of the parts; ties are broken by the index
    of the point, so the partition depends only on the input.
    """
    points = np.asarray(points, dtype=float)
    weights = np.asarray(weights, dtype=float)
    if nparts < 1:
        raise ValueError(f"nparts must be >= 1, got {nparts}")
    if points.ndim != 2 or points.shape[1] != 3 or weights.shape != (points.shape[0],):
        raise ValueError("points must have shape (n, 3) and weights shape (n,)")
    if np.any(~(weights > 0)):
        raise ValueError("weights must be > 0")
    part = np.zeros(points.shape[0], dtype=np.int32)
    stack = [(np.arange(points.shape[0]), 0, nparts)]  # (points, first part, number of parts)
    while stack:  # one entry per group of parts: 2 nparts - 1 splits in all
        members, first, count = stack.pop()
        if count == 1 or members.size == 0:
            part[members] = first
            continue
        left_parts = count // 2
        p = points[members]
        axis = int(np.argmax(p.max(axis=0) - p.min(axis=0)))
        order = members[np.lexsort((members, p[:, axis]))]
        cumulative = np.cumsum(weights[order])
        share = cumulative[-1] * left_parts / count
        cut = int(np.searchsorted(cumulative, share, side="left"))
        # the point that straddles the share goes to the side it fills the least
        if cut < order.size and cumulative[cut] - share < share - (
            cumulative[cut - 1] if cut else 0.0
        ):
            cut += 1
        stack.append((order[:cut], first, left_parts))
        stack.append((order[cut:], first + left_parts, count - left_parts))
    return part


def particle_partitioner(
    centres: np.ndarray,
    cells_per_particle: int,
    nodes_per_cell: int,
    weights: np.ndarray | None = None,
) -> Callable:
    """A DOLFINx cell partitioner (``dolfinx.mesh.create_mesh(partitioner=)``) that keeps every
    particle whole on one rank, ranks being compact regions (:func:`coordinate_bisection` of the
    ``centres``, mm, weighted by ``weights``, default: equal). The mesh's input cells must be
    numbered particle by particle, ``cells_per_particle`` cells of ``nodes_per_cell`` nodes each,
    all on one rank."""
    centres = np.asarray(centres, dtype=float)
    w = np.ones(centres.shape[0]) if weights is None else np.asarray(weights, dtype=float)

    def partition(comm, nparts, cell_types, cells):
        num_cells = cells[0].size // nodes_per_cell
        part = coordinate_bisection(centres, w, nparts) if num_cells else np.zeros(0, np.int32)
        dest = part[np.arange(num_cells) // cells_per_particle].astype(np.int32)
        return AdjacencyList_int32(dest)  # DOLFINx's C++ list: one destination per cell

    return partition
