"""Verification workflows of the foundation: homogeneous uniaxial tension and a sphere squeezed
between two prescribed caps. Shared by ``demos/`` and ``tests/``.

Sign convention: the uniaxial *tension* test reports the true (Cauchy) stress as positive in
tension (it is a material curve, sigma_0 + K eps_p^n); the squeezed sphere reports the
compressive cap force as positive (thesis convention, compression > 0).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx

from ..io import History
from ..io.fields import CellFields, ParaViewWriter
from ..io.render import render_deformed
from ..loading import PrescribedDisplacements, component_dofs
from ..material import LEAD, ElastoPlastic
from ..meshes import ParticleVolumes, particle_mesh
from ..parameters import check_parameters, parameter
from ..problem import SolidProblem
from ..solvers import SOLVERS, StepControl, create_solver, loading_amplitude, solver_kind
from ..solvers.explicit import ExplicitSettings


def _log_mass_scaling(solver, log) -> None:
    """A dynamic solver's increment and mass scaling (a static one has none)."""
    if not solver_kind(solver.name).static:
        log(
            f"explicit: dt = {solver.dt:.3g} s (stable unscaled {solver.dt_stable_unscaled:.3g} s, "
            f"max mass scaling {solver.mass_scaling_max:.3g})"
        )


@dataclass(frozen=True)
class UniaxialCase:
    """Homogeneous uniaxial tension of a 1 mm cube (a verification case), checked on construction
    (ValueError naming the field)."""

    solver: str = parameter(
        "implicit",
        "implicit (Newton, adaptive steps) or explicit (central differences, mass scaling)",
        choices=SOLVERS,
    )
    log_strain: float = parameter(
        0.5, "final logarithmic strain along x (-)", low=0, high=2, open_low=True
    )
    cells: int = parameter(2, "hexahedra per edge of the 1 mm cube", low=1, high=32)
    material: ElastoPlastic = LEAD
    explicit_time: float = parameter(
        4e-3, "explicit: loading time, mass-scaled (s)", low=0, open_low=True
    )
    explicit_steps: int = parameter(8000, "explicit: increments over the loading", low=10)
    rows: int = parameter(400, "explicit: history rows", low=2, high=100000)

    def __post_init__(self):
        check_parameters(self)


@dataclass(frozen=True)
class SqueezeCase:
    """One cube-sphere particle squeezed between two prescribed caps, checked on construction
    (ValueError naming the field)."""

    solver: str = parameter(
        "implicit",
        "implicit (Newton, adaptive steps) or explicit (central differences, mass scaling)",
        choices=SOLVERS,
    )
    reduction: float = parameter(
        0.3, "height reduction of the particle (-)", low=0, high=0.6, open_low=True, open_high=True
    )
    radius: float = parameter(1.0, "particle radius (mm)", low=0, open_low=True)
    cap: float = parameter(
        0.75,
        "nodes with |z| >= cap x radius are the prescribed caps (-)",
        low=0.3,
        high=1,
        open_low=True,
        open_high=True,
    )
    refinement: int = parameter(1, "cube-sphere refinement (1 = 561 nodes)", low=1, high=4)
    material: ElastoPlastic = LEAD
    explicit_time: float = parameter(
        2e-3, "explicit: loading time, mass-scaled (s)", low=0, open_low=True
    )
    explicit_steps: int = parameter(6000, "explicit: increments over the loading", low=10)
    rows: int = parameter(40, "history rows (explicit)", low=2, high=100000)
    #: the particle's cells: "hexahedron" (cube-sphere, SRI) or "tetrahedron" (gmsh, order
    #: ``tet_order``, size ``tet_size`` mm)
    cell_type: str = parameter(
        "hexahedron",
        "particle cells: hexahedron (cube-sphere) or tetrahedron (gmsh)",
        choices=("hexahedron", "tetrahedron"),
    )
    tet_order: int = parameter(2, "tetrahedra: polynomial order", low=1, high=2)
    tet_size: float = parameter(0.3, "tetrahedra: element size (mm)", low=0, open_low=True)
    full_integration: bool = False  # hexahedra without the reduced volumetric rule (they lock)
    visual: bool = False  # ParaView series and a PNG of the deformed particle

    def __post_init__(self):
        check_parameters(self)


def _mean_over_points(problem: SolidProblem, values: np.ndarray) -> float:
    """Volume average of a quadrature-point field over all ranks."""
    return problem.integrate_points(values) / problem.integrate_points(np.ones_like(values))


