"""Solvers: quasi-static implicit (Newton / SNES) and explicit central difference. What the
workflows call on either is the :class:`Solver` protocol (:mod:`.interface`; the explicit one
is also a :class:`DynamicSolver`, the implicit one a :class:`StaticSolver`); the rules that
differ between them are their kinds (:mod:`.kinds`); :func:`create_solver` builds one."""

from .factory import create_solver, loading_amplitude
from .implicit import ImplicitSolver, NonConvergence, StepControl
from .interface import DynamicSolver, Solver, StaticSolver
from .kinds import SOLVER_KINDS, SOLVERS, SolverKind, solver_kind

__all__ = [
    "DynamicSolver",
    "ImplicitSolver",
    "NonConvergence",
    "SOLVER_KINDS",
    "SOLVERS",
    "Solver",
    "SolverKind",
    "StaticSolver",
    "StepControl",
    "create_solver",
    "loading_amplitude",
    "solver_kind",
]
