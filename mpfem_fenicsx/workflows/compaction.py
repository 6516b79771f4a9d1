"""Compaction of a periodic granular volume (thesis chapter 2): packing -> assembly with
duplicated particles -> GDH / GDF / CLPS / CLP constraints -> contact -> solver -> history.

Sign convention: reported stresses are positive in compression (sigma_m > 0 in compaction);
strains keep their sign (h_v < 0 in compaction). Units mm, N, MPa, s.

Data flow: :class:`CompactionCase` -> :func:`build_compaction` (:class:`CompactionModel`) ->
:func:`make_solver` -> :class:`CompactionRun` (the loop, :class:`HistoryRecorder` for the rows,
:class:`CompactionCheckpoints`) -> :class:`CompactionResult`. History columns:
:mod:`.history_recorder`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..boundary import KINDS, boundary_kind
from ..constraints.granular import GranularBoundaryConditions, periodic_lattice
from ..contact import ContactLaw, ContactModel
from ..contact.laws import default_penalty
from ..homogenization import solid_volume
from ..io import History
from ..io.checkpoint import (CheckpointError, checkpoint_path, load_checkpoint, prune_checkpoints,
                             resolve_checkpoint, save_checkpoint)
from ..io.fields import CellFields, ParaViewWriter
from ..io.plots import plot_loading_path
from ..io.progress import Progress
from ..io.render import render_deformed
from ..loading import PROFILES, GradientPath, compaction_gradient
from ..material import LEAD, ElastoPlastic
from ..meshes.cubesphere import RESOLUTIONS, unit_ball_hex
from ..meshes import node_particles, particle_mesh, particle_volumes
from ..meshes.admission import Admission, admit_packing
from ..meshes.packing import (Duplicates, Packing, assembly_particles, duplicate_particles, generate_packing,
                              packing_format, periodic_pair_realizations, read_packing,
                              write_packing)
from ..problem import SolidProblem
from ..parameters import check_parameters, parameter
from ..solvers import SOLVERS, NonConvergence, StepControl, create_solver, solver_kind
from ..solvers.constraint_mass import CONSTRAINT_MASSES
from ..solvers.explicit import ExplicitSettings
from .history_recorder import (COLUMNS, QUASI_STATIC_CHECK_COLUMNS, HistoryRecorder, QuasiStaticCheck,
                               quasi_static_check)


@dataclass
class CompactionCase:
    """A compaction run. Radii in mm (thesis: 0.082-0.147 mm), densities relative (-)."""

    particles: int = parameter(24, "particles of the generated periodic packing", low=2, high=5000)
    target_density: float = parameter(0.92, "relative density to reach, above the packing's initial one (-)",
                                      low=0, high=1, open_low=True, open_high=True)
    loading: str = parameter("isotropic", "isotropic or die (uniaxial strain along z) compaction",
                             choices=("isotropic", "die"))
    bc: str = parameter("CLP", "GDH, GDF (driven particles), CLPS (simplified periodic) or CLP (periodic)",
                        choices=tuple(KINDS))
    #: CLP realization: True = contact with periodic images shifted by F0 (L o s), False = tied
    #: copies (thesis eq. 2.14); None = images for CLP. Images are the default: the copies exist
    #: only near half of the faces, and particles drifting out of their reach lose contacts
    #: (bench/README.md, issue 22)
    images: bool | None = parameter(None, "CLP realized by contact with periodic images (default for CLP) or, "
                                    "false, by tied copies", kind=bool)
    solver: str = parameter("explicit", "explicit (central differences, mass scaling) or implicit (Newton; "
                            "experimental for granular volumes)", choices=SOLVERS)
    seed: int = parameter(1, "seed of the packing generator", low=0)
    packing_file: str | None = parameter(None, "packing file instead of the generator: 'dx dy dz' then one "
                                         "'x y z r' line per sphere (mm)", kind=str)
    packing: Packing | None = None  # or a packing object
    r_min: float = parameter(0.082, "smallest radius of the generated packing (mm)", low=0, open_low=True)
    r_max: float = parameter(0.147, "largest radius of the generated packing (mm)", low=0, open_low=True)
    packing_fraction: float | None = parameter(None, "stop the generator at this solid fraction (default: "
                                               "jammed, ~0.63) (-)", kind=float, low=0.1, high=0.66)
    d_bc: float | None = parameter(None, "duplication distance / r_max (default: thesis table 2.3: 1.8 CLP, "
                                   "2.5 others) (-)", kind=float, low=0, high=10, open_low=True)
    #: duplicate across edges and corners too (False: face copies only, e.g. the 12 copies of the
    #: ordered simple cubic cell, thesis §2.6)
    corners: bool = True
    radius_factor: float = parameter(0.99, "radii shrunk by this factor before meshing: no initial "
                                     "interpenetration (-)", low=0.5, high=1)
    #: named cube-sphere resolution (meshes.cubesphere.RESOLUTIONS): "chapter2" (the thesis'
    #: appendix-A particle, 6x6 quadrilaterals per cube face, 561 nodes), "chapter4" (10x10, 1 933
    #: nodes), "coarse" (4x4 and 4 shell layers, 517 nodes: the earlier default)
    mesh: str = parameter("chapter2", "cube-sphere particle: chapter2 = the thesis' appendix-A particle (6x6 "
                          "quadrilaterals per cube face, 561 nodes), chapter4 = its 10x10 O-grid (1 933 nodes), "
                          "coarse = 4x4 with 4 shell layers (517 nodes); every one holds its sphere's volume",
                          choices=tuple(RESOLUTIONS))
    refinement: int = parameter(1, "cube-sphere refinement: multiplies the resolution's subdivisions (chapter2: "
                                "1 = 561 nodes per particle, 2 = 3 929)", low=1, high=4)
    #: particle meshes hold their sphere's volume (nodes scaled by ~1 %, meshes.cubesphere); False:
    #: inscribed in the sphere (e.g. touching spheres of an ordered cell with radius_factor 1)
    exact_volume: bool = True
    #: override the resolution's hexahedra per inner-cube edge (odd: the contact points of
    #: axis-aligned neighbours fall on facet centres instead of nodes) and shell layers
    divisions: int | None = parameter(None, "hexahedra per inner-cube edge (default: the resolution's)", kind=int,
                                      low=1, high=16)
    layers: int | None = parameter(None, "shell layers (default: the resolution's)", kind=int, low=1, high=16)
    #: (3, 3) rotation of every particle mesh about its centre (None: cube-sphere axes along x, y,
    #: z). One generic rotation for all keeps identical particles exact translates of each other
    #: while their contact points fall inside facets, not on nodes (ordered packings)
    mesh_rotation: np.ndarray | None = None
    material: ElastoPlastic = LEAD
    friction: float = parameter(0.1, "Coulomb friction coefficient mu (-)", low=0, high=2)
    gamma: float = parameter(0.0, "Dupre adhesion energy (mJ/mm^2)", low=0, high=1)
    delta_max: float = parameter(5e-4, "opening at which adhesion vanishes (mm)", low=0, high=0.01, open_low=True)
    asperity_yield: float = parameter(5.0, "asperity yield stress, p0 = 3 x it (MPa)", low=0, open_low=True)
    penalty_factor: float = parameter(10.0, "penalty k = factor x E / h, h the contact element size (-)", low=0,
                                      open_low=True)
    duration: float = parameter(1e-3, "loading time, mass-scaled (s)", low=0, open_low=True)
    #: relaxation hold at the final gradient after the compaction, in units of ``duration`` (its
    #: rows have time > duration); explicit: at the compaction's increment
    hold: float = parameter(0.0, "explicit relaxation hold at the final gradient after the loading, in units of "
                            "the loading duration (rows with time > duration)", low=0, high=10)
    #: amplitude of the compaction segment in time (loading.amplitude.PROFILES): "smooth-ramps",
    #: a constant Hencky strain rate between smooth ramps over the first 10 % and the last 30 % of
    #: the duration (peak rate 1.25 x the mean), or "smooth-step" (Abaqus SMOOTH STEP, peak 1.875 x
    #: the mean at mid-path, i.e. in the rearrangement range rho ~0.75-0.82)
    profile: str = parameter("smooth-ramps", "amplitude of the compaction in time: constant strain rate between "
                             "smooth ramps, or the Abaqus smooth step (peak rate mid-path)", choices=tuple(PROFILES))
    #: explicit increments over the compaction (the mass-scaled increment is duration / increments);
    #: 6000 with smooth-ramps: sigma_m within 0.7 % of 12 000 on the flagship (bench/README.md)
    increments: int = parameter(6000, "explicit increments over the loading", low=10)
    #: further segments of the macroscopic path after the compaction, ((duration s, increment
    #: gradient G (3, 3)), ...): e.g. the unload F^d and a reload F^r of thesis eq. 4.7-4.9. Explicit
    #: runs keep the compaction's increment duration / increments (make durations multiples of it)
    segments_after: tuple = ()
    #: amplitude in time of each of ``segments_after`` (loading.amplitude.PROFILES; missing ones:
    #: "smooth-step"), e.g. a chapter-4 reload at a constant strain rate ("smooth-ramps")
    segment_profiles: tuple = ()
    #: viscous damping of each particle's rigid motion relative to the imposed homogeneous flow, in
    #: units of 1 / duration (ExplicitSettings.damping; dissipation in E_damp). Off by default: it
    #: drags the particles towards the affine flow, a rate-dependent stress (bench/README.md)
    damping: float = parameter(0.0, "explicit viscous damping of the particles' rigid motion relative to the "
                               "imposed flow (1/duration); it drags the particles towards the affine flow and "
                               "adds a rate-dependent stress", low=0)
    #: local non-viscous damping alpha of each particle's rigid motion (ExplicitSettings.local_damping,
    #: per body): -alpha |F_b| sign(W_b), against oscillations only, no steady drag (loading-rate
    #: study in bench/README.md)
    local_damping: float = parameter(0.7, "explicit local non-viscous damping alpha of the particles' rigid "
                                     "motion (Cundall): removes oscillations, resists no steady motion (-)",
                                     low=0, high=1, open_high=True)
    #: explicit: the constrained model's reduced mass (ExplicitSettings.constraint_mass): "lumped"
    #: row sums, which make the couplings' nodes heavy (CLPS, GDF, GDH), or "consistent" P^T M P
    constraint_mass: str = parameter("lumped", "explicit reduced mass of the constrained model: lumped row sums "
                                     "or the consistent P^T M P", choices=CONSTRAINT_MASSES)
    #: carry every particle with the homogeneous flow at its centre (GranularBoundaryConditions
    #: comoving; the unknowns are the motions relative to it). False: only the constrained nodes
    #: follow F0, free particles move only when pushed (the carrier experiment of bench/README.md)
    comoving: bool = True
    #: CLPS: the copies' reference points turn with their originals' (thesis eq. 2.16); False:
    #: translation coupling only (eq. 2.15; the measurement of bench/README.md, issue 22 item 7)
    equal_rotations: bool = True
    #: mixed strain / stress control (loading.mixed.StressControl) replacing the compaction path:
    #: a servo on the measured stress (its ``measure``, every ``every`` explicit increments; CLP /
    #: CLPS, explicit; the control keeps its state: one run per control)
    control: object | None = None
    steps: int = parameter(100, "implicit load steps (adaptive, cut back when Newton fails)", low=1)
    #: implicit: steps of each of ``segments_after`` (missing ones: the compaction's increment
    #: duration / steps); each segment is stepped on its own, from its start to its end
    segment_steps: tuple = ()
    #: implicit: pseudo-time drag k_i = regularization E V_i / h^2 towards the last converged
    #: state (V_i nodal volume, h contact element size): holds particles before contact
    regularization: float = 0.05
    outputs: int = parameter(40, "history rows and ParaView frames", low=1, high=100000)
    #: explicit: a history row every so many increments (0: ``outputs`` rows over the whole path)
    output_every: int = parameter(0, "explicit: a history row every so many increments (0: from outputs)", low=0)
    #: write a checkpoint every so many outputs (and at the end) into out_dir/checkpoints; 0: never
    checkpoint_every: int = parameter(10, "checkpoint every so many outputs (0: none)", low=0)
    checkpoint_keep: int = parameter(2, "newest checkpoints kept (0: all)", low=0)
    visual: bool = parameter(True, "write ParaView files and PNG figures")
    out_dir: str = "results/isotropic"

    def __post_init__(self):
        check_parameters(self)  # each field's range, from its parameter() declaration
        if self.images is True and self.bc != "CLP":
            raise ValueError(f"images=True realizes CLP only, got bc={self.bc!r}")
        if self.mesh_rotation is not None:
            Q = np.asarray(self.mesh_rotation, dtype=float)
            if Q.shape != (3, 3) or not np.allclose(Q @ Q.T, np.eye(3), atol=1e-12) or np.linalg.det(Q) < 0:
                raise ValueError("mesh_rotation must be a (3, 3) proper rotation matrix")
        if any(int(n) < 1 for n in self.segment_steps) or len(self.segment_steps) > len(self.segments_after):
            raise ValueError(f"segment_steps must hold >= 1 implicit steps for at most the {len(self.segments_after)} "
                             f"segments_after, got {self.segment_steps}")
        if len(self.segment_profiles) > len(self.segments_after) or any(p not in PROFILES for p in self.segment_profiles):
            raise ValueError(f"segment_profiles must name one of {', '.join(PROFILES)} for at most the "
                             f"{len(self.segments_after)} segments_after, got {self.segment_profiles}")
        if self.control is not None and (not boundary_kind(self.bc).periodic or not solver_kind(self.solver).stress_control):
            raise ValueError(f"control (stress-driven components) needs bc CLP or CLPS and the explicit solver, got "
                             f"bc={self.bc!r}, solver={self.solver!r}")

    @property
    def uses_images(self) -> bool:
        """CLP realized by contact with periodic images (no copies)."""
        return boundary_kind(self.bc).tied_nodes and self.images is not False

    @property
    def mesh_divisions(self) -> tuple[int, int]:
        """(divisions, layers) of the particle meshes: the named resolution with the overrides."""
        divisions, layers = RESOLUTIONS[self.mesh]
        return (self.divisions or divisions, self.layers or layers)


class RunFailure(RuntimeError):
    """A run that diverged or did not converge: ``step`` and ``t`` where it stopped, the history
    written so far and the last good checkpoint (None if none was written)."""

    def __init__(self, message: str, step: int, t: float, history: Path, checkpoint: Path | None):
        super().__init__(message)
        self.step, self.t, self.history, self.checkpoint = step, t, history, checkpoint


@dataclass
class CompactionResult:
    history: History
    packing: Packing
    num_dofs: int
    num_particles_model: int
    wall_time: float
    increments: int
    out_dir: Path
    model: CompactionModel | None = None  # what the run was made of (packing -> ... -> contact)
    solver: object | None = None  # the solver at the end of the run (its state, energies, timings)
    #: explicit runs: the energy balance's and the balance's verdict on the loading rate (also logged)
    quasi_static: QuasiStaticCheck | None = None


def initial_packing(case: CompactionCase, log=None) -> Admission:
    """The case's packing (its object, its file, or the generator) admitted for the run by
    :func:`~mpfem_fenicsx.meshes.admission.admit_packing`, before any mesh: spheres in the cell,
    no overlap of the spheres through the particle meshes' nodes at the start (the default
    radius reduction lowered for a DEM packing's contact overlaps), and the initial relative
    density rho0 = V_p / V0 with the meshed radii (thesis eq. 2.5) below the target. ``log``
    reports what was decided. Raises ValueError naming the file, particle or field."""
    if case.packing is not None:
        packing = case.packing
    elif case.packing_file is not None:
        packing = read_packing(case.packing_file, validate=False)
        if log is not None:
            log(f"packing: {case.packing_file} read as {packing_format(case.packing_file)}")
    else:
        packing = generate_packing(case.particles, case.r_min, case.r_max, seed=case.seed,
                                   target_fraction=case.packing_fraction)
    divisions, layers = case.mesh_divisions
    particle = unit_ball_hex(divisions, layers, case.refinement, exact_volume=case.exact_volume)
    admitted = admit_packing(packing, case.radius_factor, particle.radius_scale,
                             target_density=case.target_density,
                             automatic=case.radius_factor == CompactionCase.radius_factor)
    for note in admitted.notes if log is not None else ():
        log(f"packing: {note}")
    return admitted


@dataclass
class CompactionModel:
    """Everything a compaction run is made of (data flow: packing -> assembly -> problem ->
    constraints + contact), before any increment."""

    case: CompactionCase
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
        return np.any(self.shift != 0, axis=1)

    @property
    def num_dofs(self) -> int:
        """Displacement dofs of the whole assembly, all ranks (3 per node)."""
        return self.problem.V.dofmap.index_map.size_global * 3

    def follow(self, case: CompactionCase) -> None:
        """Reuse this model for ``case`` (same packing, mesh and contact settings): its loading
        path replaces the model's, the constraints follow it."""
        self.case = case
        self.path = self.bcs.gradient = loading_path(case, self.rho0)


