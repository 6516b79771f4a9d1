"""Compaction of a periodic granular volume (thesis chapter 2): packing -> assembly with
duplicated particles -> GDH / GDF / CLPS / CLP constraints -> contact -> solver -> history.

Sign convention: reported stresses are positive in compression (sigma_m > 0 in compaction);
strains keep their sign (h_v < 0 in compaction). Units mm, N, MPa, s.

Data flow: :class:`~mpfem_fenicsx.case.CompactionCase` (in sections) -> :func:`build_compaction`
(:class:`CompactionModel`: :func:`initial_packing` takes the packing and mesh sections,
:func:`contact_law` the contact section and the material, :func:`loading_path` the loading
section) -> :func:`make_solver` (the solver section) -> :class:`CompactionRun` (the loop,
:class:`HistoryRecorder` for the rows, :class:`CompactionCheckpoints` the output section) ->
:class:`CompactionResult`. History columns: :mod:`.history_recorder`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..boundary import boundary_kind
from ..case import (
    DIRECT_SOLVER_DOFS,
    BoundarySection,
    CompactionCase,
    ContactSection,
    LoadingSection,
    MeshSection,
    PackingSection,
    SolverSection,
)
from ..constraints.granular import GranularBoundaryConditions, periodic_lattice
from ..contact import ContactLaw, ContactModel
from ..contact.laws import default_penalty
from ..homogenization import solid_volume
from ..io import History
from ..io.checkpoint import (
    CheckpointError,
    checkpoint_path,
    load_checkpoint,
    prune_checkpoints,
    resolve_checkpoint,
    save_checkpoint,
)
from ..io.fields import CellFields, ParaViewWriter
from ..io.plots import plot_loading_path
from ..io.progress import Progress
from ..io.render import render_deformed
from ..loading import GradientPath, compaction_gradient
from ..material import ElastoPlastic
from ..meshes import node_particles, particle_mesh, particle_volumes
from ..meshes.admission import Admission, admit_packing
from ..meshes.cubesphere import unit_ball_hex
from ..meshes.packing import (
    Duplicates,
    Packing,
    assembly_particles,
    duplicate_particles,
    generate_packing,
    packing_format,
    periodic_pair_realizations,
    read_packing,
    write_packing,
)
from ..problem import SolidProblem
from ..solvers import NonConvergence, StepControl, create_solver, solver_kind
from ..solvers.explicit import ExplicitSettings
from ..solvers.implicit import FORCE_RTOL, ITERATIVE_OPTIONS, SNAP_INCREMENT, STALL_WINDOW
from .history_recorder import (
    COLUMNS,
    QUASI_STATIC_CHECK_COLUMNS,
    STATIC_CHECK_COLUMNS,
    HistoryRecorder,
    QuasiStaticCheck,
    StaticCheck,
    quasi_static_check,
    static_check,
)

#: partition weight of a CLP copy (tied nodes, no material: only its contact surface works) next
#: to a particle's 1
TIED_COPY_WORK = 0.3


class _Reached(Exception):
    """Raised by :meth:`CompactionRun.record` when the run's ``until`` holds."""


class RunFailure(RuntimeError):
    """A run that diverged or did not converge: ``step`` and ``t`` where it stopped, the history
    written so far and the last good checkpoint (None if none was written)."""

    def __init__(self, message: str, step: int, t: float, history: Path, checkpoint: Path | None):
        super().__init__(message)
        self.step, self.t, self.history, self.checkpoint = step, t, history, checkpoint


@dataclass
class CompactionResult:
    """What a compaction run returns: its history, packing, dof and model particle counts, wall
    time (s), increments and results folder."""

    history: History
    packing: Packing
    num_dofs: int
    num_particles_model: int
    wall_time: float
    increments: int
    out_dir: Path
    model: CompactionModel | None = None  # what the run was made of (packing -> ... -> contact)
    # the solver at the end of the run (its state, energies, timings)
    solver: object | None = None
    #: explicit runs: the energy balance's and the balance's verdict on the loading rate (also
    #: logged)
    quasi_static: QuasiStaticCheck | StaticCheck | None = None
    case: CompactionCase | None = (
        None  # the case the run ran (with the checkpoint's packing on restart)
    )


def initial_packing(
    spheres: PackingSection, mesh: MeshSection, target_density: float, log=None
) -> Admission:
    """The packing section's spheres (its object, its file, or the generator) admitted for the
    run by :func:`~mpfem_fenicsx.meshes.admission.admit_packing`, before any mesh: spheres in the
    cell, no overlap of the spheres through the particle meshes' nodes at the start (the default
    radius reduction ``mesh.radius_factor`` lowered for a DEM packing's contact overlaps), and
    the initial relative density rho0 = V_p / V0 with the meshed radii (thesis eq. 2.5) below
    ``target_density``. ``log`` reports what was decided. Raises ValueError naming the file,
    particle or field."""
    if spheres.spheres is not None:
        packing = spheres.spheres
    elif spheres.file is not None:
        packing = read_packing(spheres.file, validate=False)
        if log is not None:
            log(f"packing: {spheres.file} read as {packing_format(spheres.file)}")
    else:
        packing = generate_packing(
            spheres.particles,
            spheres.r_min,
            spheres.r_max,
            seed=spheres.seed,
            target_fraction=spheres.fraction,
        )
    divisions, layers = mesh.subdivisions
    particle = unit_ball_hex(divisions, layers, mesh.refinement, exact_volume=mesh.exact_volume)
    admitted = admit_packing(
        packing,
        mesh.radius_factor,
        particle.radius_scale,
        target_density=target_density,
        automatic=mesh.radius_factor == MeshSection.radius_factor,
    )
    for note in admitted.notes if log is not None else ():
        log(f"packing: {note}")
    return admitted


