"""Command-line options of the demos and of ``mpfem``, from declared parameters: type, default,
choices, meaning, unit and allowed range come from a :class:`~mpfem_fenicsx.parameters.Range` (a
case section's :func:`~mpfem_fenicsx.parameters.parameter` declaration), and a refused value
exits 2 with one line naming the option, like a refused case file (argparse's own errors print
the usage too).

The compaction demos (``demos/isotropic.py``, ``demos/die.py``) share one set of options:
:func:`compaction_parser` declares them, :func:`compaction_case` turns them into a
:class:`~mpfem_fenicsx.case.CompactionCase`, :func:`report_compaction` prints the end state.
"""

from __future__ import annotations

import argparse
from contextlib import contextmanager
from functools import partial
from typing import Any

from .case import (
    SECTIONS,
    BoundarySection,
    CompactionCase,
    ContactSection,
    LoadingSection,
    MeshSection,
    OutputSection,
    PackingSection,
    SolverSection,
)
from .exits import BAD_INPUT, RUN_FAILED, bad_input_exits, fail
from .parameters import Range, parameter_default, parameter_range


def add_range_option(
    parser, flag: str, name: str, allowed: Range, default: Any, help: str | None = None
) -> None:
    """The option ``flag`` of ``parser``, parsed as ``allowed.kind`` and checked by ``allowed``;
    ``help`` is prepended to the range's meaning."""
    if allowed.kind is bool:
        raise ValueError(f"{name} is a switch: give the demo its own --{name} / --no-{name}")

    def value(text: str):
        try:
            parsed = {int: int, float: float, str: str}[allowed.kind](text)
        except ValueError:
            fail(
                BAD_INPUT,
                f"argument {flag}: {text!r} is not "
                f"{'an integer' if allowed.kind is int else 'a number'}",
                parser.prog,
            )
        why = allowed.problem(parsed)
        if why is not None:
            fail(BAD_INPUT, f"argument {flag}: {flag} = {parsed!r} {why}", parser.prog)
        return parsed

    meaning = (allowed.doc if help is None else f"{help}; {allowed.doc}").replace(
        "%", "%%"
    )  # argparse formats help
    extent = "" if allowed.choices else f"; {allowed.allowed()}"
    parser.add_argument(
        flag,
        type=value,
        default=default,
        choices=allowed.choices,
        metavar=None if allowed.choices else name.upper(),
        help=f"{meaning}{extent} (default: %(default)s)",
    )


def add_parameter_option(
    parser,
    cls: type,
    name: str,
    flag: str | None = None,
    default: Any = "field",
    help: str | None = None,
) -> None:
    """The option of the dataclass field ``cls.name`` declared with ``parameter()`` (``flag``:
    default ``--name`` with dashes; ``default``: another default than the field's)."""
    add_range_option(
        parser,
        flag or "--" + name.replace("_", "-"),
        name,
        parameter_range(cls, name),
        parameter_default(cls, name) if default == "field" else default,
        help,
    )


def add_case_option(
    parser,
    section: str,
    name: str,
    flag: str | None = None,
    default: Any = "field",
    help: str | None = None,
) -> None:
    """The option of the case-file key ``[section] name`` (a field of the case's ``section``:
    its type, default, choices and help); ``flag``: default ``--name`` with dashes."""
    add_parameter_option(parser, SECTIONS[section], name, flag, default, help)


