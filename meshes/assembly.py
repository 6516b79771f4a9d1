"""Many particles (centres, radii) -> one distributed DOLFINx mesh.

All particles live in a single mesh made of disconnected components. Tags:
- cell tags: value = particle id (0-based) of the cell;
- facet tags: value = particle id for every facet on that particle's surface (all exterior
  facets of the mesh are particle surfaces, since particles are disconnected).

The mesh is built on rank 0 and distributed whole particle by whole particle (hexahedra,
``partition.particle_partitioner``; tetrahedra: DOLFINx's graph partitioner); particle ids are
recovered on every rank from the original cell index, so no extra communication is needed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

import basix.ufl
import dolfinx
import dolfinx.mesh
import ufl

from .cubesphere import mobius_ball, unit_ball_hex
from .partition import particle_partitioner


@dataclass
class ParticleAssembly:
    """A DOLFINx mesh of particles with their tags and reference geometry (mm)."""

    mesh: dolfinx.mesh.Mesh
    cell_tags: dolfinx.mesh.MeshTags
    facet_tags: dolfinx.mesh.MeshTags
    centres: np.ndarray  # (N, 3) initial centres, mm
    radii: np.ndarray  # (N,) radii of the meshed spheres, mm (already reduced)
    cell_type: str

    @property
    def num_particles(self) -> int:
        """Number of meshed particles (spheres)."""
        return self.radii.size


def _check_particles(centres, radii) -> tuple[np.ndarray, np.ndarray]:
    centres = np.atleast_2d(np.asarray(centres, dtype=float))
    radii = np.atleast_1d(np.asarray(radii, dtype=float))
    if centres.ndim != 2 or centres.shape[1] != 3:
        raise ValueError(f"centres must have shape (N, 3), got {centres.shape}")
    if radii.shape != (centres.shape[0],):
        raise ValueError(f"radii must have shape ({centres.shape[0]},), got {radii.shape}")
    bad = np.flatnonzero(~(radii > 0))
    if bad.size:
        raise ValueError(
            f"radius must be > 0 mm; particles {bad.tolist()} have {radii[bad].tolist()}"
        )
    return centres, radii


def _tag_mesh(mesh: dolfinx.mesh.Mesh, particle_of_original_cell: np.ndarray):
    tdim = mesh.topology.dim
    num_owned = mesh.topology.index_map(tdim).size_local
    num_cells = num_owned + mesh.topology.index_map(tdim).num_ghosts
    original = np.asarray(mesh.topology.original_cell_index, dtype=np.int64)[:num_cells]
    cell_particle = particle_of_original_cell[original].astype(np.int32)
    cells = np.arange(num_cells, dtype=np.int32)
    cell_tags = dolfinx.mesh.meshtags(mesh, tdim, cells, cell_particle)

    mesh.topology.create_connectivity(tdim - 1, tdim)
    facets = dolfinx.mesh.exterior_facet_indices(mesh.topology)
    f2c = mesh.topology.connectivity(tdim - 1, tdim)
    owner_cell = (
        np.array([f2c.links(f)[0] for f in facets], dtype=np.int32)
        if facets.size
        else np.zeros(0, dtype=np.int32)
    )
    facet_tags = dolfinx.mesh.meshtags(
        mesh, tdim - 1, facets.astype(np.int32), cell_particle[owner_cell]
    )
    return cell_tags, facet_tags


@dataclass
class BodyAssembly:
    """Several disconnected bodies in one mesh: cell tag = facet tag = body id."""

    mesh: dolfinx.mesh.Mesh
    cell_tags: dolfinx.mesh.MeshTags
    facet_tags: dolfinx.mesh.MeshTags
    num_bodies: int


def box_bodies_mesh(boxes, comm: MPI.Comm = MPI.COMM_WORLD) -> BodyAssembly:
    """Structured hexahedral boxes as bodies of one mesh.

    Args:
        boxes: list of (lower corner (3,), upper corner (3,), divisions (nx, ny, nz)), mm.
    """
    from .cubesphere import _lattice_cells

    xs, cs, owners = [], [], []
    offset = 0
    for body, (lo, hi, divisions) in enumerate(boxes):
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        if np.any(hi <= lo):
            raise ValueError(f"box {body}: upper corner {hi} must exceed lower corner {lo}")
        axes = [np.linspace(lo[d], hi[d], int(divisions[d]) + 1) for d in range(3)]
        X, Y, Z = np.meshgrid(*axes, indexing="ij")
        xs.append(np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1))
        cells = _lattice_cells(tuple(int(n) for n in divisions)) + offset
        cs.append(cells)
        owners.append(np.full(cells.shape[0], body))
        offset += xs[-1].shape[0]
    if comm.rank == 0:
        x, cells = np.concatenate(xs), np.concatenate(cs)
    else:
        x, cells = np.zeros((0, 3)), np.zeros((0, 8), dtype=np.int64)
    element = basix.ufl.element("Lagrange", "hexahedron", 1, shape=(3,))
    mesh = dolfinx.mesh.create_mesh(comm, cells, ufl.Mesh(element), x)
    cell_tags, facet_tags = _tag_mesh(mesh, np.concatenate(owners))
    return BodyAssembly(mesh, cell_tags, facet_tags, len(boxes))


def particle_mesh(
    centres,
    radii,
    comm: MPI.Comm = MPI.COMM_WORLD,
    *,
    cell_type: str = "hexahedron",
    divisions: int | None = None,
    layers: int | None = None,
    refinement: int = 1,
    exact_volume: bool = True,
    tet_order: int = 1,
    tet_size: float = 0.25,
    tet_refine: list | None = None,
    rotations: np.ndarray | None = None,
    grading: np.ndarray | None = None,
    weights: np.ndarray | None = None,
) -> ParticleAssembly:
    """Mesh the spheres ``(centres[i], radii[i])`` (mm) as one DOLFINx mesh on ``comm``.

    Args:
        cell_type: ``"hexahedron"`` (cube-sphere O-grid, Q1) or ``"tetrahedron"`` (gmsh, P1/P2).
        divisions, layers, refinement: cube-sphere resolution (see :func:`unit_ball_hex`; None:
            the default ``"chapter2"`` resolution, 561 nodes per particle).
        exact_volume: hexahedral particles hold the volume of their sphere (nodes scaled, see
            :func:`unit_ball_hex`); False: inscribed in it.
        tet_order: geometric/field order of the gmsh tetrahedra (1 or 2).
        tet_size: gmsh target element size relative to the radius.
        tet_refine: local gmsh refinement, see :func:`meshes.tetra.gmsh_spheres`.
        rotations: optional (N, 3, 3) rotation of each hexahedral particle mesh about its centre
            (random orientations avoid aligned, node-on-node contacts between particles); an
            orthogonal matrix of determinant -1 mirrors the mesh (its cells re-ordered to keep
            a positive Jacobian).
        grading: optional (N, 3) vectors g (|g| < 1): particle i's hexahedra are refined towards
            the surface point in direction g/|g| by the conformal map of :func:`mobius_ball`
            (element size x (1 - |g|)/(1 + |g|) there), e.g. at a known contact point.
        weights: optional (N,) work of each particle for the partition over MPI ranks (default:
            equal; see :func:`meshes.partition.particle_partitioner`: hexahedral particles are
            kept whole on one rank, ranks as compact regions, when there are at least as many
            particles as ranks).
    """
    centres, radii = _check_particles(centres, radii)
    if cell_type == "hexahedron":
        ball = unit_ball_hex(divisions, layers, refinement, exact_volume=exact_volume)
        n_nodes, n_cells = ball.num_nodes, ball.num_cells
        if comm.rank == 0:
            unit = np.broadcast_to(ball.points, (radii.size,) + ball.points.shape)
            if grading is not None:
                grading = np.asarray(grading, dtype=float).reshape(radii.size, 3)
                # the conformal map keeps the unit sphere: apply it to the inscribed ball, then
                # scale
                s = ball.radius_scale
                unit = np.stack(
                    [
                        s * mobius_ball(ball.points / s, -g) if np.any(g) else ball.points
                        for g in grading
                    ]
                )
            if rotations is not None:
                rotations = np.asarray(rotations, dtype=float)
                if rotations.shape != (radii.size, 3, 3):
                    raise ValueError(
                        f"rotations must have shape ({radii.size}, 3, 3), got {rotations.shape}"
                    )
                unit = np.einsum("pij,pnj->pni", rotations, unit)
            x = (centres[:, None, :] + radii[:, None, None] * unit).reshape(-1, 3)
            cells = ball.cells[None] + n_nodes * np.arange(radii.size)[:, None, None]
            if rotations is not None:
                # a mirrored particle: its hexahedra's first reference direction reversed
                mirrored = np.linalg.det(rotations) < 0
                cells[mirrored] = cells[mirrored][:, :, [1, 0, 3, 2, 5, 4, 7, 6]]
            cells = cells.reshape(-1, 8)
        else:
            x = np.zeros((0, 3))
            cells = np.zeros((0, 8), dtype=np.int64)
        element = basix.ufl.element("Lagrange", "hexahedron", 1, shape=(3,))
        # whole particles per rank, ranks as compact regions weighted by the particles' work
        # (fewer particles than ranks: DOLFINx's graph partitioner splits them)
        partitioner = (
            particle_partitioner(centres, n_cells, 8, weights) if radii.size >= comm.size else None
        )
        mesh = dolfinx.mesh.create_mesh(comm, cells, ufl.Mesh(element), x, partitioner=partitioner)
        particle_of_cell = np.repeat(np.arange(radii.size), n_cells)
        cell_tags, facet_tags = _tag_mesh(mesh, particle_of_cell)
        return ParticleAssembly(mesh, cell_tags, facet_tags, centres, radii, cell_type)
    if cell_type == "tetrahedron":
        from .tetra import gmsh_spheres

        mesh, cell_tags, facet_tags = gmsh_spheres(
            centres, radii, comm, order=tet_order, size=tet_size, refine=tet_refine
        )
        return ParticleAssembly(mesh, cell_tags, facet_tags, centres, radii, "tetrahedron")
    raise ValueError(f"cell_type must be 'hexahedron' or 'tetrahedron', got {cell_type!r}")


def _moment_degree(mesh: dolfinx.mesh.Mesh) -> int:
    """Quadrature degree of the volume / first-moment integrals: on Q1 hexahedra J dX =
    det(d(X + u)/d xi) d xi has degree 2 per direction and (X + u) J degree 3, so 2 Gauss points
    per direction are exact (27 cost 3x for nothing); other cells keep degree 4."""
    q1_hexahedra = mesh.topology.cell_name() == "hexahedron" and mesh.geometry.cmaps[0].degree == 1
    return 3 if q1_hexahedra else 4


class CellVolumes:
    """Current volume (mm^3) of each owned cell, int_cell det(I + grad u) dX (exact for Q1).

    The form is compiled once; calling the object re-assembles it for the current ``u``.
    """

    def __init__(self, mesh: dolfinx.mesh.Mesh, u: dolfinx.fem.Function | None = None):
        V0 = dolfinx.fem.functionspace(mesh, ("DG", 0))
        w = ufl.TestFunction(V0)
        J = 1.0 if u is None else ufl.det(ufl.Identity(3) + ufl.grad(u))
        dx = ufl.dx(domain=mesh, metadata={"quadrature_degree": _moment_degree(mesh)})
        self._form = dolfinx.fem.form(J * w * dx)
        owned = mesh.topology.index_map(mesh.topology.dim).size_local
        self._dofs = V0.dofmap.list[:owned, 0]
        self._vec = dolfinx.fem.Function(V0)

    def __call__(self) -> np.ndarray:
        """Volume (mm^3) of each owned cell at the current ``u``."""
        self._vec.x.array[:] = 0.0
        dolfinx.fem.assemble_vector(self._vec.x.array, self._form)
        return self._vec.x.array[self._dofs].copy()


class ParticleVolumes:
    """Current volume (mm^3) of each particle, summed over ranks (compiled once)."""

    def __init__(self, assembly: ParticleAssembly, u: dolfinx.fem.Function | None = None):
        self._cells = CellVolumes(assembly.mesh, u)
        owned = assembly.mesh.topology.index_map(assembly.mesh.topology.dim).size_local
        # cell_tags cover cells 0..num_cells-1 in order (see _tag_mesh)
        self._pid = assembly.cell_tags.values[:owned]
        self._n = assembly.num_particles
        self._comm = assembly.mesh.comm

    def __call__(self) -> np.ndarray:
        """Current volume (mm^3) of each particle, (N,), the same on every rank."""
        local = np.bincount(self._pid, weights=self._cells(), minlength=self._n)
        return self._comm.allreduce(local, op=MPI.SUM)


class ParticleCentroids:
    """Current centroid (mm) of each particle, int_p (X + u) J dX / int_p J dX (compiled once).

    One assembly of a 4-component DG0 form gives the three first moments and the volumes
    together (the geometry and grad u are evaluated once per cell, not once per moment);
    :attr:`volumes` keeps the particle volumes (mm^3) of the last call.
    """

    def __init__(self, assembly: ParticleAssembly, u: dolfinx.fem.Function):
        mesh = assembly.mesh
        W = dolfinx.fem.functionspace(mesh, ("DG", 0, (4,)))
        w = ufl.TestFunction(W)
        x = ufl.SpatialCoordinate(mesh) + u
        J = ufl.det(ufl.Identity(3) + ufl.grad(u))
        dx = ufl.dx(domain=mesh, metadata={"quadrature_degree": _moment_degree(mesh)})
        moments = ufl.as_vector([x[0] * J, x[1] * J, x[2] * J, J])
        self._form = dolfinx.fem.form(ufl.inner(moments, w) * dx)
        owned = mesh.topology.index_map(mesh.topology.dim).size_local
        self._dofs = W.dofmap.list[:owned, 0]
        self._pid = assembly.cell_tags.values[:owned]
        self._n = assembly.num_particles
        self._comm = mesh.comm
        self._vec = dolfinx.fem.Function(W)
        self.volumes = np.zeros(self._n)

    def __call__(self) -> np.ndarray:
        """Current centroid (mm) of each particle, (N, 3), the same on every rank."""
        self._vec.x.array[:] = 0.0
        dolfinx.fem.assemble_vector(self._vec.x.array, self._form)
        cell_moments = self._vec.x.array.reshape(-1, 4)[self._dofs]
        sums = np.stack(
            [
                np.bincount(self._pid, weights=cell_moments[:, k], minlength=self._n)
                for k in range(4)
            ]
        )
        sums = self._comm.allreduce(sums, op=MPI.SUM)
        self.volumes = sums[3].copy()
        return (sums[:3] / sums[3]).T


def particle_volumes(
    assembly: ParticleAssembly, u: dolfinx.fem.Function | None = None
) -> np.ndarray:
    """One-off evaluation of :class:`ParticleVolumes` (compiles a form: not for time loops)."""
    return ParticleVolumes(assembly, u)()


def node_particles(V: dolfinx.fem.FunctionSpace, cell_particle: np.ndarray) -> np.ndarray:
    """Particle id of every owned node (a node is reached by owned cells of its particle, or,
    near a partition boundary, only by ghost cells: those take the id through a DG0 scatter)."""
    mesh = V.mesh
    cell_map = mesh.topology.index_map(3)
    DG0 = dolfinx.fem.functionspace(mesh, ("DG", 0))
    tag = dolfinx.fem.Function(DG0)
    tag.x.array[DG0.dofmap.list[: cell_map.size_local, 0]] = cell_particle
    tag.x.scatter_forward()
    cells = cell_map.size_local + cell_map.num_ghosts
    ids = np.rint(tag.x.array[DG0.dofmap.list[:cells, 0]]).astype(np.int64)
    dofs = V.dofmap.list[:cells]
    node = np.zeros(V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts, np.int64)
    node[dofs.ravel()] = np.repeat(ids, dofs.shape[1])
    return node[: V.dofmap.index_map.size_local]
