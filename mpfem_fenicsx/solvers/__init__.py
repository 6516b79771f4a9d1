"""Solvers: quasi-static implicit (Newton / SNES) and explicit central difference."""

from .implicit import ImplicitSolver, NonConvergence, StepControl

__all__ = ["ImplicitSolver", "NonConvergence", "StepControl"]
