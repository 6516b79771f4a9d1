"""Solver mechanics: cut-backs, stable increment and mass scaling, constraint satisfaction."""

import numpy as np
import pytest
from mpi4py import MPI

import dolfinx

from mpfem_fenicsx.loading import PrescribedDisplacements, SmoothStep, component_dofs
from mpfem_fenicsx.material import LEAD
from mpfem_fenicsx.meshes import particle_mesh
from mpfem_fenicsx.problem import SolidProblem
from mpfem_fenicsx.solvers import ImplicitSolver, StepControl
from mpfem_fenicsx.solvers.explicit import ExplicitSettings, ExplicitSolver


def _squeeze_bcs(V, travel):
    cap = lambda x, s: s * x[2] >= 0.75 - 1e-9  # noqa: E731
    bcs = PrescribedDisplacements(V)
    top = component_dofs(V, lambda x: cap(x, 1), 2)
    bcs.add(top, lambda t: -travel * t).add(component_dofs(V, lambda x: cap(x, -1), 2), lambda t: travel * t)
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
    mesh = dolfinx.mesh.create_box(MPI.COMM_SELF, [[0, 0, 0], [length] * 3], [n] * 3,
                                   dolfinx.mesh.CellType.hexahedron)
    prob = SolidProblem(mesh, LEAD, tangent=False)
    bcs = PrescribedDisplacements(prob.V).add(component_dofs(prob.V, lambda x: np.isclose(x[0], 0), 0))
    xi = 0.06
    expected = 0.9 * (length / n) / LEAD.dilatational_wave_speed * (np.sqrt(1 + xi ** 2) - xi)
    free = ExplicitSolver(prob, bcs, ExplicitSettings(t_end=1e-5))
    assert free.dt == pytest.approx(expected, rel=1e-12)
    assert free.total_mass == pytest.approx(LEAD.density * length ** 3, rel=1e-12)
    target = 10 * expected
    scaled = ExplicitSolver(prob, bcs, ExplicitSettings(t_end=1e-5, target_dt=target, deformation_margin=1.0))
    assert scaled.dt == target
    assert scaled.mass_scaling_max == pytest.approx(100.0, rel=1e-10)
    assert scaled.total_mass == pytest.approx(100.0 * LEAD.density * length ** 3, rel=1e-10)


def test_explicit_is_stable_at_the_scaled_increment():
    """A free elastic block set in motion by a smooth step keeps bounded energy (no blow-up)."""
    mesh = dolfinx.mesh.create_box(MPI.COMM_SELF, [[0, 0, 0], [1, 1, 1]], [3] * 3,
                                   dolfinx.mesh.CellType.hexahedron)
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

