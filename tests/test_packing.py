"""Periodic sphere packings (thesis §2.2.1): container, I/O, generator,
duplicates."""

import time
from pathlib import Path

import numpy as np
import pytest
from mpfem_fenicsx.meshes.packing import (
    Packing,
    _periodic_pairs,
    assembly_particles,
    duplicate_particles,
    generate_packing,
    read_packing,
    simple_cubic_packing,
    write_packing,
)

R_MIN, R_MAX = 0.082, 0.147  # thesis radii, mm


@pytest.fixture(scope="module")
def jammed50():
    return generate_packing(50, R_MIN, R_MAX, seed=0)


def simple_cubic(r=1.0):
    """8 spheres at (r, r, r) + {0, 2r}^3 in a cube of side 4r (touching, also through the
    faces)."""
    return simple_cubic_packing(r)


def contact_numbers(packing, gap_tol):
    i, j, _, dist = _periodic_pairs(
        packing.centres, packing.radii, packing.cell, 2 * packing.radii.max()
    )
    c = dist - packing.radii[i] - packing.radii[j] < gap_tol
    return np.bincount(i[c], minlength=packing.num_particles) + np.bincount(
        j[c], minlength=packing.num_particles
    )


# ---------------------------------------------------------------------------------- Packing


def test_simple_cubic_packing_properties():
    p = simple_cubic(0.5).validate()
    assert p.num_particles == 8
    assert p.solid_fraction == pytest.approx(np.pi / 6)
    assert (
        p.max_overlap() == 0.0
    )  # every sphere touches its 6 neighbours, two of them through a face
    assert (contact_numbers(p, 1e-12) == 6).all()
    q = p.scaled(0.99)
    assert np.array_equal(q.radii, 0.99 * p.radii) and np.array_equal(q.centres, p.centres)
    assert q.solid_fraction == pytest.approx(0.99**3 * np.pi / 6)
    assert not p.radii.flags.writeable  # frozen: arrays are read-only copies
    assert p.scaled(1.01).max_overlap() == pytest.approx((1.01 - 1.0) / 0.505)


@pytest.mark.parametrize(
    "centres, radii, match",
    [
        ([[1.0, 1, 1], [1.9, 1, 1]], [0.5, 0.5], r"overlap of particles 0 and 1"),
        (
            [[0.1, 1, 1], [3.8, 1, 1]],
            [0.2, 0.2],
            r"overlap of particles 0 and 1 \(image shift \[-1, 0, 0\]\)",
        ),
        ([[1.0, 1, 1], [4.0, 1, 1]], [0.5, 0.5], r"centre of particle 1 outside the cell: x=4.0"),
        (
            [[1.0, 1, -0.1], [3.0, 1, 1]],
            [0.5, 0.5],
            r"centre of particle 0 outside the cell: z=-0.1",
        ),
        ([[1.0, 1, 1], [3.0, 1, 1]], [0.5, -0.5], r"radius must be > 0 mm; particle 1"),
        ([[1.0, 1, 1], [3.0, 1, 1]], [0.5, 2.5], r"radius must be < min\(cell\)/2"),
    ],
)
def test_validate_errors(centres, radii, match):
    with pytest.raises(ValueError, match=match):
        Packing([4.0, 4.0, 4.0], centres, radii).validate()


def test_constructor_and_argument_errors():
    with pytest.raises(ValueError, match="cell must be 3 sizes"):
        Packing([1.0, 1.0], [[0.5, 0.5, 0.5]], [0.1])
    with pytest.raises(ValueError, match="radii must have shape"):
        Packing([1.0, 1.0, 1.0], [[0.5, 0.5, 0.5]], [0.1, 0.1])
    with pytest.raises(ValueError, match="cell sizes must be finite and > 0"):
        Packing([1.0, 0.0, 1.0], [[0.5, 0.0, 0.5]], [0.1]).validate()
    with pytest.raises(ValueError, match="radius_factor"):
        simple_cubic().scaled(0.0)
    with pytest.raises(ValueError, match="r_max must be >= r_min"):
        generate_packing(50, 0.2, 0.1, seed=0)
    with pytest.raises(ValueError, match="target_fraction must be in"):
        generate_packing(50, R_MIN, R_MAX, seed=0, target_fraction=0.9)
    with pytest.raises(ValueError, match="n=5 too small"):
        generate_packing(5, R_MIN, R_MAX, seed=0)


