"""Rank-local contact: a rank holds its particles and their neighbours, never the whole surface.

A row of particles pressed together along x is split over 3 ranks by the particle partition
(whole particles, compact regions): the end ranks do not touch each other, so each must receive
only the facets of the particles next to its own, hold only the part of them within reach, and
the contact forces must be those of the serial run.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mpfem_fenicsx.meshes.partition import coordinate_bisection

from mpfem_fenicsx.contact.search import boxes_hold_a_point

MPIRUN = Path(sys.executable).parent / "mpirun"

ROW_RUN = """
import json, sys
import numpy as np
from mpi4py import MPI
import dolfinx
from mpfem_fenicsx.contact import ContactLaw, ContactModel
from mpfem_fenicsx.contact.search import corner_normals
from mpfem_fenicsx.contact.surface import ROW_BYTES
from mpfem_fenicsx.meshes import particle_mesh

comm = MPI.COMM_WORLD
n = 9
spacing, press = (float(a) for a in sys.argv[3:5]) if len(sys.argv) > 4 else (0.98, 0.01)
rigid = len(sys.argv) > 5 and sys.argv[5] == "rigid"
k = np.arange(n)
centres = np.column_stack([spacing * k, 0.08 * np.sin(k), 0.06 * np.cos(1.3 * k)])
assembly = particle_mesh(centres, np.full(n, 0.5), comm)
V = dolfinx.fem.functionspace(assembly.mesh, ("Lagrange", 1, (3,)))
law = ContactLaw(penalty=1e4, friction=0.3)
skin = float(sys.argv[2]) if len(sys.argv) > 2 and sys.argv[2] != "-" else None
contact = ContactModel(V, assembly.facet_tags, n, law, search_distance=0.05, skin=skin)
u = dolfinx.fem.Function(V)
x = V.tabulate_dof_coordinates()
# press the row together: a uniform strain, or moving the particles rigidly towards the middle
near = np.linalg.norm(x[:, None] - centres[None], axis=2).argmin(axis=1)
moved = (centres[near] if rigid else x) - centres.mean(axis=0)
u.x.array[:] = (-press * moved).ravel()
contact.evaluate(u)
s = contact.surface
owned_cells = assembly.mesh.topology.index_map(3).size_local
own = np.unique(assembly.cell_tags.values[:owned_cells])
ghost = np.setdiff1d(s.bodies, own)
rows = {
    "rank": comm.rank,
    "own": own.tolist(),
    "held": s.bodies.tolist(),
    "ghost_facets": int(np.isin(s.facet_body, ghost).sum()),
    "held_facets": int(s.facets.shape[0]),
    "halo_bytes": s.bytes_received["halo"],
    "displacement_bytes": s.bytes_received["displacement"],
    "gathers": s.gathers,
    "builds": contact.halo_builds,
    "pairs": contact.search.pairs_examined,
}
facets = comm.allreduce(int(np.sum(s.facet_body[np.isin(s.facet_body, own)] >= 0)))
forces = contact.body_forces()
count = contact.count()

# the ring: hold of each neighbour only the facet nearest this rank's particles; its corner
# normals must be those of the whole particle (they average the facets around each vertex)
target = s.X[s.owned_nodes].mean(axis=0)
def nearest(xf, body):
    d = np.linalg.norm(xf.mean(axis=1) - target, axis=1)
    return np.array([d[i] == d[body == body[i]].min() for i in range(len(body))])
def corners(ghost_only):
    x = s.X + s.gather(u)
    cn = corner_normals(x, s)
    centroid = x[s.facets].mean(axis=1)
    rows = {}
    for b in ghost:
        f = np.flatnonzero(s.facet_body == b)
        f = f[np.argmin(np.linalg.norm(centroid[f] - target, axis=1))]
        rows[tuple(s.blocks[s.facets[f]])] = cn[f]
    return rows, int(np.isin(s.facet_body, ghost).sum())
