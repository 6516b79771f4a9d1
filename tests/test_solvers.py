"""Solver mechanics: cut-backs, stable increment and mass scaling, constraint satisfaction."""

import numpy as np
import pytest
from mpfem_fenicsx.meshes import particle_mesh
from mpi4py import MPI

import dolfinx

from mpfem_fenicsx.loading import PrescribedDisplacements, SmoothStep, component_dofs
from mpfem_fenicsx.material import LEAD
from mpfem_fenicsx.problem import HEX_VERTICES, SolidProblem
from mpfem_fenicsx.solvers import ImplicitSolver, StepControl
from mpfem_fenicsx.solvers.explicit import ExplicitSettings, ExplicitSolver


def _squeeze_bcs(V, travel):
    cap = lambda x, s: s * x[2] >= 0.75 - 1e-9  # noqa: E731
    bcs = PrescribedDisplacements(V)
    top = component_dofs(V, lambda x: cap(x, 1), 2)
    bcs.add(top, lambda t: -travel * t).add(
        component_dofs(V, lambda x: cap(x, -1), 2), lambda t: travel * t
    )
    bcs.add(component_dofs(V, lambda x: (np.abs(x[0]) < 1e-9) & (np.abs(x[2]) >= 0.75 - 1e-9), 0))
    bcs.add(component_dofs(V, lambda x: (np.abs(x[1]) < 1e-9) & (np.abs(x[2]) >= 0.75 - 1e-9), 1))
    return bcs, top


def test_cut_backs_recover_a_too_large_increment():
    a = particle_mesh([[0, 0, 0]], [1.0], MPI.COMM_SELF)
    forces = {}
    for dt in (1.0, 0.05):
        prob = SolidProblem(a.mesh, LEAD)
        bcs, top = _squeeze_bcs(prob.V, 0.3)
        solver = ImplicitSolver(prob, bcs)
        messages = []
        solver.run(StepControl(t_end=1.0, dt=dt, dt_max=dt), log=messages.append)
        forces[dt] = -solver.reactions(top)
        if dt == 1.0:
            assert any("cut-back" in m for m in messages)
        # prescribed values hold exactly after the solve
        u = prob.u.x.array
        assert np.abs(u[bcs.constraint.prescribed] - bcs.values(1.0)).max() < 1e-12
    assert forces[1.0] == pytest.approx(forces[0.05], rel=0.02)


def test_stable_increment_and_mass_scaling():
    n, length = 4, 1.0
    mesh = dolfinx.mesh.create_box(
        MPI.COMM_SELF, [[0, 0, 0], [length] * 3], [n] * 3, dolfinx.mesh.CellType.hexahedron
    )
    prob = SolidProblem(mesh, LEAD, tangent=False)
    bcs = PrescribedDisplacements(prob.V).add(
        component_dofs(prob.V, lambda x: np.isclose(x[0], 0), 0)
    )
    xi = 0.06
    expected = 0.9 * (length / n) / LEAD.dilatational_wave_speed * (np.sqrt(1 + xi**2) - xi)
    free = ExplicitSolver(prob, bcs, ExplicitSettings(t_end=1e-5))
    assert free.dt == pytest.approx(expected, rel=1e-12)
    assert free.total_mass == pytest.approx(LEAD.density * length**3, rel=1e-12)
    target = 10 * expected
    scaled = ExplicitSolver(
        prob, bcs, ExplicitSettings(t_end=1e-5, target_dt=target, deformation_margin=1.0)
    )
    assert scaled.dt == target
    assert scaled.mass_scaling_max == pytest.approx(100.0, rel=1e-10)
    assert scaled.total_mass == pytest.approx(100.0 * LEAD.density * length**3, rel=1e-10)


#: a cell of the isotropic CLPS run at 12 000 increments, folded at the edge of a copy's coupling
#: zone (two corners pushed inside; vertices in mm, lexicographic order; bench/README.md,
#: element_frequencies.py)
FOLDED_CELL = np.array(
    [
        [0.359428, -0.188714, 0.456085],
        [0.374347, -0.201915, 0.465375],
        [0.351191, -0.169286, 0.465198],
        [0.367394, -0.175300, 0.471781],
        [0.363333, -0.184883, 0.475242],
        [0.373256, -0.200636, 0.482225],
        [0.351715, -0.173551, 0.483331],
        [0.366501, -0.179018, 0.488062],
    ]
)


