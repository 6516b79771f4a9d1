"""Cost of a granular compaction step, split by phase.

    python bench/compaction.py                                   # 50 particles, CLP, 200 increments
    python bench/compaction.py --particles 50 --bc GDF --steps 200
    python bench/compaction.py --particles 50 --bc CLP --full    # the whole run to --target-density
    mpirun -n 2 python bench/compaction.py --particles 350 --bc GDF

Short mode (default): the compaction of the reference case (isotropic, lead, thesis table 2.1,
explicit with the increment of a full ``--increments`` run) is built, then ``--steps`` increments
are timed from a state already in contact (``--warmup`` increments first, not timed), so the
figure is the cost per step of the contact-rich part of a run. Full mode: the whole run.

Prints one JSON object: case, dofs, particles in the model, nodes per particle, steps, wall_s
(timed part), s_per_step, us_per_dof_step, phases (s, the largest over ranks, and per rank:
material, assembly, contact_search, contact_forces, contact_halo, constraints, update; plus
setup), their shares, peak resident memory (MB, max and sum over ranks), rho reached and the
number of ranks.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import tempfile
import time

import numpy as np
from mpfem_fenicsx.meshes.cubesphere import RESOLUTIONS, unit_ball_hex
from mpi4py import MPI

import mpfem_fenicsx  # noqa: F401  (mpi4py before dolfinx)
from mpfem_fenicsx.boundary import KINDS
from mpfem_fenicsx.case import CompactionCase, MeshSection, SolverSection
from mpfem_fenicsx.solvers.constraint_mass import CONSTRAINT_MASSES
from mpfem_fenicsx.workflows.compaction import CompactionRun, run_compaction


def main(argv=None) -> dict:
    """Time one compaction (short or --full) and return its timings, phases and memory."""
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--particles", type=int, default=50)
    p.add_argument("--bc", choices=KINDS, default="CLP")
    p.add_argument(
        "--solver",
        choices=("explicit",),
        default="explicit",
        help="explicit (the implicit granular solver is experimental)",
    )
    p.add_argument("--steps", type=int, default=200, help="timed increments (short mode)")
    p.add_argument(
        "--warmup",
        type=int,
        default=None,
        help="untimed increments before (default: 55 %% of --increments, contacts established)",
    )
    p.add_argument(
        "--increments", type=int, default=4000, help="increments of the whole run (sets dt)"
    )
    p.add_argument("--full", action="store_true", help="time the whole run to --target-density")
    p.add_argument(
        "--copies",
        action="store_true",
        help="CLP by copies tied to their originals (the default, since 2026-11-24: periodic "
        "images)",
    )
    p.add_argument(
        "--mesh",
        choices=tuple(RESOLUTIONS),
        default=MeshSection.resolution,
        help="named cube-sphere resolution (chapter2: 561 nodes per particle, the default; "
        "chapter4: 1 933; coarse: 517, the default before 2026-11-24)",
    )
    p.add_argument(
        "--radius-factor",
        type=float,
        default=MeshSection.radius_factor,
        help="[mesh] radius_factor (the coarse volume-exact particle needs <= 0.9778)",
    )
    p.add_argument(
        "--constraint-mass",
        choices=CONSTRAINT_MASSES,
        default=SolverSection.constraint_mass,
        help="explicit reduced mass of the constrained model ([solver] constraint_mass)",
    )
    p.add_argument("--target-density", type=float, default=0.95)
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args(argv)
    for name, value, low in (
        ("--particles", args.particles, 1),
        ("--steps", args.steps, 1),
        ("--increments", args.increments, 2),
    ):
        if value < low:
            p.error(f"{name} = {value} must be >= {low}")
    if args.warmup is not None and not 0 <= args.warmup < args.increments:
        p.error(f"--warmup = {args.warmup} must be in [0, --increments = {args.increments})")
    comm = MPI.COMM_WORLD

    nodes = unit_ball_hex(*RESOLUTIONS[args.mesh]).num_nodes
    out = tempfile.mkdtemp(prefix="mpfem-bench-") if comm.rank == 0 else None
    out = comm.bcast(out)
    base = dict(
        particles=args.particles,
        condition=args.bc,
        kind=args.solver,
        seed=args.seed,
        target_density=args.target_density,
        increments=args.increments,
        resolution=args.mesh,
        radius_factor=args.radius_factor,
        images=False if args.copies else None,
        constraint_mass=args.constraint_mass,
        visual=False,
        checkpoint_every=0,
        directory=out,
    )
    quiet = lambda *a, **k: None  # noqa: E731
    warmup = (
        0 if args.full else (int(0.55 * args.increments) if args.warmup is None else args.warmup)
    )
    start = time.perf_counter()
    marks = {}  # contact exchange counters at the start of the timed part
    if args.full:
        case = CompactionCase.build(**base, outputs=40)
        res = run_compaction(case, comm, log=quiet)
        timed_steps = res.solver.step
        solver = res.solver
        phases = dict(solver.timings)
        wall = time.perf_counter() - start
        setup = wall - sum(phases.values())
    else:
        # build + warm-up to the contact-rich state, then the timed increments (outputs: none in
        # between, one at the end to include the homogenization's cost once)
        every = max(
            1, args.increments // 40
        )  # 40 outputs: rho and contacts known at the end of the warm-up
        warmup = max(every, warmup // every * every)
        case = CompactionCase.build(**base, outputs=40)
        res = CompactionRun(case, comm, log=quiet).run(max_steps=warmup)
        solver = res.solver
        setup = time.perf_counter() - start
        before = dict(solver.timings)
        marks = _contact_counters(res.model.contact)
        comm.Barrier()
        t0 = time.perf_counter()
        step0 = solver.step
        solver.run(None, max_steps=args.steps)
        comm.Barrier()
        wall = time.perf_counter() - t0
        timed_steps = solver.step - step0
        phases = {k: v - before.get(k, 0.0) for k, v in solver.timings.items()}
        phases.pop("output", None)
    per_rank = {k: [round(x, 4) for x in comm.allgather(v)] for k, v in sorted(phases.items())}
    phases = {k: max(v) for k, v in per_rank.items()}
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # MB (Linux: KB)
    rho = float(res.history.column("rho")[-1]) if res.history.rows else float("nan")
    result = {
        "case": f"{args.particles} particles, {args.bc}{' (copies)' if args.copies else ''}, "
        f"isotropic, {args.solver}",
        "mode": "full" if args.full else "short",
        "ranks": comm.size,
        "particles_in_model": res.num_particles_model,
        "mesh": args.mesh,
        "nodes_per_particle": nodes,
        "dofs": res.num_dofs,
        "free_dofs": res.model.bcs.constraint.num_reduced_global,
        "increments_of_run": args.increments,
        "steps": timed_steps,
        "wall_s": round(wall, 3),
        "setup_s": round(setup, 3),
        "s_per_step": wall / max(timed_steps, 1),
        "us_per_dof_step": 1e6 * wall / max(timed_steps, 1) / res.num_dofs,
        "phases_s": {k: round(v, 4) for k, v in sorted(phases.items())},
        "phase_share": {k: round(v / wall, 4) for k, v in sorted(phases.items())},
        "phases_s_per_rank": per_rank,
        "peak_rss_mb_max": round(comm.allreduce(rss, op=MPI.MAX), 1),
        "peak_rss_mb_sum": round(comm.allreduce(rss, op=MPI.SUM), 1),
        "rho": rho,
        "peak_rss_mb_per_rank": [round(v, 1) for v in comm.allgather(rss)],
        "contact": _contact_report(res.model, marks, timed_steps, comm),
    }
    if comm.rank == 0:
        print(json.dumps(result))
        sys.stdout.flush()
    return result


def _contact_counters(contact) -> dict:
    """The contact model's running counters: bytes received, gathers, pairs, halo builds."""
    s = contact.surface
    return {
        **{f"bytes_{k}": v for k, v in s.bytes_received.items()},
        "gathers": s.gathers,
        "pairs": contact.search.pairs_examined,
        "builds": contact.halo_builds,
    }