def loading_path(case: CompactionCase, rho0: float) -> GradientPath:
    """F0(t): the compaction from ``rho0`` to the target density, then ``case.segments_after``;
    or the case's mixed control."""
    if case.control is not None:
        return case.control
    hold = [(case.hold * case.duration, np.eye(3))] if case.hold > 0 else []
    return GradientPath([(case.duration, compaction_gradient(case.loading, rho0, case.target_density)),
                         *hold, *case.segments_after],
                        profiles=(case.profile, *("smooth-step" for _ in hold), *case.segment_profiles))


def build_compaction(case: CompactionCase, comm: MPI.Comm = MPI.COMM_WORLD, log=print) -> CompactionModel:
    """Packing, duplicated particles, mesh, bulk problem, constraints and contact of a case."""
    admitted = initial_packing(case, log)  # the start-overlap rule and the radius reduction
    packing, rho0 = admitted.packing, admitted.rho0
    n = packing.num_particles
    kind = boundary_kind(case.bc)
    d_bc = (case.d_bc if case.d_bc is not None else kind.default_d_bc) * float(packing.radii.max())
    if case.uses_images:  # CLP by periodic images: no copies
        copies = Duplicates(np.zeros(0, np.int64), np.zeros((0, 3), np.int64), np.zeros((0, 3)), np.zeros(0))
    else:
        copies = duplicate_particles(packing, d_bc, faces=kind.copy_faces,
                                     corners=case.corners)
    centres, radii, original, shift = assembly_particles(packing, copies)
    radii = radii * admitted.radius_factor
    is_copy = np.any(shift != 0, axis=1)
    log(f"packing: {n} particles, solid fraction {packing.solid_fraction:.4f}, cell {packing.cell}; "
        f"{int(is_copy.sum())} duplicated particles (d_bc = {d_bc:.4g} mm, bc {case.bc})")

    solid0 = solid_volume(radii[:n])  # thesis eq. 2.5, initial (meshed) radii

    divisions, layers = case.mesh_divisions
    # surface element edge at a cube-face centre of the smallest particle (equi-angular grid)
    h_contact = float(radii.min()) * np.pi / (2 * divisions * case.refinement)
    law = ContactLaw(penalty=default_penalty(case.material.E, h_contact, case.penalty_factor),
                     friction=case.friction, gamma=case.gamma, delta_max=case.delta_max,
                     asperity_yield=case.asperity_yield)
    law.require_softening_branch()  # before meshing: the penalty follows the mesh resolution
    rotations = None if case.mesh_rotation is None else np.broadcast_to(case.mesh_rotation, (radii.size, 3, 3))
    assembly = particle_mesh(centres, radii, comm, divisions=divisions, layers=layers, refinement=case.refinement,
                             exact_volume=case.exact_volume, rotations=rotations)
    mesh = assembly.mesh
    owned_cells = mesh.topology.index_map(3).size_local
    cell_particle = assembly.cell_tags.values[:owned_cells]
    active = np.flatnonzero(~is_copy[cell_particle]) if kind.tied_nodes else None
    problem = SolidProblem(mesh, case.material, tangent=solver_kind(case.solver).tangent,
                           active_cells=active)
    V = problem.V

    rho0_fe = float(particle_volumes(assembly, problem.u)[:n].sum()) / float(np.prod(packing.cell))
    path = loading_path(case, rho0)

    # CLP's tied copies: one body pair per periodic pair (copy-copy only for mixed lattice shifts);
    # solid copies (GDH, GDF, CLPS) touch each other as separate bodies
    allowed = (periodic_pair_realizations(original, shift) if kind.tied_nodes
               else np.ones((radii.size, radii.size), dtype=bool))
    contact = ContactModel(V, assembly.facet_tags, radii.size, law,
                           search_distance=max(0.05 * float(radii.min()), 2 * case.delta_max), allowed=allowed,
                           shifts=periodic_lattice() * packing.cell if case.uses_images else None)
    bcs = GranularBoundaryConditions(V, cell_particle, centres, radii, original, shift, packing.cell, case.bc, path,
                                     images=contact if case.uses_images else None, anchor=solver_kind(case.solver).anchored,
                                     comoving=case.comoving, equal_rotations=case.equal_rotations)
    return CompactionModel(case, packing, centres, radii, original, shift, assembly, problem, bcs, contact, path,
                           solid0, rho0, rho0_fe, h_contact)