@dataclass
class CompactionModel:
    """Everything a compaction run is made of (data flow: packing -> assembly -> problem ->
    constraints + contact), before any increment."""

    boundary: BoundarySection  # the boundary condition the model realizes
    loading: LoadingSection  # the path the constraints follow
    packing: Packing
    centres: np.ndarray  # assembly particles (originals first, then copies), reference, mm
    radii: np.ndarray  # meshed radii (mm)
    original: np.ndarray
    shift: np.ndarray
    assembly: object
    problem: SolidProblem
    bcs: GranularBoundaryConditions
    contact: ContactModel
    path: GradientPath
    solid_volume0: float  # V_p = 4/3 pi sum r^3 of the VEP particles' meshed radii (mm^3)
    rho0: float  # V_p / V0
    rho0_fe: float  # finite-element particle volumes / V0
    contact_length: float  # surface element edge of the smallest cube-sphere (mm)

    @property
    def is_copy(self) -> np.ndarray:
        """Boolean mask over the assembly particles: True for the periodic copies."""
        return np.any(self.shift != 0, axis=1)

    @property
    def num_dofs(self) -> int:
        """Displacement dofs of the whole assembly, all ranks (3 per node)."""
        return self.problem.V.dofmap.index_map.size_global * 3

    def follow(self, loading: LoadingSection) -> None:
        """Reuse this model for another loading (same packing, mesh and contact settings): its
        path replaces the model's, the constraints follow it."""
        self.loading = loading
        self.path = self.bcs.gradient = loading_path(loading, self.rho0)


def loading_path(loading: LoadingSection, rho0: float) -> GradientPath:
    """F0(t): the compaction from ``rho0`` to the target density (thesis §2.2.3), a hold, then
    ``loading.segments_after``; or the loading's mixed control."""
    if loading.control is not None:
        return loading.control
    hold = [(loading.hold * loading.duration, np.eye(3))] if loading.hold > 0 else []
    return GradientPath(
        [
            (loading.duration, compaction_gradient(loading.path, rho0, loading.target_density)),
            *hold,
            *loading.segments_after,
        ],
        profiles=(loading.profile, *("smooth-step" for _ in hold), *loading.segment_profiles),
    )


def contact_law(contact: ContactSection, material: ElastoPlastic, h_contact: float) -> ContactLaw:
    """The contact law of the ``[contact]`` section (thesis §3.3) with the penalty
    ``penalty_factor x E / h_contact`` (h_contact: the surface element edge, mm) and the
    tangential penalty ``tangential_penalty_ratio`` x it (eq. 3.14); raises
    ValueError if the adhesive law has no softening branch at that penalty."""
    penalty = default_penalty(material.E, h_contact, contact.penalty_factor)
    law = ContactLaw(
        penalty=penalty,
        tangential_penalty=contact.tangential_penalty_ratio * penalty,
        friction=contact.friction,
        gamma=contact.gamma,
        delta_max=contact.delta_max,
        asperity_yield=contact.asperity_yield,
    )
    law.require_softening_branch()  # before meshing: the penalty follows the mesh resolution
    return law


