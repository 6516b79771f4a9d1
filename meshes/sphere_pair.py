"""Quarter model of two identical spheres touching at the origin, hexahedra refined at the contact.

Spheres of radius r centred at (0, 0, -r) (body 0) and (0, 0, r) (body 1), cut by the symmetry
planes x = 0 and y = 0 (the quarter x >= 0, y >= 0 is kept). gmsh meshes each quarter ball with
tetrahedra whose size is ``size_min`` r within ``refine_radius`` r of the contact point and grows
to ``size_max`` r over ``refine_width`` r (or, with ``grading``, whose size is ``size_min`` r on
the spherical surface within ``refine_radius`` r of the axis and grows by ``grading`` per unit
distance from that contact cap, into the bulk and along the surface: fine contact meshes at a
fraction of the ball's cost); every tetrahedron is then split into four hexahedra
(``Mesh.SubdivisionAlgorithm = 2``), so the Q1 + selective-reduced-integration hexahedra of the
particles (no volumetric locking under plastic flow) get a local refinement that the cube-sphere
O-grid cannot give. The hexahedra are about half the tetrahedra's size. The two quarters are
meshed independently, so their surface nodes do not face each other node on node.

Tags: cell tag = body id; facet tag = body id on the spherical surfaces only (the flat symmetry
faces are not contact surfaces).
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

import basix.ufl
import dolfinx
import dolfinx.mesh
import ufl

from .assembly import BodyAssembly
from .cubesphere import _orient_positive
from .tetra import ball_size_field, gmsh_to_dolfinx, size_from_background


def quarter_sphere_pair(
    radius: float = 1.0,
    comm: MPI.Comm = MPI.COMM_WORLD,
    *,
    size_min: float = 0.03,
    refine_radius: float = 0.2,
    refine_width: float = 0.5,
    size_max: float = 0.3,
    grading: float | None = None,
) -> BodyAssembly:
    """Mesh the two quarter spheres (mm); sizes relative to ``radius`` (tetrahedra before
    splitting)."""
    checks = [
        ("size_min", size_min, 1e-3, 0.5),
        ("size_max", size_max, size_min, 1.0),
        ("refine_radius", refine_radius, 0.0, 1.0),
        ("refine_width", refine_width, 0.0, 2.0),
    ]
    if grading is not None:
        checks.append(("grading", grading, 0.05, 2.0))
    for name, value, lo, hi in checks:
        if not lo <= value <= hi:
            raise ValueError(
                f"sphere pair {name} = {value} is out of range [{lo}, {hi}] "
                "(relative to the radius)"
            )
    r = float(radius)

    def build(gmsh):
        occ = gmsh.model.occ
        volumes = []
        for sign in (-1.0, 1.0):
            ball = occ.addSphere(0.0, 0.0, sign * r, r)
            box = occ.addBox(0.0, 0.0, sign * r - 1.5 * r, 1.5 * r, 1.5 * r, 3.0 * r)
            out, _ = occ.intersect([(3, ball)], [(3, box)])
            volumes.append(out[0][1])
        occ.synchronize()
        for body, tag in enumerate(volumes):
            gmsh.model.addPhysicalGroup(3, [tag], body + 1)
            # spherical boundary = the faces not lying on a symmetry plane x = 0 or y = 0
            curved = []
            for dim, face in gmsh.model.getBoundary([(3, tag)], oriented=False):
                c = occ.getCenterOfMass(dim, face)
                if abs(c[0]) > 1e-9 * r and abs(c[1]) > 1e-9 * r:
                    curved.append(face)
            gmsh.model.addPhysicalGroup(2, curved, body + 1)
        if grading is None:
            field = ball_size_field(
                gmsh,
                (0.0, 0.0, 0.0),
                size_min * r,
                refine_radius * r,
                (refine_radius + refine_width) * r,
                size_max * r,
            )
        else:
            field = _contact_cap_size_field(
                gmsh, r, size_min * r, refine_radius * r, grading, size_max * r
            )
        size_from_background(gmsh, field)
        gmsh.option.setNumber("Mesh.SubdivisionAlgorithm", 2)  # every tetrahedron -> 4 hexahedra
        gmsh.model.mesh.generate(3)

    mesh, cell_tags, facet_tags = gmsh_to_dolfinx("sphere_pair", build, comm)
    if mesh.topology.cell_name() != "hexahedron":
        raise RuntimeError(
            f"gmsh subdivision gave {mesh.topology.cell_name()} cells, expected hexahedra"
        )
    return BodyAssembly(mesh, cell_tags, facet_tags, 2)


def _contact_cap_size_field(
    gmsh,
    r: float,
    size_in: float,
    cap_radius: float,
    grading: float,
    size_out: float,
    section: bool = False,
) -> int:
    """gmsh MathEval field (mm): size_in + grading * (distance from the contact cap), at most
    size_out. The cap: the spherical surfaces (centres (0, 0, -+r)) within cap_radius of the z axis;
    the distance combines the depth below the surface and the radial distance beyond the cap.
    ``section``: the field of the meridian section drawn in gmsh's (x, y) = (rho, z) plane."""
    rho, z = ("x", "y") if section else ("Sqrt(x*x + y*y)", "z")
    depth = f"({r} - Sqrt({rho}*{rho} + ({r} - Abs({z}))^2))"
    field = gmsh.model.mesh.field.add("MathEval")
    gmsh.model.mesh.field.setString(
        field,
        "F",
        f"Min({size_out}, {size_in} + {grading} * "
        f"Sqrt(Max({rho} - {cap_radius}, 0)^2 + {depth}^2))",
    )
    return field


