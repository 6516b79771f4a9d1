"""Particle meshes: cube-sphere counts and quality, multi-particle tags, gmsh tetrahedra."""

import numpy as np
import pytest
from mpfem_fenicsx.meshes import particle_mesh, particle_volumes, unit_ball_hex
from mpfem_fenicsx.meshes.cubesphere import RESOLUTIONS, _orient_positive
from mpi4py import MPI


def test_default_cube_sphere_is_the_thesis_particle():
    ball = unit_ball_hex()
    # thesis appendix A: 6^3 core + one shell layer of 6x6 quadrilaterals per face = 432 C3D8R,
    # 561 nodes, 218 surface nodes
    assert ball.num_cells == 216 + 6 * 36 == 432
    assert ball.num_nodes == 343 + 218 == 561
    assert ball.surface_nodes.size == 218
    # orientation: re-orienting changes nothing, i.e. every Jacobian is already positive
    assert np.array_equal(_orient_positive(ball.points, ball.cells), ball.cells)
    # named resolutions: the chapter-4 O-grid (1 934 nodes with the reference node) and the
    # old default
    assert unit_ball_hex(*RESOLUTIONS["chapter4"]).num_nodes == 1933
    assert unit_ball_hex(*RESOLUTIONS["coarse"]).num_nodes == 517


@pytest.mark.parametrize("name", ["chapter2", "chapter4", "coarse"])
def test_particle_mesh_holds_its_sphere_volume(name):
    """DOLFINx's volume integral (an independent measure of the nodes' scaling) equals 4/3 pi r^3;
    the surface nodes lie outside r by the scale, the facet centres inside."""
    divisions, layers = RESOLUTIONS[name]
    radii = np.array([1.0, 0.5])
    a = particle_mesh(
        [[0, 0, 0], [3.0, 0, 0]], radii, MPI.COMM_SELF, divisions=divisions, layers=layers
    )
    exact = 4.0 / 3.0 * np.pi * radii**3
    assert np.allclose(particle_volumes(a), exact, rtol=1e-10)
    ball = unit_ball_hex(divisions, layers)
    assert 1.0 < ball.radius_scale < 1.03
    assert np.allclose(np.linalg.norm(ball.points[ball.surface_nodes], axis=1), ball.radius_scale)
    inscribed = particle_mesh(
        [[0, 0, 0]], [1.0], MPI.COMM_SELF, divisions=divisions, layers=layers, exact_volume=False
    )
    assert particle_volumes(inscribed)[0] < 0.995 * exact[0]  # 1.07 % (10x10) to 6.5 % (4x4) short


def test_inscribed_refinement_converges_to_sphere_volume():
    exact = 4.0 / 3.0 * np.pi
    errors = []
    for k in (1, 2, 3):
        a = particle_mesh([[0, 0, 0]], [1.0], MPI.COMM_SELF, refinement=k, exact_volume=False)
        errors.append(abs(particle_volumes(a)[0] - exact) / exact)
    assert errors[0] < 0.03
    # polyhedral approximation of a curved surface: error ~ h^2
    assert errors[1] < errors[0] / 3.0 and errors[2] < errors[1] / 1.8


def test_many_particles_one_mesh_with_tags():
    centres = np.array([[0, 0, 0], [3.0, 0, 0], [0, 2.5, 0.5]])
    radii = np.array([1.0, 0.6, 0.8])
    a = particle_mesh(centres, radii, MPI.COMM_SELF)
    assert a.mesh.topology.index_map(3).size_global == 3 * 432
    counts = np.bincount(a.cell_tags.values, minlength=3)
    assert counts.tolist() == [432, 432, 432]
    facet_counts = np.bincount(a.facet_tags.values, minlength=3)
    assert facet_counts.tolist() == [216, 216, 216]
    vols = particle_volumes(a)
    ratio = vols / (4.0 / 3.0 * np.pi * radii**3)
    assert np.allclose(ratio, ratio[0], rtol=1e-10)  # same shape, scaled
    # facets of particle i lie on its (volume-exact: slightly scaled) sphere
    x = a.mesh.geometry.x
    a.mesh.topology.create_connectivity(2, 0)
    f2v = a.mesh.topology.connectivity(2, 0)
    for facet, pid in zip(a.facet_tags.indices, a.facet_tags.values, strict=True):
        vertices = f2v.links(facet)
        d = np.linalg.norm(x[vertices] - centres[pid], axis=1)
        assert np.allclose(d, radii[pid] * unit_ball_hex().radius_scale, rtol=1e-9)