def test_stable_length_bounds_the_highest_frequency_of_a_folded_cell():
    """omega_e L / c_d, omega_e the exact highest frequency of the elastic Q1 cell with its lumped
    mass (bench/element_frequencies.py): 2 sqrt((1 + nu) / (1 - nu)) = 3.19 for a cube (for which
    L = h is exact on a regular grid, 2 c_d / h); the folded cell reached 8.7 with the vertex
    distances and volume / face area and rang at the central difference's limit; the Gauss-point
    bound keeps every valid cell at or below 8 / sqrt(3)."""
    import sys
    from pathlib import Path

    import basix.ufl
    import ufl

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
    from element_frequencies import elasticity_matrix, element_highest_omega2

    element = basix.ufl.element("Lagrange", "hexahedron", 1, shape=(3,))
    c_d = LEAD.dilatational_wave_speed
    cube = HEX_VERTICES.astype(float) * 0.02
    for vertices, reference in (
        (cube, 2 * np.sqrt((1 + LEAD.nu) / (1 - LEAD.nu))),
        (FOLDED_CELL, None),
    ):
        mesh = dolfinx.mesh.create_mesh(
            MPI.COMM_SELF, np.arange(8, dtype=np.int64)[None], ufl.Mesh(element), vertices
        )
        length = SolidProblem(mesh, LEAD, tangent=False).min_cell_length()[0]
        omega = np.sqrt(
            element_highest_omega2(
                vertices[None], elasticity_matrix(LEAD.E, LEAD.nu), np.array([LEAD.density])
            )
        )[0]
        if reference is not None:
            assert length == pytest.approx(0.02, rel=1e-12)
            assert omega * length / c_d == pytest.approx(reference, rel=1e-10)
        else:
            assert omega * length / c_d <= 8 / np.sqrt(3) * (1 + 1e-12)


#: a cell of copy 147 of the isotropic CLPS run (6000 increments, step 5700, after the fix above):
#: a cube of edge 0.014967597 mm in the coupling zone, squeezed at one Gauss point (J 0.018 there,
#: 1.0 at the centre, where the volumetric part is integrated); current vertices (mm, lexicographic)
SQUEEZED_CELL_ORIGIN, SQUEEZED_CELL_EDGE = (
    np.array([0.316803567, -0.294636775, 0.476693410]),
    0.014967597,
)
SQUEEZED_CELL = np.array(
    [
        [0.334255397, -0.202675520, 0.443779183],
        [0.352069187, -0.202742743, 0.441526467],
        [0.329254689, -0.181069036, 0.451798893],
        [0.348437279, -0.176796127, 0.450335157],
        [0.340961372, -0.185731255, 0.454463796],
        [0.359275421, -0.189388673, 0.457075197],
        [0.333241389, -0.174562824, 0.466584106],
        [0.350635388, -0.170897463, 0.467112491],
    ]
)


def test_deformed_stable_length_bounds_the_tangent_of_a_squeezed_cell():
    """The deformed cell's highest frequency with the run's element (volumetric part at the
    centre) and the Hencky tangent, whose moduli act per reference volume (bench/
    element_frequencies.py; on the run it reproduces the force increments of the model to 1 %): it
    reached omega_e L / c_d = 13.0 with the length weighted by the current Jacobians, and rang;
    with the reference ones it stays below 8 / sqrt(3)."""
    import sys
    from pathlib import Path

    import basix.ufl
    import ufl

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
    from element_frequencies import elasticity_matrix, element_highest_omega2

    reference = SQUEEZED_CELL_ORIGIN + HEX_VERTICES * SQUEEZED_CELL_EDGE
    element = basix.ufl.element("Lagrange", "hexahedron", 1, shape=(3,))
    mesh = dolfinx.mesh.create_mesh(
        MPI.COMM_SELF, np.arange(8, dtype=np.int64)[None], ufl.Mesh(element), reference
    )
    problem = SolidProblem(mesh, LEAD, tangent=False)
    dof_points = problem.V.tabulate_dof_coordinates()
    vertex = np.argmin(np.linalg.norm(dof_points[:, None] - reference[None], axis=-1), axis=1)
    problem.u.x.array[:] = (SQUEEZED_CELL - reference)[vertex].ravel()
    length = problem.min_cell_length(deformed=True)[0]
    omega = np.sqrt(
        element_highest_omega2(
            SQUEEZED_CELL[None],
            elasticity_matrix(LEAD.E, LEAD.nu),
            np.array([LEAD.density]),
            volumetric=LEAD.bulk,
            reference=reference[None],
        )
    )[0]
    assert omega * length / LEAD.dilatational_wave_speed <= 8 / np.sqrt(3)


