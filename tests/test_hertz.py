"""Hertz contact of two identical elastic spheres, frictionless (implicit).

CI size: contact element size 0.01 r (the demo uses 0.005 r and stays within 3 %). The smallest
approach, delta/r = 5e-4, has a contact radius of 1.6 elements; from delta/r = 1e-3 on the
contact patch spans >= 2 elements and the force is within 5 % of Hertz."""

from types import SimpleNamespace

import numpy as np
import pytest
from mpi4py import MPI

from mpfem_fenicsx.workflows.hertz import HertzCase, plane_contact_radius, run_hertz


@pytest.fixture(scope="module")
def hertz(tmp_path_factory):
    case = HertzCase(size_min=0.01, steps=10)
    return case, run_hertz(
        case, tmp_path_factory.mktemp("hertz"), MPI.COMM_SELF, log=lambda *a: None
    )


def test_force_follows_hertz(hertz):
    case, res = hertz
    h = res.history
    delta, force, ref = h.column("delta_mm"), h.column("force_N"), h.column("force_hertz_N")
    assert delta[-1] == pytest.approx(case.delta_max_over_r * case.radius)
    assert np.allclose(ref, case.hertz_force(delta))
    resolved = delta >= 1e-3 * case.radius
    assert np.abs(force[resolved] / ref[resolved] - 1.0).max() < 0.05
    assert np.abs(force / ref - 1.0).max() < 0.08
    # F ~ delta^(3/2): log-log slope
    slope = np.polyfit(np.log(delta[resolved]), np.log(force[resolved]), 1)[0]
    assert slope == pytest.approx(1.5, abs=0.05)


def test_newton_converges_fast(hertz):
    _, res = hertz
    # consistent node-to-surface tangent: a handful of iterations per load step
    assert max(res.newton_iterations) <= 8


@pytest.fixture(scope="module")
def on_plane(tmp_path_factory):
    """The upper sphere of the same mesh pressed on a rigid frictionless plane by half the
    approach: the plane is the two spheres' symmetry plane."""
    case = HertzCase(size_min=0.01, steps=10, partner="plane", delta_max_over_r=0.0025)
    return case, run_hertz(
        case, tmp_path_factory.mktemp("hertz_plane"), MPI.COMM_SELF, log=lambda *a: None
    )


def test_sphere_on_a_rigid_plane_carries_the_two_spheres_force_at_half_the_approach(
    hertz, on_plane
):
    _, pair = hertz
    case, plane = on_plane
    h = plane.history
    delta, force, ref = h.column("delta_mm"), h.column("force_N"), h.column("force_hertz_N")
    assert np.allclose(2.0 * delta, pair.history.column("delta_mm"))
    # two realizations of one problem: within 2 % at every load step where the contact spans
    # two elements (measured: 0.2 %; 2.7 % at the first step, a contact radius of 1.6 elements)
    resolved = delta >= 5e-4 * case.radius
    assert np.abs(force / pair.history.column("force_N") - 1.0)[resolved].max() < 0.02
    # and Hertz's sphere on a plane, R = r, E* = E / (1 - nu^2)
    assert np.allclose(
        ref, 4.0 / 3.0 * case.E / (1 - case.nu**2) * np.sqrt(case.radius) * delta**1.5
    )
    assert np.abs(force[resolved] / ref[resolved] - 1.0).max() < 0.05
    assert max(plane.newton_iterations) <= 6  # the tool's tangent keeps Newton quadratic


def test_lead_sphere_on_a_rigid_plane_carries_the_two_lead_spheres_force(tmp_path):
    """The same two realizations with the thesis' lead (yield, power-law hardening): plastic
    flattening instead of Hertz. CI mesh (contact elements 0.01 r): within 2.5 % where the
    contact spans two elements (measured 0.0-2.0 %); at 0.005 r the plane is 1.0-2.0 % below
    the pair from delta / r = 0.001 on (bench/README.md, "Rigid tools")."""
    quiet = lambda *a: None  # noqa: E731
    pair = run_hertz(
        HertzCase(size_min=0.01, steps=10, material="lead", delta_max_over_r=0.01),
        tmp_path / "pair",
        MPI.COMM_SELF,
        log=quiet,
    ).history
    plane = run_hertz(
        HertzCase(size_min=0.01, steps=10, material="lead", partner="plane"),
        tmp_path / "plane",
        MPI.COMM_SELF,
        log=quiet,
    ).history
    delta = plane.column("delta_mm")
    assert np.allclose(2.0 * delta, pair.column("delta_mm"))
    ratio = plane.column("force_N") / pair.column("force_N")
    resolved = delta >= 1e-3
    assert np.abs(ratio[resolved] - 1.0).max() < 0.025
    # plastic: far below the elastic Hertz force of the same approach
    assert plane.column("force_N")[-1] < 0.5 * plane.column("force_hertz_N")[-1]


