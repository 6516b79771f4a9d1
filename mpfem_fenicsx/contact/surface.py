"""The particles' contact surface, replicated on every rank.

Every rank holds the whole surface (nodes, facets, particle of each facet): surfaces are small
next to volumes (218 of the 561 nodes of a default particle), and a replicated master surface
makes the search independent of the partition. Each rank *treats as slave* only the surface
nodes it owns, so every contact point is computed exactly once, and results do not depend on
the number of ranks beyond round-off.

Facets are Q1 quadrilaterals (hexahedra) or P1 triangles (tetrahedra), oriented so that the
parametric normal x_xi x x_eta points out of the particle. Quadrilateral vertices are kept in
DOLFINx's lexicographic order, i.e. the bilinear map on [0, 1]^2 is
    x = (1-xi)(1-eta) x0 + xi (1-eta) x1 + (1-xi) eta x2 + xi eta x3.
Triangles: x = (1-xi-eta) x0 + xi x1 + eta x2, vertex 3 = -1.
"""

from __future__ import annotations

import numpy as np

import basix
import dolfinx


class ContactSurface:
    """Global surface of the bodies of ``V``'s mesh, from facet tags (value = body id).

    Attributes (identical on all ranks):
        blocks: (nS,) global dof-block index of each surface node (sorted).
        X: (nS, 3) reference coordinates (mm).
        facets: (nF, 4) surface-node indices (-1 as 4th vertex of triangles).
        facet_body: (nF,) body id of each facet.
        node_body: (nS,) body id of each surface node.
        node_facet_ptr, node_facets: facets around each node (CSR).
    Per rank:
        owned_nodes: surface nodes whose dof block this rank owns (its slave nodes).
    """

    def __init__(
        self, V: dolfinx.fem.FunctionSpace, facet_tags: dolfinx.mesh.MeshTags, num_bodies: int
    ):
        mesh = V.mesh
        comm = mesh.comm
        self.comm = comm
        self.V = V
        self.num_bodies = num_bodies
        if V.element.basix_element.degree != 1:
            raise NotImplementedError(
                "contact surfaces need a degree-1 displacement space (Q1 or P1)"
            )
        tdim = mesh.topology.dim
        mesh.topology.create_connectivity(tdim - 1, tdim)
        mesh.topology.create_connectivity(tdim, tdim - 1)
        f2c = mesh.topology.connectivity(tdim - 1, tdim)
        c2f = mesh.topology.connectivity(tdim, tdim - 1)
        cell_name = mesh.topology.cell_name()
        local_facet_vertices = basix.topology(getattr(basix.CellType, cell_name))[tdim - 1]
        nv = len(local_facet_vertices[0])
        imap = V.dofmap.index_map
        num_owned_facets = mesh.topology.index_map(tdim - 1).size_local

        keep = facet_tags.indices < num_owned_facets  # each facet once, by its owner
        tagged = facet_tags.indices[keep]
        bodies = facet_tags.values[keep]
        geom = mesh.geometry
        dofmap = V.dofmap.list
        gdofmap = geom.dofmaps[0]
        rows_blocks = np.zeros((tagged.size, 4), dtype=np.int64)
        rows_x = np.zeros((tagged.size, 4, 3))
        for n, facet in enumerate(tagged):  # setup only: once per facet
            cell = f2c.links(facet)[0]
            local = int(np.flatnonzero(c2f.links(cell) == facet)[0])
            verts = local_facet_vertices[local]
            blocks = dofmap[cell][verts]
            x = geom.x[gdofmap[cell][verts]]
            centre_cell = geom.x[gdofmap[cell]].mean(axis=0)
            # quad (lexicographic) and triangle alike: x_xi ~ x1 - x0, x_eta ~ x2 - x0 at vertex 0
            normal = np.cross(x[1] - x[0], x[2] - x[0])
            order = [0, 1, 2, 3] if nv == 4 else [0, 1, 2]
            if normal @ (x.mean(axis=0) - centre_cell) < 0:
                order = [0, 2, 1, 3] if nv == 4 else [0, 2, 1]
            gblocks = imap.local_to_global(blocks[order].astype(np.int32))
            rows_blocks[n, :nv] = gblocks
            rows_blocks[n, nv:] = -1
            rows_x[n, :nv] = x[order]
        gathered = comm.allgather((rows_blocks, rows_x, bodies.astype(np.int32)))
        all_blocks = np.concatenate([g[0] for g in gathered])
        all_x = np.concatenate([g[1] for g in gathered])
        all_bodies = np.concatenate([g[2] for g in gathered])
        # deterministic order, independent of the partition: sort facets by their vertex blocks
        order = np.lexsort(all_blocks.T[::-1])
        all_blocks, all_x, all_bodies = all_blocks[order], all_x[order], all_bodies[order]

        valid = all_blocks >= 0
        self.blocks, inverse = np.unique(all_blocks[valid], return_inverse=True)
        facets = -np.ones_like(all_blocks)
        facets[valid] = inverse
        self.facets = facets.astype(np.int64)
        self.facet_body = all_bodies
        self.vertices_per_facet = nv
        X = np.zeros((self.blocks.size, 3))
        X[inverse] = all_x[valid]
        self.X = X
        node_body = np.zeros(self.blocks.size, dtype=np.int32)
        node_body[inverse] = np.repeat(all_bodies, nv)
        self.node_body = node_body
        # node -> facets incidence (CSR), for nodal quantities gathered from the facets
        flat = self.facets[:, :nv].ravel()
        order = np.argsort(flat, kind="stable")
        self.node_facets = (order // nv).astype(np.int64)
        self.node_facet_ptr = np.searchsorted(flat[order], np.arange(self.blocks.size + 1)).astype(
            np.int64
        )

        # local access: which surface nodes this rank owns, and their local dof blocks
        lo, hi = imap.local_range
        owned = (self.blocks >= lo) & (self.blocks < hi)
        self.owned_nodes = np.flatnonzero(owned)
        self.owned_local_blocks = (self.blocks[owned] - lo).astype(np.int32)
        self._counts = np.array(comm.allgather(self.owned_nodes.size))
        self._order = np.concatenate(comm.allgather(self.owned_nodes))
        self.bs = V.dofmap.index_map_bs

    @property
    def num_nodes(self) -> int:
        """Number of surface nodes (all ranks)."""
        return self.blocks.size

    def gather(self, u: dolfinx.fem.Function) -> np.ndarray:
        """Displacement (nS, 3) of every surface node on every rank (one allgather)."""
        values = u.x.array.reshape(-1, self.bs)[self.owned_local_blocks]
        parts = self.comm.allgather(values)
        out = np.empty((self.num_nodes, 3))
        out[self._order] = np.concatenate(parts)
        return out