def test_explicit_is_stable_at_the_scaled_increment():
    """A free elastic block set in motion by a smooth step keeps bounded energy (no blow-up)."""
    mesh = dolfinx.mesh.create_box(
        MPI.COMM_SELF, [[0, 0, 0], [1, 1, 1]], [3] * 3, dolfinx.mesh.CellType.hexahedron
    )
    prob = SolidProblem(mesh, LEAD, tangent=False)
    amp = SmoothStep(2e-4)
    bcs = PrescribedDisplacements(prob.V)
    bcs.add(component_dofs(prob.V, lambda x: np.isclose(x[0], 0), 0))
    bcs.add(component_dofs(prob.V, lambda x: np.isclose(x[0], 1), 0), lambda t: 1e-4 * amp(t))
    s = ExplicitSolver(prob, bcs, ExplicitSettings(t_end=4e-4, target_dt=2e-7))
    s.run()
    e = s.energies
    assert np.isfinite(e.kinetic) and e.external > 0
    assert e.balance_error() < 1e-6 * e.external


def test_energy_balance_counts_the_kinetic_energy_mass_scaling_adds():
    """Variable mass scaling raises the mass of squeezed elements while they move: the kinetic
    energy 1/2 w'^T dM w' it adds is tallied (E_mass), and W_ext + E_mass balances the rest to
    round-off. Measured: E_mass 0.43 % of W_ext, balance 4e-19 mJ (without the tally: 1.4e-5)."""
    a = particle_mesh([[0, 0, 0]], [1.0], MPI.COMM_SELF)
    prob = SolidProblem(a.mesh, LEAD, tangent=False)
    bcs, _ = _squeeze_bcs(prob.V, 0.4)
    s = ExplicitSolver(
        prob,
        bcs,
        ExplicitSettings(t_end=1e-3, target_dt=2e-5, deformation_margin=1.0, rescale_every=10),
    )
    s.run()
    e = s.energies
    assert e.mass_scaling > 1e-3 * e.external  # the squeeze raised masses of moving nodes
    assert e.balance_error() < 1e-9 * e.external
    assert s.energy_record()["E_mass"] == e.mass_scaling


def test_energy_balance_of_a_start_out_of_equilibrium_misses_the_start_up_term():
    """Released from a pre-strained state (f_0 != 0), the one-sided first step leaves the balance
    off by exactly 1/2 (dt/2 a_0)^T M (dt/2 a_0), whatever follows (solvers.explicit docstring);
    from an equilibrium start it is zero (the other balance tests)."""
    mesh = dolfinx.mesh.create_box(
        MPI.COMM_SELF, [[0, 0, 0], [1, 1, 1]], [3] * 3, dolfinx.mesh.CellType.hexahedron
    )
    prob = SolidProblem(mesh, LEAD, tangent=False)
    s = ExplicitSolver(
        prob, PrescribedDisplacements(prob.V), ExplicitSettings(t_end=1e-5, target_dt=2e-7)
    )
    s.x.array[:] = 1e-5 * np.random.default_rng(0).standard_normal(s.x.array.size)
    s.advance()
    start_up = 0.5 * np.sum(s.mass_red.array * (0.5 * s.dt * s.a_red.array) ** 2)
    for _ in range(40):
        s.advance()
    e = s.energies
    assert start_up > 0.1 * abs(e.internal)  # not negligible: a random pre-strain, high modes
    assert e.balance_error() == pytest.approx(start_up, rel=1e-9)


def test_bulk_viscosity_coefficients_are_checked_and_may_be_integers():
    """An integer coefficient (0) builds (a UFL constant of an int was refused with a bare
    "Unsupported dtype"); a negative one is refused by name."""
    settings = ExplicitSettings(t_end=1e-5, bulk_viscosity_linear=0, bulk_viscosity_quadratic=0)
    assert isinstance(settings.bulk_viscosity_linear, float)
    mesh = dolfinx.mesh.create_box(
        MPI.COMM_SELF, [[0, 0, 0], [1, 1, 1]], [2] * 3, dolfinx.mesh.CellType.hexahedron
    )
    prob = SolidProblem(mesh, LEAD, tangent=False)
    ExplicitSolver(prob, PrescribedDisplacements(prob.V), settings)
    with pytest.raises(ValueError, match="bulk_viscosity_quadratic must be >= 0"):
        ExplicitSettings(t_end=1e-5, bulk_viscosity_quadratic=-1.0)