s.hold(ghost)
whole, _ = corners(ghost)
s.hold(ghost, u.x.array[: s.num_owned_values], select=nearest)
part, ring_facets = corners(ghost)
ring_error = max([np.abs(part[k] - whole[k]).max() for k in part], default=0.0)
rows["ring_error"] = float(ring_error) if part.keys() == whole.keys() else 1.0
rows["ring_facets"] = ring_facets
gathered = comm.gather(rows)
if comm.rank == 0:
    out = {"ranks": gathered, "surface_facets": facets, "row_bytes": ROW_BYTES,
           "body_forces": forces.tolist(), "count": count}
    json.dump(out, open(sys.argv[1], "w"))
"""


def _row(tmp_path: Path, ranks: int, skin: float | None = None, approach=None) -> dict:
    """The row on ``ranks`` ranks (``approach``: (spacing, press, "strain" or "rigid") instead of
    the default (0.98, 0.01, "strain"); particles of radius 0.5 mm)."""
    script = tmp_path / "row.py"
    script.write_text(ROW_RUN)
    out = tmp_path / f"row{ranks}_{skin}_{approach}.json"
    cmd = [str(MPIRUN), "-n", str(ranks), sys.executable, str(script), str(out)]
    cmd += ["-" if skin is None else str(skin)] + (
        [] if approach is None else list(map(str, approach))
    )
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    return json.loads(out.read_text())


@pytest.mark.mpi
def test_each_rank_holds_and_receives_only_its_neighbours_halo(tmp_path):
    serial, three = _row(tmp_path, 1), _row(tmp_path, 3)
    ranks = three["ranks"]
    # the partition: whole particles, three compact groups of three along the row
    assert [r["own"] for r in ranks] == [[0, 1, 2], [3, 4, 5], [6, 7, 8]]
    # held: own particles and the next particle on each side, nothing of the far rank
    assert [r["held"] for r in ranks] == [[0, 1, 2, 3], [2, 3, 4, 5, 6], [5, 6, 7, 8]]
    total = three["surface_facets"]
    assert total == serial["surface_facets"]
    row = three["row_bytes"]
    per_particle = total // 9
    for r in ranks:
        assert r["held_facets"] < 0.45 * total
        # held of a neighbour: the facets within reach of this rank's and their ring, about a
        # quarter of the particle
        whole = (len(r["held"]) - len(r["own"])) * per_particle
        assert 0 < r["ghost_facets"] < 0.35 * whole
        # the halo received at each build: the neighbours' facets (whole, from their home),
        # their nodes' displacements for the selection (~ one node per facet) and the few body
        # ids asked for; far below the whole surface
        halo = r["halo_bytes"] / r["builds"]
        assert whole * row <= halo <= whole * (row + 1.1 * 3 * 8) + 1000
        assert halo < total * row / 3
        # displacements: the held ghost facets' nodes only (a patch: a few more nodes than facets)
        assert 0 < r["displacement_bytes"] / r["gathers"] < r["ghost_facets"] * 3 * 8 * 1.4
        # broad phase: only this rank's slave particles against their neighbours
        assert r["pairs"] < 0.6 * serial["ranks"][0]["pairs"]
    assert serial["ranks"][0]["held"] == list(range(9))
    # the same contact forces as the serial run (8 contacts, both directions)
    assert three["count"] == serial["count"] > 0
    f1, f3 = np.array(serial["body_forces"]), np.array(three["body_forces"])
    assert np.abs(f1[np.arange(8), np.arange(1, 9), 0]).min() > 0
    assert np.abs(f3 - f1).max() <= 1e-12 * np.abs(f1).max()
    # a uniform strain moves the held set with the flow: no rebuild, though the ends move by
    # 0.045 mm (2 x 0.045 mm exceeds the 0.05 mm skin) ...
    assert [r["builds"] for r in ranks] == [1, 1, 1]
    # ... until the strain times (reach + facet side, 0.06 + 0.14 mm) exceeds the skin (0.01 mm)
    for press, builds in ((0.045, 1), (0.055, 2)):
        strained = _row(tmp_path, 3, skin=0.01, approach=(0.98, press, "strain"))
        assert [r["builds"] for r in strained["ranks"]] == [builds] * 3
    for r in ranks:  # each neighbour's nearest facet held with its ring (3 x 3 facets)
        assert r["ring_error"] <= 1e-12
        assert r["ring_facets"] == 9 * (len(r["held"]) - len(r["own"]))
    # particles apart at the build (gaps of 0.2 mm) pressed into contact within the skin: no
    # rebuild, so the facets held must be those that the motion brings within reach
    apart = [_row(tmp_path, ranks, skin=3.2, approach=(1.2, 0.19, "rigid")) for ranks in (1, 3)]
    assert [r["builds"] for r in apart[1]["ranks"]] == [1, 1, 1]
    assert apart[1]["count"] == apart[0]["count"] > 0
    g1, g3 = np.array(apart[0]["body_forces"]), np.array(apart[1]["body_forces"])
    assert np.abs(g3 - g1).max() <= 1e-12 * np.abs(g1).max()
    # a skin far below the facet size: the held facets end where the contacts' corner normals
    # need their neighbours (the ring); the forces are still the serial ones
    thin = _row(tmp_path, 3, skin=1e-3)
    # one rank holds the whole surface: it never rebuilds (here 3 ranks do)
    assert _row(tmp_path, 1, skin=1e-3)["ranks"][0]["builds"] == 1
    assert [r["builds"] for r in thin["ranks"]] == [2, 2, 2]
    assert thin["count"] == serial["count"]
    assert sum(r["ghost_facets"] for r in thin["ranks"]) < sum(r["ghost_facets"] for r in ranks)
    assert np.abs(np.array(thin["body_forces"]) - f1).max() <= 1e-12 * np.abs(f1).max()


def test_coordinate_bisection_balances_weight_in_compact_groups():
    rng = np.random.default_rng(3)
    points = rng.uniform(0, 10, (1000, 3))
    weights = np.where(rng.uniform(size=1000) < 0.2, 0.3, 1.0)  # some light copies
    for nparts in (1, 2, 3, 4, 7):
        part = coordinate_bisection(points, weights, nparts)
        load = np.bincount(part, weights=weights, minlength=nparts)
        assert set(np.unique(part)) == set(range(nparts))
        # balanced by weight (not by count) within one particle's weight
        assert load.max() - load.min() <= 1.0
        # compact: no group is a slab (4 slabs of the cube would have an aspect ratio of 4)
        for k in range(nparts):
            extent = np.ptp(points[part == k], axis=0)
            assert extent.max() / extent.min() <= 3.5
    # deterministic: the same input gives the same parts
    assert np.array_equal(
        coordinate_bisection(points, weights, 4), coordinate_bisection(points, weights, 4)
    )
    with pytest.raises(ValueError, match="weights must be > 0"):
        coordinate_bisection(points, np.zeros(1000), 2)


def test_boxes_hold_a_point_agrees_with_brute_force():
    """The held facets' selection kernel (a grid of cells) against testing every point."""
    rng = np.random.default_rng(5)
    points = rng.uniform(0, 10, (3000, 3))
    centre = rng.uniform(-1, 11, (2000, 3))
    half = rng.uniform(0.05, 1.0, (2000, 3))
    lo, hi = centre - half, centre + half
    lo[:3], hi[:3] = points[:3], points[:3]  # degenerate boxes on a point: bounds included
    got = boxes_hold_a_point(lo, hi, points)
    inside = (points[None] >= lo[:, None]) & (points[None] <= hi[:, None])
    assert np.array_equal(got, inside.all(axis=2).any(axis=1))
    assert 0.1 < got.mean() < 0.9 and got[:3].all()
    assert not boxes_hold_a_point(lo, hi, points[:0]).any()