# ------------------------------------------------------------------------------------ I/O


def test_file_round_trip_is_exact(tmp_path, jammed50):
    path = tmp_path / "p.txt"
    write_packing(jammed50, path)
    lines = path.read_text().splitlines()
    assert len(lines) == 51 and len(lines[0].split()) == 3 and len(lines[1].split()) == 4
    q = read_packing(path)
    for a in ("cell", "centres", "radii"):
        assert np.array_equal(getattr(q, a), getattr(jammed50, a))


def test_read_comments_and_blank_lines(tmp_path):
    path = tmp_path / "p.txt"
    path.write_text("# exported by a YADE script\n\n4 4 4  # cell\n1 1 1 1\n# spheres\n3 1 1 1\n\n")
    p = read_packing(path)
    assert p.cell.tolist() == [4, 4, 4] and p.num_particles == 2 and p.radii.tolist() == [1, 1]


@pytest.mark.parametrize(
    "text, match",
    [
        ("4 4 4\n1 1 1 0.5\n3 1 1\n", r"line 3: sphere line 'x y z r' must hold 4 numbers, got 3"),
        ("# c\n4 4\n1 1 1 0.5\n", r"line 2: cell line 'dx dy dz' must hold 3 numbers"),
        (
            "4 4 4\n1 1 one 0.5\n",
            r"line 2: sphere line 'x y z r' must hold 4 numbers, got '1 1 one 0.5'",
        ),
        ("4 4 4\n", r"at least one sphere line"),
        ("4 4 4\n1 1 1 1\n2.5 1 1 1\n", r"overlap of particles 0 and 1"),
        ("4 4 4\n1 1 1 -1\n", r"radius must be > 0 mm"),
    ],
)
def test_read_errors(tmp_path, text, match):
    path = tmp_path / "bad.txt"
    path.write_text(text)
    with pytest.raises(ValueError, match=match):
        read_packing(path)


def test_read_without_validation(tmp_path):
    path = tmp_path / "p.txt"
    path.write_text("4 4 4\n1 1 1 1\n2.5 1 1 1\n")
    assert read_packing(path, validate=False).max_overlap() == pytest.approx(0.5)
    assert read_packing(path, overlap_tolerance=0.6).num_particles == 2


# ------------------------------------------------------------------------------ generator


def test_generator_reproducible_by_seed():
    a = generate_packing(50, R_MIN, R_MAX, seed=3, target_fraction=0.55)
    b = generate_packing(50, R_MIN, R_MAX, seed=3, target_fraction=0.55)
    c = generate_packing(50, R_MIN, R_MAX, seed=4, target_fraction=0.55)
    for name in ("cell", "centres", "radii"):
        assert np.array_equal(getattr(a, name), getattr(b, name))
        assert not np.array_equal(getattr(a, name), getattr(c, name))


def test_generator_jammed_reproducible(jammed50):
    again = generate_packing(50, R_MIN, R_MAX, seed=0)
    assert np.array_equal(again.centres, jammed50.centres) and np.array_equal(
        again.cell, jammed50.cell
    )


def test_target_fraction_reached_overlap_free():
    p = generate_packing(50, R_MIN, R_MAX, seed=1, target_fraction=0.55)
    assert abs(p.solid_fraction - 0.55) < 1e-3
    p.validate()
    assert p.max_overlap() < 1e-6
    assert R_MIN <= p.radii.min() and p.radii.max() <= R_MAX
    assert ((p.centres >= 0) & (p.centres < p.cell)).all()


@pytest.mark.parametrize("n, seed", [(50, 0), (100, 2)])
def test_jammed_packing(n, seed, jammed50):
    p = jammed50 if (n, seed) == (50, 0) else generate_packing(n, R_MIN, R_MAX, seed=seed)
    assert 0.58 <= p.solid_fraction <= 0.67
    p.validate()
    assert p.max_overlap() < 1e-6
    assert R_MIN <= p.radii.min() and p.radii.max() <= R_MAX
    assert ((p.centres >= 0) & (p.centres < p.cell)).all()
    # jammed = isostatic: the non-rattlers (>= 4 contacts) have ~6 contacts on average
    z = contact_numbers(p, 1e-3 * R_MIN)
    assert (z < 4).sum() <= 0.15 * n
    assert 5.5 < z[z >= 4].mean() < 6.5