def wedge_sphere_pair(
    radius: float = 1.0,
    comm: MPI.Comm = MPI.COMM_WORLD,
    *,
    angle: float = 2.0,
    size_min: float = 0.004,
    cap_radius: float = 0.2,
    grading: float = 0.3,
    size_max: float = 0.2,
) -> BodyAssembly:
    """Thin wedge (``angle`` degrees about the z axis) of the same two spheres: one layer of
    hexahedra revolved from a quadrilateral mesh of the meridian half-disks (x >= 0 in the plane
    y = 0), for axisymmetric loadings. The wedge lies between the plane y = 0 and the plane at
    ``angle`` from it; the workflow ties every node of the second plane to its partner in the first,
    rotated (cyclic symmetry, ``workflows.two_spheres``), which makes the one-cell wedge an
    axisymmetric model (trilinear across the angle: the chord error 1 - cos(angle / 2) is 1.5e-4
    at 2 degrees). A contact can then be resolved at the thesis' size (0.00125 r) with ~1e4 cells:
    the cost of a 2-D model, the code of the 3-D one.

    gmsh meshes the meridian half-disks with triangles of size ``size_min`` r on the spherical arc
    within ``cap_radius`` r of the axis, growing by ``grading`` per unit distance from that cap
    (``_contact_cap_size_field``), split into quadrilaterals (half that size). The cells touching
    the axis are hexahedra with one collapsed edge (two vertices at the same point: the axis node
    is duplicated, one copy per plane; the workflow ties the copies). Tags as the quarter model:
    cell tag = body id, facet tag = body id on the spherical surfaces only.
    """
    checks = [
        ("angle", angle, 0.1, 30.0),
        ("size_min", size_min, 2e-4, 0.5),
        ("size_max", size_max, size_min, 1.0),
        ("cap_radius", cap_radius, 0.0, 1.0),
        ("grading", grading, 0.05, 2.0),
    ]
    for name, value, lo, hi in checks:
        if not lo <= value <= hi:
            raise ValueError(f"wedge sphere pair {name} = {value} is out of range [{lo}, {hi}]")
    r = float(radius)
    theta = np.radians(angle)
    if comm.rank == 0:
        section, quads, body = _meridian_quads(
            r, size_min * r, cap_radius * r, grading, size_max * r
        )
        n = section.shape[0]
        rho, z = section[:, 0], section[:, 1]
        x = np.concatenate(
            [
                np.stack([rho, np.zeros(n), z], axis=1),
                np.stack([rho * np.cos(theta), rho * np.sin(theta), z], axis=1),
            ]
        )
        # tensor-product (DOLFINx) vertex order: quad (a, b, c, d) -> (a, b, d, c) in both planes
        q = quads[:, [0, 1, 3, 2]]
        cells = _orient_positive(x, np.concatenate([q, q + n], axis=1))
    else:
        x, cells, body = np.zeros((0, 3)), np.zeros((0, 8), np.int64), np.zeros(0, np.int64)
    element = basix.ufl.element("Lagrange", "hexahedron", 1, shape=(3,))
    mesh = dolfinx.mesh.create_mesh(comm, cells, ufl.Mesh(element), x)
    body = comm.bcast(body, root=0)
    num_cells = mesh.topology.index_map(3).size_local + mesh.topology.index_map(3).num_ghosts
    original = np.asarray(mesh.topology.original_cell_index, dtype=np.int64)[:num_cells]
    cell_tags = dolfinx.mesh.meshtags(
        mesh, 3, np.arange(num_cells, dtype=np.int32), body[original].astype(np.int32)
    )

    def on_sphere(sign):
        return lambda p: (
            np.abs(np.sqrt(p[0] ** 2 + p[1] ** 2 + (p[2] - sign * r) ** 2) - r) < 1e-9 * r
        )

    facets, values = [], []
    for b, sign in enumerate((-1.0, 1.0)):
        found = dolfinx.mesh.locate_entities_boundary(mesh, 2, on_sphere(sign))
        mid = dolfinx.mesh.compute_midpoints(mesh, 2, found)
        found = found[sign * mid[:, 2] > 0]  # the pole vertex lies on both spheres
        facets.append(found)
        values.append(np.full(found.size, b, np.int32))
    facets, values = np.concatenate(facets), np.concatenate(values)
    order = np.argsort(facets)
    facet_tags = dolfinx.mesh.meshtags(mesh, 2, facets[order].astype(np.int32), values[order])
    return BodyAssembly(mesh, cell_tags, facet_tags, 2)


