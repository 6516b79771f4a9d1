"""Tetrahedral particle meshes with gmsh (P1 or P2 geometry), one DOLFINx mesh for all spheres.

Optional alternative to the cube-sphere hexahedra; P2 tetrahedra are locking-free for
isochoric plastic flow without any reduced integration.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

import dolfinx
import dolfinx.io.gmsh


def gmsh_to_dolfinx(name: str, build, comm: MPI.Comm):
    """Run ``build(gmsh)`` on rank 0 in a fresh gmsh model, then distribute its mesh over ``comm``.

    Physical groups numbered from 1 become 0-based cell tags (volumes) and facet tags (surfaces).
    Returns (mesh, cell_tags, facet_tags).
    """
    import gmsh

    started = gmsh.isInitialized()
    if not started:
        gmsh.initialize(interruptible=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add(name)
    try:
        if comm.rank == 0:
            build(gmsh)
        data = dolfinx.io.gmsh.model_to_mesh(gmsh.model, comm, 0, gdim=3)
    finally:
        gmsh.model.remove()
        if not started:
            gmsh.finalize()
    mesh = data.mesh
    ct, ft = data.cell_tags, data.facet_tags
    cell_tags = dolfinx.mesh.meshtags(mesh, 3, ct.indices, ct.values - 1)
    facet_tags = dolfinx.mesh.meshtags(mesh, 2, ft.indices, ft.values - 1)
    return mesh, cell_tags, facet_tags


def ball_size_field(
    gmsh, centre, size_in: float, radius: float, outer: float, size_out: float
) -> int:
    """gmsh Ball field (mm): size_in within ``radius`` of ``centre``, growing to size_out at
    ``outer``. (A field, not an extra geometric point: that would become an orphan mesh node.)"""
    ball = gmsh.model.mesh.field.add("Ball")
    for key, value in dict(
        Radius=radius,
        Thickness=outer - radius,
        VIn=size_in,
        VOut=size_out,
        XCenter=centre[0],
        YCenter=centre[1],
        ZCenter=centre[2],
    ).items():
        gmsh.model.mesh.field.setNumber(ball, key, float(value))
    return ball


def size_from_background(gmsh, field: int) -> None:
    """Element sizes from ``field`` only (not from points, boundaries or curvature)."""
    gmsh.model.mesh.field.setAsBackgroundMesh(field)
    for key in (
        "Mesh.MeshSizeExtendFromBoundary",
        "Mesh.MeshSizeFromPoints",
        "Mesh.MeshSizeFromCurvature",
    ):
        gmsh.option.setNumber(key, 0)


def gmsh_spheres(
    centres: np.ndarray,
    radii: np.ndarray,
    comm: MPI.Comm,
    *,
    order: int = 1,
    size: float = 0.25,
    refine: list | None = None,
):
    """Mesh each sphere with gmsh: (mesh, cell tags, facet tags), tag = particle id (0-based).

    ``refine``: optional list of (point (3,), size_min, distance_min, distance_max) in mm: the
    element size is size_min within distance_min of the point, growing linearly to the global
    size at distance_max (gmsh Distance + Threshold fields), e.g. around contact points.
    """
    if order not in (1, 2):
        raise ValueError(f"tet_order must be 1 or 2, got {order}")
    if not 0.01 <= size <= 1.0:
        raise ValueError(f"tet_size must be in [0.01, 1] (relative to the radius), got {size}")

    def build(gmsh):
        vols = []
        for c, r in zip(centres, radii, strict=False):
            tag = gmsh.model.occ.addSphere(*c, r)
            vols.append(tag)
            gmsh.model.occ.synchronize()
        gmsh.model.occ.synchronize()
        for pid, (tag, r) in enumerate(zip(vols, radii, strict=False)):
            gmsh.model.addPhysicalGroup(3, [tag], pid + 1)
            bnd = gmsh.model.getBoundary([(3, tag)], oriented=False)
            gmsh.model.addPhysicalGroup(2, [b[1] for b in bnd], pid + 1)
            pts = gmsh.model.getBoundary([(3, tag)], combined=False, recursive=True)
            gmsh.model.mesh.setSize(pts, size * r)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 12)
        gmsh.option.setNumber("Mesh.MeshSizeMax", float(size * radii.max()))
        if refine:
            fields = []
            for point, size_min, dist_min, dist_max in refine:
                fields.append(
                    ball_size_field(gmsh, point, size_min, dist_min, dist_max, size * radii.max())
                )
            field = gmsh.model.mesh.field.add("Min")
            gmsh.model.mesh.field.setNumbers(field, "FieldsList", fields)
            size_from_background(gmsh, field)
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.setOrder(order)

    return gmsh_to_dolfinx("particles", build, comm)
