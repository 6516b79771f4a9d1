"""Contact search and forces without a solve: action-reaction, symmetry, periodic shifts."""

import numpy as np
import pytest
from mpfem_fenicsx.meshes import particle_mesh
from mpi4py import MPI
from petsc4py import PETSc

from mpfem_fenicsx.contact import ContactLaw, ContactModel
from mpfem_fenicsx.material import LEAD
from mpfem_fenicsx.problem import SolidProblem


def _model(centres, radii, shifts=None):
    a = particle_mesh(centres, radii, MPI.COMM_SELF)
    prob = SolidProblem(a.mesh, LEAD, tangent=False)
    law = ContactLaw(penalty=1e6, friction=0.0)
    model = ContactModel(prob.V, a.facet_tags, len(radii), law, search_distance=0.1, shifts=shifts)
    model.evaluate(prob.u)
    return model


def test_action_reaction_and_direction():
    # the second particle is offset along a general direction, overlapping by 0.06
    direction = np.array([1.0, 0.6, -0.3]) / np.linalg.norm([1.0, 0.6, -0.3])
    model = _model([[0, 0, 0], 1.94 * direction], [1.0, 1.0])
    forces = model.body_forces()  # force of j on i
    assert np.linalg.norm(forces[0, 1]) > 0
    assert np.allclose(forces[0, 1], -forces[1, 0], atol=1e-9 * np.linalg.norm(forces[0, 1]))
    # repulsive, roughly along the line of centres (faceted surfaces tilt it a little)
    cosine = -forces[0, 1] @ direction / np.linalg.norm(forces[0, 1])
    assert cosine > 0.9
    # nodal forces sum to zero
    _, values = model.nodal_forces()
    assert np.abs(values.reshape(-1, 3).sum(axis=0)).max() < 1e-9 * np.abs(values).max()


def test_two_pass_treatment_is_symmetric():
    """Relabelling the particles leaves the pair force unchanged (no privileged body)."""
    c = [[0, 0, 0], [1.9, 0.1, 0.05]]
    f_ab = _model(c, [1.0, 1.0]).body_forces()[0, 1]
    f_ba = _model(c[::-1], [1.0, 1.0]).body_forces()[1, 0]
    assert np.allclose(f_ab, f_ba, rtol=1e-10)
    # both passes find contact points
    m = _model(c, [1.0, 1.0])
    bodies = m.surface.node_body[m.evaluation.points.slave]
    assert set(bodies.tolist()) == {0, 1}


def test_periodic_image_contact_equals_direct_contact():
    """A particle touching the image of another through a lattice shift feels the same force as
    with the other particle placed at the shifted position."""
    cell = 4.0
    offset = np.array([1.94, 0.07, 0.03])  # generic: no node-on-node tie between the poles
    direct = _model([[0, 0, 0], offset], [1.0, 1.0]).body_forces()[0, 1]
    shifts = np.array([[0, 0, 0], [cell, 0, 0], [-cell, 0, 0]], dtype=float)
    image = _model([[0, 0, 0], offset - [cell, 0, 0]], [1.0, 1.0], shifts=shifts).body_forces()[
        0, 1
    ]
    assert np.linalg.norm(direct) > 0
    assert np.allclose(image, direct, rtol=1e-8, atol=1e-9 * np.linalg.norm(direct))


def test_points_name_their_lattice_shift():
    """Each contact point carries the index of its master's lattice shift (the history key's):
    particle 1 sits one cell to the left of its contact with particle 0, so the points of 0 meet
    1 through the shift +cell (index 2) and those of 1 meet 0 through -cell (index 1)."""
    cell = 5.0  # the particles' direct gap (1.06 mm) beyond the search distance
    shifts = np.array([[0, 0, 0], [-cell, 0, 0], [cell, 0, 0]], dtype=float)
    m = _model([[0, 0, 0], [1.94 - cell, 0.07, 0.03]], [1.0, 1.0], shifts=shifts)
    pts = m.evaluation.points
    slave_body = m.surface.node_body[pts.slave]
    assert pts.size > 0 and set(slave_body.tolist()) == {0, 1}
    assert np.array_equal(m.search.shifts[pts.shift_index], pts.shift)
    assert np.array_equal(pts.shift_index, np.where(slave_body == 0, 2, 1))


