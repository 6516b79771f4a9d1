"""Volumes pressed by rigid tools: particles without a periodic cell, moved by contact only.

The shared stages of the tool-driven workflows (closed die, box of six planes, the simple cubic
cell between walls): mesh the spheres, build the bulk problem and the contact with the tools,
integrate with the explicit solver (each particle's rigid motion damped, the force-controlled
tools moved by their servos after every increment) or by Newton (:func:`tooled_newton`: the
static path of displacement-driven tools, each particle's core held by a pseudo-time drag until
its contacts hold it) and record one history row per output:

- ``time`` (s); per tool ``<name>_ux/_uy/_uz`` its translation (mm), ``<name>_Fx/_Fy/_Fz`` the
  force the particles exert on it (N), ``<name>_N`` the sum of the normal forces pressing on it
  (N, compression > 0);
- ``contact_points`` (loaded points, particle-particle and on tools), the energies (mJ; the
  tools' work on the particles is in W_ext) and the out-of-balance ratio ``unbalanced`` (-).

No gravity, no carrier: a particle not touched stays where it is.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..case import SolverSection
from ..contact import ContactLaw, ContactModel
from ..io import History
from ..io.checkpoint import (
    CheckpointError,
    checkpoint_path,
    load_checkpoint,
    prune_checkpoints,
    resolve_checkpoint,
    save_checkpoint,
)
from ..loading import PrescribedDisplacements
from ..material import LEAD, ElastoPlastic
from ..meshes import node_particles, particle_mesh, particle_volumes
from ..meshes.cubesphere import RESOLUTIONS, unit_ball_hex
from ..problem import SolidProblem
from ..solvers import create_solver
from ..solvers.explicit import ExplicitSettings
from .compaction import HELD_CONTACTS, granular_step_control, particle_core_drag

#: relative gap between the particles' start spheres (through their surface nodes) and to the
#: tools: a packing that touches starts touching, without overlap
START_GAP = 1e-4
#: the energies of a history row
ENERGIES = ("W_ext", "E_int", "E_p", "E_contact", "E_c", "E_damp", "E_visc", "E_mass")


def mesh_radii(radii: np.ndarray, resolution: str, exact_volume: bool = True) -> np.ndarray:
    """The radii to mesh spheres of ``radii`` with (mm): the volume-exact particles' surface
    nodes lie at ``radius_scale`` times their radius; they are put START_GAP inside the sphere."""
    divisions, layers = RESOLUTIONS[resolution]
    scale = unit_ball_hex(divisions, layers, exact_volume=exact_volume).radius_scale
    return (1.0 - START_GAP) / scale * np.asarray(radii, dtype=float)


def particle_law(radii, resolution: str, penalty_factor: float, friction: float) -> ContactLaw:
    """The lead particles' contact law of a tool-driven volume: penalty ``penalty_factor`` x E /
    h_contact (thesis §3.3), h_contact = pi r_mean / (2 divisions) the surface element size of
    the ``resolution``'s cube-sphere, Coulomb ``friction``."""
    h_contact = float(np.mean(radii)) * np.pi / (2 * RESOLUTIONS[resolution][0])
    return ContactLaw(penalty=penalty_factor * LEAD.E / h_contact, friction=friction)


def tool_law(law: ContactLaw, friction: float) -> ContactLaw:
    """The particles' law against a rigid tool with its own ``friction``: twice the particles'
    penalty (a wall is the symmetry plane of a particle-particle contact, whose penalty spring
    spans both sides of it: a sphere on a wall at delta / 2 then carries two spheres' force at
    delta), the same adhesion."""
    return ContactLaw(
        penalty=2.0 * law.penalty,
        tangential_penalty=None if law.tangential_penalty is None else 2 * law.tangential_penalty,
        friction=friction,
        gamma=law.gamma,
        delta_max=law.delta_max,
        asperity_yield=law.asperity_yield,
        alpha_forced=law.alpha_forced,
    )


