"""Rigid tools' shapes and motions: gaps and normals against analytic geometry and brute force."""

import numpy as np
import pytest

from mpfem_fenicsx.contact import ContactLaw
from mpfem_fenicsx.tools import (
    CylinderInside,
    KeyframePath,
    Plane,
    RigidTool,
    TriangulatedSurface,
    read_stl,
    write_stl,
)
from mpfem_fenicsx.tools.shapes import closest_points_on_triangles

RNG = np.random.default_rng(7)


def test_plane_gap_is_the_signed_distance_along_its_normal():
    plane = Plane(point=(1.0, 0.0, 0.0), normal=(2.0, 0.0, 0.0))  # normalized
    x = RNG.uniform(-2, 3, (50, 3))
    idx, gap, normal = plane.gap_normal(x, reach=0.5)
    assert np.array_equal(idx, np.flatnonzero(x[:, 0] - 1.0 < 0.5))
    assert np.allclose(gap, x[idx, 0] - 1.0)
    assert np.allclose(normal, [1.0, 0.0, 0.0])


def test_cylinder_inside_gap_and_normal_point_to_the_axis():
    die = CylinderInside(radius=2.0, point=(1.0, 1.0, 0.0), axis=(0.0, 0.0, 3.0))
    x = RNG.uniform(-2, 4, (200, 3))
    idx, gap, normal = die.gap_normal(x, reach=0.3)
    rho = np.hypot(x[:, 0] - 1.0, x[:, 1] - 1.0)
    assert np.array_equal(idx, np.flatnonzero(2.0 - rho < 0.3))
    assert np.allclose(gap, 2.0 - rho[idx])
    inward = -(x[idx, :2] - 1.0) / rho[idx, None]
    assert np.allclose(normal[:, :2], inward) and np.allclose(normal[:, 2], 0.0)


def test_closest_points_on_triangles_match_a_dense_sampling():
    m = 400
    a, b, c = (RNG.normal(size=(m, 3)) for _ in range(3))
    p = 2.0 * RNG.normal(size=(m, 3))
    cp, inside = closest_points_on_triangles(p, a, b, c)
    # dense barycentric sampling of each triangle
    s = np.linspace(0, 1, 121)
    u, v = np.meshgrid(s, s)
    keep = u + v <= 1.0
    u, v = u[keep], v[keep]
    samples = a[:, None] + u[None, :, None] * (b - a)[:, None] + v[None, :, None] * (c - a)[:, None]
    brute = np.linalg.norm(samples - p[:, None], axis=2).min(axis=1)
    exact = np.linalg.norm(cp - p, axis=1)
    assert np.all(exact <= brute + 1e-12)  # never farther than a sample
    assert np.allclose(exact, brute, atol=2e-2 * np.linalg.norm(b - a, axis=1).max())
    # a point inside the face region projects on the face
    q = (a + b + c) / 3.0 + np.cross(b - a, c - a)
    cq, face = closest_points_on_triangles(q, a, b, c)
    assert face.all() and np.allclose(cq, (a + b + c) / 3.0)


def _square(z=0.0, size=4.0, flip=False):
    v = np.array([[-1, -1, z], [1, -1, z], [1, 1, z], [-1, 1, z]], float) * [size, size, 1]
    t = np.array([[0, 1, 2], [0, 2, 3]])
    return TriangulatedSurface(v, t[:, ::-1] if flip else t)


def test_triangulated_square_is_the_plane_over_it():
    x = RNG.uniform(-3, 3, (300, 3))
    idx, gap, normal = _square().gap_normal(x, reach=1.0)
    ref_idx, ref_gap, ref_normal = Plane().gap_normal(x, reach=1.0)
    assert np.array_equal(idx, ref_idx)
    assert np.allclose(gap, ref_gap) and np.allclose(normal, ref_normal)
    # reversed triangles: the particles are on the other side
    idx, gap, normal = _square(flip=True).gap_normal(x, reach=1.0)
    assert np.array_equal(idx, np.flatnonzero(-x[:, 2] < 1.0))
    assert np.allclose(gap, -x[idx, 2]) and np.allclose(normal, [0, 0, -1])


