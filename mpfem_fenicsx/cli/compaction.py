"""Command line of the compaction demos (``demos/isotropic.py``, ``demos/die.py``)."""

from __future__ import annotations

import argparse
from contextlib import contextmanager
from functools import partial

from mpi4py import MPI

from ..io.progress import Progress
from ..solvers import solver_kind
from ..workflows.compaction import CompactionCase, CompactionRun, RunFailure
from .casefile import add_schema_option
from .exits import BAD_INPUT, RUN_FAILED, bad_input_exits, fail


def parser(loading: str, doc: str) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    option = partial(add_schema_option, p)  # type, default, range, unit and help from the case-file schema
    option("packing", "particles")
    option("loading", "target_density")
    option("boundary", "condition", "--bc")
    realization = p.add_mutually_exclusive_group()
    realization.add_argument("--images", dest="images", action="store_const", const=True, default=None,
                             help="CLP by contact with periodic images (the default for CLP)")
    realization.add_argument("--copies", dest="images", action="store_const", const=False,
                             help="CLP by copies tied to their originals (thesis eq. 2.14)")
    option("solver", "kind", "--solver")
    p.add_argument("--packing", default=None, help="packing file (ours: header dx dy dz, then x y z r lines; "
                   "YADE export.text, LAMMPS / LIGGGHTS dumps)")
    option("packing", "fraction", "--packing-fraction")
    option("packing", "seed")
    option("boundary", "d_bc")
    option("contact", "gamma")
    option("contact", "friction")
    option("solver", "increments")
    option("loading", "profile")
    option("solver", "steps")
    option("mesh", "resolution", "--mesh")
    option("mesh", "refinement")
    option("output", "outputs")
    p.add_argument("--no-visual", action="store_true", help="skip ParaView output and the PNG")
    option("output", "checkpoint_every")
    p.add_argument("--restart", default=None, metavar="CHECKPOINT",
                   help="continue from a checkpoint (directory, or a results folder: its newest one)")
    p.add_argument("--out", default=f"results/{loading}")
    return p


def case_from_args(args: argparse.Namespace, loading: str) -> CompactionCase:
    """The compaction case of parsed :func:`parser` arguments (exits 2 with a one-line error on bad input)."""
    with bad_input_exits():
        return CompactionCase(particles=args.particles, target_density=args.target_density, loading=loading,
                              bc=args.bc, images=args.images, solver=args.solver, seed=args.seed,
                              packing_file=args.packing, packing_fraction=args.packing_fraction, d_bc=args.d_bc,
                              gamma=args.gamma, friction=args.friction, increments=args.increments, steps=args.steps,
                              profile=args.profile,
                              mesh=args.mesh, refinement=args.refinement, outputs=args.outputs, visual=not args.no_visual,
                              checkpoint_every=args.checkpoint_every, out_dir=args.out)


@contextmanager
def run_exits():
    """Inside the block: bad input found while building the model (a packing file, an
    unreachable density...) exits 2, a diverging run exits 3 (its history and last checkpoint
    kept), each with one line."""
    try:
        yield
    except RunFailure as err:
        fail(RUN_FAILED, str(err))
    except (ValueError, OSError) as err:
        fail(BAD_INPUT, str(err))


def report(result, args: argparse.Namespace, say=print) -> None:
    """The end state of a compaction run and where its outputs are."""
    h = result.history
    say(f"done: rho = {h.column('rho')[-1]:.4f} (imposed {h.column('rho_imposed')[-1]:.4f}), "
        f"sigma_m = {h.column('sigma_m')[-1]:.3f} MPa, sigma_d = {h.column('sigma_d')[-1]:.3f} MPa, "
        f"{round(h.column('n_contacts')[-1])} contacts (Z {h.column('Z')[-1]:.2f}); "
        f"{result.num_particles_model} particles in the model, {result.num_dofs} dofs, {result.increments} "
        f"{solver_kind(args.solver).increment_word}, wall {result.wall_time:.0f} s")
    say(f"outputs in {result.out_dir}/: history.csv, packing.txt"
        + ("" if not args.checkpoint_every else ", checkpoints/")
        + ("" if args.no_visual else ", particles.xdmf (ParaView), particles.png, loading_path.png"))


def main(loading: str, doc: str, argv=None) -> None:
    """The compaction demos' steps (``demos/isotropic.py`` spells them out)."""
    args = parser(loading, doc).parse_args(argv)
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    case = case_from_args(args, loading)
    with run_exits():
        result = CompactionRun(case, comm, say, restart=args.restart, progress=Progress(comm)).run()
    report(result, args, say)
