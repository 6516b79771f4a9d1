"""The two solvers as one type owning their rules: what the problem must assemble, how a periodic
model is held, what the loading may be, which checkpoints a solver continues. Workflows ask a
:class:`SolverKind` instead of comparing solver names. What they call on a solver is the
:class:`~mpfem_fenicsx.solvers.interface.Solver` protocol (``static``: a
:class:`~mpfem_fenicsx.solvers.interface.StaticSolver`, else a
:class:`~mpfem_fenicsx.solvers.interface.DynamicSolver`)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SolverKind:
    """A solver's rules, by name: what the problem assembles, how a periodic model is held, what
    loading and which checkpoints it accepts."""

    name: str
    #: the problem assembles the Jacobian forms (Newton's tangent)
    tangent: bool
    #: a periodic model holds one node (a static solve has no rigid translation to absorb)
    anchored: bool
    #: mixed strain / stress control runs (its servo acts between increments of a dynamic run)
    stress_control: bool
    #: its checkpoints' solvers it continues (implicit: an explicit state relaxed to rest too;
    #: the reverse has no velocities)
    continues: tuple[str, ...]
    #: the loading profile its runs use by default for a single segment (quasi-static: a ramp;
    #: dynamic: a smooth step, no jolt)
    static: bool
    #: what its increments are called in messages
    increment_word: str


EXPLICIT = SolverKind(
    "explicit",
    tangent=False,
    anchored=False,
    stress_control=True,
    continues=("explicit",),
    static=False,
    increment_word="increments",
)
IMPLICIT = SolverKind(
    "implicit",
    tangent=True,
    anchored=True,
    stress_control=False,
    continues=("implicit", "explicit"),
    static=True,
    increment_word="steps",
)
SOLVER_KINDS = {kind.name: kind for kind in (EXPLICIT, IMPLICIT)}
SOLVERS = tuple(SOLVER_KINDS)


def solver_kind(name: str) -> SolverKind:
    """The kind of the solver ``name``; ValueError naming the allowed ones."""
    try:
        return SOLVER_KINDS[name]
    except KeyError:
        raise ValueError(f"solver must be one of {', '.join(SOLVERS)}, got {name!r}") from None