def test_anisotropic_cell():
    p = generate_packing(60, R_MIN, R_MAX, seed=5, target_fraction=0.5, cell_aspect=(1.0, 1.0, 2.0))
    assert p.cell[2] / p.cell[0] == pytest.approx(2.0) and abs(p.solid_fraction - 0.5) < 1e-3
    p.validate()


def test_unreachable_target_fraction():
    with pytest.raises(ValueError, match=r"target_fraction=0.7 unreachable: jammed at 0\.6"):
        generate_packing(50, R_MIN, R_MAX, seed=0, target_fraction=0.7)


@pytest.mark.heavy
def test_generator_1000_particles():
    t = time.perf_counter()
    p = generate_packing(1000, R_MIN, R_MAX, seed=0)
    elapsed = time.perf_counter() - t
    print(f"N=1000 jammed: {elapsed:.1f} s, solid fraction {p.solid_fraction:.4f}")
    p.validate()
    assert 0.60 <= p.solid_fraction <= 0.66


# ----------------------------------------------------------------------------- duplicates


@pytest.mark.parametrize(
    "d_bc, faces, corners, expected",
    [
        # x_min = r, x_max = 3r: with d_bc = 1.5 r one layer is near each plane
        (1.5, "all", True, 8 + 16 + 32),  # x: 4 + 4; y: all 16; z: all 32 -> 4^3 - 8
        (1.5, "half", True, 4 + 6 + 9),  # + side only: half of 8, 12, 18 -> 3^3 - 8
        (1.5, "all", False, 3 * 8),  # faces only
        (1.5, "half", False, 3 * 4),  # thesis §2.6: simple cubic with CLP, 12 copies
        (2.5, "all", True, 8 * 27 - 8),  # every particle near both planes of every axis
        (2.5, "half", True, 8 + 16 + 32),
        (0.5, "all", True, 56),  # the extreme layers are at distance 0 < d_bc
    ],
)
def test_duplicates_simple_cubic(d_bc, faces, corners, expected):
    p = simple_cubic(1.0)
    d = duplicate_particles(p, d_bc, faces=faces, corners=corners)
    assert d.num_copies == expected
    assert np.array_equal(d.centres, p.centres[d.original] + d.shift * p.cell)
    assert np.array_equal(d.radii, p.radii[d.original])
    assert np.abs(d.shift).max() == 1 and (np.abs(d.shift).sum(axis=1) > 0).all()
    if faces == "half":
        assert (d.shift >= 0).all()
    if not corners:
        assert (np.abs(d.shift).sum(axis=1) == 1).all()
    keys = np.column_stack([d.original, d.shift])
    assert np.unique(keys, axis=0).shape[0] == d.num_copies


@pytest.mark.parametrize("faces", ["all", "half"])
def test_duplicates_match_rule(jammed50, faces):
    """Copies = all (i, s != 0) with s_a = +1 if near min_a, -1 if near max_a (all), 0 otherwise."""
    p, d_bc = jammed50, 2.0 * R_MAX
    d = duplicate_particles(p, d_bc, faces=faces)
    lo, hi = p.centres.min(axis=0), p.centres.max(axis=0)
    expected = set()
    for i, c in enumerate(p.centres):
        choices = [
            [0]
            + ([1] if c[a] - lo[a] < d_bc else [])
            + ([-1] if faces == "all" and hi[a] - c[a] < d_bc else [])
            for a in range(3)
        ]
        expected |= {
            (i, *s) for s in np.array(np.meshgrid(*choices)).reshape(3, -1).T.tolist() if any(s)
        }
    got = {tuple(k) for k in np.column_stack([d.original, d.shift]).tolist()}
    assert got == expected and len(got) == d.num_copies
    assert np.allclose(d.centres, p.centres[d.original] + d.shift * p.cell, rtol=0, atol=1e-15)
    a = assembly_particles(p, d)
    n = p.num_particles
    assert a.centres.shape == (n + d.num_copies, 3) and a.radii.shape == (n + d.num_copies,)
    assert np.array_equal(a.original[:n], np.arange(n)) and not a.shift[:n].any()
    assert np.array_equal(a.centres[n:], d.centres) and np.array_equal(a.original[n:], d.original)
    assert np.allclose(a.centres, p.centres[a.original] + a.shift * p.cell, rtol=0, atol=1e-15)


