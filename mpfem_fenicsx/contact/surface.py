"""The particles' contact surface, distributed: each rank holds only the surface near its own.

A rank *treats as slave* the surface nodes whose dof block it owns (every contact point is
computed exactly once) and *holds* the facets they may touch: its slave bodies whole, and of the
other bodies within reach only the facets within reach (chosen by the contact model,
:meth:`ContactSurface.hold`), each with the ring of facets around its vertices. Whole slave bodies
keep the slave side exact and independent of the partition (facets, normals, tributary areas);
the ring keeps the masters' smoothed corner normals exact. Nothing in a step is gathered over
the whole surface:

- the facets of a body come from its *home* rank (the rank with most of its facets), by
  point-to-point messages between the ranks concerned, only when the held set is rebuilt;
- the displacements of the held nodes come from their owners through a PETSc scatter
  (``gather``), whose messages go only to the ranks that own held nodes;
- nodal sums (contact stiffness per node) go back to the owners through the same scatter.

Local numbering: held surface nodes sorted by global dof block, held facets sorted by their
vertices' global blocks, held bodies sorted by id. The relative order of any two nodes or
facets is therefore the same on every rank and for every partition, so the search and the law
do the same arithmetic whatever the number of ranks.

Facets are Q1 quadrilaterals (hexahedra) or P1 triangles (tetrahedra), oriented so that the
parametric normal x_xi x x_eta points out of the particle. Quadrilateral vertices are kept in
DOLFINx's lexicographic order, i.e. the bilinear map on [0, 1]^2 is
    x = (1-xi)(1-eta) x0 + xi (1-eta) x1 + (1-xi) eta x2 + xi eta x3.
Triangles: x = (1-xi-eta) x0 + xi x1 + eta x2, vertex 3 = -1.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import basix
import dolfinx

from ..exchange import KeyedRows
from .search import body_boxes

#: one facet row as exchanged: body id, 4 global vertex blocks, 4 x 3 reference coordinates
ROW_BYTES = 8 + 4 * 8 + 12 * 8


def _owned_facet_rows(V, facet_tags) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """This rank's owned tagged facets: global vertex blocks (m, 4), reference coordinates
    (m, 4, 3) in outward order, body ids (m,), and the vertices per facet."""
    mesh = V.mesh
    tdim = mesh.topology.dim
    mesh.topology.create_connectivity(tdim - 1, tdim)
    mesh.topology.create_connectivity(tdim, tdim - 1)
    f2c = mesh.topology.connectivity(tdim - 1, tdim)
    c2f = mesh.topology.connectivity(tdim, tdim - 1)
    local_facet_vertices = basix.topology(getattr(basix.CellType, mesh.topology.cell_name()))[
        tdim - 1
    ]
    nv = len(local_facet_vertices[0])
    imap = V.dofmap.index_map
    num_owned_facets = mesh.topology.index_map(tdim - 1).size_local
    keep = facet_tags.indices < num_owned_facets  # each facet once, by its owner
    tagged = facet_tags.indices[keep]
    geom = mesh.geometry
    # the (first) cell of each facet and the facet's local index in it
    cells = f2c.array[f2c.offsets[tagged]]
    per_cell = len(local_facet_vertices)
    cell_facets = c2f.array[c2f.offsets[cells][:, None] + np.arange(per_cell)]
    local = np.argmax(cell_facets == tagged[:, None], axis=1)
    verts = np.asarray(local_facet_vertices)[local]  # (m, nv) cell-local vertices
    blocks = V.dofmap.list[cells[:, None], verts]
    gdofs = geom.dofmaps[0]
    x = geom.x[gdofs[cells[:, None], verts]]
    centre_cell = geom.x[gdofs[cells]].mean(axis=1)
    # quad (lexicographic) and triangle alike: x_xi ~ x1 - x0, x_eta ~ x2 - x0 at vertex 0;
    # outward when the normal points away from the cell's centre, else swap vertices 1 and 2
    normal = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    inward = np.einsum("ij,ij->i", normal, x.mean(axis=1) - centre_cell) < 0
    order = np.where(inward[:, None], [0, 2, 1, 3][:nv], [0, 1, 2, 3][:nv])
    blocks = np.take_along_axis(blocks, order, axis=1)
    x = np.take_along_axis(x, order[:, :, None], axis=1)
    rows_blocks = np.full((tagged.size, 4), -1, dtype=np.int64)
    rows_x = np.zeros((tagged.size, 4, 3))
    if tagged.size:
        rows_blocks[:, :nv] = imap.local_to_global(blocks.ravel().astype(np.int32)).reshape(-1, nv)
    rows_x[:, :nv] = x
    return rows_blocks, rows_x, facet_tags.values[keep].astype(np.int32), nv


class ContactSurface:
    """This rank's part of the surface of the bodies of ``V``'s mesh (facet tag = body id).

    Attributes of the held part (local numbering, rebuilt by :meth:`hold`):
        bodies: (nB,) global ids of the held bodies (sorted).
        blocks: (nS,) global dof-block index of each held surface node (sorted).
        X: (nS, 3) reference coordinates (mm).
        facets: (nF, 4) held-node indices (-1 as 4th vertex of triangles).
        facet_body, node_body: (nF,), (nS,) global body id of each facet and node.
        facet_body_local, node_body_local: the same as indices into ``bodies``.
        node_facet_ptr, node_facets: facets around each held node (CSR).
        owned_nodes: held nodes whose dof block this rank owns: its slave nodes (the same
            nodes, in the same order, whatever the held set).
        owned_local_blocks: their local dof-block indices.
        version: incremented by every :meth:`hold` (caches keyed on it).
    Attributes of the rank:
        num_bodies: number of bodies of the whole model.
        slave_bodies: global ids of the bodies of the owned surface nodes.
        home: (num_bodies,) rank that keeps each body's facets for the others (-1: no facet).
        bytes_received: bytes received by this rank, by kind ("setup", "halo", "displacement").
        gathers: number of displacement exchanges so far.
    """

    def __init__(
        self, V: dolfinx.fem.FunctionSpace, facet_tags: dolfinx.mesh.MeshTags, num_bodies: int
    ):
        comm = V.mesh.comm
        self.comm = comm
        self.V = V
        self.num_bodies = int(num_bodies)
        if V.element.basix_element.degree != 1:
            raise NotImplementedError(
                "contact surfaces need a degree-1 displacement space (Q1 or P1)"
            )
        self.bs = V.dofmap.index_map_bs
        imap = V.dofmap.index_map
        self._range = imap.local_range
        self.bytes_received = {"setup": 0, "halo": 0, "displacement": 0}
        self.version = 0
        self.gathers = 0  # displacement exchanges (``gather``), for the byte counts

        blocks, x, bodies, nv = _owned_facet_rows(V, facet_tags)
        self.vertices_per_facet = nv
        # the surface nodes this rank owns, with their body: marked by the facets' owners
        self._imap = imap  # layout of the displacement (blocks of bs)
        mark = self._global_vec()
        valid = blocks >= 0
        mark.setValues(
            (blocks[valid] * self.bs).astype(PETSc.IntType),
            np.repeat(bodies + 1.0, nv),
            addv=PETSc.InsertMode.INSERT_VALUES,
        )
        mark.assemble()
        owned_body = mark.getArray(readonly=True).reshape(-1, self.bs)[:, 0]
        owned_blocks = np.flatnonzero(owned_body > 0)
        self._owned_global = owned_blocks.astype(np.int64) + self._range[0]
        self.slave_bodies = np.unique((owned_body[owned_blocks] - 1).astype(np.int32))
        mark.destroy()

        # each body's facets kept whole by its home rank (nothing moves for whole particles)
        self._facets = KeyedRows(comm, bodies, (blocks, x), self.num_bodies)
        self.home = self._facets.home
        self.bytes_received["setup"] += self._facets.bytes_received
        self._scatter = None
        self.hold(self.slave_bodies)

    # -- the held part ---------------------------------------------------------------------------
    def _global_vec(self) -> PETSc.Vec:
        """A zero PETSc vector with the layout of the displacement (no ghosts)."""
        imap = self._imap
        vec = PETSc.Vec().createMPI(
            (imap.size_local * self.bs, imap.size_global * self.bs), bsize=self.bs, comm=self.comm
        )
        vec.set(0.0)
        return vec

    def hold(
        self,
        bodies: np.ndarray,
        owned_u: np.ndarray | None = None,
        select: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    ) -> None:
        """Hold ``bodies`` (global ids; the slave bodies are always added, whole): receive their
        facets from their homes, renumber, and rebuild the displacement scatter. Collective.

        With ``select``, the other bodies are held in part: ``select(x, body)`` receives their
        facets' current vertex positions x (m, 4, 3; ``owned_u`` gives the displacement, this
        rank's owned dof values; the 4th vertex of a triangle repeats the first) and body ids
        (m,), and returns which facets the contact needs (bool, m). Each selected facet comes
        with every facet that shares a vertex with it (the ring that its corner normals average
        over); the rest is dropped."""
        bodies = np.union1d(np.asarray(bodies, dtype=np.int64), self.slave_bodies)
        bodies = bodies[self.home[bodies] >= 0]
        before = self._facets.bytes_received
        all_bodies, all_blocks, all_x = self._facets.fetch(bodies)
        self.bytes_received["halo"] += self._facets.bytes_received - before
        if select is not None:
            keep = self._selected(all_blocks, all_x, all_bodies, owned_u, select)
            all_bodies, all_blocks, all_x = all_bodies[keep], all_blocks[keep], all_x[keep]
        self._number(all_blocks, all_x, all_bodies.astype(np.int32))
        self._build_scatter()
        self.version += 1

    def _selected(self, blocks, x, bodies, owned_u, select) -> np.ndarray:
        """Facets to hold among fetched rows: those of the slave bodies, the others' that
        ``select`` picks, and their rings (see :meth:`hold`)."""
        keep = np.isin(bodies, self.slave_bodies)
        other = np.flatnonzero(~keep)
        if other.size == 0:
            return keep
        nv = self.vertices_per_facet
        vb = blocks[other, :nv]
        unique, inverse = np.unique(vb, return_inverse=True)
        source, local, scatter = self._scatter_to(unique)  # one-off: nodes not yet held
        source.array_w[:] = owned_u
        scatter.scatter(source, local, PETSc.InsertMode.INSERT_VALUES, PETSc.ScatterMode.FORWARD)
        U = local.array_r.reshape(-1, self.bs)[inverse.reshape(vb.shape)]
        lo, hi = self._range
        self.bytes_received["halo"] += (
            8 * self.bs * int(np.count_nonzero((unique < lo) | (unique >= hi)))
        )
        for obj in (scatter, local, source):
            obj.destroy()
        xc = x[other].copy()
        xc[:, :nv] += U
        xc[:, nv:] = xc[:, :1]
        chosen = np.asarray(select(xc, bodies[other]), dtype=bool)
        ring = np.isin(vb, vb[chosen]).any(axis=1)  # facets sharing a vertex with a chosen one
        keep[other[ring]] = True
        return keep

    def _number(self, all_blocks, all_x, all_bodies) -> None:
        """Local numbering of the held facets, nodes and bodies (see the module docstring)."""
        nv = self.vertices_per_facet
        order = np.lexsort(all_blocks.T[::-1])  # by vertex blocks: partition-independent
        all_blocks, all_x, all_bodies = all_blocks[order], all_x[order], all_bodies[order]
        valid = all_blocks >= 0
        self.blocks, inverse = np.unique(all_blocks[valid], return_inverse=True)
        facets = -np.ones_like(all_blocks)
        facets[valid] = inverse
        self.facets = facets.astype(np.int64)
        self.bodies, self.facet_body_local = np.unique(all_bodies, return_inverse=True)
        self.facet_body_local = self.facet_body_local.astype(np.int64)
        self.facet_body = all_bodies.astype(np.int64)
        X = np.zeros((self.blocks.size, 3))
        X[inverse] = all_x[valid]
        self.X = X
        self.node_body = np.zeros(self.blocks.size, dtype=np.int64)
        self.node_body[inverse] = np.repeat(all_bodies, nv)
        self.node_body_local = np.searchsorted(self.bodies, self.node_body).astype(np.int64)
        flat = self.facets[:, :nv].ravel()
        order = np.argsort(flat, kind="stable")
        self.node_facets = (order // nv).astype(np.int64)
        self.node_facet_ptr = np.searchsorted(flat[order], np.arange(self.blocks.size + 1)).astype(
            np.int64
        )
        lo, hi = self._range
        owned = (self.blocks >= lo) & (self.blocks < hi)
        self.owned_nodes = np.flatnonzero(owned)
        self.owned_local_blocks = (self.blocks[owned] - lo).astype(np.int32)
        if not np.array_equal(self.blocks[owned], self._owned_global):
            raise RuntimeError("contact surface: a held body misses one of this rank's nodes")

    def _scatter_to(self, blocks: np.ndarray) -> tuple[PETSc.Vec, PETSc.Vec, PETSc.Scatter]:
        """(source, local, scatter): the displacement layout -> the values of the global dof
        ``blocks`` (len(blocks) * bs, sequential, in that order)."""
        idx = (blocks[:, None] * self.bs + np.arange(self.bs)).ravel().astype(PETSc.IntType)
        source = self._global_vec()
        local = PETSc.Vec().createSeq(idx.size, comm=MPI.COMM_SELF)
        index_set = PETSc.IS().createGeneral(idx, comm=MPI.COMM_SELF)
        scatter = PETSc.Scatter().create(source, index_set, local, None)
        index_set.destroy()
        return source, local, scatter

    def _build_scatter(self) -> None:
        """PETSc scatter: displacement vector -> the held nodes' values (nS * bs, sequential)."""
        if self._scatter is not None:
            self._scatter.destroy()
            self._local.destroy()
            self._source.destroy()
        self._source, self._local, self._scatter = self._scatter_to(self.blocks)
        lo, hi = self._range
        self._remote_values = int(np.count_nonzero((self.blocks < lo) | (self.blocks >= hi)))

    @property
    def num_nodes(self) -> int:
        """Number of held surface nodes."""
        return self.blocks.size

    @property
    def num_owned_values(self) -> int:
        """Number of displacement values (blocks x bs) this rank owns."""
        return self._imap.size_local * self.bs

    @property
    def num_owned(self) -> int:
        """Number of surface nodes this rank owns (its slave nodes)."""
        return self.owned_nodes.size

    # -- exchanges -------------------------------------------------------------------------------
    def gather(self, u: dolfinx.fem.Function) -> np.ndarray:
        """Displacement (nS, 3) of the held surface nodes (from their owners, point to point)."""
        owned = u.x.array[: self.num_owned_values]
        return self.gather_owned_array(owned)

    def gather_owned_array(self, owned: np.ndarray) -> np.ndarray:
        """Held nodes' values (nS, bs) of a nodal field given by its owned values on each rank
        (``owned``: this rank's owned dof values, blocks of bs)."""
        self._source.array_w[:] = owned
        self._scatter.scatter(
            self._source, self._local, PETSc.InsertMode.INSERT_VALUES, PETSc.ScatterMode.FORWARD
        )
        self.bytes_received["displacement"] += 8 * self.bs * self._remote_values
        self.gathers += 1
        return self._local.array_r.reshape(-1, self.bs).copy()

    def sum_to_owners(self, values: np.ndarray) -> np.ndarray:
        """Sum a per-held-node scalar ``values`` (nS,) over the ranks holding each node; returns
        the sums at this rank's owned nodes (``owned_nodes`` order)."""
        self._local.zeroEntries()
        self._local.array_w.reshape(-1, self.bs)[:, 0] = values
        self._source.zeroEntries()
        self._scatter.scatter(
            self._local, self._source, PETSc.InsertMode.ADD_VALUES, PETSc.ScatterMode.REVERSE
        )
        return self._source.array_r.reshape(-1, self.bs)[self.owned_local_blocks, 0].copy()

    def owned_body_boxes(self, x: np.ndarray) -> np.ndarray:
        """(num_bodies, 2, 3) min / max corners of every body's surface at held positions ``x``
        (nS, 3): each rank reduces its owned nodes, one reduction over the bodies (not the
        surface). Bodies without nodes get (+inf, -inf)."""
        owned = self.owned_nodes
        boxes = body_boxes(x[owned], self.node_body[owned], self.num_bodies)
        lo, hi = np.empty((self.num_bodies, 3)), np.empty((self.num_bodies, 3))
        self.comm.Allreduce(np.ascontiguousarray(boxes[:, 0]), lo, op=MPI.MIN)
        self.comm.Allreduce(np.ascontiguousarray(boxes[:, 1]), hi, op=MPI.MAX)
        return np.stack([lo, hi], axis=1)

    def owned_body_spheres(self, x: np.ndarray, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centres (num_bodies, 3, the centres of ``boxes`` from :meth:`owned_body_boxes`) and
        radii (num_bodies,) of spheres holding every body's surface at held positions ``x``:
        one reduction over the bodies."""
        centre = 0.5 * (boxes[:, 0] + boxes[:, 1])
        owned = self.owned_nodes
        body = self.node_body[owned]
        local = np.zeros(self.num_bodies)
        if owned.size:
            np.maximum.at(local, body, np.linalg.norm(x[owned] - centre[body], axis=1))
        radius = np.empty_like(local)
        self.comm.Allreduce(local, radius, op=MPI.MAX)
        return centre, radius
