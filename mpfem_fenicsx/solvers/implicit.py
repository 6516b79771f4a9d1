"""Quasi-static implicit solver: Newton (PETSc SNES) on the constrained (reduced) system with
adaptive load stepping and cut-backs.

Unknowns are the reduced coordinates x of u = P x + g(t) (``constraints.AffineConstraint``):
    r_red(x) = P^T r(u),    J_red = P^T K P,
with r the assembled internal force (N) and K its consistent tangent (N/mm). Reactions at
prescribed dofs are the full residual there (N, sign: force exerted *on* the body).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx

from ..loading import PrescribedDisplacements
from ..problem import SolidProblem
from ..runtime import configure_runtime
from .state import check_layout, histories_state, load_histories


class NonConvergence(RuntimeError):
    """Raised when the load step cannot be reduced further without Newton converging."""


@dataclass
class StepControl:
    """Pseudo-time stepping on [0, t_end] (s): initial, minimum and maximum increments."""

    t_end: float = 1.0
    dt: float = 0.05
    dt_min: float = 1e-6
    dt_max: float = 0.1
    grow: float = 1.5  # increment growth after an easy step (<= easy_iterations)
    easy_iterations: int = 6
    #: converged increments after a cut-back before the increment may grow again (a cut
    #: increment grown straight back would pose the failed problem again; granular volumes: 2)
    settle_steps: int = 0
    #: Newton's stall test window (iterations; None: no stall test, the iteration limit only)
    stall_window: int | None = None
    #: times that increments land on exactly (e.g. the end of loading before unloading)
    breakpoints: tuple[float, ...] = ()
    #: an adhesive point cycling a third time snaps off only on increments of at most this
    #: fraction of ``dt``; on a longer one the attempt ends and the increment is cut back
    #: (1: on any increment; granular volumes: SNAP_INCREMENT)
    snap_increment: float = 1.0
    #: Newton also converges when its residual is at most this fraction of the internal forces'
    #: norm ||P^T f_int|| at the last converged state (0: the absolute and relative PETSc
    #: tolerances only; granular volumes: FORCE_RTOL)
    force_rtol: float = 0.0

    def __post_init__(self):
        if not 0 < self.dt_min <= self.dt <= self.t_end:
            raise ValueError(f"step control needs 0 < dt_min <= dt <= t_end, got {self}")
        if not 0 < self.snap_increment <= 1:
            raise ValueError(
                f"step control snap_increment must lie in (0, 1], got {self.snap_increment}"
            )
        if not 0 <= self.force_rtol < 1:
            raise ValueError(f"step control force_rtol must lie in [0, 1), got {self.force_rtol}")
        if any(not 0 < b < self.t_end for b in self.breakpoints):
            raise ValueError(
                f"step control breakpoints must lie in (0, t_end = {self.t_end}), "
                f"got {self.breakpoints}"
            )

    def next_stop(self, t: float) -> float:
        """First breakpoint (or t_end) after time t."""
        later = [b for b in self.breakpoints if b > t * (1 + 1e-12) + 1e-300]
        return min(later) if later else self.t_end


DEFAULT_OPTIONS = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "basic",
    "snes_rtol": 1e-9,
    "snes_atol": 1e-9,
    "snes_stol": 0.0,
    "snes_max_it": 25,
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
}


#: PETSc options of the iterative linear solver: GMRES (the frictional contact tangent is not
#: symmetric) preconditioned by smoothed-aggregation AMG, with the rigid-body modes as its
#: near-nullspace (:func:`rigid_body_modes`); an inexact Newton step to 1e-8 of the residual
ITERATIVE_OPTIONS = {
    "ksp_type": "gmres",
    "ksp_gmres_restart": 200,
    "ksp_rtol": 1e-8,
    "ksp_max_it": 2000,
    "pc_type": "gamg",
    "pc_gamg_threshold": 0.01,
    "mg_levels_ksp_type": "chebyshev",
    "mg_levels_pc_type": "jacobi",
}


#: Newton's failures as the cut-back messages name them (PETSc's converged reasons)
FAILURES = {
    PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT: "reached its iteration limit",
    PETSc.SNES.ConvergedReason.DIVERGED_DTOL: "stalled",
    PETSc.SNES.ConvergedReason.DIVERGED_LINE_SEARCH: "line search failed",
    PETSc.SNES.ConvergedReason.DIVERGED_LINEAR_SOLVE: "linear solve failed",
    PETSc.SNES.ConvergedReason.DIVERGED_FUNCTION_NANORINF: "residual not finite",
}

#: a failed backtracking line search: the attempt is retried once with the full update
#: (:meth:`ImplicitSolver._retry_full_step`)
LINE_SEARCH_FAILED = PETSc.SNES.ConvergedReason.DIVERGED_LINE_SEARCH

#: Newton's stall test (:meth:`ImplicitSolver._converged`, on when a step control sets its
#: ``stall_window``, e.g. the granular volumes' STALL_WINDOW): an attempt ends when its residual
#: has not fallen below STALL_RATIO x its value ``stall_window`` iterations before
STALL_WINDOW = 8
STALL_RATIO = 0.5

#: the granular volumes' StepControl.snap_increment: an adhesive point cycling a third time
#: between softening and the adhesive loading line
#: (:class:`~mpfem_fenicsx.contact.guards.AdhesiveGuards`) snaps off only on increments of at most
#: 1/16 of the nominal one; on a longer increment the attempt ends and the increment is cut back
#: (a cycle that shorter increments resolve is Newton's, not a snap)
SNAP_INCREMENT = 1.0 / 16.0

#: the granular volumes' StepControl.force_rtol: Newton has converged once its residual is at
#: most 1e-4 of the internal forces' norm (an out-of-balance ratio 500 times below the explicit
#: runs' quasi-static check), also where a kink of the adhesive law stalls it above PETSc's
#: absolute tolerance of 1e-9 N
FORCE_RTOL = 1e-4


def rigid_body_modes(constraint, positions: np.ndarray) -> list[PETSc.Vec]:
    """The six rigid-body modes (three translations, three rotations about the origin) of the
    bodies at ``positions`` (owned nodes, (n, 3), mm), in the reduced coordinates of
    ``constraint`` (a reduced unknown is its free dof's value), orthonormalized: the
    near-nullspace of smoothed-aggregation AMG. An aggregate sees them restricted to its nodes,
    i.e. the rigid modes of the part of a particle it covers: the modes the particles'
    elasticity leaves soft, which a plain (scalar) aggregation cannot represent."""
    free = constraint.free
    node, comp = free // 3, free % 3
    x = positions[node]
    modes = np.zeros((6, free.size))
    for c in range(3):
        modes[c, comp == c] = 1.0
    # rotation about axis a: (e_a x X) component comp
    cross = {
        0: {1: -x[:, 2], 2: x[:, 1]},
        1: {0: x[:, 2], 2: -x[:, 0]},
        2: {0: -x[:, 1], 1: x[:, 0]},
    }
    for a, parts in cross.items():
        for c, values in parts.items():
            modes[3 + a, comp == c] = values[comp == c]
    vectors = []
    for row in modes:  # modified Gram-Schmidt (collective dots)
        v = constraint.create_reduced_vector()
        v.array_w[:] = row
        for w in vectors:
            v.axpy(-v.dot(w), w)
        v.normalize()
        vectors.append(v)
    return vectors


class ImplicitSolver:
    """Newton-Raphson on the reduced system, one SNES solve per load increment: a
    :class:`~mpfem_fenicsx.solvers.interface.StaticSolver` (the solver interface; ``step``
    counts converged increments, :meth:`run_path` runs the ``controls`` of the path, one per
    segment)."""

    #: drag_scale when K_total was last assembled (the predictor's drag load uses it)
    _tangent_drag_scale = 1.0

    name = "implicit"

    def __init__(
        self,
        problem: SolidProblem,
        bcs: PrescribedDisplacements,
        *,
        contact=None,
        petsc_options: dict | None = None,
        prefix: str = "mpfem_implicit_",
        regularization: np.ndarray | None = None,
        controls: list[StepControl] | None = None,
        drag_update: Callable[[], np.ndarray] | None = None,
        drag_frame: Callable[[float], np.ndarray] | None = None,
    ):
        """``controls``: the step controls :meth:`run_path` runs one after the other (one per
        segment of the loading path). ``regularization``: stiffness k_i (N/mm) per owned dof of a
        pseudo-time viscous drag r_i += k_i (w_i - w_i,n) towards the last converged state
        (w = u - g, the motion relative to the moving offsets, e.g. a comoving homogeneous
        flow): it makes free-floating bodies
        (particles before contact) solvable and vanishes as the state stops changing; its work
        is accumulated in :attr:`regularization_work` (mJ) and must stay small. The drag is
        viscous, c (w_i - w_i,n) / dt with c = k_i dt0 (dt0 the step control's increment): a cut
        increment dt < dt0 stiffens it by dt0 / dt (:attr:`drag_scale`), so that a cut-back
        shortens the pseudo-time step even where the boundary does not move (a hold at a fixed
        gradient, whose every retry would otherwise pose the same Newton problem).

        ``drag_update``: the drag stiffness per owned dof for the committed state (e.g. weaker on
        the particles their contacts hold), called at every commit and after a restart (a
        function of the committed state: restarts stay exact).

        ``drag_frame``: t -> a reference displacement (mm, owned dofs) whose motion the drag lets
        pass, for models without moving offsets (tool-driven volumes: the homogeneous flow
        between the tools, the role the comoving offsets play in a periodic volume): the drag
        acts on w = u - g - frame(t), and each increment's predictor takes the frame's increment
        as a load through the drag (a particle its drag holds follows the frame, one its
        contacts hold follows the tools' motion)."""
        if problem.jacobian_forms is None:
            raise ValueError("the implicit solver needs SolidProblem(..., tangent=True)")
        configure_runtime(problem.comm)
        self.problem = problem
        self.contact = contact  # optional ContactModel: forces and tangent added to the bulk ones
        self.bcs = bcs
        self.constraint = bcs.constraint or bcs.build()
        self.comm = problem.comm
        self.x = self.constraint.create_reduced_vector()
        self.x_old = self.x.duplicate()
        self.r_red = self.x.duplicate()
        self.r_full = problem.create_vector()
        self.K = problem.create_matrix()
        self.K_total = self.K  # bulk + contact tangent (a separate matrix once contact is on)
        self._J_contact = None  # P^T K_total P with the current contact pattern
        self.t = 0.0
        self.step = 0  # converged increments (an adopted explicit state continues its count)
        self.controls = list(controls or [])
        self.iterations_total = 0
        self.dt_next = None  # increment to try next (kept for restarts)
        self.regularization = None
        self.regularization_work = 0.0
        #: factor of the drag's stiffness in the increment being solved: dt0 / dt on a cut
        #: increment, 1 on a full one (and in the tangent kept between increments)
        self.drag_scale = 1.0
        self.drag_update = drag_update
        self.drag_frame = drag_frame
        self._frame = self._frame_at(0.0)
        self.step_limits: list[float] = []  # contact step fractions applied (diagnostics)
        self.last_iterations = 0  # Newton iterations of the last converged increment
        self.last_linear_iterations = 0  # its linear solver iterations (predictor included)
        self.cutbacks = 0  # failed attempts (increments retried shorter) since the start
        self.full_step_retries = 0  # attempts retried with the full update (line search failed)
        self._since_cutback = np.inf  # converged increments since the last cut-back
        self._stall_window = None  # the running step control's (None: no stall test)
        self._force_rtol = 0.0  # the running step control's force_rtol
        self._force_scale = 0.0  # ||P^T f_int|| at the last converged state (N)
        self._snap_refused = False  # the last attempt ended on a refused snap-off
        self._unbalanced = float("nan")
        #: plastic dissipation of the converged increments (mJ), accumulated before each commit
        #: (after it the material's trial increment is the converged state's: zero)
        self.plastic_work = 0.0
        if regularization is not None:
            self.regularization = self.r_full.duplicate()
            self.regularization.array_w[:] = regularization
            self._w_converged = self._peculiar().copy()
            self._regularization_matrix = None
            self.set_regularization(regularization)
        self.timings = {
            "material": 0.0,
            "residual": 0.0,
            "contact": 0.0,
            "jacobian": 0.0,
            "reduce": 0.0,
        }

        # start from the current state of the problem (a new solver continues a load path)
        self.constraint.reduce_values(problem.u, self.x)
        self.bcs.apply(0.0)
        self._residual(None, self.x, self.r_red)
        self._assemble_tangent()
        self.J_red = self.constraint.reduce_matrix(self.K_total)
        self._tangent_valid = True

        self.snes = PETSc.SNES().create(self.comm)
        self.snes.setOptionsPrefix(prefix)
        opts = PETSc.Options()
        options = {**DEFAULT_OPTIONS, **(petsc_options or {})}
        if options["pc_type"] not in ("lu", "cholesky"):  # iterative: no factorization package
            options.pop("pc_factor_mat_solver_type")
        for key, value in options.items():
            opts[prefix + key] = value
        #: smoothed-aggregation AMG gets the rigid-body modes as its near-nullspace
        self._near_nullspace = options["pc_type"] == "gamg"
        self._attach_near_nullspace(self.J_red)
        self.snes.setFromOptions()
        self.snes.setConvergenceHistory(reset=True)
        if contact is not None:
            self._direction = dolfinx.fem.Function(problem.V)
            self.snes.setLineSearchPreCheck(self._limit_contact_step)
        self.snes.setConvergenceTest(self._converged)
        self.snes.setFunction(self._residual, self.r_red)
        self.snes.setJacobian(self._jacobian, self.J_red, self.J_red)

    def _converged(self, snes, its: int, norms) -> int:
        """Newton's convergence test: PETSc's absolute and relative residual tests and iteration
        limit, the step control's ``force_rtol`` (a residual at most that fraction of
        ||P^T f_int|| at the last converged state), and (the step control's ``stall_window``
        set) a stall test: after that many
        iterations or more, a residual that has not fallen below ``STALL_RATIO`` x its value that
        many iterations before ends the attempt (DIVERGED_DTOL; contact or stick / slip states
        cycling: a shorter increment is the remedy, and each further iteration wastes a
        factorization)."""
        fnorm = norms[2]
        if its == 0:
            self._fnorms = []
        self._fnorms.append(fnorm)
        rtol, atol, _, max_it = snes.getTolerances()
        reason = PETSc.SNES.ConvergedReason
        if not np.isfinite(fnorm):
            return reason.DIVERGED_FUNCTION_NANORINF
        if fnorm <= atol or fnorm <= self._force_rtol * self._force_scale:
            return reason.CONVERGED_FNORM_ABS
        if its > 0 and fnorm <= rtol * self._fnorms[0]:
            return reason.CONVERGED_FNORM_RELATIVE
        if its >= max_it:
            return reason.DIVERGED_MAX_IT
        if self.contact is not None and self.comm.allreduce(
            self.contact.guards.refused.size, op=MPI.SUM
        ):
            self._snap_refused = True
            return reason.DIVERGED_DTOL
        window = self._stall_window
        if (
            window is not None
            and its >= window
            and fnorm > STALL_RATIO * self._fnorms[its - window]
        ):
            return reason.DIVERGED_DTOL
        return reason.ITERATING

    def _residual_trace(self) -> str:
        """The failed attempt's residual norms, first / smallest / last: over the force target
        (``force_rtol`` x ||P^T f_int|| at the last converged state) where there is one, else
        in N. A first one far above the target however short the increment is a jump at the
        converged state, not too long an increment."""
        norms = np.asarray(getattr(self, "_fnorms", None) or [], dtype=float)
        if not norms.size:
            return ""
        target = self._force_rtol * self._force_scale
        what = "residual / target" if target > 0.0 else "residual (N)"
        f = norms / target if target > 0.0 else norms
        return f" ({what}: first {f[0]:.3g}, best {f.min():.3g}, last {f[-1]:.3g})"

    def _attach_near_nullspace(self, J: PETSc.Mat) -> None:
        """Give ``J`` the rigid-body modes of the current configuration as its near-nullspace
        (an AMG preconditioner only)."""
        if not self._near_nullspace:
            return
        V = self.problem.V
        n = V.dofmap.index_map.size_local
        positions = V.tabulate_dof_coordinates()[:n] + self.problem.u.x.array[: 3 * n].reshape(
            -1, 3
        )
        modes = rigid_body_modes(self.constraint, positions)
        J.setNearNullSpace(PETSc.NullSpace().create(vectors=modes, comm=self.comm))
        for v in modes:
            v.destroy()

    def set_regularization(self, stiffness: np.ndarray) -> None:
        """The drag stiffness k_i (N/mm) per owned dof from now on (the next tangent takes it);
        the dofs without drag stay those of the first call (the diagonal matrix's pattern)."""
        stiffness = np.asarray(stiffness, dtype=float)
        self.regularization.array_w[:] = stiffness
        n = self.constraint.num_owned
        if self._regularization_matrix is None:
            self._drag_rows = np.flatnonzero(stiffness > 0)
        elif np.any(stiffness[np.setdiff1d(np.arange(n), self._drag_rows)] != 0.0):
            raise ValueError("set_regularization: a drag on a dof that had none")
        else:
            self._regularization_matrix.destroy()
        # diagonal matrix on the drag's dofs (their diagonal is in K's pattern)
        rows = self._drag_rows
        lo = self.K.getOwnershipRange()[0]
        indptr = np.zeros(n + 1, dtype=PETSc.IntType)
        indptr[rows + 1] = 1
        indptr = np.cumsum(indptr).astype(PETSc.IntType)
        self._regularization_matrix = PETSc.Mat().createAIJ(
            self.K.getSizes(),
            csr=(indptr, (lo + rows).astype(PETSc.IntType), stiffness[rows]),
            comm=self.comm,
        )
        self._regularization_matrix.assemble()

    def _update_drag(self) -> None:
        """The drag of the committed state (``drag_update``), if any."""
        if self.regularization is not None and self.drag_update is not None:
            self.set_regularization(self.drag_update())

    def _peculiar(self) -> np.ndarray:
        """w = u - g on the owned dofs: the displacement relative to the moving offsets (and to
        the drag's frame at the time being solved, if any)."""
        n = self.constraint.num_owned
        return self.problem.u.x.array[:n] - self.constraint.g.x.array[:n] - self._frame

    def _frame_at(self, t: float) -> np.ndarray | float:
        """The drag frame's displacement at ``t`` (owned dofs; 0 without a frame)."""
        if self.drag_frame is None:
            return 0.0
        return np.asarray(self.drag_frame(t), dtype=float)[: self.constraint.num_owned]

    # -- SNES callbacks -----------------------------------------------------------------------
    def _residual(self, snes, x: PETSc.Vec, r: PETSc.Vec) -> None:
        t0 = time.perf_counter()
        self.constraint.expand(x, self.problem.u)
        self.problem.update_material(tangent=True)
        t1 = time.perf_counter()
        self.problem.assemble_residual(self.r_full)
        t2 = time.perf_counter()
        if self.regularization is not None:
            n = self.constraint.num_owned
            drag = self.drag_scale * self.regularization.array_r
            self.r_full.array_w[:n] += drag * (self._peculiar() - self._w_converged)
        if self.contact is not None:
            self.contact.evaluate(self.problem.u, tangent=True)
            self.contact.add_residual(self.r_full)
        t3 = time.perf_counter()
        self.constraint.restrict(self.r_full, r)
        self.timings["material"] += t1 - t0
        self.timings["residual"] += t2 - t1
        self.timings["contact"] += t3 - t2

    def _limit_contact_step(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """Line-search pre-check: shorten the Newton update (x <- x - y) so that open contact
        points do not overshoot into the masters nor slipping points back through their stick
        range (:meth:`ContactModel.step_limit`); at least a tenth of the step is kept so that
        Newton cannot stall."""
        self.constraint.expand(y, self._direction, with_offset=False)
        self._direction.x.array[:] *= -1.0
        lam = max(self.contact.step_limit(self._direction), 0.1)
        if lam < 1.0:
            y.scale(lam)
        self.step_limits.append(lam)

    def _assemble_tangent(self) -> bool:
        """Assemble K (and K_total = K + K_contact); True when the sparsity pattern changed."""
        self.problem.assemble_jacobian(self.K)
        self._tangent_drag_scale = self.drag_scale  # the drag's factor in this tangent
        if self.regularization is not None:
            self.K.axpy(
                self.drag_scale,
                self._regularization_matrix,
                PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN,
            )
        if self.contact is None:
            return False
        K_c = self.contact.tangent_matrix(self.K)
        rows, cols = self.contact.tangent_pattern
        key = (rows.size, hash(rows.tobytes()), hash(cols.tobytes()))
        # collective: another rank's contact points may add entries to this rank's rows
        changed = self.comm.allreduce(key != getattr(self, "_contact_pattern", None), op=MPI.LOR)
        self._contact_pattern = key
        if self.K_total is self.K or changed:
            if self.K_total is not self.K:
                self.K_total.destroy()
            self.K_total = self.K.duplicate(copy=True)
            self.K_total.axpy(1.0, K_c, PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        else:  # same contact couplings as the last time: refill in place
            self.K_total.zeroEntries()
            self.K_total.axpy(1.0, self.K, PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
            self.K_total.axpy(1.0, K_c, PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
        K_c.destroy()
        return changed

    def _jacobian(self, snes, x, J, P) -> None:
        t0 = time.perf_counter()
        changed = self._assemble_tangent()
        t1 = time.perf_counter()
        if self.contact is None:
            self.constraint.reduce_matrix(self.K, self.J_red)
        elif not changed and self._J_contact is not None:
            # same pattern: P^T K P reuses its symbolic product; J_red's pattern contains it
            self.constraint.reduce_matrix(self.K_total, self._J_contact)
            self.J_red.zeroEntries()
            self.J_red.axpy(1.0, self._J_contact, PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
        else:  # the contact couplings changed the pattern: rebuild J_red's pattern
            if self._J_contact is not None:
                self._J_contact.destroy()
            self._J_contact = self.constraint.reduce_matrix(self.K_total)
            self.J_red.zeroEntries()
            self.J_red.axpy(1.0, self._J_contact, PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
            # the merged matrix may carry a nonzero state the factorization mistakes for the old
            # pattern: drop the factorization so that the next solve redoes the analysis
            if hasattr(self, "snes"):
                self.snes.getKSP().getPC().reset()
        self.timings["jacobian"] += t1 - t0
        self.timings["reduce"] += time.perf_counter() - t1

    # -- results ------------------------------------------------------------------------------
    def reactions(self, dofs: np.ndarray) -> float:
        """Sum over ranks of the reaction (N) on the given local unrolled dofs (owned ones)."""
        owned = np.asarray(dofs)[np.asarray(dofs) < self.constraint.num_owned]
        return self.comm.allreduce(float(self.r_full.array_r[owned].sum()))

    @property
    def macroscopic_reaction(self) -> np.ndarray:
        """The reaction the Schmidt stress (eq. 2.19) is built from: :attr:`reaction` (static)."""
        return self.reaction

    def energy_record(self) -> dict[str, float]:
        """The energies of a history row (mJ): quasi-static, no kinetic or viscous energy; E_el the
        stored energy, E_p the plastic work of the converged increments (the whole model), E_damp
        the regularization's work; E_int, E_contact, W_ext not tallied (NaN)."""
        return dict(
            E_int=np.nan,
            E_el=self.problem.stored_energy(),
            E_p=self.plastic_work,
            E_contact=np.nan,
            E_c=0.0,
            E_visc=0.0,
            E_damp=self.regularization_work,
            E_mass=0.0,
            W_ext=np.nan,
        )

    def unbalanced_ratio(self) -> float:
        """Out-of-balance ratio of the last converged increment (-): ||P^T f_reg|| / ||P^T f_int||
        with f_reg the regularization's drag at convergence, the one force of the converged
        residual that is not the medium's (Newton's tolerance bounds the rest): what the
        particles would still carry out of balance without it, the measure of the explicit
        solver's ratio. 0 without regularization; NaN before any internal force."""
        return self._unbalanced

    def iteration_record(self) -> dict[str, float]:
        """Newton and linear solver iterations of the last converged increment (the linear ones
        of its predictor too) and the cut-backs since t = 0 (the failed attempts, counted from
        this solver's start or its checkpoint)."""
        return dict(
            newton_iterations=float(self.last_iterations),
            linear_iterations=float(self.last_linear_iterations),
            cutbacks=float(self.cutbacks),
        )

    def _internal_force_norm(self) -> float:
        """||P^T f_int|| (N) at the current displacement: the medium's internal forces on the
        reduced unknowns (no drag, no contact). Collective."""
        force = self.problem.create_vector()
        self.problem.assemble_residual(force)
        reduced = self.x.duplicate()
        self.constraint.restrict(force, reduced)
        norm = reduced.norm()
        force.destroy()
        reduced.destroy()
        return norm

    def _out_of_balance(self) -> float:
        """:meth:`unbalanced_ratio` at the converged trial state, before its commit (the drag
        towards the last converged state vanishes at the commit). Collective."""
        if self.regularization is None:
            return 0.0
        n = self.constraint.num_owned
        scale = self._internal_force_norm()
        drag = self.problem.create_vector()
        drag.array_w[:n] = (
            self.drag_scale * self.regularization.array_r * (self._peculiar() - self._w_converged)
        )
        reduced = self.x.duplicate()
        self.constraint.restrict(drag, reduced)
        ratio = reduced.norm() / scale if scale > 0.0 else float("nan")
        for vec in (drag, reduced):
            vec.destroy()
        return ratio

    @property
    def total_steps(self) -> int:
        """Increments of :attr:`controls` at their initial increments (no cut-back)."""
        starts = [0.0] + [c.t_end for c in self.controls[:-1]]
        return sum(
            round((c.t_end - t0) / c.dt) for c, t0 in zip(self.controls, starts, strict=False)
        )

    def run_path(
        self,
        on_output: Callable[[ImplicitSolver], None] | None = None,
        *,
        outputs: int = 0,
        every: int | None = None,
        max_steps: int | None = None,
        on_step=None,
        log: Callable[[str], None] | None = None,
    ) -> int:
        """The solver interface's run: each of :attr:`controls` from the current time (a restart
        enters one), ``on_output`` after every converged increment (``outputs``, ``every``,
        ``on_step`` unused: every increment is an output). Returns the increments made."""
        if max_steps is not None or on_step is not None:
            raise ValueError("ImplicitSolver.run_path: max_steps and on_step are explicit-only")
        total = 0
        for control in self.controls:
            if self.t < control.t_end * (1 - 1e-12):
                total += self.run(control, on_step=on_output, log=log)
        return total

    @property
    def reaction(self) -> np.ndarray:
        """Reaction (N) on every owned unrolled dof: the full residual (zero on free dofs)."""
        return self.r_full.array_r[: self.constraint.num_owned]

    # -- stepping -----------------------------------------------------------------------------
    def _refresh_tangent(self) -> None:
        """Residual and tangent at the current (converged) x, in a fresh reduced matrix.

        Called at every converged state and after a restart: the next increment's predictor and
        first Newton step then see the same tangent, with the same sparsity pattern (the pattern
        of the current contacts only, not the union of every pattern met so far, which would
        change MUMPS' pivoting and round-off), whether the run was interrupted or not."""
        self._residual(None, self.x, self.r_red)
        self._force_scale = self._internal_force_norm()  # the scale of Newton's force_rtol
        self._update_drag()  # of the committed state (its contact forces just evaluated)
        self._assemble_tangent()
        if self._J_contact is not None:
            self._J_contact.destroy()
            self._J_contact = None
        reduced = self.constraint.reduce_matrix(self.K_total)
        if self.contact is not None:
            self._J_contact = reduced
            reduced = reduced.duplicate(copy=True)
        self.J_red.destroy()
        self.J_red = reduced
        if hasattr(self, "snes"):
            self._attach_near_nullspace(self.J_red)
        self.snes.setJacobian(self._jacobian, self.J_red, self.J_red)
        self.snes.getKSP().getPC().reset()
        self._tangent_valid = True

    def solve_increment(self, t_new: float) -> tuple[bool, int]:
        """Newton at time t_new, starting from the tangent predictor.

        Predictor: x = x_n - J_red^-1 P^T ((K - C) dg + dr_masters - C df), i.e. the boundary
        motion (the offsets' dg = g(t_new) - g(t_n), the periodic images' and the rigid tools',
        ContactModel.add_master_motion, and the drag frame's df; the drag C acts on
        u - g - frame, so that the offsets and the frame carry its anchor) is spread
        through the body by the last tangent instead of distorting the boundary layer (the same
        role as DOLFINx's lifting of incremental Dirichlet values).
        """
        if not self._tangent_valid:
            self._refresh_tangent()
        if self.contact is not None:
            self.contact.begin_increment()
        g_old = self.constraint.g.x.petsc_vec.copy()
        frame_old, self._frame = self._frame, self._frame_at(t_new)
        self.bcs.apply(t_new)
        dg = self.constraint.g.x.petsc_vec.copy()
        dg.axpy(-1.0, g_old)
        force = self.K_total.createVecLeft()
        self.K_total.mult(dg, force)
        if self.contact is not None:  # the images' and tools' motion (not in the offsets g)
            self.contact.add_master_motion(force)
        if self.regularization is not None:
            # the drag acts on u - g - frame: the offsets' and the frame's motion load it by
            # -C (dg + df), which also takes back the C dg that K_total's drag put in
            n = self.constraint.num_owned
            drag = self._tangent_drag_scale * self.regularization.array_r
            force.array_w[:n] -= drag * (dg.array_r[:n] + (self._frame - frame_old))
        rhs = self.x.duplicate()
        self.constraint.restrict(force, rhs)
        rhs.scale(-1.0)
        ksp = self.snes.getKSP()
        ksp.setOperators(self.J_red, self.J_red)
        dx = self.x.duplicate()
        ksp.solve(rhs, dx)
        self.x.axpy(1.0, dx)
        for vec in (g_old, dg, force, rhs, dx):
            vec.destroy()
        predictor_its = ksp.getIterationNumber()
        start = time.perf_counter()
        self.snes.solve(None, self.x)
        self.timings["newton"] = self.timings.get("newton", 0.0) + time.perf_counter() - start
        #: linear solver iterations of the last attempt (predictor and Newton steps; 1 per solve
        #: for a direct solver)
        self.attempt_linear_iterations = predictor_its + self.snes.getLinearSolveIterations()
        #: residual norms of the last Newton solve (N), for convergence-rate checks
        self.residual_norms = np.array(self.snes.getConvergenceHistory()[0], dtype=float)
        its = self.snes.getIterationNumber()
        reason = self.snes.getConvergedReason()
        if reason <= 0:
            self._tangent_valid = False
        return reason > 0, its

    def _retry_full_step(self, t_new: float, its: int, log) -> tuple[bool, int]:
        """The failed attempt at ``t_new`` once more from the last converged state with Newton's
        full update (no line search; the contact pre-check still applies): at a kink of the
        contact or adhesive law the update need not decrease ||r||, and the backtracking line
        search then fails even on short increments where the full update lands. Returns
        (converged, both attempts' iterations)."""
        line_search = self.snes.getLineSearch()
        kind = line_search.getType()
        if kind == "basic":
            return False, its
        self._restore_converged()
        self.full_step_retries += 1
        if log:
            log(f"  line search failed at t={t_new:.6g}: the attempt again with the full update")
        try:
            self._set_line_search("basic")
            ok, more = self.solve_increment(t_new)
        finally:
            self._set_line_search(kind)
        return ok, its + more

    def _restore_converged(self) -> None:
        """Back to the last converged state after a failed attempt: unknowns, boundary values
        and the drag's frame at the current time."""
        self.x_old.copy(self.x)
        self.bcs.apply(self.t)
        self._frame = self._frame_at(self.t)

    def _line_search_failed(self) -> bool:
        """The last attempt ended with a failed line search."""
        return self.snes.getConvergedReason() == LINE_SEARCH_FAILED

    def _set_line_search(self, kind: str) -> None:
        """Newton's line search type, with the contact pre-check set again."""
        self.snes.getLineSearch().setType(kind)
        if self.contact is not None:
            self.snes.setLineSearchPreCheck(self._limit_contact_step)

    # -- checkpoints --------------------------------------------------------------------------
    def state_dict(self) -> dict[str, np.ndarray]:
        """This rank's converged state (for checkpoints): time, next increment, reduced and full
        displacement, regularization anchor and work, plastic work, Newton count; with the
        material and contact histories (prefixes ``material/`` and ``contact/``)."""
        data = {
            "t": np.array(self.t),
            "step": np.array(self.step),
            "dt_next": np.array(np.nan if self.dt_next is None else self.dt_next),
            "iterations_total": np.array(self.iterations_total),
            "last_iterations": np.array(self.last_iterations),
            "last_linear_iterations": np.array(self.last_linear_iterations),
            "cutbacks": np.array(self.cutbacks),
            "since_cutback": np.array(float(self._since_cutback)),
            "unbalanced": np.array(self._unbalanced),
            "x": self.x.array_r.copy(),
            "u": self.problem.u.x.array.copy(),
            "regularization_work": np.array(self.regularization_work),
            "plastic_work": np.array(self.plastic_work),
        }
        if self.regularization is not None:
            data["w_converged"] = self._w_converged.copy()
        data.update(histories_state(self.problem, self.contact))
        return data

    def load_state(self, data: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict` (same model, same number of ranks and partition)."""
        check_layout(data, self.x, self.problem.u)
        self.t = float(data["t"])
        self.step = int(data.get("step", 0))  # checkpoints before 2026-11-25 did not record it
        self.dt_next = None if np.isnan(data["dt_next"]) else float(data["dt_next"])
        self.iterations_total = int(data["iterations_total"])
        # checkpoints before 2026-12-02 did not record these
        self.last_iterations = int(data.get("last_iterations", 0))
        self.last_linear_iterations = int(data.get("last_linear_iterations", 0))
        self.cutbacks = int(data.get("cutbacks", 0))
        self._since_cutback = float(data.get("since_cutback", np.inf))
        self._unbalanced = float(data.get("unbalanced", np.nan))
        self.regularization_work = float(data["regularization_work"])
        self.plastic_work = float(data["plastic_work"])
        self._frame = self._frame_at(self.t)
        load_histories(self.problem, self.contact, data)
        self.bcs.apply(self.t)
        self.x.array_w[:] = data["x"]
        self.problem.u.x.array[:] = data["u"]
        if self.regularization is not None:
            self._w_converged[:] = data["w_converged"]
        self.x.copy(self.x_old)
        self._refresh_tangent()

    def adopt_state(
        self, data: dict[str, np.ndarray], translation: np.ndarray | None = None
    ) -> None:
        """Continue from another solver's state on the same model and partition, e.g. an explicit
        checkpoint relaxed to rest: time, displacement, material and contact histories. The
        reduced coordinates are recomputed from u, the stepping starts afresh (``dt_next``, the
        regularization work, the plastic work and the Newton count from zero: set
        :attr:`plastic_work` to continue a tally). ``translation`` (mm): a rigid
        translation subtracted from u and from the contact's committed surface displacement
        (slip increments are unchanged), e.g. the displacement of the node an anchored periodic
        model holds at zero; a periodic state is invariant under it."""
        check_layout({"x": self.x.array_r, "u": data["u"]}, self.x, self.problem.u)
        data = dict(data)
        if translation is not None:
            c = np.asarray(translation, dtype=float)
            data["u"] = (data["u"].reshape(-1, 3) - c).ravel()
            key = "contact/surface_displacement"
            if key in data:
                data[key] = data[key] - c
        self.t = float(data["t"])
        self.step = int(data.get("step", 0))
        self.dt_next, self.iterations_total, self.regularization_work, self.plastic_work = (
            None,
            0,
            0.0,
            0.0,
        )
        load_histories(self.problem, self.contact, data)
        self.bcs.apply(self.t)
        self._frame = self._frame_at(self.t)
        self.problem.u.x.array[:] = data["u"]
        self.constraint.reduce_values(self.problem.u, self.x)
        self.constraint.expand(self.x, self.problem.u)
        if self.regularization is not None:
            self._w_converged[:] = self._peculiar()
        self.x.copy(self.x_old)
        self._refresh_tangent()

    def run(
        self,
        control: StepControl,
        on_step: Callable[[ImplicitSolver], None] | None = None,
        log: Callable[[str], None] | None = None,
    ) -> int:
        """Advance from the current time to control.t_end; ``on_step`` after each converged step
        (a restarted solver continues with the increment it would have tried next)."""
        dt = control.dt if self.dt_next is None else min(self.dt_next, control.dt_max)
        self._stall_window = control.stall_window
        self._force_rtol = control.force_rtol
        steps = 0
        self.x.copy(self.x_old)
        while self.t < control.t_end * (1 - 1e-12):
            # a viscous drag: stiffer on a cut increment (not on a sliver landing on a stop)
            self.drag_scale = max(1.0, control.dt / dt)
            stop = control.next_stop(self.t)
            dt = min(dt, stop - self.t)
            # land on the stop instead of leaving a sliver of an increment before it
            t_new = stop if self.t + dt > stop - 1e-9 * control.t_end else self.t + dt
            dt = t_new - self.t
            if self.contact is not None:
                allowed = control.snap_increment * control.dt * (1 + 1e-9)
                self.contact.guards.snap_allowed = dt <= allowed
            self._snap_refused = False
            ok, its = self.solve_increment(t_new)
            if not ok and self._line_search_failed():
                ok, its = self._retry_full_step(t_new, its, log)
            self.iterations_total += its
            if not ok:
                self.cutbacks += 1
                self._since_cutback = 0
                self._restore_converged()
                dt *= 0.5
                if log:
                    why = self.snes.getConvergedReason()
                    what = (
                        "met an adhesive point cycling (no snap-off on this increment)"
                        if self._snap_refused
                        else FAILURES.get(why, why)
                    )
                    log(
                        f"  cut-back at t={self.t:.4g}: Newton {what} after "
                        f"{its} iterations, dt -> {dt:.3g}{self._residual_trace()}"
                    )
                if dt < control.dt_min:
                    raise NonConvergence(
                        f"Newton did not converge at t={self.t:.6g} even with dt={dt:.3g} < dt_min"
                    )
                continue
            self._unbalanced = self._out_of_balance()
            self.last_iterations = its
            self.last_linear_iterations = self.attempt_linear_iterations
            self.plastic_work += self.problem.plastic_dissipation_increment()
            self.problem.commit()
            if self.contact is not None:
                self.contact.commit(self.problem.u)
            if self.regularization is not None:
                dw = self._peculiar() - self._w_converged
                self.regularization_work += self.comm.allreduce(
                    float(self.drag_scale * np.sum(self.regularization.array_r * dw * dw))
                )
                self._w_converged[:] = self._peculiar()
            self.t = t_new
            self.step += 1
            steps += 1
            self.x.copy(self.x_old)
            self.drag_scale = 1.0  # the tangent kept between increments, as a restart builds it
            self._refresh_tangent()  # as a restart from here would (restarts are exact)
            self._since_cutback += 1
            if its <= control.easy_iterations and self._since_cutback > control.settle_steps:
                dt = min(dt * control.grow, control.dt_max)
            self.dt_next = dt  # before on_step: a checkpoint written there continues with it
            if on_step:
                on_step(self)
        return steps