def make_solver(case: CompactionCase, model: CompactionModel, log=print):
    """The solver factory: the case's solver on the model (the one place that reads its name),
    with the increments of the whole path."""
    problem, bcs, path = model.problem, model.bcs, model.path
    model_line = (f"model: {model.radii.size} particles, {model.num_dofs} dofs ({bcs.constraint.num_reduced_global} free), "
                  f"rho0 = {model.rho0:.4f}")
    if solver_kind(case.solver).static:
        log("WARNING: implicit granular runs are experimental: with the pseudo-time drag the free "
            "particles are solvable, but Newton needs many cut-backs once contacts yield, and may stall on "
            "frictional stick / slip switches (verified on the 8-sphere simple cubic cell: compaction, "
            "restart, chapter-4 reloads); use the explicit solver for production runs")
        nodal_volume = problem.lumped_mass(1.0).x.array[: bcs.constraint.num_owned]
        # backtracking line search: frictional stick / slip switches make full Newton steps cycle
        # (an explicit state relaxed to rest stalled at 1e-1 of its residual without it)
        solver = create_solver(case.solver, problem, bcs, contact=model.contact,
                               petsc_options={"snes_linesearch_type": "bt"},
                               regularization=case.regularization * case.material.E * nodal_volume
                               / model.contact_length ** 2, controls=implicit_step_controls(case, path))
        log(f"{model_line} -> {case.target_density}, implicit, {solver.total_steps} steps")
        return solver
    settings = ExplicitSettings(t_end=path.duration, target_dt=case.duration / case.increments,
                                damping=case.damping / case.duration, local_damping=case.local_damping,
                                constraint_mass=case.constraint_mass)
    node_particle = node_particles(problem.V, model.assembly.cell_tags.values[: problem.num_cells])
    solver = create_solver(case.solver, problem, bcs, contact=model.contact, settings=settings,
                           damped_bodies=damped_bodies(case.bc, model.original)[node_particle])
    log(f"{model_line} (finite elements {model.rho0_fe:.4f}) -> "
        f"{'stress-controlled' if case.control is not None else case.target_density}, dt = {solver.dt:.3g} s "
        f"(unscaled {solver.dt_stable_unscaled:.3g} s), {case.increments} increments")
    return solver