def build_compaction(
    case: CompactionCase, comm: MPI.Comm = MPI.COMM_WORLD, log=print
) -> CompactionModel:
    """Packing, duplicated particles, mesh, bulk problem, constraints and contact of a case: the
    pipeline's stages, each given the sections it needs."""
    mesh_section, boundary = case.mesh, case.boundary
    # the start-overlap rule and the radius reduction
    admitted = initial_packing(case.packing, mesh_section, case.loading.target_density, log)
    packing, rho0 = admitted.packing, admitted.rho0
    n = packing.num_particles
    kind = boundary_kind(boundary.condition)
    duplication_distance = boundary.d_bc_ratio() * float(packing.radii.max())  # mm
    if boundary.uses_images:  # CLP by periodic images: no copies
        copies = Duplicates(
            np.zeros(0, np.int64), np.zeros((0, 3), np.int64), np.zeros((0, 3)), np.zeros(0)
        )
    else:
        copies = duplicate_particles(
            packing, duplication_distance, faces=kind.copy_faces, corners=boundary.corners
        )
    centres, radii, original, shift = assembly_particles(packing, copies)
    radii = radii * admitted.radius_factor
    is_copy = np.any(shift != 0, axis=1)
    log(
        f"packing: {n} particles, solid fraction {packing.solid_fraction:.4f}, "
        f"cell {packing.cell}; "
        f"{int(is_copy.sum())} duplicated particles (d_bc = {duplication_distance:.4g} mm, bc "
        f"{boundary.condition})"
    )

    solid0 = solid_volume(radii[:n])  # thesis eq. 2.5, initial (meshed) radii

    divisions, layers = mesh_section.subdivisions
    # surface element edge at a cube-face centre of the smallest particle (equi-angular grid)
    h_contact = float(radii.min()) * np.pi / (2 * divisions * mesh_section.refinement)
    law = contact_law(case.contact, case.material, h_contact)
    rotations = None
    if mesh_section.rotation is not None:  # one for all, or one per particle (copies: theirs)
        Q = np.asarray(mesh_section.rotation, dtype=float)
        if Q.ndim == 3 and Q.shape[0] != n:
            raise ValueError(
                f"mesh.rotation has {Q.shape[0]} matrices for a packing of {n} particles"
            )
        rotations = np.broadcast_to(Q, (radii.size, 3, 3)) if Q.ndim == 2 else Q[original]
    assembly = particle_mesh(
        centres,
        radii,
        comm,
        divisions=divisions,
        layers=layers,
        refinement=mesh_section.refinement,
        exact_volume=mesh_section.exact_volume,
        rotations=rotations,
        # a tied copy carries no material work, only its contact surface's
        weights=np.where(is_copy, TIED_COPY_WORK, 1.0) if kind.tied_nodes else None,
    )
    mesh = assembly.mesh
    owned_cells = mesh.topology.index_map(3).size_local
    cell_particle = assembly.cell_tags.values[:owned_cells]
    active = np.flatnonzero(~is_copy[cell_particle]) if kind.tied_nodes else None
    solver = solver_kind(case.solver.kind)
    problem = SolidProblem(mesh, case.material, tangent=solver.tangent, active_cells=active)
    V = problem.V

    rho0_fe = float(particle_volumes(assembly, problem.u)[:n].sum()) / float(np.prod(packing.cell))
    path = loading_path(case.loading, rho0)

    # CLP's tied copies: one body pair per periodic pair (copy-copy only for mixed lattice shifts);
    # solid copies (GDH, GDF, CLPS) touch each other as separate bodies
    allowed = (
        periodic_pair_realizations(original, shift)
        if kind.tied_nodes
        else np.ones((radii.size, radii.size), dtype=bool)
    )
    contact = ContactModel(
        V,
        assembly.facet_tags,
        radii.size,
        law,
        search_distance=max(0.05 * float(radii.min()), 2 * case.contact.delta_max),
        allowed=allowed,
        shifts=periodic_lattice() * packing.cell if boundary.uses_images else None,
    )
    bcs = GranularBoundaryConditions(
        V,
        cell_particle,
        centres,
        radii,
        original,
        shift,
        packing.cell,
        boundary.condition,
        path,
        images=contact if boundary.uses_images else None,
        anchor=solver.anchored,
        comoving=boundary.comoving,
        equal_rotations=boundary.equal_rotations,
    )
    return CompactionModel(
        boundary,
        case.loading,
        packing,
        centres,
        radii,
        original,
        shift,
        assembly,
        problem,
        bcs,
        contact,
        path,
        solid0,
        rho0,
        rho0_fe,
        h_contact,
    )


def make_solver(solver: SolverSection, model: CompactionModel, log=print):
    """The solver factory: the ``[solver]`` section's solver on the model (the one place that
    reads its name), with the increments of the model's whole loading path."""
    problem, bcs, path, loading = model.problem, model.bcs, model.path, model.loading
    model_line = (
        f"model: {model.radii.size} particles, {model.num_dofs} dofs "
        f"({bcs.constraint.num_reduced_global} free), rho0 = {model.rho0:.4f}"
    )
    if solver_kind(solver.kind).static:
        log(
            "WARNING: implicit granular runs are experimental: the drag on the particles' cores "
            "holds them until their contacts do, and Newton takes ~7 iterations per load step "
            "once contacts yield (the flagship: ~40 min to rho 0.92, against minutes explicit; "
            "die paths much longer); use the explicit solver for production runs"
        )
        # backtracking line search: frictional stick / slip switches make full Newton steps cycle
        # (an explicit state relaxed to rest stalled at 1e-1 of its residual without it)
        implicit = create_solver(
            solver.kind,
            problem,
            bcs,
            contact=model.contact,
            petsc_options={"snes_linesearch_type": "bt", **linear_solver_options(solver, model)},
            regularization=core_drag(model, solver.regularization),
            drag_update=held_drag(model, solver),
            controls=implicit_step_controls(solver, loading.duration, path),
        )
        log(f"{model_line} -> {loading.target_density}, implicit, {implicit.total_steps} steps")
        return implicit
    settings = ExplicitSettings(
        t_end=path.duration,
        target_dt=loading.duration / solver.increments,
        damping=solver.damping / loading.duration,
        local_damping=solver.local_damping,
        constraint_mass=solver.constraint_mass,
    )
    node_particle = node_particles(problem.V, model.assembly.cell_tags.values[: problem.num_cells])
    explicit = create_solver(
        solver.kind,
        problem,
        bcs,
        contact=model.contact,
        settings=settings,
        damped_bodies=damped_bodies(model.boundary.condition, model.original)[node_particle],
    )
    log(
        f"{model_line} (finite elements {model.rho0_fe:.4f}) -> "
        f"{'stress-controlled' if loading.control is not None else loading.target_density}, "
        f"dt = {explicit.dt:.3g} s (unscaled {explicit.dt_stable_unscaled:.3g} s), "
        f"{solver.increments} increments"
    )
    return explicit