@dataclass
class ToolModel:
    """A tool-driven volume: its meshed particles, bulk problem, contact (with the tools) and
    the (empty) prescribed displacements that move the tools."""

    assembly: object
    problem: SolidProblem
    contact: ContactModel
    bcs: PrescribedDisplacements
    radii: np.ndarray  # meshed radii (mm)
    solid_volume: float  # the particles' finite-element volume at the start (mm^3)
    centres: np.ndarray  # (n, 3) the particles' centres at the start (mm)

    @property
    def num_dofs(self) -> int:
        """Displacement dofs of the whole model."""
        return self.problem.V.dofmap.index_map.size_global * 3

    @property
    def tools(self):
        """The contact with the tools (:class:`~mpfem_fenicsx.contact.rigid.RigidContact`)."""
        return self.contact.tools


def build_tooled(
    centres: np.ndarray,
    radii: np.ndarray,
    tools: list,
    law: ContactLaw,
    material: ElastoPlastic,
    comm: MPI.Comm = MPI.COMM_WORLD,
    *,
    resolution: str = "chapter2",
    refinement: int = 1,
    exact_volume: bool = True,
    rotation: np.ndarray | None = None,
    tangent: bool = False,
) -> ToolModel:
    """Mesh spheres (``radii``: the meshed ones, :func:`mesh_radii`), the bulk problem and the
    contact between the particles and with ``tools`` (:class:`~mpfem_fenicsx.tools.RigidTool`);
    ``resolution`` and ``refinement``: the cube-sphere particle (``[mesh]``'s fields);
    ``tangent``: the problem carries the consistent tangent (the implicit solver needs it)."""
    if resolution not in RESOLUTIONS:
        raise ValueError(f"resolution = {resolution!r} must be one of {sorted(RESOLUTIONS)}")
    if not 1 <= int(refinement) <= 4:
        raise ValueError(f"refinement = {refinement} must be an integer in [1, 4]")
    divisions, layers = RESOLUTIONS[resolution]
    radii = np.asarray(radii, dtype=float)
    assembly = particle_mesh(
        centres,
        radii,
        comm,
        divisions=divisions,
        layers=layers,
        refinement=int(refinement),
        exact_volume=exact_volume,
        rotations=None if rotation is None else np.broadcast_to(rotation, (radii.size, 3, 3)),
    )
    problem = SolidProblem(assembly.mesh, material, tangent=tangent)
    contact = ContactModel(
        problem.V,
        assembly.facet_tags,
        radii.size,
        law,
        search_distance=max(0.05 * float(radii.min()), 2 * law.delta_max),
        tools=tools,
    )
    bcs = PrescribedDisplacements(problem.V)  # nothing prescribed: the tools move the particles
    bcs.followers.append(contact.tools.move)
    solid = float(particle_volumes(assembly, problem.u).sum())
    centres = np.asarray(centres, dtype=float).reshape(-1, 3)
    return ToolModel(assembly, problem, contact, bcs, radii, solid, centres)


def tooled_solver(model: ToolModel, settings: ExplicitSettings, damping: str = "node"):
    """The explicit solver of a tool-driven volume. ``damping``: what the local damping acts on,
    every node's motion ("node": the particles' vibrations between the tools die out too, as in
    a static relaxation), or every particle's rigid motion only ("particle": the particles'
    deformation is not resisted)."""
    if damping not in ("node", "particle"):
        raise ValueError(f"damping = {damping!r} must be 'node' or 'particle'")
    cell_particle = model.assembly.cell_tags.values[: model.problem.num_cells]
    bodies = node_particles(model.problem.V, cell_particle) if damping == "particle" else None
    return create_solver(
        "explicit",
        model.problem,
        model.bcs,
        contact=model.contact,
        settings=settings,
        damped_bodies=bodies,
    )


