"""Hertz contact of two identical elastic spheres, or of a sphere on a rigid plane,
frictionless (a verification case).

Spheres of radius r centred at (0, 0, -r) and (0, 0, r), touching at the origin; P1 tetrahedra
from gmsh, refined around the contact point. Each sphere is driven by a small rigid core (the
nodes within ``core`` r of its centre) moving by -/+ delta/2 along z, so delta is the approach of
the centres. Reference: F = 4/3 E* sqrt(R) delta^(3/2), E* = E / (2 (1 - nu^2)), R = r / 2.

``partner="plane"``: the upper sphere alone pressed by its core onto the rigid plane z = 0 (a
:class:`~mpfem_fenicsx.tools.RigidTool`), delta the approach of its centre to the plane;
reference R = r, E* = E / (1 - nu^2). The plane is the symmetry plane of the two-sphere contact:
the sphere on the plane at delta / 2 carries the two spheres' force at delta, when the plane's
penalty is twice the particles' (the particle-particle spring spans both sides of the symmetry
plane, the tool's one side only). On the plane the history also holds the contact radius a
(from the second moment of the plane's nodal forces) and Hertz's force at it,
F = 4 E* a^3 / (3 R): a relation local to the contact, which the compliance of the finite sphere
between its core and the contact (of order a / r in the force at an approach) leaves alone.

``HertzCase(solver="explicit")`` runs the same case with central differences (mass scaling to
``explicit_increments`` increments, smooth-step approach): slow enough, it should reproduce the
implicit force-approach curve (checked by ``demos/hertz.py --solver explicit``,
too long for CI; measured in ``bench/README.md``, "Single contacts").
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..contact import ContactLaw, ContactModel
from ..contact.laws import default_penalty
from ..io import History
from ..loading import PrescribedDisplacements, component_dofs
from ..material import LEAD, ElastoPlastic
from ..meshes import particle_mesh
from ..parameters import check_parameters, parameter
from ..problem import SolidProblem
from ..solvers import SOLVERS, StepControl, create_solver, loading_amplitude, solver_kind
from ..solvers.explicit import ExplicitSettings
from ..tools import Plane, RigidTool


@dataclass(frozen=True)
class HertzCase:
    """The Hertz case: spheres, mesh, contact penalty and approach (MPa, mm)."""

    E: float = parameter(200000.0, "Young's modulus of both spheres (MPa)", low=0, open_low=True)
    nu: float = parameter(0.3, "Poisson's ratio (-)", low=0, high=0.5, open_high=True)
    radius: float = parameter(1.0, "sphere radius r (mm)", low=0, open_low=True)
    delta_max_over_r: float = parameter(
        0.005, "final approach of the centres / r (-)", low=0, high=0.05, open_low=True
    )
    steps: int = parameter(10, "implicit load steps", low=1)
    size_min: float = parameter(
        0.005, "element size at the contact / r (-; <= size)", low=0, open_low=True
    )
    #: size_min within this distance of the contact point (relative)
    refine_radius: float = parameter(
        0.06, "refined zone around the contact point / r (-)", low=0, open_low=True
    )
    size: float = parameter(
        0.3, "element size away from the contact / r (-)", low=0, high=1, open_low=True
    )
    core: float = parameter(
        0.1, "rigid driving core radius / r (-)", low=0, high=0.5, open_low=True
    )
    #: k = factor * E / (size_min r), see contact.laws.default_penalty
    penalty_factor: float = parameter(
        10.0, "penalty k = factor x E / h, h the contact element size (-)", low=0, open_low=True
    )
    solver: str = parameter(
        "implicit",
        "implicit (Newton, the reference curve) or explicit (central differences, "
        "smooth-step approach)",
        choices=SOLVERS,
    )
    explicit_increments: int = parameter(
        8000, "explicit: mass-scaled increments of the approach (slow loading)", low=100
    )
    explicit_time: float = parameter(
        1e-3, "explicit: time of the approach, mass-scaled (s)", low=0, open_low=True
    )
    rows: int = parameter(40, "explicit: history rows", low=2, high=100000)
    material: str = parameter(
        "elastic",
        "elastic (E, nu) or the thesis' lead (table 2.1: yield and power-law hardening; the "
        "Hertz column is then its elastic reference)",
        choices=("elastic", "lead"),
    )
    partner: str = parameter(
        "sphere",
        "what the sphere is pressed against: an identical sphere, or a rigid plane",
        choices=("sphere", "plane"),
    )

    def __post_init__(self):
        check_parameters(self, prefix="HertzCase.")
        if self.size_min > self.size:
            raise ValueError(
                f"HertzCase.size_min = {self.size_min} must be <= size = {self.size} (relative to "
                "r)"
            )

    def hertz_moduli(self) -> tuple[float, float]:
        """Hertz's effective modulus E* (MPa) and radius R (mm) of this contact."""
        plane = self.partner == "plane"
        E, nu = (LEAD.E, LEAD.nu) if self.material == "lead" else (self.E, self.nu)
        e_star = E / ((1.0 if plane else 2.0) * (1.0 - nu**2))
        return e_star, self.radius if plane else self.radius / 2.0

    def hertz_force(self, delta):
        """Hertz force (N) at the centre approach ``delta`` (mm): F = 4/3 E* sqrt(R) delta^3/2."""
        e_star, R = self.hertz_moduli()
        return 4.0 / 3.0 * e_star * np.sqrt(R) * np.asarray(delta) ** 1.5

    def hertz_force_at_radius(self, a):
        """Hertz force (N) at the contact radius ``a`` (mm): F = 4 E* a^3 / (3 R).

        Unlike the force at an approach, this relation is local to the contact: the compliance
        of a finite sphere between its driving core and the contact (of order a / r against
        the half-space's approach) shifts the approach, not the contact's size and pressure."""
        e_star, R = self.hertz_moduli()
        return 4.0 * e_star * np.asarray(a) ** 3 / (3.0 * R)


