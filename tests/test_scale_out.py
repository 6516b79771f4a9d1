"""Rank-local contact: a rank holds its particles and their neighbours, never the whole surface.

A row of particles pressed together along x is split over 3 ranks by the particle partition
(whole particles, compact regions): the end ranks do not touch each other, so each must receive
only the facets of the particles next to its own, and the contact forces must be those of the
serial run.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mpfem_fenicsx.meshes.partition import coordinate_bisection

MPIRUN = Path(sys.executable).parent / "mpirun"

ROW_RUN = """
import json, sys
import numpy as np
from mpi4py import MPI
import dolfinx
from mpfem_fenicsx.contact import ContactLaw, ContactModel
from mpfem_fenicsx.contact.surface import ROW_BYTES
from mpfem_fenicsx.meshes import particle_mesh

comm = MPI.COMM_WORLD
n = 9
centres = np.column_stack([0.98 * np.arange(n), 0.01 * np.sin(np.arange(n)), np.zeros(n)])
assembly = particle_mesh(centres, np.full(n, 0.5), comm)
V = dolfinx.fem.functionspace(assembly.mesh, ("Lagrange", 1, (3,)))
law = ContactLaw(penalty=1e4, friction=0.3)
contact = ContactModel(V, assembly.facet_tags, n, law, search_distance=0.05)
u = dolfinx.fem.Function(V)
x = V.tabulate_dof_coordinates()
u.x.array[:] = (-0.01 * (x - centres.mean(axis=0))).ravel()  # press the row together
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
gathered = comm.gather(rows)
facets = comm.allreduce(int(np.sum(s.facet_body[np.isin(s.facet_body, own)] >= 0)))
forces = contact.body_forces()
count = contact.count()
if comm.rank == 0:
    out = {"ranks": gathered, "surface_facets": facets, "row_bytes": ROW_BYTES,
           "body_forces": forces.tolist(), "count": count}
    json.dump(out, open(sys.argv[1], "w"))
"""


def _row(tmp_path: Path, ranks: int) -> dict:
    script = tmp_path / "row.py"
    script.write_text(ROW_RUN)
    out = tmp_path / f"row{ranks}.json"
    cmd = [str(MPIRUN), "-n", str(ranks), sys.executable, str(script), str(out)]
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
    for r in ranks:
        assert r["held_facets"] < 0.6 * total
        # the halo received: the ghost particles' facets (and the few body ids asked for), far
        # below the whole surface
        halo = r["halo_bytes"] / r["builds"]
        assert r["ghost_facets"] * row <= halo <= r["ghost_facets"] * row + 1000
        assert halo < total * row / 3 + r["ghost_facets"] * row
        # displacements: the ghost particles' surface nodes only (about one per facet)
        assert 0 < r["displacement_bytes"] / r["gathers"] < r["ghost_facets"] * 3 * 8 * 1.2
        # broad phase: only this rank's slave particles against their neighbours
        assert r["pairs"] < 0.6 * serial["ranks"][0]["pairs"]
    assert serial["ranks"][0]["held"] == list(range(9))
    # the same contact forces as the serial run (8 contacts, both directions)
    assert three["count"] == serial["count"] > 0
    f1, f3 = np.array(serial["body_forces"]), np.array(three["body_forces"])
    assert np.abs(f1[np.arange(8), np.arange(1, 9), 0]).min() > 0
    assert np.abs(f3 - f1).max() <= 1e-12 * np.abs(f1).max()


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