def test_no_contact_when_apart():
    m = _model([[0, 0, 0], [2.5, 0, 0]], [1.0, 1.0])
    assert m.evaluation.size == 0
    assert np.allclose(m.body_forces(), 0.0)


def test_search_distance_must_cover_delta_max():
    a = particle_mesh([[0, 0, 0], [2.5, 0, 0]], [1.0, 1.0], MPI.COMM_SELF)
    prob = SolidProblem(a.mesh, LEAD, tangent=False)
    with pytest.raises(ValueError, match="delta_max"):
        ContactModel(
            prob.V, a.facet_tags, 2, ContactLaw(gamma=1e-3, delta_max=0.5), search_distance=0.1
        )


def test_pair_forces_and_centroids():
    """Pair resultants match the body forces; centroids of an undeformed assembly are the centres;
    the Love-Weber branch vector of the pair points from i to j."""
    from mpfem_fenicsx.meshes import ParticleCentroids

    centres = np.array([[0, 0, 0], [1.94, 0.07, 0.03], [0, 1.95, 0.02]])
    a = particle_mesh(centres, [1.0, 1.0, 1.0], MPI.COMM_SELF)
    prob = SolidProblem(a.mesh, LEAD, tangent=False)
    model = ContactModel(
        prob.V, a.facet_tags, 3, ContactLaw(penalty=1e6, friction=0.0), search_distance=0.1
    )
    model.evaluate(prob.u)
    pairs = model.pair_forces()
    assert pairs["pairs"].tolist() == [[0, 1], [0, 2]]
    bodies = model.body_forces()
    for (i, j), f in zip(pairs["pairs"], pairs["force"], strict=True):
        assert np.allclose(f, bodies[i, j], rtol=1e-10)
    assert np.all(pairs["area"] > 0) and np.all(pairs["points"] > 0)
    # no adhesion: every loaded point compressive
    assert np.array_equal(pairs["area_closed"], pairs["area"])
    centroids = ParticleCentroids(a, prob.u)()
    assert np.allclose(centroids, centres, atol=1e-12)
    branch = centroids[1] - centroids[0]
    assert pairs["force"][0] @ branch < 0  # repulsion: the force of 1 on 0 points away from 1


def test_penetration_is_found_for_a_steep_slave_face():
    """A slab tilted 80 deg pokes 0.08 mm into a base: nodes of its steep face (node normal at
    100 deg to the base's normal) that are inside the base must be contact points with
    gap = -depth. (A master-facet cut-off at n_m . n_s < -0.2 missed them: they went unseen
    until the penetration was deep, then kicked the die compaction apart.)"""
    from mpfem_fenicsx.meshes import box_bodies_mesh

    from mpfem_fenicsx.loading import body_dofs

    a = box_bodies_mesh(
        [
            ([-1, -1, -0.5], [1, 1, 0], (8, 8, 1)),  # base, top face z = 0
            # slab, 0.04 mm rows
            ([0, -0.3, 0], [0.6, 0.3, 0.2], (15, 6, 2)),
        ],
        MPI.COMM_SELF,
    )
    prob = SolidProblem(a.mesh, LEAD, tangent=False)
    theta = np.radians(80.0)
    c, s = np.cos(theta), np.sin(theta)
    R = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])  # the slab's bottom face rises at 80 deg
    lift = np.array([0.3, 0.0, -0.08])
    X = prob.V.tabulate_dof_coordinates()
    blocks = body_dofs(prob.V, a.cell_tags, 1, component=0) // 3
    u = prob.u.x.array.reshape(-1, 3)
    u[blocks] = X[blocks] @ R.T + lift - X[blocks]
    model = ContactModel(
        prob.V, a.facet_tags, 2, ContactLaw(penalty=1e6, friction=0.0), search_distance=0.1
    )
    model.evaluate(prob.u)
    surf = model.surface
    x = surf.X + surf.gather(prob.u)
    inside = np.flatnonzero((surf.node_body == 1) & (x[:, 2] < -0.01))
    # the steep face's rows at 0.04 mm from the lowest edge are among them
    assert np.any(np.abs(x[inside, 2] + 0.08 - 0.04 * s) < 1e-9)
    pts = model.evaluation.points
    found = {
        int(n): g for n, g, m in zip(pts.slave, pts.gap, pts.master_body, strict=True) if m == 0
    }
    missing = [int(n) for n in inside if int(n) not in found]
    assert not missing, f"penetrating slab nodes without a contact point: {missing}"
    assert np.allclose([found[int(n)] for n in inside], x[inside, 2], atol=1e-9)