@dataclass
class UniaxialResult:
    """The uniaxial test's curve: log strain, true stress (MPa, tension > 0), plastic strain."""

    log_strain: np.ndarray
    true_stress: np.ndarray  # MPa, tension > 0
    eps_p: np.ndarray
    energies: History | None
    wall_time: float
    csv: Path
    plastic_work: float = 0.0  # mJ, the solver's tally of the plastic dissipation


def run_uniaxial(
    case: UniaxialCase = UniaxialCase(),
    out_dir: str | Path = "results/uniaxial",
    comm: MPI.Comm = MPI.COMM_WORLD,
    log=print,
) -> UniaxialResult:
    """Stretch a unit cube (1 mm, ``cells``^3 hexahedra) homogeneously to ``log_strain`` (``case``).

    Symmetry rollers on x=0, y=0, z=0; u_x prescribed on x=1. Implicit: ramp in pseudo-time with
    adaptive steps. Explicit: smooth-step amplitude over ``explicit_time`` s with mass scaling to
    ``explicit_time / explicit_steps``. Writes ``stress_strain.csv`` (log_strain, true_stress_MPa,
    eps_p) and, for the explicit solver, ``energy.csv``.
    """
    solver, material, log_strain, cells = case.solver, case.material, case.log_strain, case.cells
    explicit_time, explicit_steps, rows = case.explicit_time, case.explicit_steps, case.rows
    out_dir = Path(out_dir)
    length = 1.0
    mesh = dolfinx.mesh.create_box(
        comm, [[0, 0, 0], [length] * 3], [cells] * 3, dolfinx.mesh.CellType.hexahedron
    )
    kind = solver_kind(solver)
    problem = SolidProblem(mesh, material, tangent=kind.tangent)
    V = problem.V
    stretch = np.exp(log_strain)
    amplitude = loading_amplitude(solver, explicit_time)
    bcs = PrescribedDisplacements(V)
    for axis in range(3):
        bcs.add(component_dofs(V, lambda x, a=axis: np.isclose(x[a], 0.0), axis))
    loaded = component_dofs(V, lambda x: np.isclose(x[0], length), 0)
    bcs.add(loaded, lambda t: (stretch - 1.0) * length * amplitude(t))

    history = History(
        out_dir / "stress_strain.csv", ["log_strain", "true_stress_MPa", "eps_p"], comm
    )
    energy = None

    def record(s):
        F = problem.deformation_gradients()
        lateral = _mean_over_points(problem, F[:, 1, 1]) * _mean_over_points(problem, F[:, 2, 2])
        force = s.reactions(loaded)
        u_end = (stretch - 1.0) * length * amplitude(s.t)
        history.append(
            log_strain=np.log1p(u_end / length),
            true_stress_MPa=force / (lateral * length**2),
            eps_p=_mean_over_points(problem, problem.material.eps_p),
        )

    if not kind.static:  # a dynamic run's energy balance
        energy = History(
            out_dir / "energy.csv",
            ["time", "W_ext", "E_int", "E_p", "E_el", "E_kin", "E_visc"],
            comm,
        )

    def on_output(s):
        record(s)
        if energy is not None:
            e = s.energy_record()
            energy.append(
                time=s.t,
                W_ext=e["W_ext"],
                E_int=e["E_int"],
                E_p=e["E_p"],
                E_el=e["E_el"],
                E_kin=e["E_c"],
                E_visc=e["E_visc"],
            )

    start = time.perf_counter()
    s = create_solver(
        solver,
        problem,
        bcs,
        controls=[StepControl(t_end=1.0, dt=0.01, dt_max=0.02)],
        settings=ExplicitSettings(t_end=explicit_time, target_dt=explicit_time / explicit_steps),
    )
    _log_mass_scaling(s, log)
    s.run_path(on_output, outputs=rows)
    if energy is not None:
        energy.write()
    wall = time.perf_counter() - start
    csv = history.write()
    data = history.array()
    plastic_work = s.energy_record()["E_p"]
    return UniaxialResult(data[:, 0], data[:, 1], data[:, 2], energy, wall, csv, plastic_work)


@dataclass
class SqueezeResult:
    """The sphere squeeze's history, initial volume (mm^3) and wall time (s)."""

    history: History
    initial_volume: float
    wall_time: float
    num_dofs: int