def test_contact_radius_of_a_hertz_pressure_from_its_second_moment():
    """Nodal forces of p0 sqrt(1 - rho^2 / a^2) on a fine grid (an off-axis centre excluded):
    the moment measure returns a."""
    a, h = 0.07, 0.0005
    g = np.arange(-0.1, 0.1, h) + 0.3 * h
    x, y = (c.ravel() for c in np.meshgrid(g, g))
    rho2 = x**2 + y**2
    T1 = 1000.0 * np.sqrt(np.clip(1.0 - rho2 / a**2, 0.0, None))
    loaded = T1 > 0
    evaluation = SimpleNamespace(
        area=np.full(loaded.sum(), h * h),
        T1=T1[loaded],
        reference=np.c_[x[loaded], y[loaded], np.zeros(loaded.sum())],
    )
    assert plane_contact_radius(evaluation, MPI.COMM_SELF) == pytest.approx(a, rel=2e-3)


def test_force_on_the_plane_at_its_contact_radius_approaches_hertz(on_plane):
    """Hertz's force at the contact radius (F = 4 E* a^3 / 3 R, local to the contact) and at the
    approach of the centre core (which also holds the finite sphere's compliance, of order a / r).
    CI mesh (contact elements 0.01 r): the radius within 3.5 % of Hertz's at the force (measured
    -3.1 % .. -1.7 % past delta / r = 0.001; within 1 % on 0.005 r elements, the heavy test
    below)."""
    case, plane = on_plane
    h = plane.history
    force, a = h.column("force_N"), h.column("contact_radius_mm")
    e_star, R = case.hertz_moduli()
    a_hertz = (3.0 * force * R / (4.0 * e_star)) ** (1.0 / 3.0)
    resolved = h.column("delta_mm") >= 1e-3 * case.radius
    assert np.all(a[resolved] < a_hertz[resolved])  # the loaded nodes end inside the edge
    assert np.abs(a[resolved] / a_hertz[resolved] - 1.0).max() < 0.035
    assert np.allclose(h.column("force_hertz_radius_N"), case.hertz_force_at_radius(a))


@pytest.mark.heavy
def test_sphere_on_a_plane_within_3_percent_of_hertz_on_a_contact_refined_mesh(tmp_path):
    """Contact elements 0.005 r in a zone of 0.1 r (49 k dofs, CG + GAMG, ~3 min): Hertz's force
    at the contact radius within 3 % wherever the contact radius spans 8 elements or more
    (delta / r >= 0.002; measured +2.1 / +1.5 / +1.2 / +1.2 %), while against the approach of
    the driving core the force is 4-8 % below Hertz (the finite sphere's compliance and its
    finite strains)."""
    case = HertzCase(size_min=0.005, refine_radius=0.1, steps=5, partner="plane")
    gamg = {"ksp_type": "cg", "pc_type": "gamg", "ksp_rtol": 1e-10, "pc_gamg_threshold": 0.01}
    h = run_hertz(case, tmp_path, MPI.COMM_SELF, petsc_options=gamg, log=lambda *a: None).history
    resolved = h.column("delta_mm") >= 2e-3 * case.radius
    at_radius = h.column("force_N") / h.column("force_hertz_radius_N") - 1.0
    assert np.abs(at_radius[resolved]).max() < 0.03
    at_approach = h.column("force_N") / h.column("force_hertz_N") - 1.0
    assert np.all((-0.09 < at_approach[resolved]) & (at_approach[resolved] < -0.03))