def linear_solver_options(solver: SolverSection, model: CompactionModel) -> dict:
    """PETSc options of the ``[solver] linear_solver``: none for the direct solver (the implicit
    solver's MUMPS default), the iterative solver's (``ITERATIVE_OPTIONS``) otherwise; ``auto``
    takes the direct one up to ``DIRECT_SOLVER_DOFS`` free dofs."""
    choice = solver.linear_solver
    if choice == "auto":
        free = model.bcs.constraint.num_reduced_global
        choice = "direct" if free <= DIRECT_SOLVER_DOFS else "iterative"
    return {} if choice == "direct" else dict(ITERATIVE_OPTIONS)


#: the particle core that carries the implicit solver's drag: nodes within this fraction of the
#: radius from the particle's centre (reference configuration)
DRAG_CORE_RADIUS = 0.5


def core_drag(model: CompactionModel, factor: float) -> np.ndarray:
    """The implicit solver's pseudo-time drag stiffness k_i (N/mm) per owned dof: on each
    particle a total factor E V_p / h^2 (V_p the particle's volume, h the contact element size),
    spread over the nodes of its core (within ``DRAG_CORE_RADIUS`` r of its centre) in
    proportion to their nodal volumes; zero elsewhere.

    The drag holds what the static problem cannot: the rigid motion of a particle before its
    contacts do (singular without it). The core moves with the particle's rigid motion and
    barely deforms (plastic flow is at the contacts), so the drag leaves the contact zones'
    deformation free: on the flagship's first contacts its work is 2-5 % of E_p, against
    ~50 % with the same total spread over every node (which resists each increment's
    deformation with a few % of the elastic stiffness, more than a yielding contact has)."""
    problem = model.problem
    return particle_core_drag(
        problem,
        model.assembly.cell_tags.values[: problem.num_cells],
        model.centres,
        model.radii,
        factor * problem.params.E / model.contact_length**2,
    )[: model.bcs.constraint.num_owned]


def particle_core_drag(
    problem: SolidProblem,
    cell_particle: np.ndarray,
    centres: np.ndarray,
    radii: np.ndarray,
    stiffness: float,
) -> np.ndarray:
    """The drag of :func:`core_drag` on any assembly of particles (``cell_particle``: the
    particle of each owned cell; ``centres``, ``radii``: mm, reference configuration): per owned
    node dof (blocks of 3), each particle's total ``stiffness`` x V_p (N/mm, ``stiffness`` in
    N/mm^4) spread over its core's nodes by their nodal volumes. A particle without volume (a
    tied copy's massless shell) has none."""
    V = problem.V
    particle = node_particles(V, cell_particle)
    X = V.tabulate_dof_coordinates()[: particle.size]
    radius = radii[particle]
    core = np.linalg.norm(X - centres[particle], axis=1) < DRAG_CORE_RADIUS * radius
    volume = problem.lumped_mass(1.0).x.array[: 3 * particle.size : 3]
    # each particle's total and core nodal volume, summed over ranks (a particle may be split)
    bodies = radii.size
    totals = np.bincount(particle, weights=volume, minlength=bodies)
    in_core = np.bincount(particle, weights=np.where(core, volume, 0.0), minlength=bodies)
    totals, in_core = (problem.comm.allreduce(a) for a in (totals, in_core))
    if np.any((totals > 0.0) & (in_core <= 0.0)):
        raise ValueError("core_drag: a particle has no node within its drag core")
    ratio = np.divide(totals, in_core, out=np.zeros(bodies), where=in_core > 0.0)
    k = np.where(core, stiffness * volume * ratio[particle], 0.0)
    return np.repeat(k, 3)


#: force-carrying contacts from which the implicit drag counts a particle as held by its
#: contacts (d + 1 in 3-D: the rattler threshold of the coordination number)
HELD_CONTACTS = 4


def held_drag(model: CompactionModel, solver: SolverSection):
    """The implicit solver's ``drag_update``: :func:`core_drag` at ``solver.regularization`` on
    the particles with fewer than ``HELD_CONTACTS`` force-carrying contacts at the committed
    state (counted per volume particle: a copy shares its original's), at
    ``solver.held_regularization`` on the others. The drag holds particles until their contacts
    do; on a held particle it only steadies Newton (a drag as strong as the free particles'
    resists the network's rearrangement and adds a stress of several %)."""
    full = core_drag(model, solver.regularization)
    held = full * (solver.held_regularization / solver.regularization)
    V = model.problem.V
    particle = node_particles(V, model.assembly.cell_tags.values[: model.problem.num_cells])
    body = model.original[np.repeat(particle, 3)[: full.size]]

    def update() -> np.ndarray:
        forces = model.contact.pair_forces()  # summed over ranks
        pairs = forces["pairs"][forces["points"] > 0]
        contacts = np.bincount(model.original[pairs.ravel()], minlength=model.original.size)
        return np.where(contacts[body] >= HELD_CONTACTS, held, full)

    return update


