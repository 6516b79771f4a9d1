"""Conformal (Moebius) refinement of the cube-sphere towards a contact point."""

import numpy as np
from mpfem_fenicsx.meshes.cubesphere import _orient_positive, mobius_ball, unit_ball_hex


def test_mobius_grading_keeps_the_sphere_and_refines_the_pole():
    ball = unit_ball_hex(refinement=2, exact_volume=False)  # the map keeps the unit sphere
    t = 0.6
    y = mobius_ball(ball.points, np.array([0.0, 0.0, t]))  # crowds nodes towards (0, 0, -1)
    assert np.allclose(np.linalg.norm(y[ball.surface_nodes], axis=1), 1.0, atol=1e-12)
    assert np.all(np.linalg.norm(y, axis=1) <= 1.0 + 1e-12)
    assert np.array_equal(_orient_positive(y, ball.cells), ball.cells)  # orientation preserved

    def edge_near(points, pole):
        x = points[ball.cells]
        centre = x.mean(axis=1)
        near = np.linalg.norm(centre - pole, axis=1) < 0.3
        return np.linalg.norm(x[near, 1] - x[near, 0], axis=1).mean()

    ratio = edge_near(y, [0, 0, -1]) / edge_near(ball.points, [0, 0, -1])
    # conformal factor (1 - t) / (1 + t) = 0.25 at the pole, larger a little away from it
    assert 0.2 < ratio < 0.45