def test_duplicates_errors():
    with pytest.raises(ValueError, match="faces must be 'all' or 'half'"):
        duplicate_particles(simple_cubic(), 1.5, faces="quarter")
    with pytest.raises(ValueError, match="d_bc must be > 0 mm"):
        duplicate_particles(simple_cubic(), -1.0)


# ---------------------------------------------------------------- periodic pairs of CLP copies


def realizations(allowed, original, shift, i, j, s):
    """Allowed body pairs standing for the periodic pair (i, j, s) (or (j, i, -s))."""
    p, q = np.nonzero(np.triu(allowed, 1))
    rel = shift[q] - shift[p]
    same = (original[p] == i) & (original[q] == j) & np.all(rel == s, axis=1)
    mirrored = (original[p] == j) & (original[q] == i) & np.all(rel == -np.asarray(s), axis=1)
    return int(np.count_nonzero(same | mirrored))


def test_every_periodic_neighbour_pair_is_realized_once_by_clp_copies(jammed50):
    """Random 50 spheres, half-face copies at d_bc = 2.5 r_max, neighbours at the spacing of rho
    0.95: every periodic pair in reach -- mixed-shift ones included, whose only realization is a
    pair of copies -- is allowed exactly once. (Forbidding every copy-copy pair, as before, left 8
    of the 232 pairs without a contact; d_bc = 1.8 r_max leaves one pair without copies.)"""
    from mpfem_fenicsx.meshes.packing import periodic_pair_realizations

    p = jammed50
    d = duplicate_particles(p, 2.5 * R_MAX, faces="half")
    a = assembly_particles(p, d)
    allowed = periodic_pair_realizations(a.original, a.shift)
    assert np.array_equal(allowed, allowed.T) and not allowed.diagonal().any()
    shrink = (p.solid_fraction / 0.95) ** (1.0 / 3.0)  # affine compaction to rho 0.95
    i, j, s, dist = _periodic_pairs(p.centres, p.radii, p.cell, 2 * p.radii.max() / shrink)
    near = dist * shrink < p.radii[i] + p.radii[j]
    mixed = near & np.any(s > 0, axis=1) & np.any(s < 0, axis=1)
    assert near.sum() > 100 and mixed.sum() > 0  # the case that copies on half of the faces miss
    counts = [
        realizations(allowed, a.original, a.shift, *k)
        for k in zip(i[near], j[near], s[near], strict=True)
    ]
    assert counts == [1] * int(near.sum())


# ------------------------------------------------------------------------------ DEM exports
# What DEM codes write: YADE's export.text (#format x_y_z_r, the cell in a header a
# script adds, or given), LAMMPS / LIGGGHTS dumps (box bounds, x y z radius among other columns).
YADE_HEADER = (
    "# dx dy dz (mm) = 0.827 0.827 0.827 ; solid_fraction = 0.02 ; N = 3\n"
    "0.1 0.2 0.3 0.08\n0.2595 0.2 0.3 0.08\n0.85 0.5 0.5 0.07\n"
)  # 3rd centre outside: wrapped
YADE_FORMAT = "#format x_y_z_r_matId\n0.1 0.2 0.3 0.08 1\n0.5 0.5 0.5 0.07 1\n"
LAMMPS_DUMP = """ITEM: TIMESTEP
0
ITEM: NUMBER OF ATOMS
1
ITEM: BOX BOUNDS pp pp pp
0 1
0 1
0 1
ITEM: ATOMS id type x y z radius
1 1 0.5 0.5 0.5 0.3
ITEM: TIMESTEP
5000
ITEM: NUMBER OF ATOMS
2
ITEM: BOX BOUNDS pp pp pp
-0.4 0.4
-0.4 0.4
-0.4 0.4
ITEM: ATOMS id type x y z vx vy vz diameter
1 1 0.0 0.0 0.0 0 0 0 0.2
2 1 0.35 -0.39 0.2 0 0 0 0.16
"""