def _meridian_quads(r: float, size_in: float, cap_radius: float, grading: float, size_out: float):
    """Quadrilateral mesh (gmsh, rank 0) of the two meridian half-disks rho >= 0 centred at
    z = -+r, drawn in gmsh's (x, y) = (rho, z) plane. Returns (points (N, 2), quads (M, 4)
    counter-clockwise, body of each quad)."""
    import gmsh

    started = gmsh.isInitialized()
    if not started:
        gmsh.initialize(interruptible=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("meridian")
    try:
        occ = gmsh.model.occ
        surfaces = []
        for sign in (-1.0, 1.0):
            disk = occ.addDisk(0.0, sign * r, 0.0, r, r)
            box = occ.addRectangle(0.0, sign * r - 1.5 * r, 0.0, 1.5 * r, 3.0 * r)
            out, _ = occ.intersect([(2, disk)], [(2, box)])
            surfaces.append(out[0][1])
        occ.synchronize()
        field = _contact_cap_size_field(
            gmsh, r, size_in, cap_radius, grading, size_out, section=True
        )
        size_from_background(gmsh, field)
        gmsh.option.setNumber("Mesh.SubdivisionAlgorithm", 1)  # every triangle -> 3 quadrilaterals
        gmsh.model.mesh.generate(2)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        index = np.full(int(tags.max()) + 1, -1, np.int64)
        index[tags.astype(np.int64)] = np.arange(tags.size)
        points = coords.reshape(-1, 3)[:, :2].copy()
        points[np.abs(points[:, 0]) < 1e-12 * r, 0] = 0.0  # exactly on the axis
        quads, body = [], []
        for b, surface in enumerate(surfaces):
            types, _, nodes = gmsh.model.mesh.getElements(2, surface)
            if list(types) != [3]:
                raise RuntimeError(
                    f"gmsh gave element types {list(types)} on the meridian, "
                    "expected quadrilaterals (3)"
                )
            q = index[nodes[0].astype(np.int64)].reshape(-1, 4)
            quads.append(q)
            body.append(np.full(q.shape[0], b, np.int64))
    finally:
        gmsh.model.remove()
        if not started:
            gmsh.finalize()
    quads = np.concatenate(quads)
    # counter-clockwise in (rho, z)
    p = points[quads]
    area2 = np.sum(
        p[:, :, 0] * np.roll(p[:, :, 1], -1, axis=1) - np.roll(p[:, :, 0], -1, axis=1) * p[:, :, 1],
        axis=1,
    )
    quads[area2 < 0] = quads[area2 < 0][:, ::-1]
    # drop the nodes no quadrilateral uses (the geometry's corner points)
    used, quads = np.unique(quads, return_inverse=True)
    return points[used], quads.reshape(-1, 4), np.concatenate(body)