def run_sphere_squeeze(
    case: SqueezeCase = SqueezeCase(),
    out_dir: str | Path = "results/sphere_squeeze",
    comm: MPI.Comm = MPI.COMM_WORLD,
    log=print,
) -> SqueezeResult:
    """Squeeze one cube-sphere particle between two prescribed caps to a height reduction.

    The caps are the nodes with |z| >= cap * radius: their u_z is prescribed (-/+ reduction *
    radius at the end, i.e. the height 2r shrinks by ``reduction``), u_x and u_y stay free; one
    node row is held in x and y to remove the rigid motions. History columns: time,
    height_reduction, force_N (compressive cap force > 0), volume_mm3, volume_change.
    ``full_integration``: hexahedra without the reduced volumetric rule (they lock). With
    ``visual``: ParaView series ``<solver>.xdmf`` (displacement, von Mises, eps_p) and a
    PNG of the final deformed particle coloured by von Mises stress.
    """
    solver, material, reduction, radius, cap = (
        case.solver,
        case.material,
        case.reduction,
        case.radius,
        case.cap,
    )
    explicit_time, explicit_steps, rows, visual = (
        case.explicit_time,
        case.explicit_steps,
        case.rows,
        case.visual,
    )
    out_dir = Path(out_dir)
    assembly = particle_mesh(
        [[0.0, 0.0, 0.0]],
        [radius],
        comm,
        refinement=case.refinement,
        cell_type=case.cell_type,
        tet_order=case.tet_order,
        tet_size=case.tet_size,
    )
    problem = SolidProblem(
        assembly.mesh,
        material,
        tangent=solver_kind(solver).tangent,
        full_integration=case.full_integration,
    )
    V = problem.V
    amplitude = loading_amplitude(solver, explicit_time)
    travel = reduction * radius  # each cap moves by half of the total height change 2 r reduction
    tol = 1e-9 * radius
    top = component_dofs(V, lambda x: x[2] >= cap * radius - tol, 2)
    bottom = component_dofs(V, lambda x: x[2] <= -cap * radius + tol, 2)
    bcs = PrescribedDisplacements(V)
    bcs.add(top, lambda t: -travel * amplitude(t))
    bcs.add(bottom, lambda t: travel * amplitude(t))
    # rigid-body modes in the plane: fix x on the y-z plane nodes of the caps, y on x-z ones
    on_x0 = lambda x: (np.abs(x[0]) < tol) & (np.abs(x[2]) >= cap * radius - tol)  # noqa: E731
    on_y0 = lambda x: (np.abs(x[1]) < tol) & (np.abs(x[2]) >= cap * radius - tol)  # noqa: E731
    bcs.add(component_dofs(V, on_x0, 0), 0.0)
    bcs.add(component_dofs(V, on_y0, 1), 0.0)

    v0 = float(ParticleVolumes(assembly)()[0])
    current_volume = ParticleVolumes(assembly, problem.u)
    history = History(
        out_dir / f"{solver}.csv",
        ["time", "height_reduction", "force_N", "volume_mm3", "volume_change"],
        comm,
    )

    writer = None
    if visual:
        fields = CellFields(problem, assembly.cell_tags)
        writer = ParaViewWriter(out_dir / f"{solver}.xdmf", problem, fields)

    def record(s):
        if writer is not None:
            writer.write(s.t)
        vol = float(current_volume()[0])
        history.append(
            time=s.t,
            height_reduction=2 * travel * amplitude(s.t) / (2 * radius),
            force_N=-s.reactions(top),
            volume_mm3=vol,
            volume_change=vol / v0 - 1.0,
        )

    start = time.perf_counter()
    s = create_solver(
        solver,
        problem,
        bcs,
        controls=[StepControl(t_end=1.0, dt=0.01, dt_max=0.025, dt_min=1e-5)],
        settings=ExplicitSettings(t_end=explicit_time, target_dt=explicit_time / explicit_steps),
    )
    _log_mass_scaling(s, log)
    s.run_path(record, outputs=rows, log=log)
    wall = time.perf_counter() - start
    history.write()
    if writer is not None:
        writer.close()
        render_deformed(
            problem.u,
            fields.von_mises,
            out_dir / f"{solver}.png",
            title=f"lead particle, {100 * reduction:.0f} % height reduction ({solver})",
        )
    return SqueezeResult(history, v0, wall, V.dofmap.index_map.size_global * 3)