def test_dem_exports_are_read_as_they_come(tmp_path):
    from mpfem_fenicsx.meshes.packing import packing_format

    yade = tmp_path / "yade.txt"
    yade.write_text(YADE_HEADER)
    p = read_packing(yade, validate=False)
    assert packing_format(yade) == "yade" and p.cell.tolist() == [0.827] * 3
    assert p.centres[2].tolist() == pytest.approx([0.85 - 0.827, 0.5, 0.5])  # wrapped into the cell
    # 0.1 % of a radius of contact overlap, as a DEM packing held under 10 kPa: removed by the run's
    # 0.99 reduction, refused without it
    assert p.max_overlap() == pytest.approx(0.0005 / 0.08)
    p.validate(radius_factor=0.99)
    with pytest.raises(ValueError, match="overlap of particles 0 and 1"):
        p.validate()
    formatted = tmp_path / "format.txt"
    formatted.write_text(YADE_FORMAT)
    with pytest.raises(ValueError, match="without its periodic cell.*--cell"):
        read_packing(formatted)
    q = read_packing(formatted, cell=(1, 1, 1), length_scale=2.0)  # e.g. a file in other units
    assert (
        q.cell.tolist() == [2, 2, 2]
        and q.radii.tolist() == [0.16, 0.14]
        and q.centres[1].tolist() == [1, 1, 1]
    )
    dump = tmp_path / "dump.liggghts"
    dump.write_text(LAMMPS_DUMP)
    d = read_packing(dump)  # the last snapshot, its box's lower corner as the origin, diameter / 2
    assert (
        packing_format(dump) == "lammps"
        and d.num_particles == 2
        and d.cell.tolist() == pytest.approx([0.8] * 3)
    )
    assert d.radii.tolist() == [0.1, 0.08]
    np.testing.assert_allclose(d.centres, [[0.4] * 3, [0.75, 0.01, 0.6]], atol=1e-12)
    tri = tmp_path / "tri.dump"
    tri.write_text(
        LAMMPS_DUMP.replace(
            "BOX BOUNDS pp pp pp\n-0.4 0.4\n-0.4 0.4\n-0.4 0.4",
            "BOX BOUNDS xy xz yz pp pp pp\n-0.4 0.4 0\n-0.4 0.4 0\n-0.4 0.4 0",
        )
    )
    with pytest.raises(ValueError, match="triclinic"):
        read_packing(tri)


def test_overlap_beyond_the_radius_reduction_is_refused():
    """A 3 % overlap is not a DEM contact: the 0.99 reduction (2 % of r_i + r_j) leaves it."""
    p = Packing([1, 1, 1], [[0.2, 0.2, 0.2], [0.394, 0.2, 0.2]], [0.1, 0.1])
    assert p.max_overlap() == pytest.approx(0.06)
    with pytest.raises(ValueError, match=r"after the radius reduction x0.99"):
        p.validate(radius_factor=0.99)


# ------------------------------------------------------------------------ admission for a run
# One rule for `mpfem pack --input`, `mpfem run --check` and the run (meshes.admission): the
# spheres through the particle meshes' nodes (1.0100 x the meshed radius for the default 6x6
# volume-exact particle) must not overlap at the start.
YADE_50 = Path(__file__).parent / "data" / "yade_50_overlapping.txt"
NODE_SCALE = 1.0100435833250068  # unit_ball_hex(6, 1).radius_scale, the default particle


def yade_50_recipe(overlap=0.0012):
    """How tests/data/yade_50_overlapping.txt was made: a generated 50-sphere packing whose radii
    grow until the largest overlap is ``overlap`` of the smaller radius (a DEM packing at rest
    under ~10 kPa), written as a YADE export.text with its cell in a '# dx dy dz =' header."""
    p = generate_packing(50, R_MIN, R_MAX, seed=1)
    lo, hi = 1.0, 1.01
    for _ in range(60):
        g = 0.5 * (lo + hi)
        lo, hi = (g, hi) if p.scaled(g).max_overlap() < overlap else (lo, g)
    return p.scaled(lo)


def test_the_yade_fixture_is_its_recipe():
    from mpfem_fenicsx.meshes.cubesphere import unit_ball_hex

    read, made = read_packing(YADE_50, validate=False), yade_50_recipe()
    np.testing.assert_allclose(read.cell, made.cell, rtol=1e-11)
    np.testing.assert_allclose(
        np.column_stack([read.centres, read.radii]),
        np.column_stack([made.centres, made.radii]),
        rtol=1e-11,
        atol=1e-12,
    )
    assert read.max_overlap() == pytest.approx(0.0012, rel=1e-6)
    # a fresh installation may move the particle mesh by a rounding
    assert unit_ball_hex(6, 1).radius_scale == pytest.approx(NODE_SCALE, rel=1e-13)


