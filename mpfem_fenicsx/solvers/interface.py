"""The solver interface: what the workflows call on a solver, as :class:`typing.Protocol` types.

:class:`Solver` is what both solvers are (``isinstance`` works: the protocols are runtime
checkable, on the members' presence). :class:`DynamicSolver` adds what the explicit solver
also offers (its increment, mass scaling and energy tallies), :class:`StaticSolver` what the
implicit one also offers (adopting an explicit state). A workflow asks the solver's
:class:`~mpfem_fenicsx.solvers.kinds.SolverKind` (``static``) before it uses either.

Units mm, N, MPa, mJ (= N mm), s; the time of a static solver is a pseudo-time. Reactions are
forces exerted on the bodies, per unrolled dof; the stresses built from them are in the
mechanics convention (tension > 0) until reported (compression > 0).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from .energy import Energies


@runtime_checkable
class Solver(Protocol):
    """A solver of a :class:`~mpfem_fenicsx.problem.SolidProblem` along a prescribed path."""

    #: the solver's name, a key of :data:`~mpfem_fenicsx.solvers.kinds.SOLVER_KINDS`
    name: str
    #: time of the current state (s; pseudo-time in [0, t_end] for a static solver)
    t: float
    #: increments made from t = 0 (a restarted or adopting solver continues the count)
    step: int
    #: wall time (s) spent per phase of the increments, accumulated (keys are the solver's)
    timings: dict[str, float]

    @property
    def total_steps(self) -> int:
        """Increments of the whole path at the planned increment (no cut-back)."""
        ...

    def run_path(
        self,
        on_output: Callable[[Solver], None] | None = None,
        *,
        outputs: int = 100,
        every: int | None = None,
        max_steps: int | None = None,
        on_step: Callable[[Solver], None] | None = None,
        log: Callable[[str], None] | None = None,
    ) -> int:
        """Advance from the current state to the end of the path; ``on_output(solver)`` at the
        output increments (about ``outputs`` of them, or every ``every``; a static solver: every
        increment), ``on_step(solver)`` after every increment (dynamic solvers only, e.g. a
        stress servo), ``max_steps`` increments of this call at most (dynamic solvers only),
        ``log`` for one-line messages. Returns the number of increments of the path (dynamic)
        or made (static)."""
        ...

    @property
    def macroscopic_reaction(self) -> np.ndarray:
        """The forces (N) on every owned unrolled dof that the Schmidt stress (eq. 2.19) is built
        from: the medium's static forces, without inertia or relaxation damping."""
        ...

    def reactions(self, dofs: np.ndarray) -> float:
        """Sum over the ranks of the reaction (N) on the local unrolled ``dofs`` (owned ones
        count) at the current state: the force the prescribed displacements exert on the bodies
        there (a platen pressing down on a top face: negative along z)."""
        ...

    def energy_record(self) -> dict[str, float]:
        """The energies (mJ) of a history row: E_int, E_el, E_p, E_contact, E_c (kinetic), E_visc,
        E_damp, E_mass, W_ext; NaN for what the solver does not tally."""
        ...

    def unbalanced_ratio(self) -> float:
        """Out-of-balance ratio (-) of the current state, >= 0, 0 in static equilibrium; NaN when
        the solver has no such measure."""
        ...

    def iteration_record(self) -> dict[str, float]:
        """The increments' nonlinear iterations of a history row: ``newton_iterations`` of the
        last increment and the ``cutbacks`` (failed attempts) so far; NaN for a solver without
        them."""
        ...

    def state_dict(self) -> dict[str, np.ndarray]:
        """This rank's complete state after an increment (a checkpoint's arrays)."""
        ...

    def load_state(self, data: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict` on the same model, number of ranks and partition: the run
        then continues as if never interrupted."""
        ...


@runtime_checkable
class DynamicSolver(Solver, Protocol):
    """A solver that integrates in time (central differences): its increment and mass scaling."""

    #: the increment (s)
    dt: float
    #: the smallest element stable increment of the unscaled model (s)
    dt_stable_unscaled: float
    #: the largest density factor of mass scaling (-, >= 1)
    mass_scaling_max: float
    #: the cumulated energies (mJ)
    energies: Energies


@runtime_checkable
class StaticSolver(Solver, Protocol):
    """A quasi-static solver (load increments in pseudo-time) that may continue another solver's
    state."""

    #: plastic dissipation of the converged increments (mJ); set it to continue a tally
    plastic_work: float

    def adopt_state(
        self, data: dict[str, np.ndarray], translation: np.ndarray | None = None
    ) -> None:
        """Continue from another solver's :meth:`state_dict` on the same model and partition (e.g.
        an explicit state relaxed to rest): time, displacement and histories; ``translation`` (mm)
        a rigid translation taken off the displacement."""
        ...