def tooled_newton(
    model: ToolModel,
    t_end: float,
    steps: int,
    contact_length: float,
    regularization: float = SolverSection.regularization,
    held_regularization: float = SolverSection.held_regularization,
    frame=None,
):
    """The implicit solver of a tool-driven volume (``build_tooled(..., tangent=True)``; tools
    driven by displacement only): Newton over [0, ``t_end``] s in ``steps`` load steps, cut
    back and grown as the granular volumes' (:func:`~.compaction.granular_step_control`), with
    the compaction's line search. No carrier holds a particle before its contacts do: a
    pseudo-time drag on its core does (:func:`~.compaction.particle_core_drag`),
    ``regularization`` x E V_p / h^2
    (``contact_length`` h, mm) on a particle with fewer than HELD_CONTACTS loaded contacts
    (particles and tools counted together), ``held_regularization`` x E V_p / h^2 on the others,
    re-chosen at every converged state; its work is the history's E_damp. ``frame``: the
    motion the drag lets pass (:func:`flow_displacement`; None: the drag resists every motion,
    and the particles a tool pushes through their drag carry a share of its force)."""
    if any(tool.servo is not None for tool in model.tools.tools):
        raise ValueError("tooled_newton: force-controlled tools need the explicit solver")
    problem = model.problem
    cell_particle = model.assembly.cell_tags.values[: problem.num_cells]
    scale = problem.params.E / contact_length**2
    n = (model.bcs.constraint or model.bcs.build()).num_owned
    full, held = (
        particle_core_drag(problem, cell_particle, model.centres, model.radii, f * scale)[:n]
        for f in (regularization, held_regularization)
    )
    body = np.repeat(node_particles(problem.V, cell_particle), 3)[: full.size]

    def update() -> np.ndarray:
        pairs = model.contact.pair_forces()
        loaded = pairs["pairs"][pairs["points"] > 0]
        contacts = np.bincount(loaded.ravel(), minlength=model.radii.size)
        contacts = contacts + model.tools.tools_touched(model.radii.size)
        return np.where(contacts[body] >= HELD_CONTACTS, held, full)

    return create_solver(
        "implicit",
        problem,
        model.bcs,
        contact=model.contact,
        controls=[granular_step_control(t_end, t_end / steps)],
        petsc_options={"snes_linesearch_type": "bt"},
        regularization=full,
        drag_update=update,
        drag_frame=frame,
    )


def flow_displacement(model: ToolModel, pairs):
    """The homogeneous flow between pairs of planes as a displacement field, the implicit
    drag's frame (:func:`tooled_newton`): ``pairs`` as in :func:`flow_between_tools`; along each
    axis a node's displacement interpolates the lower and upper tools' translations linearly in
    its reference coordinate between the planes. Returns t -> displacement (mm, owned dofs)."""
    V = model.problem.V
    n = V.dofmap.index_map.size_local
    X = V.tabulate_dof_coordinates()[:n]
    tools = model.tools.tools

    def displacement(t: float) -> np.ndarray:
        u = np.zeros((n, 3))
        for axis, lo, hi, x_lo, x_hi in pairs:
            s = np.clip((X[:, axis] - x_lo) / (x_hi - x_lo), 0.0, 1.0)
            d_lo, d_hi = tools[lo].motion(t)[axis], tools[hi].motion(t)[axis]
            u[:, axis] = d_lo + (d_hi - d_lo) * s
        return u.ravel()

    return displacement


def flow_between_tools(model: ToolModel, pairs, h: float):
    """The homogeneous flow between pairs of planes, as a damping reference of the explicit
    solver (``solver.damping_reference``): ``pairs`` of (axis, lower tool, upper tool, lower
    plane's reference coordinate, upper's) (tool indices, mm); along each axis the velocity
    grows linearly from the lower plane's to the upper one's, the tools' velocities by central
    differences of their motions over ``h`` (s). Returns t -> velocity (mm/s, owned dofs)."""
    V = model.problem.V
    n = V.dofmap.index_map.size_local
    X = V.tabulate_dof_coordinates()[:n]
    tools = model.tools.tools

    def velocity(t: float) -> np.ndarray:
        u = model.problem.u.x.array[: 3 * n].reshape(-1, 3)
        v = np.zeros((n, 3))
        for axis, lo, hi, x_lo, x_hi in pairs:
            p_lo = x_lo + tools[lo].motion(t)[axis]
            p_hi = x_hi + tools[hi].motion(t)[axis]
            v_lo = (tools[lo].motion(t + h)[axis] - tools[lo].motion(t - h)[axis]) / (2 * h)
            v_hi = (tools[hi].motion(t + h)[axis] - tools[hi].motion(t - h)[axis]) / (2 * h)
            s = np.clip((X[:, axis] + u[:, axis] - p_lo) / (p_hi - p_lo), 0.0, 1.0)
            v[:, axis] = v_lo + (v_hi - v_lo) * s
        return v.ravel()

    return velocity