def test_admission_lowers_the_default_reduction_for_a_dem_export_and_says_so():
    """At the default 0.99 the fixture's contacts start 0.08 % interpenetrated (0.99 x 1.0100 x
    r_i + r_j > d_ij): the default is lowered to the 4-decimal factor that leaves a 1e-4 gap."""
    from mpfem_fenicsx.meshes.admission import START_GAP, admit_packing

    p = read_packing(YADE_50, validate=False)
    assert p.scaled(0.99 * NODE_SCALE).max_overlap() > 5e-4  # what the old rule let through
    a = admit_packing(p, 0.99, NODE_SCALE, target_density=0.92, automatic=True)
    assert a.automatic and a.radius_factor == 0.9895 and a.overlap == pytest.approx(0.0012)
    assert p.scaled(a.radius_factor * NODE_SCALE).max_overlap() == 0.0
    assert p.contact_ratio() / (a.radius_factor * NODE_SCALE) - 1 >= START_GAP
    assert a.rho0 == pytest.approx(p.solid_fraction * 0.9895**3, rel=1e-14)
    assert a.notes == (
        "radius reduction x0.9895 (instead of x0.99) for the packing's 0.12 % "
        "overlaps and the particle's nodes at 1.0100 x its radius",
    )


def test_admission_keeps_the_factor_that_works_and_refuses_one_too_large(jammed50):
    """A generated packing (no overlap) keeps 0.99 (its run is unchanged bit for bit: the same
    rho0 as V_p / V0 of the reduced radii); a factor that does not work is refused with the
    largest one that does, automatic or not, when the packing itself does not overlap."""
    from mpfem_fenicsx.meshes.admission import admit_packing

    from mpfem_fenicsx.homogenization import solid_volume

    a = admit_packing(jammed50, 0.99, NODE_SCALE, target_density=0.92, automatic=True)
    assert (a.radius_factor, a.automatic, a.notes) == (0.99, False, ())
    assert a.rho0 == solid_volume(jammed50.radii * 0.99) / float(np.prod(jammed50.cell))
    coarse = 1.0226902051510787  # the 4x4 particle's nodes
    with pytest.raises(ValueError, match=r"^radius_factor 0.99: .* 1.0227 x .* <= 0.9778, more"):
        admit_packing(jammed50, 0.99, coarse, automatic=True)
    assert admit_packing(jammed50, 0.9778, coarse).radius_factor == 0.9778
    dem = read_packing(YADE_50, validate=False)
    with pytest.raises(ValueError, match=r"radius_factor 0.995: .* <= 0.9896 \(or leave the"):
        admit_packing(dem, 0.995, NODE_SCALE)
    assert admit_packing(dem, 0.9896, NODE_SCALE).radius_factor == 0.9896  # the one it names


def test_admission_refuses_overlaps_beyond_a_dem_contact_and_unreachable_densities():
    from mpfem_fenicsx.meshes.admission import admit_packing

    centres = [[0.2, 0.2, 0.2], [0.394, 0.2, 0.2], [0.7, 0.7, 0.7]]
    p = Packing([1, 1, 1], centres, [0.1, 0.1, 0.1])  # 6 % overlap
    with pytest.raises(
        ValueError,
        match=r"^overlap of particles 0 and 1 \(image shift \[0, 0, 0\]"
        r"\): 6 % of the smaller radius, beyond the 2 % .* <= 0.9603",
    ):
        admit_packing(p, 0.99, NODE_SCALE, automatic=True)
    assert admit_packing(p, 0.96, NODE_SCALE).radius_factor == 0.96  # a user's: taken as given
    ok = read_packing(YADE_50, validate=False)
    with pytest.raises(ValueError, match=r"target_density = 0.6 is out of range: .* \(0.6133, 1\)"):
        admit_packing(ok, 0.99, NODE_SCALE, target_density=0.6, automatic=True)