def test_triangulated_cylinder_approaches_the_analytic_die():
    k, nz, R = 256, 4, 2.0
    theta = np.linspace(0, 2 * np.pi, k, endpoint=False)
    z = np.linspace(-3, 3, nz + 1)
    ring = np.column_stack([R * np.cos(theta), R * np.sin(theta)])
    vertices = np.array([[*ring[i], zj] for zj in z for i in range(k)])
    tris = []
    for j in range(nz):
        for i in range(k):
            a, b = j * k + i, j * k + (i + 1) % k
            c, d = a + k, b + k
            tris += [[a, c, b], [b, c, d]]  # normals inwards
    surface = TriangulatedSurface(vertices, np.array(tris))
    assert np.all(
        np.einsum("ij,ij->i", surface.face_normals, -vertices[np.array(tris)[:, 0]] / R)[:, None]
        > 0.99
    )
    x = np.column_stack([*(RNG.uniform(-2.2, 2.2, (2, 500))), RNG.uniform(-2, 2, 500)])
    idx, gap, normal = surface.gap_normal(x, reach=0.3)
    ref_idx, ref_gap, ref_normal = CylinderInside(radius=R).gap_normal(x, reach=0.3)
    common, i1, i2 = np.intersect1d(idx, ref_idx, return_indices=True)
    assert common.size > 100 and common.size >= 0.97 * ref_idx.size
    sag = R * (1 - np.cos(np.pi / k))  # chord error of the polygon
    assert np.abs(gap[i1] - ref_gap[i2]).max() <= sag + 1e-12
    assert np.einsum("ij,ij->i", normal[i1], ref_normal[i2]).min() > np.cos(2 * np.pi / k)


@pytest.mark.parametrize("binary", [False, True])
def test_stl_round_trip(tmp_path, binary):
    square = _square(z=0.5)
    corners = square.vertices[square.triangles]
    path = tmp_path / "punch.stl"
    if binary:
        rec = np.zeros(
            len(corners), dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
        )
        rec["v"] = corners
        path.write_bytes(b"\0" * 80 + np.uint32(len(corners)).tobytes() + rec.tobytes())
    else:
        write_stl(path, corners)
    assert np.allclose(read_stl(path), corners)
    loaded = TriangulatedSurface.from_stl(path)
    x = RNG.uniform(-3, 3, (100, 3))
    for a, b in zip(loaded.gap_normal(x, 1.0), square.gap_normal(x, 1.0), strict=True):
        assert np.allclose(a, b)


def test_keyframe_path_stops_at_its_keyframes():
    path = KeyframePath((0.0, 1.0, 2.0), ((0, 0, 0), (0, 0, -1), (0, 0, -0.5)))
    assert np.allclose(path(-1.0), 0) and np.allclose(path(1.0), [0, 0, -1])
    assert np.allclose(path(0.5), [0, 0, -0.5])  # smooth step: half-way at mid-time
    assert np.allclose(path(5.0), [0, 0, -0.5])
    linear = KeyframePath((0.0, 1.0), ((0, 0, 0), (2, 0, 0)), smooth=False)
    assert np.allclose(linear(0.25), [0.5, 0, 0])
    # the smooth step leaves and reaches each keyframe at rest
    h = 1e-6
    assert np.allclose((path(h) - path(0.0)) / h, 0.0, atol=1e-6)
    assert np.allclose((path(1.0 + h) - path(1.0 - h)) / (2 * h), 0.0, atol=1e-6)


def test_a_ramped_path_moves_at_constant_speed_between_its_ramps():
    """A press at constant speed: 1 / (1 - r) of the mean speed between the ramps, at rest at
    both keyframes, continuous speed, the whole travel at the end."""
    r, h = 0.1, 1e-7
    path = KeyframePath((0.0, 2.0), ((0, 0, 0), (0, 0, -1)), ramp=r)
    speed = [(path(t + h)[2] - path(t - h)[2]) / (2 * h) for t in np.linspace(0.2 + h, 1.8, 9)]
    assert np.allclose(speed, -0.5 / (1 - r), rtol=1e-6)
    assert abs(path(h)[2] - path(0.0)[2]) / h < 1e-5 and np.allclose(path(2.0), [0, 0, -1])
    t = np.linspace(0.0, 2.0, 2001)
    v = np.gradient([path(x)[2] for x in t], t)
    assert np.abs(np.diff(v)).max() < 0.01  # no jump of speed at the ramps' ends
    with pytest.raises(ValueError, match="ramp = 0.7 is out of range"):
        KeyframePath((0.0, 1.0), ((0, 0, 0), (0, 0, 1)), ramp=0.7)


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: Plane(normal=(0, 0, 0)), "plane normal"),
        (lambda: CylinderInside(radius=-1.0), "cylinder radius"),
        (lambda: CylinderInside(axis=(0, 0, np.nan)), "cylinder axis"),
        (lambda: TriangulatedSurface(np.zeros((3, 3)), [[0, 1, 2]]), "degenerate"),
        (lambda: TriangulatedSurface(np.eye(3), [[0, 1, 3]]), "out of range"),
        (lambda: KeyframePath((0.0, 0.0), ((0, 0, 0), (0, 0, 1))), "increase"),
        (lambda: KeyframePath((0.0, 1.0), ((0, 0, 0),)), "one per time"),
        (lambda: RigidTool("", Plane()), "name"),
        (lambda: RigidTool("wall", Plane(), ContactLaw(friction=-0.1)), "friction"),
    ],
)
def test_bad_tool_input_is_refused_with_the_field_named(build, message):
    with pytest.raises(ValueError, match=message):
        build()