def damped_bodies(bc: str, original: np.ndarray) -> np.ndarray:
    """The body of each assembly particle whose rigid motion relative to the imposed flow the
    explicit damping relaxes: its original's index (a periodic copy, tied or coupled, moves with
    its original: one body), or -1 where F0 drives the particle's reference point (the copies of
    GDF, every particle of GDH): that motion is imposed, and damping it with the volume would tie
    the free particles to the imposed flow through their driven copies' forces."""
    driven = {
        "all": np.ones(original.size, bool),
        "copies": original != np.arange(original.size),
        "none": np.zeros(original.size, bool),
    }[boundary_kind(bc).driven]
    return np.where(driven, -1, original)


class CompactionCheckpoints:
    """The checkpoints of a compaction run in ``root``: every ``every`` history rows and at the
    end, the newest ``keep`` kept; each holds the solver's state, the history so far, the
    reference centroids, the packing, the control's state and F0 (a run continues from one bit
    for bit, explicit)."""

    def __init__(
        self,
        root: Path,
        comm: MPI.Comm,
        every: int,
        keep: int,
        solver_name: str,
        restart: Path | None = None,
    ):
        self.root, self.comm, self.every, self.keep = Path(root), comm, every, keep
        self.solver_name = solver_name  # the [solver] kind that writes (and restores) the states
        self.last: Path | None = None
        self.restart = restart

    def due(self, rows: int) -> bool:
        """Whether a checkpoint is due after ``rows`` history rows (never if ``every`` is 0)."""
        return bool(self.every) and rows % self.every == 0

    def write(
        self,
        solver,
        model: CompactionModel,
        history: History,
        reference_centroids: np.ndarray,
        wall_time: float,
    ) -> None:
        """Write a checkpoint of the run at the solver's step (collective) and prune the old ones
        to the newest ``keep``."""
        packing, V, control = model.packing, model.problem.V, model.loading.control
        arrays = {f"solver/{k}": v for k, v in solver.state_dict().items()}
        arrays["dof_coordinates"] = _dof_coordinates(V)
        directory = checkpoint_path(self.root, solver.step)
        save_checkpoint(
            directory,
            self.comm,
            arrays,
            {
                "step": solver.step,
                "t": solver.t,
                "solver": self.solver_name,
                "bc": model.boundary.condition,
                "num_dofs": model.num_dofs,
                "centroids0": reference_centroids.tolist(),
                "history": history.rows,
                "columns": history.columns,
                "control": None if control is None else control.state_dict(),
                "F0": model.path(solver.t).tolist(),
                "wall_time": wall_time,
                "packing": {
                    "cell": packing.cell.tolist(),
                    "centres": packing.centres.tolist(),
                    "radii": packing.radii.tolist(),
                },
            },
        )
        if self.comm.rank == 0:
            prune_checkpoints(self.root, self.keep)
        self.last = directory

    @property
    def resume_from(self) -> Path | None:
        """The newest good checkpoint: the last written, or the one the run restarted from."""
        return self.last or self.restart

    def restore(
        self, arrays: dict, meta: dict, solver, model: CompactionModel, history: History
    ) -> None:
        """Continue from a checkpoint read with ``load_checkpoint``: the control's state, the
        history rows, the solver's state (an implicit solver adopts an explicit state relaxed to
        rest). Raises CheckpointError if it was written for another model or partition."""
        V, num_dofs, name, bc = (
            model.problem.V,
            model.num_dofs,
            self.solver_name,
            model.boundary.condition,
        )
        control = model.loading.control
        adopt = meta["solver"] != name and meta["solver"] in solver_kind(name).continues
        if (
            meta["num_dofs"] != num_dofs
            or (meta["solver"] != name and not adopt)
            or meta["bc"] != bc
        ):
            raise CheckpointError(
                f"restart: {self.restart} was written for another model ({meta['num_dofs']} dofs, "
                f"{meta['solver']}, {meta['bc']}; this case: {num_dofs} dofs, {name}, {bc})"
            )
        if not _same_partition(arrays["dof_coordinates"], _dof_coordinates(V)):
            raise CheckpointError(
                f"restart: {self.restart} was written with another mesh partition"
            )
        if control is not None:  # the servo before the solver asks it for F0
            if meta.get("control") is not None:  # as it was (a new stress path continues it)
                control.load_state(meta["control"])
            elif meta.get("F0") is not None:  # a stress path from a strain-driven state
                control.begin(float(meta["t"]), np.array(meta["F0"], dtype=float))
            else:
                raise CheckpointError(
                    f"restart: {self.restart} does not record its gradient F0 (written before "
                    "2026-11-25): a stress-controlled run cannot continue it"
                )
        history.rows = _history_rows(meta, history.columns)
        state = {k[7:]: v for k, v in arrays.items() if k.startswith("solver/")}
        if adopt:
            solver.adopt_state(
                state, translation=_anchor_displacement(model.bcs, V, state["u"], float(state["t"]))
            )
            solver.plastic_work = history.rows[-1][
                history.columns.index("E_p_model")
            ]  # the tally goes on
        else:
            solver.load_state(state)