def compaction_parser(loading: str, doc: str) -> argparse.ArgumentParser:
    """The options of the compaction demos (``loading``: "isotropic" or "die"; ``doc``: the
    demo's description)."""
    p = argparse.ArgumentParser(
        description=doc, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    option = partial(
        add_case_option, p
    )  # type, default, range, unit and help from the declarations
    option("packing", "particles")
    option("loading", "target_density")
    option("boundary", "condition", "--bc")
    realization = p.add_mutually_exclusive_group()
    realization.add_argument(
        "--images",
        dest="images",
        action="store_const",
        const=True,
        default=None,
        help="CLP by contact with periodic images (the default for CLP)",
    )
    realization.add_argument(
        "--copies",
        dest="images",
        action="store_const",
        const=False,
        help="CLP by copies tied to their originals (thesis eq. 2.14)",
    )
    option("solver", "kind", "--solver")
    p.add_argument(
        "--packing",
        default=None,
        help="packing file (ours: header dx dy dz, then x y z r lines; "
        "YADE export.text, LAMMPS / LIGGGHTS dumps)",
    )
    option("packing", "fraction", "--packing-fraction")
    option("packing", "seed")
    option("boundary", "d_bc")
    option("contact", "gamma")
    option("contact", "friction")
    option("solver", "increments")
    option("loading", "profile")
    option("solver", "steps")
    option("solver", "linear_solver")
    option("solver", "held_regularization")
    option("mesh", "resolution", "--mesh")
    option("mesh", "refinement")
    option("output", "outputs")
    p.add_argument("--no-visual", action="store_true", help="skip ParaView output and the PNG")
    option("output", "checkpoint_every")
    p.add_argument(
        "--restart",
        default=None,
        metavar="CHECKPOINT",
        help="continue from a checkpoint (directory, or a results folder: its newest one)",
    )
    p.add_argument("--out", default=f"results/{loading}")
    return p


def compaction_case(args: argparse.Namespace, loading: str) -> CompactionCase:
    """The compaction case of parsed :func:`compaction_parser` arguments, section by section
    (exits 2 with a one-line error on bad input)."""
    with bad_input_exits():
        return CompactionCase(
            packing=PackingSection(
                particles=args.particles,
                seed=args.seed,
                file=args.packing,
                fraction=args.packing_fraction,
            ),
            mesh=MeshSection(resolution=args.mesh, refinement=args.refinement),
            contact=ContactSection(gamma=args.gamma, friction=args.friction),
            boundary=BoundarySection(condition=args.bc, images=args.images, d_bc=args.d_bc),
            loading=LoadingSection(
                path=loading, target_density=args.target_density, profile=args.profile
            ),
            solver=SolverSection(
                kind=args.solver,
                increments=args.increments,
                steps=args.steps,
                linear_solver=args.linear_solver,
                held_regularization=args.held_regularization,
            ),
            output=OutputSection(
                directory=args.out,
                outputs=args.outputs,
                visual=not args.no_visual,
                checkpoint_every=args.checkpoint_every,
            ),
        )


@contextmanager
def run_exits():
    """Inside the block: bad input found while building the model (a packing file, an
    unreachable density...) exits 2, a diverging run exits 3 (its history and last checkpoint
    kept), each with one line."""
    from .workflows.compaction import RunFailure

    try:
        yield
    except RunFailure as err:
        fail(RUN_FAILED, str(err))
    except (ValueError, OSError) as err:
        fail(BAD_INPUT, str(err))


def report_compaction(result, say=print) -> None:
    """The end state of a compaction run and where its outputs are."""
    h, case = result.history, result.case
    from .solvers import solver_kind

    say(
        f"done: rho = {h.column('rho')[-1]:.4f} (imposed {h.column('rho_imposed')[-1]:.4f}), "
        f"sigma_m = {h.column('sigma_m')[-1]:.3f} MPa, "
        f"sigma_d = {h.column('sigma_d')[-1]:.3f} MPa, "
        f"{round(h.column('n_contacts')[-1])} contacts (Z {h.column('Z')[-1]:.2f}); "
        f"{result.num_particles_model} particles in the model, {result.num_dofs} dofs, "
        f"{result.increments} "
        f"{solver_kind(case.solver.kind).increment_word}, wall {result.wall_time:.0f} s"
    )
    say(
        f"outputs in {result.out_dir}/: history.csv, packing.txt"
        + ("" if not case.output.checkpoint_every else ", checkpoints/")
        + (
            ""
            if not case.output.visual
            else ", particles.xdmf (ParaView), particles.png, loading_path.png"
        )
    )