def _neighbours(blocks, local_range, comm) -> int:
    """Number of other ranks owning held surface nodes (the sources of the displacement
    exchange); the ranges of all ranks are P pairs of integers."""
    starts = np.array([r[0] for r in comm.allgather(tuple(local_range))])
    owners = np.searchsorted(starts, blocks, side="right") - 1
    return int(np.count_nonzero(np.unique(owners) != comm.rank))


def _contact_report(model, marks: dict, steps: int, comm) -> dict:
    """Per rank (lists in rank order): the contact surface it holds and treats, next to the whole
    model's, and what it received per timed step; the mesh's ghost dofs (the halo of the bulk)."""
    contact = model.contact
    s = contact.surface
    now = _contact_counters(contact)
    delta = {k: v - marks.get(k, 0) for k, v in now.items()}
    own_bodies = s.slave_bodies
    ghost = ~np.isin(s.facet_body, own_bodies)
    rank = {
        "owned_surface_nodes": int(s.num_owned),
        "held_surface_nodes": int(s.num_nodes),
        "held_facets": int(s.facets.shape[0]),
        "ghost_facets": int(ghost.sum()),
        "held_bodies": int(s.bodies.size),
        "slave_bodies": int(own_bodies.size),
        "pairs_per_step": delta["pairs"] / max(steps, 1),
        "halo_builds": delta["builds"],
        "bytes_halo_per_step": delta["bytes_halo"] / max(steps, 1),
        "bytes_displacement_per_step": delta["bytes_displacement"] / max(steps, 1),
        "bytes_setup": now["bytes_setup"],
        "ghost_dofs": int(model.problem.V.dofmap.index_map.num_ghosts * 3),
        "neighbours": _neighbours(s.blocks, s.V.dofmap.index_map.local_range, comm),
    }
    rows = comm.allgather(rank)
    total_nodes = sum(r["owned_surface_nodes"] for r in rows)
    total_facets = comm.allreduce(int((~ghost & np.isin(s.facet_body, own_bodies)).sum()))
    total_pairs = sum(r["pairs_per_step"] for r in rows)
    out = {k: [r[k] for r in rows] for k in rank}
    out["surface_nodes_model"] = total_nodes
    # facets of bodies cut by the partition are counted by each rank treating them
    out["surface_facets_model_upper"] = total_facets
    out["held_node_share"] = [round(r["held_surface_nodes"] / total_nodes, 4) for r in rows]
    # the surface a rank holds as slave and master: its owned nodes' share of the model's nodes
    # + its ghost facets' share of the model's facets
    out["held_surface_share"] = [
        round(r["owned_surface_nodes"] / total_nodes + r["ghost_facets"] / total_facets, 4)
        for r in rows
    ]
    out["pairs_share"] = [
        round(r["pairs_per_step"] / total_pairs, 4) if total_pairs else 0.0 for r in rows
    ]
    return out


if __name__ == "__main__":
    main()