class CompactionRun:
    """One compaction run, its parts named after the data flow: the model (packing -> assembly
    -> problem -> constraints + contact, :func:`build_compaction`), the solver
    (:func:`make_solver`), the history recorder (:class:`HistoryRecorder`, the column schema),
    the checkpoints (:class:`CompactionCheckpoints`); :meth:`run` drives the loop.

    ``restart``: a checkpoint directory written by an earlier run of the same case (same
    packing, mesh and number of ranks): the run continues from it and reproduces the
    uninterrupted one (explicit: bit for bit); a case without packing takes the checkpoint's.
    ``model``: a model built earlier for the same packing, mesh and contact settings on ``comm``
    (a fan of reloads restarts one checkpoint many times; only the path of ``case`` and its
    outputs may differ), whose state the restart overwrites. The case is not modified.
    ``until``: row -> bool (the history row's columns; the same on every rank): the run ends at
    the first history row for which it holds, as at the end of its path (final checkpoint and
    outputs)."""

    def __init__(
        self,
        case: CompactionCase,
        comm: MPI.Comm = MPI.COMM_WORLD,
        log=print,
        *,
        restart: str | Path | None = None,
        progress: Progress | None = None,
        model: CompactionModel | None = None,
        until: Callable[[dict], bool] | None = None,
    ):
        self.start = time.perf_counter()
        self.until = until
        self.comm, self.log = comm, log
        arrays = meta = None
        if restart is not None:
            restart = resolve_checkpoint(restart)
            arrays, meta = load_checkpoint(
                restart, comm
            )  # checks the number of ranks before any build
            if (
                case.packing.spheres is None and case.packing.file is None
            ):  # the checkpoint's own packing
                pk = meta["packing"]
                case = case.updated(spheres=Packing(pk["cell"], pk["centres"], pk["radii"]))
        self.case = case
        self.out = Path(case.output.directory)
        if model is None:
            model = build_compaction(case, comm, log)
        else:  # reuse: only the path changes (the restart then restores every state variable)
            if restart is None:
                raise ValueError("CompactionRun: a reused model needs a restart checkpoint")
            model.follow(case.loading)
        self.model = model
        self.solver = make_solver(case.solver, model, log)
        self.recorder = HistoryRecorder(model, comm, None if meta is None else meta["centroids0"])
        self.history = History(self.out / "history.csv", COLUMNS, comm, flush_every_row=True)
        self.checkpoints = CompactionCheckpoints(
            self.out / "checkpoints",
            comm,
            case.output.checkpoint_every,
            case.output.checkpoint_keep,
            case.solver.kind,
            restart,
        )
        self.progress = progress or Progress(comm, stream=_LogStream(log))
        self.wall_offset = 0.0
        if meta is not None:  # restart: model, solver, history and clocks as they were
            self.checkpoints.restore(arrays, meta, self.solver, model, self.history)
            self.wall_offset = float(meta["wall_time"])
            log(
                f"restart from {restart}: step {meta['step']}, t = {meta['t']:.6g} s, "
                f"{len(self.history.rows)} history rows"
            )
        self.writer = self.fields = None
        if case.output.visual:
            self.fields = CellFields(model.problem, model.assembly.cell_tags)
            name = "particles.xdmf" if meta is None else f"particles_from_step{meta['step']}.xdmf"
            self.writer = ParaViewWriter(
                self.out / name, model.problem, self.fields, contact=model.contact
            )
        if comm.rank == 0:
            self.out.mkdir(parents=True, exist_ok=True)
            write_packing(model.packing, self.out / "packing.txt")

    @property
    def wall_time(self) -> float:
        """Wall time of the run (s), the restarted runs' before it included."""
        return self.wall_offset + time.perf_counter() - self.start

    def write_checkpoint(self) -> None:
        """Write a checkpoint of the run as it stands now (collective)."""
        self.checkpoints.write(
            self.solver, self.model, self.history, self.recorder.X0, self.wall_time
        )

    def record(self, solver) -> None:
        """An output: a history row, the ParaView fields, the progress line, a checkpoint when
        due."""
        row = self.recorder.measure(solver, self.wall_time)
        self.history.append(**row)
        if self.writer is not None:
            self.writer.write(solver.t)
        self.progress.update(
            solver.t / self.model.path.duration,
            solver.step,
            self.solver.total_steps,
            rho=row["rho"],
            sigma_m=row["sigma_m"],
            extra=_progress_note(row),
        )
        if self.checkpoints.due(len(self.history.rows)):
            self.write_checkpoint()
        if self.until is not None and self.until(row):
            raise _Reached

    def servo(self, solver) -> None:
        """Mixed control, every ``control.every`` increments: the measured Cauchy stress
        (compression > 0) of ``control.measure`` to the servo."""
        control = self.case.loading.control
        if solver.step % control.every == 0:
            control.update(solver.t, -self.recorder.measured_stress(solver, control.measure))

    def run(self, max_steps: int | None = None) -> CompactionResult:
        """Run to the end of the path (``max_steps``: stop after so many increments of this call,
        without the final outputs: a benchmark's part of a run). A diverging or non-converging
        run raises :class:`RunFailure` after writing its history so far; the last good
        checkpoint stays."""
        output, control, solver = self.case.output, self.case.loading.control, self.solver
        first = solver.step
        try:
            total = solver.run_path(
                self.record,
                outputs=output.outputs,
                every=output.every or None,
                max_steps=max_steps,
                on_step=self.servo if control is not None else None,
                log=self.log,
            )
        except _Reached:
            total = solver.step - first  # the increments of this call, as run_path counts them
            self.log(f"stopped at t = {solver.t:.6g} s: the run's end condition holds")
        except (FloatingPointError, NonConvergence) as err:
            self._fail(err)
        self.progress.close()
        check = None
        if max_steps is None:
            self._finish()
            check = self.quasi_static_check()
        return CompactionResult(
            self.history,
            self.model.packing,
            self.model.num_dofs,
            self.model.radii.size,
            self.wall_time,
            total,
            self.out,
            model=self.model,
            solver=solver,
            quasi_static=check,
            case=self.case,
        )

    def quasi_static_check(self) -> QuasiStaticCheck | StaticCheck | None:
        """The history's check, logged in one line: explicit runs, the quasi-static check
        (:func:`quasi_static_check`; a strain path ends at rest, a stress-controlled one need
        not); Newton runs, the static check (:func:`static_check`: the contacts carry the
        particles' stress, not the pseudo-time drag)."""
        if not self.history.rows:
            return None
        if solver_kind(self.case.solver.kind).static:
            check = static_check({c: self.history.column(c) for c in STATIC_CHECK_COLUMNS})
            self.log(check.summary())
            return check
        columns = {c: self.history.column(c) for c in QUASI_STATIC_CHECK_COLUMNS}
        check = quasi_static_check(columns, at_rest=self.case.loading.control is None)
        self.log(check.summary(self.solver.total_steps))
        return check

    def _fail(self, err: Exception):
        self.progress.close()
        self.history.write()
        if self.writer is not None:
            self.writer.close()
        solver, resume = self.solver, self.checkpoints.resume_from
        # a non-finite state is found after its increment is counted; Newton fails before
        step = solver.step + 1 if isinstance(err, NonConvergence) else solver.step
        kept = (
            f"last good checkpoint {resume} (continue with --restart)"
            if resume
            else "no checkpoint was written yet"
        )
        raise RunFailure(
            f"the run stopped at step {step} (t = {solver.t:.6g} s): {err}; history so far "
            f"in {self.history.path}, {kept}",
            step,
            solver.t,
            self.history.path,
            resume,
        ) from err

    def _finish(self) -> None:
        """The final checkpoint (the chapter-4 reloads start from it), the history, the figures."""
        case, model = self.case, self.model
        every = case.output.checkpoint_every
        if every and len(self.history.rows) % every != 0:
            self.write_checkpoint()
        self.history.write()
        if self.writer is None:
            return
        self.writer.close()
        n = model.packing.num_particles
        # CLP shell copies carry no stress: show the volume's particles only
        render_deformed(
            model.problem.u,
            self.fields.von_mises,
            self.out / "particles.png",
            cells=model.problem.material_cells,
            title=f"{n} lead particles, {case.loading.path} compaction, {case.boundary.condition}, "
            f"rho = {self.history.column('rho')[-1]:.3f}",
            save_grid=True,
        )
        if self.comm.rank == 0:
            plot_loading_path(
                self.history.path,
                self.out / "loading_path.png",
                title=f"{n} particles, {case.loading.path} compaction, {case.boundary.condition}",
            )


