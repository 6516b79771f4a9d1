"""Compaction of a periodic granular volume (thesis chapter 2): packing -> assembly with
duplicated particles -> GDH / GDF / CLPS / CLP constraints -> contact -> solver -> history.

Sign convention: reported stresses are positive in compression (sigma_m > 0 in compaction);
strains keep their sign (h_v < 0 in compaction). Units mm, N, MPa, s.

History columns (one row per output; SPEC §10, thesis §2.3, §4.2, appendix C):
- time (s); rho = V_p / (V0 det F) (eq. 2.4-2.5: V_p = 4/3 pi sum r^3 of the particles' initial,
  meshed radii; F the least-squares gradient of the VEP centroids, eq. 2.2, C.3-C.6);
  rho_imposed (same with F0, the auxiliary-node gradient); rho_fe (finite-element particle
  volumes / V0 det F: the faceted mesh holds less solid than the spheres, 6.5 % at 517 nodes);
- h_v, h_d, h_tilde_d: Hencky strain invariants of F (eq. 2.3, 2.8-2.9, 4.3-4.4; natural sign,
  h_v < 0 in compaction; Rendulic axis I = z, the die axis);
- sigma_m, sigma_d, sigma_tilde_d: Love-Weber invariants (eq. 2.6, 2.10-2.11, 4.1-4.2; compression
  > 0); F11..F33 (least squares), sigma11..sigma33 (Love-Weber tensor, compression > 0, counted
  by the appendix-C rules), sigma_schmidt_11..33 (CLP/CLPS: from the constraint reactions
  conjugate to F0, P = R / V0, sigma = P F0^T / det F0, eq. 2.19, compression > 0; empty
  otherwise);
- n_contacts (contacting particle pairs); Gamma = S / (V0 det F) (mm^-1, eq. 4.13, S the contact
  area, one per pair);
- energies (mJ): E_p plastic (eq. 4.11), E_f frictional (eq. 4.12), E_d = E_p + E_f (eq. 4.10),
  E_c kinetic (of the motion relative to the imposed flow), E_int internal work, E_el stored
  elastic, E_contact work absorbed by contact, E_visc bulk viscosity, E_damp relaxation damping,
  W_ext external work; then wall_time (s).
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
from ..homogenization import (branch_vectors, contact_weights, dissipated_energy, hencky_strain,
                              least_squares_gradient, love_weber_stress, piola_to_cauchy, relative_density,
                              rendulic_strain, rendulic_stress, solid_volume, specific_contact_surface,
                              strain_invariants, stress_invariants)
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
    #: duplicate across edges and corners too (False: face copies only, e.g. the 12 copies of the
    #: ordered simple cubic cell, thesis §2.6)
    corners: bool = True
    radius_factor: float = 0.99  # radii shrunk before meshing: no initial interpenetration
    refinement: int = 1
    #: cube-sphere hexahedra per inner-cube edge (meshes.cubesphere; odd: the contact points of
    #: axis-aligned neighbours fall on facet centres instead of nodes)
    divisions: int = 4
    #: (3, 3) rotation of every particle mesh about its centre (None: cube-sphere axes along x, y,
    #: z). One generic rotation for all keeps identical particles exact translates of each other
    #: while their contact points fall inside facets, not on nodes (ordered packings)
    mesh_rotation: np.ndarray | None = None
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
        if not 1 <= self.divisions <= 16:
            raise ValueError(f"divisions must be in [1, 16], got {self.divisions}")
        if self.mesh_rotation is not None:
            Q = np.asarray(self.mesh_rotation, dtype=float)
            if Q.shape != (3, 3) or not np.allclose(Q @ Q.T, np.eye(3), atol=1e-12) or np.linalg.det(Q) < 0:
                raise ValueError("mesh_rotation must be a (3, 3) proper rotation matrix")
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
    solid_volume0: float  # V_p = 4/3 pi sum r^3 of the VEP particles' meshed radii (mm^3)
    rho0: float  # V_p / V0
    rho0_fe: float  # finite-element particle volumes / V0
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
        copies = duplicate_particles(packing, d_bc, faces="half" if case.bc == "CLP" else "all",
                                     corners=case.corners)
    centres, radii, original, shift = assembly_particles(packing, copies)
    radii = radii * case.radius_factor
    is_copy = np.any(shift != 0, axis=1)
    log(f"packing: {n} particles, solid fraction {packing.solid_fraction:.4f}, cell {packing.cell}; "
        f"{int(is_copy.sum())} duplicated particles (d_bc = {d_bc:.4g} mm, bc {case.bc})")

    rotations = None if case.mesh_rotation is None else np.broadcast_to(case.mesh_rotation, (radii.size, 3, 3))
    assembly = particle_mesh(centres, radii, comm, divisions=case.divisions, refinement=case.refinement,
                             rotations=rotations)
    mesh = assembly.mesh
    owned_cells = mesh.topology.index_map(3).size_local
    cell_particle = assembly.cell_tags.values[:owned_cells]
    active = np.flatnonzero(~is_copy[cell_particle]) if case.bc == "CLP" else None
    problem = SolidProblem(mesh, case.material, tangent=case.solver == "implicit", active_cells=active)
    V = problem.V

    volumes = ParticleVolumes(assembly, problem.u)
    solid0 = solid_volume(radii[:n])  # thesis eq. 2.5, initial (meshed) radii
    rho0 = solid0 / float(np.prod(packing.cell))
    rho0_fe = float(volumes()[:n].sum()) / float(np.prod(packing.cell))
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
                           volumes, solid0, rho0, rho0_fe, h_contact)


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

        # every particle is carried by the imposed flow (comoving constraints): the damping relaxes
        # each particle's rigid motion relative to it; a copy's nodes belong to their original
        # (tied: one material body, whose copy nodes may hold contact mass)
        node_particle = node_particles(problem.V, assembly.cell_tags.values[: problem.num_cells])
        solver = ExplicitSolver(problem, bcs, settings, contact=contact,
                                damped_bodies=model.original[node_particle])
        log(f"model: {radii.size} particles, {num_dofs} dofs ({bcs.constraint.num_reduced_global} free), "
            f"rho0 = {rho0:.4f} (finite elements {model.rho0_fe:.4f}) -> {case.target_density}, dt = {solver.dt:.3g} s "
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
    columns = ["time", "rho", "rho_imposed", "rho_fe", "h_v", "h_d", "h_tilde_d", "sigma_m", "sigma_d",
               "sigma_tilde_d"] + [f"F{c}" for c in comps] + [f"sigma{c}" for c in comps] + \
        [f"sigma_schmidt_{c}" for c in comps] + \
        ["n_contacts", "Gamma", "E_p", "E_f", "E_d", "E_c", "E_int", "E_el", "E_contact", "E_visc", "E_damp",
         "W_ext", "wall_time"]
    periodic = case.bc in ("CLP", "CLPS")  # Schmidt stress defined
    history = History(out / "history.csv", columns, comm, flush_every_row=True)
    writer = None
    if case.visual:
        fields = CellFields(problem, assembly.cell_tags)
        writer = ParaViewWriter(out / "particles.xdmf", problem, fields)

    def record(s: ExplicitSolver) -> None:
        x = centroids()
        F, _ = least_squares_gradient(X0, x[:n])
        h = hencky_strain(F)
        h_v, h_d = strain_invariants(h)
        h_tilde_d = rendulic_strain(h)[1]
        F0 = path(s.t)
        volume = np.linalg.det(F) * cell_volume0
        rho = relative_density(solid0, cell_volume0, F)
        # Love-Weber over the model's contacts with the appendix-C counting weights
        pf = contact.pair_forces()
        pairs = pf["pairs"]
        image = np.rint(np.linalg.solve(F0, pf["shift"].T).T / packing.cell).astype(np.int64)
        weights = contact_weights(pairs[:, 0], pairs[:, 1], model.original, model.shift, case.bc, image)
        sigma_lw = love_weber_stress(pf["force"], branch_vectors(x, pairs[:, 0], pairs[:, 1], pf["shift"]),
                                     volume, weights)  # tension > 0
        sigma_m, sigma_d = stress_invariants(sigma_lw)
        sigma_tilde_d = rendulic_stress(sigma_lw)[1]
        gamma = specific_contact_surface(pf["area"], cell_volume0, F, weights)
        sigma_s = np.full((3, 3), np.nan)
        if periodic:  # Schmidt: reactions conjugate to F0 (auxiliary nodes), eq. 2.14
            sigma_s = piola_to_cauchy(bcs.macroscopic_force(s.reaction) / cell_volume0, F0)
        if case.solver == "explicit":
            e = s.energies
            energies = dict(E_int=e.internal, E_el=e.elastic, E_p=e.plastic, E_contact=e.contact,
                            E_c=e.kinetic, E_visc=e.viscous, E_damp=e.damping, W_ext=e.external)
            progress = s.step / case.increments
        else:  # quasi-static: no kinetic / viscous energy; E_damp = the regularization's work
            implicit_plastic[0] += problem.plastic_dissipation_increment()
            energies = dict(E_int=np.nan, E_el=problem.stored_energy(), E_p=implicit_plastic[0],
                            E_contact=np.nan, E_c=0.0, E_visc=0.0, E_damp=s.regularization_work, W_ext=np.nan)
            progress = s.t / case.duration
        energies["E_f"] = contact.frictional_work
        energies["E_d"] = float(dissipated_energy(energies["E_p"], energies["E_f"]))
        history.append(time=s.t, rho=rho, rho_imposed=relative_density(solid0, cell_volume0, F0),
                       rho_fe=float(volumes()[:n].sum()) / volume, h_v=h_v, h_d=h_d, h_tilde_d=h_tilde_d,
                       sigma_m=sigma_m, sigma_d=sigma_d, sigma_tilde_d=sigma_tilde_d,
                       **{f"F{c}": v for c, v in zip(comps, F.ravel())},
                       **{f"sigma{c}": v for c, v in zip(comps, -sigma_lw.ravel())},
                       **{f"sigma_schmidt_{c}": v for c, v in zip(comps, -sigma_s.ravel())},
                       n_contacts=len(pairs), Gamma=gamma, wall_time=time.perf_counter() - start, **energies)
        if writer is not None:
            writer.write(s.t)
        elapsed = time.perf_counter() - start
        eta = elapsed / max(progress, 1e-9) * (1 - progress)
        log(f"  {100 * progress:5.1f} %  t={s.t:.3e} s  rho={rho:.4f}  sigma_m={sigma_m:8.3f} MPa  "
            f"contacts={len(pairs)}  E_p={energies['E_p']:.3g} mJ  E_c={energies['E_c']:.2g}  "
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