def test_both_solvers_are_the_solver_interface():
    """Both solvers satisfy the Solver protocol (every member present, runtime check), the
    explicit one as a DynamicSolver, the implicit one as a StaticSolver; and every member of
    the protocols states its contract (a docstring or a ``#:`` comment)."""
    import inspect

    from mpfem_fenicsx.solvers import DynamicSolver, Solver, StaticSolver, create_solver, interface

    mesh = dolfinx.mesh.create_box(
        MPI.COMM_SELF, [[0, 0, 0], [1, 1, 1]], [1] * 3, dolfinx.mesh.CellType.hexahedron
    )
    prob = SolidProblem(mesh, LEAD, tangent=True)
    fixed = component_dofs(prob.V, lambda x: np.isclose(x[0], 0), 0)
    bcs = PrescribedDisplacements(prob.V).add(fixed)
    explicit = create_solver("explicit", prob, bcs, settings=ExplicitSettings(t_end=1e-5))
    implicit = create_solver("implicit", prob, bcs, controls=[StepControl()])
    assert isinstance(explicit, Solver) and isinstance(implicit, Solver)
    assert isinstance(explicit, DynamicSolver) and not isinstance(explicit, StaticSolver)
    assert isinstance(implicit, StaticSolver) and not isinstance(implicit, DynamicSolver)
    lines = inspect.getsource(interface).splitlines()
    for protocol in (Solver, DynamicSolver, StaticSolver):
        for name in protocol.__protocol_attrs__:
            member = getattr(protocol, name, None)
            if member is not None:  # a method or property: its docstring
                assert inspect.getdoc(member), f"{protocol.__name__}.{name} has no contract"
            else:  # an attribute: a "#:" comment right above its annotation
                line = next(i for i, text in enumerate(lines) if text.startswith(f"    {name}: "))
                documented = lines[line - 1].lstrip().startswith("#: ")
                assert documented, f"{protocol.__name__}.{name} has no contract"


def test_a_failed_line_search_is_retried_once_with_the_full_update():
    """An attempt whose backtracking line search fails (at a kink of the contact or adhesive
    law the Newton update need not decrease ||r||) is tried once more at the same increment
    with the full update, before any cut-back; the line search is then restored. (The first
    attempt is made to fail here; the retry is a real Newton solve of a stretched cube.)"""
    from mpfem_fenicsx.solvers import create_solver

    mesh = dolfinx.mesh.create_box(
        MPI.COMM_SELF, [[0, 0, 0], [1, 1, 1]], [1] * 3, dolfinx.mesh.CellType.hexahedron
    )
    prob = SolidProblem(mesh, LEAD, tangent=True)
    fixed = component_dofs(prob.V, lambda x: np.isclose(x[0], 0), 0)
    pulled = component_dofs(prob.V, lambda x: np.isclose(x[0], 1), 0)
    bcs = PrescribedDisplacements(prob.V).add(fixed).add(pulled, lambda t: 1e-4 * t)
    control = StepControl(t_end=1.0, dt=1.0, dt_max=1.0)
    solver = create_solver(
        "implicit", prob, bcs, controls=[control], petsc_options={"snes_linesearch_type": "bt"}
    )
    kinds, real = [], solver.solve_increment

    def attempt(t_new):
        kinds.append(solver.snes.getLineSearch().getType())
        return (False, 3) if len(kinds) == 1 else real(t_new)

    solver.solve_increment = attempt
    solver._line_search_failed = lambda: len(kinds) == 1
    solver.run(control)
    assert kinds == ["bt", "basic"]
    assert solver.full_step_retries == 1 and solver.cutbacks == 0 and solver.t == 1.0
    assert solver.snes.getLineSearch().getType() == "bt"
    assert prob.u.x.array[pulled].max() == pytest.approx(1e-4)


def test_a_cut_back_tells_the_failed_attempt_s_residuals():
    """A cut-back's log line gives the failed attempt's residuals, first / best / last (what
    tells a jump at the converged state, first far above the target however short the
    increment, from too long an increment): in N from rest, over the force target (the step
    control's ``force_rtol`` x the internal forces) once loaded."""
    import re

    a = particle_mesh([[0, 0, 0]], [1.0], MPI.COMM_SELF)
    prob = SolidProblem(a.mesh, LEAD)
    bcs, _ = _squeeze_bcs(prob.V, 0.3)
    messages = []
    ImplicitSolver(prob, bcs).run(
        StepControl(t_end=1.0, dt=1.0, dt_max=1.0, force_rtol=1e-8), log=messages.append
    )
    cut = [m for m in messages if "cut-back" in m]
    assert "residual (N): first" in cut[0]  # from rest: no internal forces to scale by
    assert any("residual / target: first" in m for m in cut[1:])
    first, best, last = (
        float(x) for x in re.search(r"first (\S+), best (\S+), last (\S+)\)", cut[0]).groups()
    )
    assert best <= min(first, last) and first > 0.0