def damped_bodies(bc: str, original: np.ndarray) -> np.ndarray:
    """The body of each assembly particle whose rigid motion relative to the imposed flow the
    explicit damping relaxes: its original's index (a periodic copy, tied or coupled, moves with
    its original: one body), or -1 where F0 drives the particle's reference point (the copies of
    GDF, every particle of GDH): that motion is imposed, and damping it with the volume would tie
    the free particles to the imposed flow through their driven copies' forces."""
    driven = {"all": np.ones(original.size, bool), "copies": original != np.arange(original.size),
              "none": np.zeros(original.size, bool)}[boundary_kind(bc).driven]
    return np.where(driven, -1, original)


class CompactionCheckpoints:
    """The checkpoints of a compaction run in ``root``: every ``every`` history rows and at the
    end, the newest ``keep`` kept; each holds the solver's state, the history so far, the
    reference centroids, the packing, the control's state and F0 (a run continues from one bit
    for bit, explicit)."""

    def __init__(self, root: Path, comm: MPI.Comm, every: int, keep: int, restart: Path | None = None):
        self.root, self.comm, self.every, self.keep = Path(root), comm, every, keep
        self.last: Path | None = None
        self.restart = restart

    def due(self, rows: int) -> bool:
        return bool(self.every) and rows % self.every == 0

    def write(self, solver, model: CompactionModel, history: History, reference_centroids: np.ndarray,
              wall_time: float) -> None:
        case, packing, V = model.case, model.packing, model.problem.V
        arrays = {f"solver/{k}": v for k, v in solver.state_dict().items()}
        arrays["dof_coordinates"] = _dof_coordinates(V)
        directory = checkpoint_path(self.root, solver.step)
        save_checkpoint(directory, self.comm, arrays, {
            "step": solver.step, "t": solver.t, "solver": case.solver, "bc": case.bc,
            "num_dofs": model.num_dofs,
            "centroids0": reference_centroids.tolist(), "history": history.rows, "columns": history.columns,
            "control": None if case.control is None else case.control.state_dict(),
            "F0": model.path(solver.t).tolist(), "wall_time": wall_time,
            "packing": {"cell": packing.cell.tolist(), "centres": packing.centres.tolist(),
                        "radii": packing.radii.tolist()}})
        if self.comm.rank == 0:
            prune_checkpoints(self.root, self.keep)
        self.last = directory

    @property
    def resume_from(self) -> Path | None:
        """The newest good checkpoint: the last written, or the one the run restarted from."""
        return self.last or self.restart

    def restore(self, arrays: dict, meta: dict, solver, model: CompactionModel, history: History) -> None:
        """Continue from a checkpoint read with ``load_checkpoint``: the control's state, the
        history rows, the solver's state (an implicit solver adopts an explicit state relaxed to
        rest). Raises CheckpointError if it was written for another model or partition."""
        case, V, num_dofs = model.case, model.problem.V, model.num_dofs
        adopt = meta["solver"] != case.solver and meta["solver"] in solver_kind(case.solver).continues
        if meta["num_dofs"] != num_dofs or (meta["solver"] != case.solver and not adopt) or meta["bc"] != case.bc:
            raise CheckpointError(f"restart: {self.restart} was written for another model ({meta['num_dofs']} dofs, "
                                  f"{meta['solver']}, {meta['bc']}; this case: {num_dofs} dofs, {case.solver}, {case.bc})")
        if arrays["dof_coordinates"].shape != _dof_coordinates(V).shape or \
                not np.array_equal(arrays["dof_coordinates"], _dof_coordinates(V)):
            raise CheckpointError(f"restart: {self.restart} was written with another mesh partition")
        if case.control is not None:  # the servo before the solver asks it for F0
            if meta.get("control") is not None:  # as it was (a new stress path continues it)
                case.control.load_state(meta["control"])
            elif meta.get("F0") is not None:  # a stress path from a strain-driven state
                case.control.begin(float(meta["t"]), np.array(meta["F0"], dtype=float))
            else:
                raise CheckpointError(f"restart: {self.restart} does not record its gradient F0 (written before "
                                      "2026-11-25): a stress-controlled run cannot continue it")
        history.rows = _history_rows(meta, history.columns)
        state = {k[7:]: v for k, v in arrays.items() if k.startswith("solver/")}
        if adopt:
            solver.adopt_state(state, translation=_anchor_displacement(model.bcs, V, state["u"], float(state["t"])))
            solver.plastic_work = history.rows[-1][history.columns.index("E_p_model")]  # the tally goes on
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
    outputs may differ), whose state the restart overwrites. The case is not modified."""

    def __init__(self, case: CompactionCase, comm: MPI.Comm = MPI.COMM_WORLD, log=print, *,
                 restart: str | Path | None = None, progress: Progress | None = None,
                 model: CompactionModel | None = None):
        self.start = time.perf_counter()
        self.comm, self.log = comm, log
        arrays = meta = None
        if restart is not None:
            restart = resolve_checkpoint(restart)
            arrays, meta = load_checkpoint(restart, comm)  # checks the number of ranks before any build
            if case.packing is None and case.packing_file is None:  # the checkpoint's own packing
                pk = meta["packing"]
                case = replace(case, packing=Packing(pk["cell"], pk["centres"], pk["radii"]))
        self.case = case
        self.out = Path(case.out_dir)
        if model is None:
            model = build_compaction(case, comm, log)
        else:  # reuse: only the path changes (the restart then restores every state variable)
            if restart is None:
                raise ValueError("CompactionRun: a reused model needs a restart checkpoint")
            model.follow(case)
        self.model = model
        self.solver = make_solver(case, model, log)
        self.recorder = HistoryRecorder(model, comm, None if meta is None else meta["centroids0"])
        self.history = History(self.out / "history.csv", COLUMNS, comm, flush_every_row=True)
        self.checkpoints = CompactionCheckpoints(self.out / "checkpoints", comm, case.checkpoint_every,
                                                 case.checkpoint_keep, restart)
        self.progress = progress or Progress(comm, stream=_LogStream(log))
        self.wall_offset = 0.0
        if meta is not None:  # restart: model, solver, history and clocks as they were
            self.checkpoints.restore(arrays, meta, self.solver, model, self.history)
            self.wall_offset = float(meta["wall_time"])
            log(f"restart from {restart}: step {meta['step']}, t = {meta['t']:.6g} s, "
                f"{len(self.history.rows)} history rows")
        self.writer = self.fields = None
        if case.visual:
            self.fields = CellFields(model.problem, model.assembly.cell_tags)
            name = "particles.xdmf" if meta is None else f"particles_from_step{meta['step']}.xdmf"
            self.writer = ParaViewWriter(self.out / name, model.problem, self.fields, contact=model.contact)
        if comm.rank == 0:
            self.out.mkdir(parents=True, exist_ok=True)
            write_packing(model.packing, self.out / "packing.txt")

    @property
    def wall_time(self) -> float:
        """Wall time of the run (s), the restarted runs' before it included."""
        return self.wall_offset + time.perf_counter() - self.start

    def write_checkpoint(self) -> None:
        self.checkpoints.write(self.solver, self.model, self.history, self.recorder.X0, self.wall_time)

    def record(self, solver) -> None:
        """An output: a history row, the ParaView fields, the progress line, a checkpoint when due."""
        row = self.recorder.measure(solver, self.wall_time)
        self.history.append(**row)
        if self.writer is not None:
            self.writer.write(solver.t)
        self.progress.update(solver.t / self.model.path.duration, solver.step, self.solver.total_steps,
                             rho=row["rho"], sigma_m=row["sigma_m"],
                             extra=f"unbalanced {row['unbalanced']:.2g}  contacts {row['n_contacts']:.0f} "
                                   f"(Z {row['Z']:.2f})  E_p {row['E_p']:.3g} mJ  E_c {row['E_c']:.2g} mJ")
        if self.checkpoints.due(len(self.history.rows)):
            self.write_checkpoint()

    def servo(self, solver) -> None:
        """Mixed control, every ``control.every`` increments: the measured Cauchy stress
        (compression > 0) of ``control.measure`` to the servo."""
        control = self.case.control
        if solver.step % control.every == 0:
            control.update(solver.t, -self.recorder.measured_stress(solver, control.measure))

    def run(self, max_steps: int | None = None) -> CompactionResult:
        """Run to the end of the path (``max_steps``: stop after so many increments of this call,
        without the final outputs: a benchmark's part of a run). A diverging or non-converging
        run raises :class:`RunFailure` after writing its history so far; the last good
        checkpoint stays."""
        case, solver = self.case, self.solver
        try:
            total = solver.run_path(self.record, outputs=case.outputs, every=case.output_every or None,
                                    max_steps=max_steps, on_step=self.servo if case.control is not None else None,
                                    log=self.log)
        except (FloatingPointError, NonConvergence) as err:
            self._fail(err)
        self.progress.close()
        check = None
        if max_steps is None:
            self._finish()
            check = self.quasi_static_check()
        return CompactionResult(self.history, self.model.packing, self.model.num_dofs,
                                self.model.radii.size, self.wall_time, total, self.out,
                                model=self.model, solver=solver, quasi_static=check)

    def quasi_static_check(self) -> QuasiStaticCheck | None:
        """Explicit runs: the quasi-static check of the history so far (:func:`quasi_static_check`;
        a strain path ends at rest, a stress-controlled one need not), logged in one line."""
        if solver_kind(self.case.solver).static or not self.history.rows:
            return None
        columns = {c: self.history.column(c) for c in QUASI_STATIC_CHECK_COLUMNS}
        check = quasi_static_check(columns, at_rest=self.case.control is None)
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
        kept = f"last good checkpoint {resume} (continue with --restart)" if resume else "no checkpoint was written yet"
        raise RunFailure(f"the run stopped at step {step} (t = {solver.t:.6g} s): {err}; history so far "
                         f"in {self.history.path}, {kept}", step, solver.t, self.history.path,
                         resume) from err

    def _finish(self) -> None:
        """The final checkpoint (the chapter-4 reloads start from it), the history, the figures."""
        case, model = self.case, self.model
        if case.checkpoint_every and len(self.history.rows) % case.checkpoint_every != 0:
            self.write_checkpoint()
        self.history.write()
        if self.writer is None:
            return
        self.writer.close()
        n = model.packing.num_particles
        # CLP shell copies carry no stress: show the volume's particles only
        render_deformed(model.problem.u, self.fields.von_mises, self.out / "particles.png",
                        cells=model.problem.material_cells,
                        title=f"{n} lead particles, {case.loading} compaction, {case.bc}, "
                              f"rho = {self.history.column('rho')[-1]:.3f}", save_grid=True)
        if self.comm.rank == 0:
            plot_loading_path(self.history.path, self.out / "loading_path.png",
                              title=f"{n} particles, {case.loading} compaction, {case.bc}")


