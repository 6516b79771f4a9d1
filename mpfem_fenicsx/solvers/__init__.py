"""Solvers: quasi-static implicit (Newton / SNES) and explicit central difference, one interface
(``t``, ``step``, ``run_path``, ``macroscopic_reaction``, ``energy_record``, ``unbalanced_ratio``,
``state_dict`` / ``load_state``) and their kinds (:mod:`.kinds`)."""

from .implicit import ImplicitSolver, NonConvergence, StepControl
from .kinds import SOLVER_KINDS, SOLVERS, SolverKind, solver_kind
from .factory import create_solver, loading_amplitude

__all__ = ["ImplicitSolver", "NonConvergence", "SOLVER_KINDS", "SOLVERS", "SolverKind", "StepControl", "create_solver",
           "loading_amplitude", "solver_kind"]
