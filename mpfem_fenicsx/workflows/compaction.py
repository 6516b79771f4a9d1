"""Compaction of a periodic granular volume (thesis chapter 2): packing -> assembly with
duplicated particles -> GDH / GDF / CLPS / CLP constraints -> contact -> solver -> history.

Sign convention: reported stresses are positive in compression (sigma_m > 0 in compaction);
strains keep their sign (h_v < 0 in compaction). Units mm, N, MPa, s.

History columns (one row per output): time, rho (solid volume / current cell volume, the cell
from the least-squares gradient), rho_imposed (from F0), h_v, h_d (Hencky strain of the
least-squares fit of the VEP centroids, appendix C), sigma_m, sigma_d (of the Love-Weber stress,
appendix C), F11..F33 (least-squares fit), sigma11..sigma33 (Love-Weber, compression > 0),
sigma_schmidt_11..33 (CLP/CLPS: from the constraint reactions conjugate to F0, P = R / V0,
sigma = P F0^T / det F0, compression > 0; empty otherwise),
n_contacts (contacting particle pairs), the energies (mJ) and the wall time (s).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..constraints.granular import KINDS, GranularBoundaryConditions, periodic_lattice
from ..contact import ContactLaw, ContactModel
from ..contact.laws import default_penalty
from ..homogenization import (branch_vectors, contact_weights, hencky_strain, least_squares_gradient,
                              love_weber_stress, piola_to_cauchy, strain_invariants, stress_invariants)
from ..io import History
from ..io.fields import CellFields, ParaViewWriter
from ..io.render import render_deformed
from ..loading import GradientPath, compaction_gradient
from ..material import LEAD, ElastoPlastic
from ..meshes import ParticleCentroids, ParticleVolumes, node_particles, particle_mesh
from ..meshes.packing import Duplicates, Packing, assembly_particles, duplicate_particles, generate_packing, read_packing, \
    write_packing
from ..problem import SolidProblem
from ..solvers import ImplicitSolver, StepControl
from ..solvers.explicit import ExplicitSettings, ExplicitSolver

#: d_bc / r_max giving stabilized results with a 50-particle volume (thesis table 2.3)
DEFAULT_D_BC = {"GDH": 2.5, "GDF": 2.5, "CLPS": 2.5, "CLP": 1.8}


@dataclass
class CompactionCase:
    """A compaction run. Radii in mm (thesis: 0.082-0.147 mm), densities relative (-)."""

    particles: int = 24
    target_density: float = 0.92
    loading: str = "isotropic"  # or "die" (uniaxial strain along z)
    bc: str = "CLP"
    images: bool = False  # CLP only: periodic images shifted by F0 (L o s) instead of tied copies
    solver: str = "explicit"
    seed: int = 1
    packing_file: str | None = None  # plain packing file instead of the generator
    packing: Packing | None = None  # or a packing object
    r_min: float = 0.082
    r_max: float = 0.147
    packing_fraction: float | None = None  # generator: stop at this solid fraction (None: jammed)
    d_bc: float | None = None  # duplication distance / r_max (None: thesis table 2.3)
    radius_factor: float = 0.99  # radii shrunk before meshing: no initial interpenetration
    refinement: int = 1
    material: ElastoPlastic = LEAD
    friction: float = 0.1
    gamma: float = 0.0  # mJ/mm^2
    delta_max: float = 5e-4  # mm
    asperity_yield: float = 5.0  # MPa
    penalty_factor: float = 10.0  # k = factor E / h (contact.laws.default_penalty)
    duration: float = 1e-3  # s of (mass-scaled) loading time
    increments: int = 4000
    #: relaxation damping of each particle's rigid motion relative to the imposed homogeneous
    #: flow, in units of 1 / duration (ExplicitSettings.damping); dissipation = history's E_damp
    damping: float = 100.0
    steps: int = 100  # implicit: load steps (adaptive, cut back when Newton fails)
    #: implicit: pseudo-time drag k_i = regularization E V_i / h^2 towards the last converged
    #: state (V_i nodal volume, h contact element size): holds particles before contact
    regularization: float = 0.05
    outputs: int = 40
    visual: bool = True
    out_dir: str = "results/isotropic"

    def __post_init__(self):
        if self.bc not in KINDS:
            raise ValueError(f"bc must be one of {', '.join(KINDS)}, got {self.bc!r}")
        if self.solver not in ("implicit", "explicit"):
            raise ValueError(f"solver must be implicit or explicit, got {self.solver!r}")
        if self.images and self.bc != "CLP":
            raise ValueError(f"images=True realizes CLP only, got bc={self.bc!r}")
        if self.loading not in ("isotropic", "die"):
            raise ValueError(f"loading must be isotropic or die, got {self.loading!r}")
        if self.packing_file is None and self.packing is None and not 2 <= self.particles <= 5000:
            raise ValueError(f"particles must be in [2, 5000], got {self.particles}")
        if not 0.0 < self.target_density < 1.0:
            raise ValueError(f"target_density must be in (0, 1), got {self.target_density}")
        if not 0.5 <= self.radius_factor <= 1.0:
            raise ValueError(f"radius_factor must be in [0.5, 1], got {self.radius_factor}")
        if self.increments < 10:
            raise ValueError(f"increments must be >= 10, got {self.increments}")


@dataclass
class CompactionResult:
    history: History
    packing: Packing
    num_dofs: int
    num_particles_model: int
    wall_time: float
    increments: int
    out_dir: Path
    extra: dict = field(default_factory=dict)


def _packing(case: CompactionCase) -> Packing:
    if case.packing is not None:
        case.packing.validate()
        return case.packing
    if case.packing_file is not None:
        return read_packing(case.packing_file)
    return generate_packing(case.particles, case.r_min, case.r_max, seed=case.seed,
                            target_fraction=case.packing_fraction)


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
    volumes: ParticleVolumes
    solid_volume0: float
    rho0: float
    contact_length: float  # surface element edge of the smallest cube-sphere (mm)

    @property
    def is_copy(self) -> np.ndarray:
        return np.any(self.shift != 0, axis=1)


def build_compaction(case: CompactionCase, comm: MPI.Comm = MPI.COMM_WORLD, log=print) -> CompactionModel:
    """Packing, duplicated particles, mesh, bulk problem, constraints and contact of a case."""
    packing = _packing(case)
    n = packing.num_particles
    d_bc = (case.d_bc if case.d_bc is not None else DEFAULT_D_BC[case.bc]) * float(packing.radii.max())
    if case.images:  # CLP by periodic images: no copies
        copies = Duplicates(np.zeros(0, np.int64), np.zeros((0, 3), np.int64), np.zeros((0, 3)), np.zeros(0))
    else:
        copies = duplicate_particles(packing, d_bc, faces="half" if case.bc == "CLP" else "all")
    centres, radii, original, shift = assembly_particles(packing, copies)
    radii = radii * case.radius_factor
    is_copy = np.any(shift != 0, axis=1)
    log(f"packing: {n} particles, solid fraction {packing.solid_fraction:.4f}, cell {packing.cell}; "
        f"{int(is_copy.sum())} duplicated particles (d_bc = {d_bc:.4g} mm, bc {case.bc})")

    assembly = particle_mesh(centres, radii, comm, refinement=case.refinement)
    mesh = assembly.mesh
    owned_cells = mesh.topology.index_map(3).size_local
    cell_particle = assembly.cell_tags.values[:owned_cells]
    active = np.flatnonzero(~is_copy[cell_particle]) if case.bc == "CLP" else None
    problem = SolidProblem(mesh, case.material, tangent=case.solver == "implicit", active_cells=active)
    V = problem.V

    volumes = ParticleVolumes(assembly, problem.u)
    solid0 = float(volumes()[:n].sum())
    rho0 = solid0 / float(np.prod(packing.cell))
    F_target = compaction_gradient(case.loading, rho0, case.target_density)
    path = GradientPath([(case.duration, F_target)])

    h_contact = float(radii.min()) * np.pi / (8 * case.refinement)
    law = ContactLaw(penalty=default_penalty(case.material.E, h_contact, case.penalty_factor),
                     friction=case.friction, gamma=case.gamma, delta_max=case.delta_max,
                     asperity_yield=case.asperity_yield)
    allowed = np.ones((radii.size, radii.size), dtype=bool)
    if case.bc == "CLP":  # copy-copy contacts repeat VEP contacts (their periodic originals)
        allowed[np.ix_(is_copy, is_copy)] = False
    contact = ContactModel(V, assembly.facet_tags, radii.size, law,
                           search_distance=max(0.05 * float(radii.min()), 2 * case.delta_max), allowed=allowed,
                           shifts=periodic_lattice() * packing.cell if case.images else None)
    bcs = GranularBoundaryConditions(V, cell_particle, centres, radii, original, shift, packing.cell, case.bc, path,
                                     images=contact if case.images else None, anchor=case.solver == "implicit")
    return CompactionModel(case, packing, centres, radii, original, shift, assembly, problem, bcs, contact, path,
                           volumes, solid0, rho0, h_contact)


def run_compaction(case: CompactionCase, comm: MPI.Comm = MPI.COMM_WORLD, log=print) -> CompactionResult:
    """Compact the volume to ``case.target_density``; see the module docstring for outputs."""
    start = time.perf_counter()
    out = Path(case.out_dir)
    model = build_compaction(case, comm, log)
    packing, problem, bcs, contact, path = model.packing, model.problem, model.bcs, model.contact, model.path
    assembly, volumes, radii = model.assembly, model.volumes, model.radii
    V = problem.V
    n = packing.num_particles
    solid0, rho0 = model.solid_volume0, model.rho0
    cell_volume0 = float(np.prod(packing.cell))

    num_dofs = V.dofmap.index_map.size_global * 3
    if case.solver == "explicit":
        settings = ExplicitSettings(t_end=case.duration, target_dt=case.duration / case.increments,
                                    damping=case.damping / case.duration)

        def flow(t: float) -> np.ndarray:  # L = dF0/dt F0^-1 (1/s)
            eps = 1e-6 * case.duration
            return (path(t + eps) - path(t - eps)) / (2 * eps) @ np.linalg.inv(path(t))

        # the damping relaxes each particle's rigid motion relative to the imposed flow
        node_particle = node_particles(problem.V, assembly.cell_tags.values[: problem.num_cells])
        solver = ExplicitSolver(problem, bcs, settings, contact=contact, background=flow,
                                damped_bodies=node_particle)
        log(f"model: {radii.size} particles, {num_dofs} dofs ({bcs.constraint.num_reduced_global} free), "
            f"rho0 = {rho0:.4f} -> {case.target_density}, dt = {solver.dt:.3g} s "
            f"(unscaled {solver.dt_stable_unscaled:.3g} s), {case.increments} increments")
    else:
        log("WARNING: implicit granular compaction is experimental: with the pseudo-time drag the free "
            "particles are solvable, but Newton needs many cut-backs once contacts yield (tested on an "
            "8-particle cell only); use the explicit solver for production runs")
        h = model.contact_length
        nodal_volume = problem.lumped_mass(1.0).x.array[: bcs.constraint.num_owned]
        solver = ImplicitSolver(problem, bcs, contact=contact,
                                regularization=case.regularization * case.material.E * nodal_volume / h ** 2)
        implicit_plastic = [0.0]
        log(f"model: {radii.size} particles, {num_dofs} dofs ({bcs.constraint.num_reduced_global} free), "
            f"rho0 = {rho0:.4f} -> {case.target_density}, implicit, {case.steps} steps")

    centroids = ParticleCentroids(assembly, problem.u)
    X0 = centroids()[:n]
    comps = [f"{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3)]
    columns = ["time", "rho", "rho_imposed", "h_v", "h_d", "sigma_m", "sigma_d"] + [f"F{c}" for c in comps] + \
        [f"sigma{c}" for c in comps] + [f"sigma_schmidt_{c}" for c in comps] + \
        ["n_contacts", "E_int", "E_el", "E_p", "E_contact", "E_kin", "E_visc", "E_damp", "W_ext", "wall_time"]
    periodic = case.bc in ("CLP", "CLPS")  # Schmidt stress defined
    history = History(out / "history.csv", columns, comm, flush_every_row=True)
    writer = None
    if case.visual:
        fields = CellFields(problem, assembly.cell_tags)
        writer = ParaViewWriter(out / "particles.xdmf", problem, fields)

    def record(s: ExplicitSolver) -> None:
        x = centroids()
        F, _ = least_squares_gradient(X0, x[:n])
        h_v, h_d = strain_invariants(hencky_strain(F))
        F0 = path(s.t)
        volume = np.linalg.det(F) * cell_volume0
        rho = float(volumes()[:n].sum()) / volume
        # Love-Weber over the model's contacts with the appendix-C counting weights
        pf = contact.pair_forces()
        pairs = pf["pairs"]
        image = np.rint(np.linalg.solve(F0, pf["shift"].T).T / packing.cell).astype(np.int64)
        weights = contact_weights(pairs[:, 0], pairs[:, 1], model.original, model.shift, case.bc, image)
        sigma_lw = love_weber_stress(pf["force"], branch_vectors(x, pairs[:, 0], pairs[:, 1], pf["shift"]),
                                     volume, weights)  # tension > 0
        sigma_m, sigma_d = stress_invariants(sigma_lw)
        sigma_s = np.full((3, 3), np.nan)
        if periodic:  # Schmidt: reactions conjugate to F0 (auxiliary nodes), eq. 2.14
            sigma_s = piola_to_cauchy(bcs.macroscopic_force(s.reaction) / cell_volume0, F0)
        if case.solver == "explicit":
            e = s.energies
            energies = dict(E_int=e.internal, E_el=e.elastic, E_p=e.plastic, E_contact=e.contact,
                            E_kin=e.kinetic, E_visc=e.viscous, E_damp=e.damping, W_ext=e.external)
            progress = s.step / case.increments
        else:  # quasi-static: no kinetic / viscous energy; E_damp = the regularization's work
            implicit_plastic[0] += problem.plastic_dissipation_increment()
            energies = dict(E_int=np.nan, E_el=problem.stored_energy(), E_p=implicit_plastic[0],
                            E_contact=np.nan, E_kin=0.0, E_visc=0.0, E_damp=s.regularization_work, W_ext=np.nan)
            progress = s.t / case.duration
        history.append(time=s.t, rho=rho, rho_imposed=solid0 / (np.linalg.det(F0) * cell_volume0), h_v=h_v,
                       h_d=h_d, sigma_m=sigma_m, sigma_d=sigma_d,
                       **{f"F{c}": v for c, v in zip(comps, F.ravel())},
                       **{f"sigma{c}": v for c, v in zip(comps, -sigma_lw.ravel())},
                       **{f"sigma_schmidt_{c}": v for c, v in zip(comps, -sigma_s.ravel())},
                       n_contacts=len(pairs), wall_time=time.perf_counter() - start, **energies)
        if writer is not None:
            writer.write(s.t)
        elapsed = time.perf_counter() - start
        eta = elapsed / max(progress, 1e-9) * (1 - progress)
        log(f"  {100 * progress:5.1f} %  t={s.t:.3e} s  rho={rho:.4f}  sigma_m={sigma_m:8.3f} MPa  "
            f"contacts={len(pairs)}  E_p={energies['E_p']:.3g} mJ  E_kin={energies['E_kin']:.2g}  "
            f"E_damp={energies['E_damp']:.2g}  elapsed {elapsed:.0f} s  ETA {eta:.0f} s")

    if comm.rank == 0:
        out.mkdir(parents=True, exist_ok=True)
        write_packing(packing, out / "packing.txt")
    if case.solver == "explicit":
        total = solver.run(record, outputs=case.outputs)
    else:
        dt = case.duration / case.steps
        total = solver.run(StepControl(t_end=case.duration, dt=dt, dt_max=dt, dt_min=dt / 256), on_step=record,
                           log=log)
    history.write()
    if writer is not None:
        writer.close()
        # CLP shell copies carry no stress: show the volume's particles only
        render_deformed(problem.u, fields.von_mises, out / "particles.png", cells=problem.material_cells,
                        title=f"{n} lead particles, {case.loading} compaction, {case.bc}, "
                              f"rho = {history.rows[-1][1]:.3f}")
    return CompactionResult(history, packing, num_dofs, radii.size, time.perf_counter() - start, total, out,
                            extra={"model": model, "solver": solver})