def test_lengths_in_metres_get_a_one_line_warning(tmp_path):
    """A LAMMPS dump in metres read as millimetres: 0.8 um cell, 80 nm radii. Admitted (the rule
    is scale-free) with a warning that names the fix; none in millimetres."""
    from mpfem_fenicsx.meshes.admission import admit_packing, metres_warning

    dump = tmp_path / "dump.liggghts"
    dump.write_text(LAMMPS_DUMP)
    mm = read_packing(dump)
    assert metres_warning(mm) is None and admit_packing(mm, 0.99, NODE_SCALE).notes == ()
    metres = read_packing(dump, length_scale=1e-3)
    notes = admit_packing(metres, 0.99, NODE_SCALE).notes
    assert len(notes) == 1 and notes[0] == metres_warning(metres)
    assert notes[0].startswith(
        "WARNING: the packing's lengths look like metres (largest radius "
        "0.0001 mm, cell 0.0008 x 0.0008 x 0.0008 mm)"
    )
    assert "--length-scale 1000" in notes[0]
    assert metres_warning(Packing([1, 1, 1], [[0.5] * 3], [5e-4])) is not None  # r under 1 um


# --------------------------------------------------------------------------------------------
# Packings in a container (a die, a box): no periodic cell
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("shape, aspect", [("cylinder", 1.5), ("box", (1.0, 1.0, 2.0))])
def test_container_packing_fills_its_container_without_overlap(shape, aspect):
    from mpfem_fenicsx.meshes.container import generate_container_packing

    s = generate_container_packing(40, 0.08, 0.14, 3, 0.45, shape=shape, aspect=aspect)
    again = generate_container_packing(40, 0.08, 0.14, 3, 0.45, shape=shape, aspect=aspect)
    assert np.array_equal(s.centres, again.centres)  # seeded: the same packing
    assert s.solid_fraction == pytest.approx(0.45, rel=1e-6)
    assert s.max_overlap() == 0.0
    assert np.all(s.container.wall_gaps(s.centres, s.radii) >= 0.0)
    if shape == "cylinder":
        assert s.container.height / (2 * s.container.radius) == pytest.approx(1.5)
    else:
        L = np.asarray(s.container.lengths)
        assert np.allclose(L / L[0], aspect)
    # an independent check of the overlaps: all pairs by brute force
    d = np.linalg.norm(s.centres[:, None] - s.centres[None], axis=2)
    gap = d - (s.radii[:, None] + s.radii[None])
    assert gap[~np.eye(40, dtype=bool)].min() >= 0.0


def test_jammed_container_packing_is_denser_than_a_requested_loose_one():
    from mpfem_fenicsx.meshes.container import generate_container_packing

    jammed = generate_container_packing(40, 0.08, 0.14, 3, None)
    assert 0.45 < jammed.solid_fraction < 0.6
    with pytest.raises(ValueError, match="unreachable"):
        generate_container_packing(40, 0.08, 0.14, 3, min(0.6, jammed.solid_fraction + 0.05))


def test_spheres_without_a_cell_round_trip(tmp_path):
    from mpfem_fenicsx.meshes.container import Spheres, read_spheres, write_spheres

    s = Spheres(np.array([[0.0, 0.0, 0.0], [0.5, 0.1, -0.2]]), np.array([0.2, 0.25]))
    write_spheres(s, tmp_path / "s.txt")
    back = read_spheres(tmp_path / "s.txt", length_scale=2.0)
    assert np.allclose(back.centres, 2 * s.centres) and np.allclose(back.radii, 2 * s.radii)
    # a periodic packing file is refused: it has a cell line
    (tmp_path / "p.txt").write_text("1 1 1\n0.5 0.5 0.5 0.1\n")
    with pytest.raises(ValueError, match="periodic packing file"):
        read_spheres(tmp_path / "p.txt")


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(target_fraction=0.7), "target_fraction"),
        (dict(shape="sphere"), "shape"),
        (dict(aspect=-1.0), "aspect"),
        (dict(r_max=0.01), "r_max"),
    ],
)
def test_container_packing_refuses_bad_input(kwargs, message):
    from mpfem_fenicsx.meshes.container import generate_container_packing

    args = dict(n=10, r_min=0.08, r_max=0.14, seed=0, target_fraction=0.3) | kwargs
    with pytest.raises(ValueError, match=message):
        generate_container_packing(**args)