@pytest.mark.parametrize("bad", [-1.0, 0.0, np.nan])
def test_bad_radius_is_rejected(bad):
    with pytest.raises(ValueError, match="radius must be > 0"):
        particle_mesh([[0, 0, 0], [3, 0, 0]], [1.0, bad], MPI.COMM_SELF)


def test_gmsh_tetrahedra_p2_volume():
    a = particle_mesh(
        [[0, 0, 0], [3, 0, 0]],
        [1.0, 0.5],
        MPI.COMM_SELF,
        cell_type="tetrahedron",
        tet_order=2,
        tet_size=0.4,
    )
    exact = 4.0 / 3.0 * np.pi * np.array([1.0, 0.125])
    assert np.allclose(particle_volumes(a), exact, rtol=2e-3)
    assert set(np.unique(a.cell_tags.values)) == {0, 1}
    assert set(np.unique(a.facet_tags.values)) == {0, 1}


def test_quarter_sphere_pair_hexahedra_refined_at_the_contact():
    """Two quarter balls (x, y >= 0) of radius 1 centred at z = -1 and z = +1: hexahedra by gmsh
    subdivision, smaller at the contact point, contact tags on the curved surface only."""
    from mpfem_fenicsx.meshes.sphere_pair import quarter_sphere_pair

    import dolfinx
    import ufl

    a = quarter_sphere_pair(1.0, MPI.COMM_SELF, size_min=0.06, size_max=0.4)
    mesh = a.mesh
    assert mesh.topology.cell_name() == "hexahedron"
    dx = ufl.Measure("dx", domain=mesh, subdomain_data=a.cell_tags)
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=a.facet_tags)
    one = dolfinx.fem.Constant(mesh, 1.0)
    for body in (0, 1):
        volume = dolfinx.fem.assemble_scalar(dolfinx.fem.form(one * dx(body)))
        area = dolfinx.fem.assemble_scalar(dolfinx.fem.form(one * ds(body)))
        # quarter of 4/3 pi and of 4 pi (symmetry faces untagged); the polyhedral surface with
        # 0.4 r facets far from the contact is ~1 % short
        assert volume == pytest.approx(np.pi / 3.0, rel=0.02)
        assert area == pytest.approx(np.pi, rel=0.02)
    # tagged facets are on the spheres (|x -+ e_z| = 1), none on the symmetry planes
    mesh.topology.create_connectivity(2, 0)
    mid = dolfinx.mesh.compute_midpoints(mesh, 2, a.facet_tags.indices)
    centre = np.where(a.facet_tags.values[:, None] == 0, [0, 0, -1.0], [0, 0, 1.0])
    assert np.abs(np.linalg.norm(mid - centre, axis=1) - 1.0).max() < 0.01
    # local refinement: cells near the contact point much smaller than far away
    h = dolfinx.cpp.mesh.h(
        mesh._cpp_object, 3, np.arange(mesh.topology.index_map(3).size_local, dtype=np.int32)
    )
    mid_cells = dolfinx.mesh.compute_midpoints(mesh, 3, np.arange(h.size, dtype=np.int32))
    near = np.linalg.norm(mid_cells, axis=1) < 0.1
    far = np.linalg.norm(mid_cells, axis=1) > 1.0
    assert near.any() and far.any()
    assert np.median(h[near]) < 0.4 * np.median(h[far])


