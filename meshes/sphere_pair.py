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

from mpi4py import MPI

from .assembly import BodyAssembly
from .tetra import ball_size_field, gmsh_to_dolfinx, size_from_background


def quarter_sphere_pair(radius: float = 1.0, comm: MPI.Comm = MPI.COMM_WORLD, *, size_min: float = 0.03,
                        refine_radius: float = 0.2, refine_width: float = 0.5, size_max: float = 0.3,
                        grading: float | None = None) -> BodyAssembly:
    """Mesh the two quarter spheres (mm); sizes relative to ``radius`` (tetrahedra before splitting)."""
    checks = [("size_min", size_min, 1e-3, 0.5), ("size_max", size_max, size_min, 1.0),
              ("refine_radius", refine_radius, 0.0, 1.0), ("refine_width", refine_width, 0.0, 2.0)]
    if grading is not None:
        checks.append(("grading", grading, 0.05, 2.0))
    for name, value, lo, hi in checks:
        if not lo <= value <= hi:
            raise ValueError(f"sphere pair {name} = {value} is out of range [{lo}, {hi}] (relative to the radius)")
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
            field = ball_size_field(gmsh, (0.0, 0.0, 0.0), size_min * r, refine_radius * r,
                                    (refine_radius + refine_width) * r, size_max * r)
        else:
            field = _contact_cap_size_field(gmsh, r, size_min * r, refine_radius * r, grading, size_max * r)
        size_from_background(gmsh, field)
        gmsh.option.setNumber("Mesh.SubdivisionAlgorithm", 2)  # every tetrahedron -> 4 hexahedra
        gmsh.model.mesh.generate(3)

    mesh, cell_tags, facet_tags = gmsh_to_dolfinx("sphere_pair", build, comm)
    if mesh.topology.cell_name() != "hexahedron":
        raise RuntimeError(f"gmsh subdivision gave {mesh.topology.cell_name()} cells, expected hexahedra")
    return BodyAssembly(mesh, cell_tags, facet_tags, 2)


def _contact_cap_size_field(gmsh, r: float, size_in: float, cap_radius: float, grading: float, size_out: float) -> int:
    """gmsh MathEval field (mm): size_in + grading * (distance from the contact cap), at most
    size_out. The cap: the spherical surfaces (centres (0, 0, -+r)) within cap_radius of the z axis;
    the distance combines the depth below the surface and the radial distance beyond the cap."""
    rho = "Sqrt(x*x + y*y)"
    depth = f"({r} - Sqrt(x*x + y*y + ({r} - Abs(z))^2))"
    field = gmsh.model.mesh.field.add("MathEval")
    gmsh.model.mesh.field.setString(
        field, "F", f"Min({size_out}, {size_in} + {grading} * Sqrt(Max({rho} - {cap_radius}, 0)^2 + {depth}^2))")
    return field