def test_contact_tangent_matrix_is_the_same_every_time():
    """The contact tangent of one evaluation, built twice: the same matrix (PETSc sorts the COO
    indices it is given in place; handing it the model's own arrays paired the second build's
    values with sorted indices, a silently wrong tangent for any second caller)."""
    a = particle_mesh([[0, 0, 0], [1.9, 0.3, -0.2]], [1.0, 1.0], MPI.COMM_SELF)
    prob = SolidProblem(a.mesh, LEAD, tangent=True)
    law = ContactLaw(penalty=1e6, friction=0.3)
    model = ContactModel(prob.V, a.facet_tags, 2, law, search_distance=0.1)
    model.evaluate(prob.u, tangent=True)
    template = prob.create_matrix()
    first, second = model.tangent_matrix(template), model.tangent_matrix(template)
    assert first.norm() > 0
    difference = first.copy()
    difference.axpy(-1.0, second)
    assert difference.norm() == 0.0


def _residual(model, prob, u_values) -> np.ndarray:
    """Contact residual r = -forces on the bodies (N, every dof) at the displacement values."""
    prob.u.x.array[:] = u_values
    model.evaluate(prob.u)
    dofs, values = model.nodal_forces()
    r = np.zeros(prob.u.x.array.size)
    np.add.at(r, dofs, -values)
    return r


def test_contact_tangent_is_the_derivative_of_the_contact_residual():
    """The contact tangent against central differences of the contact residual along a random
    motion of every node, at a deformed state with friction: the same to 1e-6. A point's force
    is its traction times its slave node's tributary area on the last converged configuration
    (held, like the masters' normals), so the point tangent, which differentiates the point's
    own nodes only, is the whole derivative (the area on the current configuration depends on
    the slave's neighbours: 2 % of the product off, Newton linear)."""
    a = particle_mesh([[0, 0, 0], [1.92, 0.31, -0.17]], [1.0, 1.0], MPI.COMM_SELF)
    prob = SolidProblem(a.mesh, LEAD, tangent=True)
    model = ContactModel(
        prob.V, a.facet_tags, 2, ContactLaw(penalty=1e6, friction=0.3), search_distance=0.1
    )
    X = prob.V.tabulate_dof_coordinates()
    u = (1e-3 * np.sin(7.0 * X[:, [1, 2, 0]])).ravel()  # mm: a non-affine deformed state
    _residual(model, prob, u)
    prob.u.x.array[:] = u
    model.evaluate(prob.u, tangent=True)
    assert model.count() >= 4
    K = model.tangent_matrix(prob.create_matrix())
    y = np.random.default_rng(3).standard_normal(u.size) * 1e-4  # mm
    Ky = K.createVecLeft()
    K.mult(PETSc.Vec().createWithArray(y.copy(), comm=MPI.COMM_SELF), Ky)
    h = 1e-3
    fd = (_residual(model, prob, u + h * y) - _residual(model, prob, u - h * y)) / (2 * h)
    assert np.linalg.norm(Ky.array) > 0
    assert np.linalg.norm(fd - Ky.array) < 1e-6 * np.linalg.norm(Ky.array)


