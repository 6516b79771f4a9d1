"""Explicit dynamics: central difference with lumped mass, mass scaling and bulk viscosity.

Reduced coordinates x of u = P x + g(t) (``constraints.AffineConstraint``):
    M_red a_n = -P^T (f_int(u_n) + f_bv(u_n, v_{n-1/2}))
with M_red the row-sum lumped |P|^T M |P| (default) or the consistent P^T M P
(``ExplicitSettings.constraint_mass``).
The offset g(t) carries no inertia: only the "peculiar" motion P x is accelerated. For prescribed
dofs this changes nothing; for a granular cell whose every node is carried by the homogeneous flow
(F0(t) - I) X (``GranularBoundaryConditions(comoving=True)``) it is the periodic-dynamics (SLLOD)
idea: mass scaling then slows the particles' motion *relative to* the imposed flow, not the flow.
    v_{n+1/2} = v_{n-1/2} + dt a_n        (v_{1/2} = v_0 + dt/2 a_0)
    x_{n+1}   = x_n + dt v_{n+1/2}
Stability: dt <= dt_e = safety * L_e / c_d * (sqrt(1 + xi^2) - xi) per element, with xi = b1 the
linear bulk-viscosity fraction (Abaqus/Explicit estimate) and L_e the element's stable length
(``SolidProblem.min_cell_length``): the smallest of the smallest vertex distance, for hexahedra
the centre-point volume over the largest face area, and the Gauss-point bound of
``problem.hexahedron_gauss_length`` (Flanagan-Belytschko). Mass scaling (element by element,
Abaqus "fixed mass scaling to a target increment", then variable re-checks, :mod:`.mass_scaling`):
rho_e = rho * max(1, (dt_target / (margin dt_e))^2); penalty contact adds mass to the surface
nodes.

Relaxation damping towards the quasi-static path (``ExplicitSettings.damping`` and
``local_damping``): :mod:`.damping`. Energy balance, exact for central differences: :mod:`.energy`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import ufl

from .. import forms
from ..loading import PrescribedDisplacements
from ..problem import SolidProblem
from ..runtime import configure_runtime
from .constraint_mass import CONSTRAINT_MASSES, ConsistentReducedMass
from .damping import RelaxationDamping
from .energy import Energies, EnergyTally
from .mass_scaling import ElementMassScaling
from .state import check_layout, histories_state, load_histories


@dataclass
class ExplicitSettings:
    """Time integration settings (s)."""

    t_end: float
    target_dt: float | None = None  # mass-scale up to this increment (None: no mass scaling)
    safety: float = 0.9
    #: the stable increment shrinks as elements deform: mass-scale for dt_target / margin
    deformation_margin: float = 0.6
    #: every so many increments, re-check the element stable increments in the deformed
    #: configuration and add mass where needed (Abaqus variable mass scaling); 0: fixed
    rescale_every: int = 100
    bulk_viscosity_linear: float = 0.06
    bulk_viscosity_quadratic: float = 1.2
    #: mass-proportional damping c (1/s) of the peculiar velocity P v_red (relative to the
    #: moving offsets g(t), e.g. the homogeneous flow of a comoving granular cell): dynamic
    #: relaxation towards the quasi-static path; its dissipation is Energies.damping
    damping: float = 0.0
    #: local non-viscous damping coefficient alpha in [0, 1) (Cundall's local damping of DEM codes,
    #: FLAC's static solution scheme): on every free reduced dof a force -alpha |F| sign(w') against
    #: the peculiar velocity w', F the dof's out-of-balance force. It removes a fraction of the
    #: energy of every oscillation, rigid or deformation mode, and vanishes with the acceleration:
    #: a steady flow (constant w', F = 0) is not resisted, so it adds no rate-dependent stress
    local_damping: float = 0.0
    #: reduced mass of the constrained model: "lumped", the row sums |P|^T M |P| (diagonal; a
    #: coupling's eliminated node hands its mass to each of its masters, so that a rigid
    #: translation of a CLPS model weighs ~2.5x its particles), or "consistent", P^T M P itself
    #: (the particles' own inertia; solved per increment through a small factorized matrix,
    #: :mod:`.constraint_mass`; stable at the unconstrained model's increment)
    constraint_mass: str = "lumped"

    def __post_init__(self):
        if not self.t_end > 0:
            raise ValueError(f"t_end must be > 0 s, got {self.t_end}")
        if self.target_dt is not None and not self.target_dt > 0:
            raise ValueError(f"target_dt must be > 0 s, got {self.target_dt}")
        if not 0 < self.deformation_margin <= 1:
            raise ValueError(f"deformation_margin must be in (0, 1], got {self.deformation_margin}")
        if not 0 < self.safety <= 1:
            raise ValueError(f"safety must be in (0, 1], got {self.safety}")
        for name in ("bulk_viscosity_linear", "bulk_viscosity_quadratic"):
            value = getattr(self, name)
            if not value >= 0:
                raise ValueError(f"{name} must be >= 0, got {value}")
            setattr(self, name, float(value))  # a UFL constant of an int is refused by dolfinx
        if self.damping < 0:
            raise ValueError(f"damping must be >= 0 1/s, got {self.damping}")
        if not 0.0 <= self.local_damping < 1.0:
            raise ValueError(f"local_damping must be in [0, 1), got {self.local_damping}")
        if self.constraint_mass not in CONSTRAINT_MASSES:
            raise ValueError(
                f"constraint_mass must be one of {CONSTRAINT_MASSES}, got {self.constraint_mass!r}"
            )


class PhaseTimes(dict):
    """Wall time (s) per phase of the time step, accumulated: ``with times("material"): ...``.

    Phases of an explicit step: material (return mapping at the quadrature points), assembly
    (bulk and bulk-viscosity force vectors), contact_search, contact_halo (rebuilds of the held
    surface), contact_forces (law, nodal forces, history), constraints (offsets, u = P x + g,
    P^T f), update (central difference and energy balance), mass_scaling (variable mass scaling
    re-checks)."""

    @contextmanager
    def __call__(self, phase: str):
        """Context manager adding the wall time (s) of its block to ``phase``'s total."""
        start = time.perf_counter()
        try:
            yield
        finally:
            self[phase] = self.get(phase, 0.0) + time.perf_counter() - start