def run_tooled(model: ToolModel, solver, on_output, outputs: int = 100) -> None:
    """Integrate to the end of the solver's time, the servos (if any) stepped after every
    increment (the explicit solver's; Newton has every increment as an output)."""
    tools = model.tools
    servos = any(tool.servo is not None for tool in tools.tools)
    on_step = (lambda s: tools.servo_step(s.t, s.dt)) if servos else None
    solver.run_path(on_output, outputs=outputs, on_step=on_step)


class ToolHistory:
    """The history of a tool-driven run (module docstring) with the caller's ``extra`` columns."""

    def __init__(self, model: ToolModel, path: str | Path, extra: tuple[str, ...] = ()):
        self.model = model
        names = model.tools.names
        per_tool = [f"{n}_{q}" for n in names for q in ("ux", "uy", "uz", "Fx", "Fy", "Fz", "N")]
        self.columns = [
            "time",
            *extra,
            *per_tool,
            "contact_points",
            *ENERGIES,
            "unbalanced",
        ]
        self.history = History(Path(path), self.columns, model.problem.comm)

    def row(self, solver, **extra) -> dict[str, np.ndarray]:
        """Measure and append a row at the solver's state; returns the tools' forces."""
        tools = self.model.tools
        forces = tools.tool_forces()
        values = {"time": solver.t, **extra}
        for i, name in enumerate(tools.names):
            for a, axis in enumerate("xyz"):
                values[f"{name}_u{axis}"] = tools.translation[i, a]
                values[f"{name}_F{axis}"] = forces["force"][i, a]
            values[f"{name}_N"] = forces["normal"][i]
        values["contact_points"] = self.model.contact.count(True) + int(forces["points"].sum())
        energies = solver.energy_record()
        values.update({k: energies[k] for k in ENERGIES})
        values["unbalanced"] = solver.unbalanced_ratio()
        self.history.append(**values)
        return forces

    def column(self, name: str) -> np.ndarray:
        """One column of the rows so far."""
        return self.history.column(name)

    def write(self) -> Path:
        """Write the CSV (rank 0)."""
        return self.history.write()


class ToolCheckpoints:
    """Checkpoints of a tool-driven run in ``root`` (e.g. ``<out>/checkpoints``): after every
    ``every`` history rows, the newest ``keep`` kept; each holds the solver's state (material,
    particle contact and tool contact histories, the tools' placements) and the history's rows
    so far. :meth:`restore` continues a killed run from the newest one (the same model on the
    same number of ranks; explicit: bit for bit)."""

    def __init__(self, root: str | Path, history: ToolHistory, every: int, keep: int = 2):
        if every < 0 or keep < 0:
            raise ValueError(f"checkpoints: every = {every} and keep = {keep} must be >= 0")
        self.root, self.history, self.every, self.keep = Path(root), history, every, keep
        self.comm = history.model.problem.comm

    def restore(self, solver) -> bool:
        """Load the newest checkpoint in ``root`` into ``solver`` and the history; False if there
        is none. Raises CheckpointError for a checkpoint of another model."""
        try:
            directory = resolve_checkpoint(self.root)
        except CheckpointError:
            return False
        arrays, meta = load_checkpoint(directory, self.comm)
        model = self.history.model
        if meta.get("num_dofs") != model.num_dofs or meta.get("columns") != self.history.columns:
            raise CheckpointError(
                f"restart: {directory} was written for another tool-driven model "
                f"({meta.get('num_dofs')} dofs; this one {model.num_dofs})"
            )
        solver.load_state({k[7:]: v for k, v in arrays.items() if k.startswith("solver/")})
        self.history.history.rows = [list(map(float, row)) for row in meta["history"]]
        return True

    def after_row(self, solver) -> None:
        """Write a checkpoint if one is due after the row just recorded (collective)."""
        rows = len(self.history.history.rows)
        if not self.every or rows % self.every:
            return
        directory = checkpoint_path(self.root, solver.step)
        save_checkpoint(
            directory,
            self.comm,
            {f"solver/{k}": v for k, v in solver.state_dict().items()},
            {
                "step": solver.step,
                "t": solver.t,
                "num_dofs": self.history.model.num_dofs,
                "columns": self.history.columns,
                "history": self.history.history.rows,
            },
        )
        if self.comm.rank == 0:
            prune_checkpoints(self.root, self.keep)
        self.history.history.write()  # the rows so far on disk too