def test_image_motion_is_the_linearized_change_of_the_contact_residual():
    """A particle pressed on the image of another: moving the images (a deformed cell) changes
    the contact residual by add_master_motion to first order (central differences over the
    shift: the same to 1e-6), the images' part of an implicit predictor."""
    cell = 4.0
    a = particle_mesh([[0, 0, 0], [1.93 - cell, 0.07, 0.03]], [1.0, 1.0], MPI.COMM_SELF)
    prob = SolidProblem(a.mesh, LEAD, tangent=True)
    lattice = np.array([[0, 0, 0], [1, 0, 0], [-1, 0, 0]], dtype=float)
    model = ContactModel(
        prob.V, a.facet_tags, 2, ContactLaw(penalty=1e6, friction=0.3), search_distance=0.1,
        shifts=lattice * cell,
    )  # fmt: skip
    vectors = cell * np.eye(3)
    model.evaluate(prob.u, tangent=True)
    assert model.count() >= 4
    r0 = _residual(model, prob, prob.u.x.array.copy())
    model.evaluate(prob.u, tangent=True)  # the tangent at the images' first position
    h = 1e-6
    dF = np.array([[-1.0, 0.2, 0.0], [0.0, 0.3, 0.0], [0.1, 0.0, -0.4]])  # the cell's motion
    model.set_periodic_images(lattice, vectors @ (np.eye(3) + h * dF).T)
    linear = prob.create_vector()
    model.add_master_motion(linear)
    plus = _residual(model, prob, prob.u.x.array.copy())
    model.set_periodic_images(lattice, vectors @ (np.eye(3) - h * dF).T)
    minus = _residual(model, prob, prob.u.x.array.copy())
    change = 0.5 * (plus - minus)
    assert np.linalg.norm(change) > 1e-6 * np.linalg.norm(r0)  # the images' motion matters
    assert np.linalg.norm(linear.array - change) < 1e-6 * np.linalg.norm(change)


def test_tool_motion_is_the_linearized_change_of_the_contact_residual():
    """A particle pressed on a rigid plane with friction and sliding on it: moving the plane
    changes the contact residual by add_master_motion to first order (central differences
    over the translation: the same to 1e-5, the point tangents being central differences
    themselves), the tools' part of an implicit predictor."""
    from mpfem_fenicsx.tools import Plane, RigidTool

    a = particle_mesh([[0, 0, 0]], [1.0], MPI.COMM_SELF)
    prob = SolidProblem(a.mesh, LEAD, tangent=True)
    law = ContactLaw(penalty=1e6, friction=0.3)
    plane = RigidTool("floor", Plane((0, 0, -0.97), (0, 0, 1)), law)
    model = ContactModel(prob.V, a.facet_tags, 1, law, search_distance=0.1, tools=[plane])
    X = prob.V.tabulate_dof_coordinates()
    u = (1e-3 * np.sin(7.0 * X[:, [1, 2, 0]])).ravel()  # mm: slides the contact patch
    _residual(model, prob, u)
    assert model.tools.evaluation.size >= 4
    model.evaluate(prob.u, tangent=True)  # the tangent at the plane's first place
    h = 1e-6
    dc = np.array([0.3, -0.2, 1.0])  # mm: the plane's motion (into the particle, sideways)
    model.tools.translation[0] = h * dc
    linear = prob.create_vector()
    model.add_master_motion(linear)
    plus = _residual(model, prob, u)
    model.tools.translation[0] = -h * dc
    minus = _residual(model, prob, u)
    change = 0.5 * (plus - minus)
    assert np.linalg.norm(change) > 0
    assert np.linalg.norm(linear.array - change) < 1e-5 * np.linalg.norm(change)