class ExplicitSolver:
    """Central-difference integrator of a :class:`SolidProblem` with prescribed displacements:
    a :class:`~mpfem_fenicsx.solvers.interface.DynamicSolver` (the solver interface)."""

    name = "explicit"

    def __init__(
        self,
        problem: SolidProblem,
        bcs: PrescribedDisplacements,
        settings: ExplicitSettings,
        contact=None,
        damped_bodies: np.ndarray | None = None,
    ):
        """``damped_bodies``: body id of every owned node: the damping then acts on each body's
        mean (rigid) peculiar velocity only, c m_node (w_b - <w>), <.> the mass average, so that
        rearrangements are relaxed while the bodies' deformation is not resisted and momentum is
        conserved (default: node by node); id -1: a node left undamped (a body whose rigid motion
        is imposed). Its forces have a first moment sum f_b (x) x_b: a
        viscous stress that the full :attr:`reaction` sees and the Love-Weber contact sum does
        not, hence :attr:`static_reaction` for the Schmidt stress (measurements: bench/README.md,
        "Damping, inertia and the Schmidt stress")."""
        configure_runtime(problem.comm)
        self.problem = problem
        self.contact = contact  # optional ContactModel: its forces join the internal ones
        self.bcs = bcs
        self.settings = settings
        self.constraint = bcs.constraint or bcs.build()
        self.comm = problem.comm
        mesh = problem.mesh

        self._element_mass_scaling(settings)
        self._contact_mass = None  # per owned surface node, set by _contact_mass_scaling
        #: P^T M P and its solve when ``settings.constraint_mass`` is "consistent", else None
        self.consistent_mass: ConsistentReducedMass | None = None
        self._build_mass()

        v = ufl.TestFunction(problem.V)
        self.velocity = dolfinx.fem.Function(problem.V, name="velocity")
        self.viscous_form = dolfinx.fem.form(
            forms.bulk_viscosity_work(
                problem.u,
                self.velocity,
                v,
                self.density,
                self.scaling.wave_speed,
                self.scaling.cell_length,
                dolfinx.fem.Constant(mesh, settings.bulk_viscosity_linear),
                dolfinx.fem.Constant(mesh, settings.bulk_viscosity_quadratic),
                problem.dx_vol,
            )
        )
        # the same force by the problem's numba loop at the volumetric points, when it reproduces
        # the form (checked with rates large enough for the quadratic term to count)
        self._viscous_loop = problem.volumetric_forces.reproduces(
            self.viscous_form,
            self._add_viscous_forces,
            [(problem.u, 1.0), (self.velocity, 50.0 * self._rate_scale())],
        )

        self.f_int = problem.create_vector()
        self.f_visc = problem.create_vector()
        self.f_cont = problem.create_vector()  # minus the contact forces on the bodies
        self.f_damp = problem.create_vector()
        self.timings = PhaseTimes()
        #: the viscous and local relaxation damping (:mod:`.damping`)
        self.relaxation = RelaxationDamping(
            settings.damping,
            settings.local_damping,
            self.constraint,
            self.comm,
            problem.create_vector(),
            damped_bodies,
            self.timings,
        )
        #: optional t -> velocity (mm/s, reduced dofs) that the local damping does not resist
        #: (node-wise damping of an unconstrained model: the homogeneous flow between rigid
        #: tools, :func:`~mpfem_fenicsx.workflows.tooled.flow_between_tools`); None: rest
        self.damping_reference = None
        self._force = problem.create_vector()  # their sum, reused every step
        self.x = self.constraint.create_reduced_vector()
        self.v_red = self.x.duplicate()
        self.a_red = self.x.duplicate()
        self.r_red = self.x.duplicate()
        self.t = 0.0
        self.step = 0
        self.tally = EnergyTally(self.comm)
        self.energies: Energies = self.tally.energies
        n = self.constraint.num_owned
        self._u_prev = np.zeros(n)
        self._v_half_prev = np.zeros(n)  # peculiar half-step velocity P v_red
        self._g_prev = np.zeros(n)
        # periodic images (bcs.image_force): their work through the moving shifts joins W_ext
        self._images = getattr(bcs, "image_force", None)
        self._image_force = None  # bcs.image_force() at the current step (saved with the state)

    def _element_mass_scaling(self, settings: ExplicitSettings) -> None:
        """Element stable increments and element-wise mass scaling (:mod:`.mass_scaling`): sets
        ``scaling`` (with the cell functions of the scaled wave speed and of the element length
        that the bulk viscosity reads), ``dt``, ``dt_stable_unscaled``, ``mass_scaling_max`` and
        the scaled ``density``."""
        self.scaling, dt_e = ElementMassScaling.build(self.problem, settings)
        self.dt_stable_unscaled = self.comm.allreduce(float(dt_e.min()), op=MPI.MIN)
        self.dt = settings.target_dt if settings.target_dt is not None else self.dt_stable_unscaled
        self.mass_scaling_max = self.scaling.largest(self.comm)
        self.density = self.scaling.density

    def _build_mass(self) -> None:
        """Lumped mass (with the contact springs' mass) and its reduction."""
        mass = self.problem.lumped_mass(self.density)
        if self.contact is not None:
            self._contact_mass_scaling(mass, self.contact, self.settings)
        self.mass = mass
        self.total_mass = self.comm.allreduce(
            float(mass.x.array[: self.constraint.num_owned].sum()) / 3.0
        )
        self.mass_red = self.constraint.reduced_lumped_mass(mass)
        if self.settings.constraint_mass == "consistent":
            self._build_consistent_mass()

    def _build_consistent_mass(self) -> None:
        """The consistent reduced mass P^T M P and its solve (:mod:`.constraint_mass`; the solves
        compared: bench/README.md). By the Rayleigh quotient over the range of P, the constrained
        model's highest frequency is at most the unconstrained one's: the mass-scaled increment
        stays stable."""
        if self.consistent_mass is not None:
            self.consistent_mass.destroy()
        self.consistent_mass = ConsistentReducedMass(self.constraint, self.mass.x.array)

    def _rescale_mass(self) -> bool:
        """Variable mass scaling: where the deformed elements' stable increment fell below dt / 0.9,
        raise their density so that it is back; the bulk viscosity takes the current lengths; the
        contact mass follows the current contact stiffness (see _contact_mass_scaling). Returns
        whether the masses were raised (rebuilt)."""
        scaling = self.scaling
        length = self.problem.min_cell_length(deformed=True)
        dt_e = scaling.stable_increments(length)
        need = (self.dt / (0.9 * dt_e)) ** 2
        grow = need > scaling.scale
        scaling.set_lengths(length)
        contact_grows = False
        if self._contact_mass is not None:
            contact_grows = bool(
                (self._contact_mass_needed(self.contact) > 1.05 * self._contact_mass).any()
            )
        if not self.comm.allreduce(bool(grow.any()) or contact_grows, op=MPI.LOR):
            return False
        scaling.scale[grow] = need[grow]
        scaling.apply()
        self.mass_red.destroy()
        self._build_mass()
        self.mass_scaling_max = scaling.largest(self.comm)
        return True

    def _contact_mass_scaling(self, mass, contact, settings) -> None:
        """Penalty contact adds springs to the surface nodes. With a target increment, add to
        every surface node the mass m_c = K_c (dt / 2 s)^2 that keeps it stable (central
        difference: dt <= 2 sqrt(m / K)), where K_c is the larger of
          - k A_ref (k penalty, A_ref reference tributary area): a node pressed over its own area;
          - 1.5 x the Gershgorin row sum of the current contact stiffness, sum_p 2 k w A_p |c_a|
            (both passes, c_a = 1 on the slave, -N_a on the master facet's nodes): a small
            particle's node pressed by a larger particle's coarser facets, or contact areas
            grown by flattening (die compaction diverged without it);
        the contact mass only grows (previous value kept). A massless CLP copy node and its
        original are one material point: its contact stiffness is added to the original's
        before the max with the floor, and the copy node gets no mass of its own (a sum of two
        floors would make particles with copies heavier than the others and break the
        translation symmetry of an ordered packing). Without a target increment,
        reduce dt to 2 s sqrt(m / (k A_ref)) instead."""
        from ..contact.search import facet_areas

        surf = contact.surface
        area = np.bincount(
            surf.facets[:, : surf.vertices_per_facet].ravel(),
            weights=np.repeat(
                facet_areas(surf.X, surf.facets, surf.vertices_per_facet) / surf.vertices_per_facet,
                surf.vertices_per_facet,
            ),
            minlength=surf.num_nodes,
        )
        k_node = contact.law.penalty * area[surf.owned_nodes]
        blocks = surf.owned_local_blocks
        m_node = mass.x.array.reshape(-1, 3)[blocks, 0]
        s = self.settings.safety
        if settings.target_dt is not None:
            tied = np.isin(blocks, self.constraint.slaves // 3)
            floor = np.where(tied, 0.0, self._spring_mass(k_node))
            added = np.maximum(floor, self._merge_tied(blocks, self._contact_mass_needed(contact)))
            added[tied] = 0.0
            if self._contact_mass is not None:
                added = np.maximum(added, self._contact_mass)
            self._contact_mass = added
            mass.x.array.reshape(-1, 3)[blocks] += added[:, None]
            mass.x.scatter_forward()
            self.contact_added_mass = self.comm.allreduce(float(added.sum()), op=MPI.SUM)
        else:
            real = m_node > 0.0
            local = (
                float((2.0 * s * np.sqrt(m_node[real] / k_node[real])).min())
                if real.any()
                else np.inf
            )
            self.dt = min(self.dt, self.comm.allreduce(local, op=MPI.MIN))
            self.contact_added_mass = 0.0

    def _merge_tied(self, blocks: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Per owned surface node (local ``blocks``), the sum of ``values`` over the material point:
        a node tied to copies (CLP) gets its copies' values added, and the copies get that sum too
        (u = P x: restrict with P^T, expand with P)."""
        full = self.constraint.P.createVecLeft()
        reduced = self.constraint.P.createVecRight()
        full.array_w[3 * blocks] = values
        self.constraint.P.multTranspose(full, reduced)
        self.constraint.P.mult(reduced, full)
        merged = full.array_r[3 * blocks].copy()
        full.destroy()
        reduced.destroy()
        return merged

    def _spring_mass(self, stiffness: np.ndarray) -> np.ndarray:
        """Nodal mass (t) for which springs ``stiffness`` (N/mm) are stable at dt, with the
        safety and deformation margins: m = K (dt / (2 s margin))^2."""
        s = self.settings
        return stiffness * (self.dt / (2.0 * s.safety * s.deformation_margin)) ** 2

    def _contact_mass_needed(self, contact) -> np.ndarray:
        """Mass (t) that keeps each owned surface node stable under 1.5 x its current contact
        stiffness row sum."""
        return self._spring_mass(1.5 * self._contact_row_sums(contact))

    def _contact_row_sums(self, contact) -> np.ndarray:
        """Gershgorin row sums (N/mm) of the current contact stiffness at this rank's owned
        surface nodes (zero before the first evaluation)."""
        return contact.nodal_stiffness()

    # -- forces ------------------------------------------------------------------------------
    def _add_viscous_forces(self, array: np.ndarray) -> None:
        s, scaling = self.settings, self.scaling
        self.problem.volumetric_forces.add_bulk_viscosity(
            self.problem.u,
            self.velocity,
            self.density,
            scaling.wave_speed,
            scaling.cell_length,
            s.bulk_viscosity_linear,
            s.bulk_viscosity_quadratic,
            array,
        )

    def _rate_scale(self) -> float:
        """A volumetric rate (1/s) at which the quadratic bulk-viscosity term is as large as the
        linear one, b1 c_d / (b2 L_e) (median cell), for checking both (the check's velocity
        field has gradients of about 0.02 per unit scale)."""
        c = (
            np.median(self.scaling.wave_speed.x.array)
            if self.scaling.wave_speed.x.array.size
            else 1.0
        )
        length = (
            np.median(self.scaling.cell_length.x.array)
            if self.scaling.cell_length.x.array.size
            else 1.0
        )
        s = self.settings
        if s.bulk_viscosity_linear == 0.0 or s.bulk_viscosity_quadratic == 0.0:
            return float(c / length)  # one term only: any rate of that order checks it
        return float(s.bulk_viscosity_linear * c / (s.bulk_viscosity_quadratic * length))

    def _assemble(self, vec: PETSc.Vec, form) -> None:
        with vec.localForm() as loc:
            loc.set(0.0)
        dolfinx.fem.petsc.assemble_vector(vec, form)
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)

    def _forces(self) -> None:
        with self.timings("material"):
            self.problem.update_material(tangent=False)
            self.problem.commit()
        with self.timings("assembly"):
            self.problem.assemble_residual(self.f_int)
            if self._viscous_loop:
                with self.f_visc.localForm() as loc:
                    loc.set(0.0)
                    self._add_viscous_forces(loc.array)
                self.f_visc.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            else:
                self._assemble(self.f_visc, self.viscous_form)
            with self.f_cont.localForm() as loc:
                loc.set(0.0)
        if self.contact is not None:
            searched, rebuilt = self.contact.search_time, self.contact.halo_time
            start = time.perf_counter()
            self.contact.evaluate(self.problem.u, tangent=False)
            self.contact.add_residual(self.f_cont)
            if self._images is not None:
                self._image_force = self._images()
            self.contact.commit(self.problem.u)
            search = self.contact.search_time - searched
            halo = self.contact.halo_time - rebuilt
            self.timings["contact_search"] = self.timings.get("contact_search", 0.0) + search
            self.timings["contact_halo"] = self.timings.get("contact_halo", 0.0) + halo
            self.timings["contact_forces"] = (
                self.timings.get("contact_forces", 0.0)
                + time.perf_counter()
                - start
                - search
                - halo
            )
        self.energies.plastic += self.problem.plastic_dissipation_increment()

    def reactions(self, dofs: np.ndarray) -> float:
        """Sum over ranks of the reaction force (N) on the given local unrolled dofs at the last
        step: R = f_int + f_bv - f_c + f_d + M a_w (peculiar inertia included)."""
        dofs = np.asarray(dofs)
        owned = dofs[dofs < self.constraint.num_owned]
        return self.comm.allreduce(float(self._reaction_last[owned].sum()) if owned.size else 0.0)

    @property
    def reaction(self) -> np.ndarray:
        """Reaction (N) on every owned unrolled dof at the last step, f_int + f_bv - f_c + f_d +
        M a_w (a_w the peculiar acceleration; P^T R = 0 up to the lumping of M_red)."""
        return self._reaction_last

    @property
    def static_reaction(self) -> np.ndarray:
        """Forces (N) the medium exerts at the current step on every owned unrolled dof, without
        the integrator's own terms: f_int + f_bv - f_c (no relaxation damping, no inertia).
        Its moment is the mean stress of the material and contacts, the reaction the Schmidt
        stress (eq. 2.19) is built from; the damping's first moment and the lumped inertia in
        :attr:`reaction` would bias it (bench/README.md, "Damping, inertia and the Schmidt
        stress")."""
        n = self.constraint.num_owned
        return self.f_int.array_r[:n] + self.f_visc.array_r[:n] + self.f_cont.array_r[:n]

    @property
    def macroscopic_reaction(self) -> np.ndarray:
        """The reaction the Schmidt stress (eq. 2.19) is built from: :attr:`static_reaction`."""
        return self.static_reaction

    def energy_record(self) -> dict[str, float]:
        """The energies of a history row (mJ): :meth:`Energies.record`; rigid tools' work on the
        particles (their forces along their motion) joins W_ext and, as the contact forces'
        tally only sees the particles' side of it, E_contact."""
        record = self.energies.record()
        tools = None if self.contact is None else self.contact.tools
        if tools is not None:
            work = float(tools.tool_work.sum())
            record["W_ext"] += work
            record["E_contact"] += work
        return record

    @property
    def total_steps(self) -> int:
        """Increments from t = 0 to settings.t_end."""
        return (
            int(np.ceil(self.settings.t_end / self.settings.target_dt - 1e-9))
            if self.settings.target_dt is not None
            else int(np.ceil(self.settings.t_end / self.dt - 1e-9))
        )

    def iteration_record(self) -> dict[str, float]:
        """NaN: an explicit increment has no Newton iterations and no cut-backs."""
        return dict.fromkeys(("newton_iterations", "linear_iterations", "cutbacks"), float("nan"))

    def unbalanced_ratio(self) -> float:
        """Out-of-balance ratio at the current step (-): ||P^T (f_int + f_bv - f_c)|| /
        ||P^T f_int||, 2-norms over the free (reduced) dofs of the forces the medium exerts,
        without the integrator's own inertia and relaxation damping, over the internal forces
        (which carry the contact loads through the particles). 0 in static equilibrium; the
        explicit relaxation's quasi-static measure (Abaqus' and DEM codes' residual-force ratios
        are of this kind). NaN before any internal force."""
        work = self._force
        self.f_int.copy(work)
        work.axpy(1.0, self.f_visc)
        work.axpy(1.0, self.f_cont)
        residual = self.r_red.duplicate()
        self.constraint.restrict(work, residual)
        self.constraint.restrict(self.f_int, self.r_red)
        scale = self.r_red.norm()
        ratio = residual.norm() / scale if scale > 0.0 else float("nan")
        residual.destroy()
        return ratio

    # -- stepping ----------------------------------------------------------------------------
    def _tally_work(self, reaction, inertia, du, dg, image_force, H_n, t_new: float) -> None:
        """The energies' increments around step n (:mod:`.energy`): the reaction's, internal,
        viscous, contact, damping and carrier work over the centred displacement increment
        ``du`` (offset part ``dg``), and the periodic images' work through their moving shifts."""
        n = self.constraint.num_owned
        self.tally.add_external_work(reaction, du)
        if image_force is not None:
            H_new = self.bcs.displacement_gradient(t_new)
            self.tally.add_image_work(image_force, H_n, H_new, first=self.step == 0)
        damping = self.f_damp.array_r[:n] if self.relaxation.active else None
        forces = (self.f_int.array_r[:n], self.f_visc.array_r[:n], self.f_cont.array_r[:n])
        self.tally.add_step_work(inertia, du, dg, forces, damping)

    def _add_local_damping(self, force: PETSc.Vec) -> None:
        """The local non-viscous damping (:mod:`.damping`) added to ``force``, to ``f_damp`` (its
        work is E_damp) and to the reduced force r_red = P^T force."""
        n = self.constraint.num_owned
        lifted = self.relaxation.local_force(
            force.array_r[:n],
            self.r_red,
            self.v_red,
            self.mass.x.array[:n],
            self.mass_red,
            self._v_half_prev,
            self.a_red,
            None if self.damping_reference is None else self.damping_reference(self.t),
        )
        if self.settings.damping > 0:
            self.f_damp.array_w[:n] += lifted
        else:
            self.f_damp.array_w[:n] = lifted
        force.array_w[:n] += lifted

    def _reduced_acceleration(self) -> None:
        """a_red = -M_red^-1 r_red: a division by the lumped reduced mass, or the solve with the
        factorized consistent one."""
        if self.consistent_mass is not None:
            with self.timings("constraints"):
                self.consistent_mass.solve(self.r_red, self.a_red)
        else:
            self.a_red.pointwiseDivide(self.r_red, self.mass_red)
        self.a_red.scale(-1.0)

    def advance(self) -> None:
        """One central-difference step t_n -> t_{n+1}."""
        dt = self.dt
        n = self.constraint.num_owned
        u = self.problem.u
        if self.step == 0:
            self.bcs.apply(0.0)
            self.constraint.expand(self.x, u)
            self._u_prev[:] = u.x.array[:n]
            self._forces()
        t2 = time.perf_counter()
        constraints0 = self.timings.get("constraints", 0.0)
        # reduced acceleration and velocity (half step at the start)
        force = self._force
        self.f_int.copy(force)
        force.axpy(1.0, self.f_visc)
        force.axpy(1.0, self.f_cont)
        if self.settings.damping > 0:
            nodal_mass = self.mass.x.array[:n].reshape(-1, 3)[:, 0]
            self.f_damp.array_w[:n] = self.relaxation.viscous_force(nodal_mass, self._v_half_prev)
            force.axpy(1.0, self.f_damp)
        with self.timings("constraints"):
            self.constraint.restrict(force, self.r_red)
        if self.settings.local_damping > 0:
            self._add_local_damping(force)
        self._reduced_acceleration()
        self.v_red.axpy(0.5 * dt if self.step == 0 else dt, self.a_red)
        self.x.axpy(dt, self.v_red)

        u_n = u.x.array[:n].copy()
        g_n = self.constraint.g.x.array[:n].copy()
        image_force = self._image_force
        if image_force is not None:
            H_n = self.bcs.displacement_gradient(self.t)
        t_new = self.t + dt
        with self.timings("constraints"):
            self.bcs.apply(t_new)
            self.constraint.expand(self.x, u)
        g_new = self.constraint.g.x.array[:n]
        # half-step velocity: peculiar part w' = P v_red (the only one with inertia), plus the
        # offsets' rate (g_{n+1} - g_n) / dt for the bulk viscosity's strain rate
        with self.timings("constraints"):
            self.constraint.expand(self.v_red, self.velocity, with_offset=False)
        v_half = self.velocity.x.array[:n].copy()
        self.velocity.x.array[:n] += (g_new - g_n) / dt
        self.velocity.x.scatter_forward()

        # reactions at step n: R = f + M a_w, a_w from the two peculiar half-step velocities
        mass = self.mass.x.array[:n]
        h = dt if self.step > 0 else 0.5 * dt
        inertia = mass * (v_half - self._v_half_prev) / h
        reaction = force.array_r[:n] + inertia
        self._reaction_last = reaction
        # centred displacement increment around step n (one-sided at the start) and its offset part
        du = 0.5 * (u.x.array[:n] - (self._u_prev if self.step > 0 else u_n))
        dg = 0.5 * (g_new - (self._g_prev if self.step > 0 else g_n))
        self._tally_work(
            reaction, inertia, du, dg, image_force, H_n if image_force is not None else None, t_new
        )
        self._u_prev[:] = u_n
        self._g_prev[:] = g_n
        self._v_half_prev[:] = v_half
        self.timings["update"] = (
            self.timings.get("update", 0.0)
            + time.perf_counter()
            - t2
            - (self.timings["constraints"] - constraints0)
        )

        self.t = t_new
        self.step += 1
        every = self.settings.rescale_every
        if every and self.settings.target_dt is not None and self.step % every == 0:
            with self.timings("mass_scaling"):
                raised = self._rescale_mass()
            if raised:  # the next steps' inertia is the new mass's
                mass_before, mass = mass, self.mass.x.array[:n]
                self.tally.add_mass_scaling(mass - mass_before, v_half)
        self.tally.set_kinetic(mass, v_half)
        # before the contact search meets non-finite positions
        if not np.isfinite(self.energies.kinetic):
            raise FloatingPointError(
                f"explicit integration diverged at step {self.step} "
                f"(t={self.t:.4g} s, dt={dt:.3g} s): "
                "non-finite velocities; use more increments (smaller target_dt) or a smaller "
                "deformation_margin"
            )
        self._forces()  # f_int(u_{n+1}), f_bv(u_{n+1}, v_{n+1/2})
        self.energies.elastic = self.problem.stored_energy()

    # -- checkpoints --------------------------------------------------------------------------
    _SCALARS = ("t", "step", "dt", "mass_scaling_max", "total_mass", "contact_added_mass")

    def state_dict(self) -> dict[str, np.ndarray]:
        """This rank's complete integrator state after a step (for checkpoints): time, step,
        increment, reduced position and velocity, the previous step's displacement, peculiar
        velocity and offsets, the forces at the current step, the (variable) mass scaling and
        the contact mass, the lumped masses, the energies; with the material and contact
        histories (prefixes ``material/`` and ``contact/``). Restoring it with :meth:`load_state`
        on the same model and partition continues the run bit for bit."""
        data = {name: np.array(getattr(self, name, 0.0)) for name in self._SCALARS}
        data.update(
            {
                "x": self.x.array_r.copy(),
                "v_red": self.v_red.array_r.copy(),
                "u": self.problem.u.x.array.copy(),
                "velocity": self.velocity.x.array.copy(),
                "u_prev": self._u_prev.copy(),
                "v_half_prev": self._v_half_prev.copy(),
                "g_prev": self._g_prev.copy(),
                "reaction": np.asarray(getattr(self, "_reaction_last", np.zeros(0))).copy(),
                "mass_scale": self.scaling.scale.copy(),
                "cell_length": self.scaling.cell_length.x.array.copy(),
                "mass": self.mass.x.array.copy(),
                "mass_red": self.mass_red.array_r.copy(),
                "H_prev": self.tally.H_prev.copy(),
                "image_force": np.zeros(0)
                if self._image_force is None
                else self._image_force.copy(),
                "contact_mass": np.zeros(0)
                if self._contact_mass is None
                else self._contact_mass.copy(),
                "energies": self.energies.to_array(),
            }
        )
        for name, vec in (
            ("f_int", self.f_int),
            ("f_visc", self.f_visc),
            ("f_cont", self.f_cont),
            ("f_damp", self.f_damp),
        ):
            with vec.localForm() as loc:
                data[name] = loc.array_r.copy()
        data.update(histories_state(self.problem, self.contact))
        return data

    def load_state(self, data: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict` (same model, same number of ranks and partition)."""
        check_layout(data, self.x, self.problem.u)
        self.t, self.step, self.dt = float(data["t"]), int(data["step"]), float(data["dt"])
        self.mass_scaling_max = float(data["mass_scaling_max"])
        self.total_mass = float(data["total_mass"])
        self.contact_added_mass = float(data["contact_added_mass"])
        self.x.array_w[:] = data["x"]
        self.v_red.array_w[:] = data["v_red"]
        self.bcs.apply(self.t)  # offsets g(t) (and periodic images) of the restored time
        self.problem.u.x.array[:] = data["u"]
        self.velocity.x.array[:] = data["velocity"]
        self._u_prev[:], self._v_half_prev[:], self._g_prev[:] = (
            data["u_prev"],
            data["v_half_prev"],
            data["g_prev"],
        )
        self._reaction_last = data["reaction"].copy()
        # mass scaling as it was (not rebuilt: the contact mass depends on the contact history)
        self.scaling.scale[:] = data["mass_scale"]
        self.scaling.apply()
        self.scaling.cell_length.x.array[:] = data["cell_length"]
        self._contact_mass = data["contact_mass"].copy() if data["contact_mass"].size else None
        self.mass.x.array[:] = data["mass"]
        self.mass_red.array_w[:] = data["mass_red"]
        if self.settings.constraint_mass == "consistent":
            self._build_consistent_mass()
        self.tally.H_prev = np.array(data["H_prev"]) if "H_prev" in data else np.zeros((3, 3))
        force = data.get("image_force", np.zeros(0))
        self._image_force = np.array(force).reshape(3, 3) if force.size else None
        self.energies.load_array(data["energies"])
        for name, vec in (
            ("f_int", self.f_int),
            ("f_visc", self.f_visc),
            ("f_cont", self.f_cont),
            ("f_damp", self.f_damp),
        ):
            with vec.localForm() as loc:
                loc.array_w[:] = data[name]
        load_histories(self.problem, self.contact, data)
        if self.contact is not None:
            # contact points of the restored state (the next mass re-check reads them); with the
            # committed history at this very state the evaluation is the committed one
            self.contact.evaluate(self.problem.u, tangent=False)

    def run(
        self,
        on_output: Callable[[ExplicitSolver], None] | None = None,
        outputs: int = 100,
        max_steps: int | None = None,
        every: int | None = None,
        on_step: Callable[[ExplicitSolver], None] | None = None,
    ) -> int:
        """Integrate to settings.t_end; ``on_output`` about ``outputs`` times (or every ``every``
        increments, counted from t = 0), and at the end; ``on_step`` after every increment (e.g. a
        stress servo). ``max_steps``: stop after so many increments of this call (benchmarks: the
        cost of a part of a run with the increment of the whole)."""
        total = int(np.ceil(self.settings.t_end / self.dt - 1e-9))
        every = every or max(1, total // max(outputs, 1))
        target = self.settings.target_dt
        # a path made of whole increments keeps the target increment itself (a run split into
        # stages, e.g. load -> checkpoint -> unload -> reload, then steps exactly as the whole)
        exact = (
            target is not None
            and abs(total * target - self.settings.t_end) <= 1e-9 * self.settings.t_end
        )
        self.dt = target if exact else self.settings.t_end / total
        stop = total if max_steps is None else min(total, self.step + max_steps)
        while self.step < stop:
            self.advance()
            if on_step is not None:
                on_step(self)
            if on_output and (self.step % every == 0 or self.step == total):
                with self.timings("output"):
                    on_output(self)
        return total

    def run_path(
        self,
        on_output: Callable[[ExplicitSolver], None] | None = None,
        *,
        outputs: int = 100,
        every: int | None = None,
        max_steps: int | None = None,
        on_step: Callable[[ExplicitSolver], None] | None = None,
        log=None,
    ) -> int:
        """The solver interface's run: :meth:`run` to settings.t_end (``log`` unused)."""
        return self.run(
            on_output, outputs=outputs, max_steps=max_steps, every=every, on_step=on_step
        )