def run_compaction(
    case: CompactionCase,
    comm: MPI.Comm = MPI.COMM_WORLD,
    log=print,
    *,
    restart: str | Path | None = None,
    progress: Progress | None = None,
    model: CompactionModel | None = None,
    until: Callable[[dict], bool] | None = None,
) -> CompactionResult:
    """Compact the volume to ``case.loading.target_density`` (or along its path, or ``until``
    a history row meets it): ``CompactionRun(...).run()``; the columns of the history:
    :mod:`.history_recorder`."""
    return CompactionRun(
        case, comm, log, restart=restart, progress=progress, model=model, until=until
    ).run()


#: columns added since the first checkpoints (which do not list theirs): filled with NaN on restart
_COLUMNS_ADDED = (
    "Gamma_model",
    "Gamma_closed",
    "newton_iterations",
    "linear_iterations",
    "cutbacks",
)


def _history_rows(meta: dict, columns: list[str]) -> list[list[float]]:
    """A checkpoint's history rows in the order of ``columns``, matched by name; columns the
    checkpoint did not have are NaN."""
    saved = meta.get("columns") or [c for c in columns if c not in _COLUMNS_ADDED]
    if any(len(row) != len(saved) for row in meta["history"]):
        raise CheckpointError(
            f"restart: the checkpoint's history rows do not match its {len(saved)} columns"
        )
    where = {c: k for k, c in enumerate(saved)}
    return [
        [float(row[where[c]]) if c in where else np.nan for c in columns] for row in meta["history"]
    ]