def test_quarter_sphere_pair_graded_from_the_contact_cap():
    """grading: the element size is size_min on the contact cap (sphere surface within
    refine_radius of the axis) and grows with the distance from it, into the bulk and along the
    surface."""
    from mpfem_fenicsx.meshes.sphere_pair import quarter_sphere_pair

    import dolfinx

    size_min, cap = 0.04, 0.15
    graded = quarter_sphere_pair(
        1.0, MPI.COMM_SELF, size_min=size_min, refine_radius=cap, grading=0.5
    )
    mesh = graded.mesh
    mesh.topology.create_connectivity(2, 3)
    facets = graded.facet_tags.indices
    h = dolfinx.cpp.mesh.h(mesh._cpp_object, 2, facets)
    mid = dolfinx.mesh.compute_midpoints(mesh, 2, facets)
    rho = np.hypot(mid[:, 0], mid[:, 1])
    # contact-cap facets: hexahedra half the tetrahedra's size_min (longest edge incl. diagonal)
    on_cap = rho < 0.8 * cap
    assert 0.35 * size_min < np.median(h[on_cap]) < 0.9 * size_min
    # the surface coarsens away from the cap: 0.5 per unit distance, capped at size_max = 0.3
    away = (rho > cap + 0.3) & (rho < cap + 0.4)
    assert np.median(h[away]) > 2.5 * np.median(h[on_cap])
    # and the bulk coarsens with the depth under the cap (the ball keeps size_min down to 0.15 r)
    hc = dolfinx.cpp.mesh.h(
        mesh._cpp_object, 3, np.arange(mesh.topology.index_map(3).size_local, dtype=np.int32)
    )
    xc = dolfinx.mesh.compute_midpoints(mesh, 3, np.arange(hc.size, dtype=np.int32))
    depth = 1.0 - np.linalg.norm(xc - np.where(xc[:, 2:] < 0, [0, 0, -1.0], [0, 0, 1.0]), axis=1)
    deep = (np.hypot(xc[:, 0], xc[:, 1]) < 0.1) & (depth > 0.08) & (depth < 0.12)
    assert deep.any() and np.median(hc[deep]) > 1.5 * np.median(h[on_cap])
    # bad input names the field and its range
    with pytest.raises(ValueError, match="grading"):
        quarter_sphere_pair(1.0, MPI.COMM_SELF, size_min=size_min, grading=5.0)


def test_wedge_sphere_pair_is_one_revolved_layer_of_hexahedra():
    """The wedge: a quadrilateral meridian mesh revolved by ``angle`` (one layer of hexahedra,
    those at the axis with a collapsed edge); its volume is the spheres' share of the angle, the
    facet tags hold only the spherical surfaces, refined to ~size_min / 2 on the contact cap."""
    from mpfem_fenicsx.meshes.sphere_pair import wedge_sphere_pair

    import dolfinx
    import ufl

    angle, size_min, cap = 3.0, 0.02, 0.2
    wedge = wedge_sphere_pair(
        1.0, MPI.COMM_SELF, angle=angle, size_min=size_min, cap_radius=cap, grading=0.5
    )
    mesh = wedge.mesh
    assert mesh.topology.cell_name() == "hexahedron"
    volume = dolfinx.fem.assemble_scalar(dolfinx.fem.form(1.0 * ufl.dx(domain=mesh)))
    assert volume == pytest.approx(2 * 4 / 3 * np.pi * angle / 360, rel=5e-3)
    x = mesh.geometry.x
    phi = np.degrees(np.arctan2(x[:, 1], x[:, 0]))
    rho = np.hypot(x[:, 0], x[:, 1])
    assert np.all(np.isclose(phi, 0, atol=1e-9) | np.isclose(phi, angle) | (rho < 1e-12))
    # one layer: every node lies in one of the two planes, as many in each
    assert np.sum(np.isclose(phi, angle)) == np.sum(np.isclose(phi, 0, atol=1e-9) & (rho > 1e-12))
    # tagged facets: all vertices on the sphere of their body
    mesh.topology.create_connectivity(2, 0)
    f2v = mesh.topology.connectivity(2, 0)
    for body, sign in ((0, -1.0), (1, 1.0)):
        facets = wedge.facet_tags.find(body)
        assert facets.size > 0
        v = np.concatenate([f2v.links(f) for f in facets])
        centre = np.array([0.0, 0.0, sign])
        assert np.allclose(np.linalg.norm(x[v] - centre, axis=1), 1.0, atol=1e-9)
    mid = dolfinx.mesh.compute_midpoints(mesh, 2, wedge.facet_tags.indices)
    radial = np.hypot(mid[:, 0], mid[:, 1])
    on_cap = radial < 0.8 * cap
    # radial facet length on the cap: quadrilaterals half the triangles' size_min
    mesh.topology.create_connectivity(2, 1)
    # longest edge (hoop or radial)
    h = dolfinx.cpp.mesh.h(mesh._cpp_object, 2, wedge.facet_tags.indices)
    assert on_cap.sum() > 2 * 0.8 * cap / size_min
    assert np.median(h[on_cap]) < 0.8 * size_min
    with pytest.raises(ValueError, match="angle"):
        wedge_sphere_pair(1.0, MPI.COMM_SELF, angle=90.0)