def plane_contact_radius(evaluation, comm: MPI.Comm) -> float:
    """The contact radius (mm) on the plane z = 0 from the second moment of its normal forces
    about the z axis: Hertz's pressure p0 sqrt(1 - rho^2 / a^2) has <rho^2> = 2 a^2 / 5.

    A moment of the nodal forces, not the outermost loaded node: it varies smoothly with the
    load instead of jumping by an element size. Over the points' reference positions: Hertz's
    linear theory poses its contact conditions on the undeformed surface, whose points in
    contact move towards the axis (by 0.9 % of a at delta / r = 0.005, nu = 0.3)."""
    f = evaluation.area * evaluation.T1  # normal force of every point (N, compression > 0)
    rho2 = evaluation.reference[:, 0] ** 2 + evaluation.reference[:, 1] ** 2
    total, moment = comm.allreduce(np.array([f.sum(), (f * rho2).sum()]), op=MPI.SUM)
    return float(np.sqrt(2.5 * moment / total)) if total > 0 else 0.0


@dataclass
class HertzResult:
    """The Hertz run's force-approach history, its number of dofs and wall time (s)."""

    history: History
    num_dofs: int
    wall_time: float
    newton_iterations: list


def run_hertz(
    case: HertzCase = HertzCase(),
    out_dir: str | Path = "results/hertz",
    comm: MPI.Comm = MPI.COMM_WORLD,
    petsc_options: dict | None = None,
    log=print,
) -> HertzResult:
    """Run the Hertz case; the force-approach history is written to ``out_dir``."""
    solver, explicit_increments, explicit_time = (
        case.solver,
        case.explicit_increments,
        case.explicit_time,
    )
    kind = solver_kind(solver)
    r = case.radius
    plane = case.partner == "plane"
    signs = (1.0,) if plane else (-1.0, 1.0)
    with warnings.catch_warnings():  # P1 tetrahedra: fine for this elastic, compressible case
        warnings.simplefilter("ignore")
        assembly = particle_mesh(
            [[0, 0, sign * r] for sign in signs],
            [r] * len(signs),
            comm,
            cell_type="tetrahedron",
            tet_order=1,
            tet_size=case.size,
            tet_refine=[
                ((0.0, 0.0, 0.0), case.size_min * r, case.refine_radius * r, 0.8 * r),
                # enough nodes in the driving cores to hold them rigidly
                *[
                    ((0.0, 0.0, sign * r), 0.3 * case.core * r, case.core * r, 0.5 * r)
                    for sign in signs
                ],
            ],
        )
        material = (
            LEAD
            if case.material == "lead"
            else ElastoPlastic(E=case.E, nu=case.nu, sigma_0=1e12, hardening="linear", K=0.0, H=0.0)
        )
        problem = SolidProblem(assembly.mesh, material, tangent=kind.tangent)
    V = problem.V
    penalty = default_penalty(material.E, case.size_min * r, case.penalty_factor)
    law = ContactLaw(penalty=penalty, friction=0.0, gamma=0.0)
    # the plane: the symmetry plane of the two spheres' contact, hence twice their penalty
    tools = [RigidTool("plane", Plane(), ContactLaw(penalty=2.0 * penalty, friction=0.0))]
    contact = ContactModel(
        V, assembly.facet_tags, len(signs), law, 0.05 * r, tools=tools if plane else None
    )
    delta_end = case.delta_max_over_r * r

    def core(sign):
        return lambda x: (x[0] ** 2 + x[1] ** 2 + (x[2] - sign * r) ** 2) <= (case.core * r) ** 2

    bcs = PrescribedDisplacements(V)
    for sign in signs:
        for c in (0, 1):
            bcs.add(component_dofs(V, core(sign), c))
    upper = component_dofs(V, core(1.0), 2)
    amplitude = loading_amplitude(solver, explicit_time)
    # each sphere's core moves by its share of the approach (all of it against the plane)
    share = 1.0 if plane else 0.5
    if not plane:
        bcs.add(component_dofs(V, core(-1.0), 2), lambda t: share * delta_end * amplitude(t))
    bcs.add(upper, lambda t: -share * delta_end * amplitude(t))
    name = ("force.csv" if kind.static else f"force_{solver}.csv").replace(
        "force", "force_plane" if plane else "force"
    )
    columns = ["delta_mm", "force_N", "force_hertz_N"]
    if plane:  # the contact radius measured on the plane and Hertz's force at that radius
        columns += ["contact_radius_mm", "force_hertz_radius_N"]
    history = History(Path(out_dir) / name, columns, comm)
    iterations = []

    def points() -> int:
        """Compressed contact points, on the other sphere or on the plane."""
        on_tools = 0 if contact.tools is None else contact.tools.tool_forces()["points"].sum()
        return contact.count(True) + int(on_tools)

    def record(s):
        delta = delta_end * amplitude(s.t)
        force = -s.reactions(upper)  # the upper core pushes down: compressive force > 0
        row = dict(delta_mm=delta, force_N=force, force_hertz_N=float(case.hertz_force(delta)))
        if plane:
            a = plane_contact_radius(contact.tools.evaluation, comm)
            row.update(
                contact_radius_mm=a, force_hertz_radius_N=float(case.hertz_force_at_radius(a))
            )
        history.append(**row)
        iterations.append(s.snes.getIterationNumber() if kind.static else 0)  # Newton's
        at_radius = (
            f", at the contact radius {100 * (force / row['force_hertz_radius_N'] - 1):+.2f} %"
            if plane
            else ""
        )
        log(
            f"  delta/r = {delta / r:.5f}: F = {force:.4f} N, Hertz {case.hertz_force(delta):.4f} "
            f"N ({100 * (force / case.hertz_force(delta) - 1):+.2f} %{at_radius}), {points()} "
            f"contact points, {iterations[-1]} Newton iterations"
        )

    log(f"Hertz: {V.dofmap.index_map.size_global * 3} dofs, penalty {penalty:.3g} N/mm^3")
    start = time.perf_counter()
    dt = 1.0 / case.steps
    s = create_solver(
        solver,
        problem,
        bcs,
        contact=contact,
        petsc_options=petsc_options,
        controls=[StepControl(t_end=1.0, dt=dt, dt_max=dt, dt_min=dt / 64)],
        settings=ExplicitSettings(
            t_end=explicit_time, target_dt=explicit_time / explicit_increments
        ),
    )
    if not kind.static:
        log(
            f"  explicit: dt = {s.dt:.3g} s (unscaled {s.dt_stable_unscaled:.3g} s), "
            f"{explicit_increments} "
            "increments"
        )
    s.run_path(record, outputs=case.rows, log=log)
    history.write()
    return HertzResult(
        history, V.dofmap.index_map.size_global * 3, time.perf_counter() - start, iterations
    )