def implicit_step_controls(
    solver: SolverSection, duration: float, path: GradientPath
) -> list[StepControl]:
    """One step control per path segment: the compaction (``duration`` s) in ``solver.steps``
    steps, then each further segment in its ``solver.segment_steps`` (default: the compaction's
    increment). Segments end exactly at their knots; an increment carried over from a segment is
    capped by the next one's (StepControl.dt_max)."""
    knots = path.knots
    controls = []
    for k in range(len(knots) - 1):
        length = knots[k + 1] - knots[k]
        if k == 0:
            n = solver.steps
        elif k - 1 < len(solver.segment_steps):
            n = int(solver.segment_steps[k - 1])
        else:
            n = max(1, round(length * solver.steps / duration))
        controls.append(granular_step_control(knots[k + 1], length / n))
    return controls


def granular_step_control(t_end: float, dt: float) -> StepControl:
    """The step control of a granular volume's segment ending at ``t_end`` (s) at increments of
    ``dt`` (s): cut back to dt / 256 at the most, grown back to dt after 2 settled increments of
    up to 20 Newton iterations, Newton's stall test on, an adhesive point's snap-off on
    increments of dt / 16 or less, Newton converged at a residual of FORCE_RTOL x the internal
    forces. A granular increment takes ~15-20
    iterations whatever its length (contact rims entering, ~100 material points crossing the
    yield surface per iteration on the flagship): growing back after a cut-back only below 6
    (the default) would keep the cut increment for the rest of the path."""
    return StepControl(
        t_end=t_end,
        dt=dt,
        dt_max=dt,
        dt_min=dt / 256,
        easy_iterations=20,
        settle_steps=2,
        stall_window=STALL_WINDOW,
        snap_increment=SNAP_INCREMENT,
        force_rtol=FORCE_RTOL,
    )


def _anchor_displacement(bcs: GranularBoundaryConditions, V, u: np.ndarray, t: float) -> np.ndarray:
    """Translation (mm) that brings the node an implicit periodic model anchors to its prescribed
    displacement at time t, from a state ``u`` (local array, blocks of 3) of a model without anchor
    (zero when there is none)."""
    c = np.zeros(3)
    if bcs.anchor_block is not None:
        lo, hi = V.dofmap.index_map.local_range
        if lo <= bcs.anchor_block < hi:
            i = 3 * (bcs.anchor_block - lo)
            c = (
                np.asarray(u[i : i + 3], dtype=float)
                - bcs.displacement_gradient(t) @ bcs.anchor_carrier
            )
    return V.mesh.comm.allreduce(c)


def _progress_note(row: dict[str, float]) -> str:
    """The progress line's measures of a history row: the out-of-balance ratio, the contacts,
    E_p; an explicit row's kinetic energy, an implicit row's Newton iterations, cut-backs and
    drag work (E_damp) over E_p."""
    note = (
        f"unbalanced {row['unbalanced']:.2g}  contacts {row['n_contacts']:.0f} "
        f"(Z {row['Z']:.2f})  E_p {row['E_p']:.3g} mJ"
    )
    if np.isnan(row["newton_iterations"]):
        return note + f"  E_c {row['E_c']:.2g} mJ"
    drag = f"{row['E_damp'] / row['E_p_model']:.2%}" if row["E_p_model"] > 0 else "-"
    return note + (
        f"  Newton {row['newton_iterations']:.0f} it  cut-backs {row['cutbacks']:.0f}  "
        f"E_drag / E_p {drag}"
    )


def _dof_coordinates(V) -> np.ndarray:
    """Coordinates of this rank's owned dof blocks (identifies the partition of a checkpoint)."""
    return V.tabulate_dof_coordinates()[: V.dofmap.index_map.size_local]


def _same_partition(saved: np.ndarray, here: np.ndarray) -> bool:
    """Whether a checkpoint's owned dof coordinates are this rank's, in the same order.

    The particle meshes are regenerated at every run: on another machine (another CPU, another
    libm) their nodes may move by round-off (~1e-16 of the cell), never by a mesh size; another
    partition or ordering moves them by a mesh size. The tolerance is 1e-10 of the extent."""
    extent = float(np.ptp(here)) if here.size else 0.0
    return saved.shape == here.shape and np.allclose(saved, here, rtol=0.0, atol=1e-10 * extent)


class _LogStream:
    """A file-like wrapper of a ``log`` function (progress lines go where the log goes)."""

    def __init__(self, log):
        self._log = log

    def write(self, text: str) -> None:
        text = text.rstrip("\n")
        if text:
            self._log(text)

    def flush(self) -> None:
        pass
