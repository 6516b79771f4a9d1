"""The solver factory: the one place where a solver's name picks a class. A static solver steps
through ``controls`` (pseudo-time, Newton); a dynamic one integrates to ``settings.t_end`` with
mass scaling. Both are a :class:`~mpfem_fenicsx.solvers.interface.Solver`."""

from __future__ import annotations

from ..loading.amplitude import Ramp, SmoothStep
from .explicit import ExplicitSettings, ExplicitSolver
from .implicit import ImplicitSolver, StepControl
from .interface import Solver
from .kinds import solver_kind


def create_solver(
    name: str,
    problem,
    bcs,
    *,
    contact=None,
    controls: list[StepControl] | None = None,
    settings: ExplicitSettings | None = None,
    petsc_options: dict | None = None,
    regularization=None,
    drag_update=None,
    drag_frame=None,
    damped_bodies=None,
) -> Solver:
    """The solver ``name`` on ``problem`` with ``bcs``: implicit with its step ``controls``
    (``petsc_options``, ``regularization``, ``drag_update``, ``drag_frame``), explicit
    with its ``settings`` (``damped_bodies``)."""
    if solver_kind(name).static:
        if not controls:
            raise ValueError("create_solver: the implicit solver needs its step controls")
        return ImplicitSolver(
            problem,
            bcs,
            contact=contact,
            petsc_options=petsc_options,
            regularization=regularization,
            drag_update=drag_update,
            drag_frame=drag_frame,
            controls=controls,
        )
    if settings is None:
        raise ValueError("create_solver: the explicit solver needs its settings")
    return ExplicitSolver(problem, bcs, settings, contact=contact, damped_bodies=damped_bodies)


def loading_amplitude(name: str, duration: float):
    """The amplitude of a single prescribed ramp for the solver ``name``: linear over pseudo-time
    [0, 1] for a static solver, Abaqus' smooth step over ``duration`` s for a dynamic one (no
    jolt at the start)."""
    return Ramp(1.0) if solver_kind(name).static else SmoothStep(duration)