def run_compaction(case: CompactionCase, comm: MPI.Comm = MPI.COMM_WORLD, log=print, *,
                   restart: str | Path | None = None, progress: Progress | None = None,
                   model: CompactionModel | None = None) -> CompactionResult:
    """Compact the volume to ``case.target_density`` (or along its path): ``CompactionRun(...).run()``;
    the columns of the history: :mod:`.history_recorder`."""
    return CompactionRun(case, comm, log, restart=restart, progress=progress, model=model).run()


#: columns added since the first checkpoints (which do not list theirs): filled with NaN on restart
_COLUMNS_ADDED = ("Gamma_model", "Gamma_closed")


def _history_rows(meta: dict, columns: list[str]) -> list[list[float]]:
    """A checkpoint's history rows in the order of ``columns``, matched by name; columns the
    checkpoint did not have are NaN."""
    saved = meta.get("columns") or [c for c in columns if c not in _COLUMNS_ADDED]
    if any(len(row) != len(saved) for row in meta["history"]):
        raise CheckpointError(f"restart: the checkpoint's history rows do not match its {len(saved)} columns")
    where = {c: k for k, c in enumerate(saved)}
    return [[float(row[where[c]]) if c in where else np.nan for c in columns] for row in meta["history"]]


def implicit_step_controls(case: CompactionCase, path: GradientPath) -> list[StepControl]:
    """One step control per path segment: the compaction in ``case.steps`` steps, then each of
    ``segments_after`` in its ``segment_steps`` (default: the compaction's increment). Segments
    end exactly at their knots; an increment carried over from a segment is capped by the next
    one's (StepControl.dt_max)."""
    knots = path.knots
    controls = []
    for k in range(len(knots) - 1):
        duration = knots[k + 1] - knots[k]
        if k == 0:
            n = case.steps
        elif k - 1 < len(case.segment_steps):
            n = int(case.segment_steps[k - 1])
        else:
            n = max(1, round(duration * case.steps / case.duration))
        dt = duration / n
        controls.append(StepControl(t_end=knots[k + 1], dt=dt, dt_max=dt, dt_min=dt / 256))
    return controls


def _anchor_displacement(bcs: GranularBoundaryConditions, V, u: np.ndarray, t: float) -> np.ndarray:
    """Translation (mm) that brings the node an implicit periodic model anchors to its prescribed
    displacement at time t, from a state ``u`` (local array, blocks of 3) of a model without anchor
    (zero when there is none)."""
    c = np.zeros(3)
    if bcs.anchor_block is not None:
        lo, hi = V.dofmap.index_map.local_range
        if lo <= bcs.anchor_block < hi:
            i = 3 * (bcs.anchor_block - lo)
            c = np.asarray(u[i:i + 3], dtype=float) - bcs.displacement_gradient(t) @ bcs.anchor_carrier
    return V.mesh.comm.allreduce(c)


def _dof_coordinates(V) -> np.ndarray:
    """Coordinates of this rank's owned dof blocks (identifies the partition of a checkpoint)."""
    return V.tabulate_dof_coordinates()[: V.dofmap.index_map.size_local]


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
