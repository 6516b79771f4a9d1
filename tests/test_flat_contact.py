"""Thesis §3.4.1: the adhesive and frictional contact law on a flat contact."""

import sys
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from mpfem_fenicsx.workflows.flat_contact import FlatContactCase, run_flat_contact, run_normal

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "demos"))
from flat_contact import summarize  # noqa: E402


@pytest.fixture(scope="module")
def checks(tmp_path_factory):
    case = FlatContactCase()
    out = tmp_path_factory.mktemp("flat")
    return case, summarize(case, *run_flat_contact(case, out, MPI.COMM_SELF))


def test_degree_of_contact(checks):
    case, c = checks
    assert c["T1_max_MPa"] == pytest.approx(3 * case.sigma_y, rel=1e-3)
    assert c["alpha_at_T1_max"] == pytest.approx(0.5, rel=1e-3)


def test_adhesive_opening(checks):
    case, c = checks
    assert c["sigma_c_MPa"] == pytest.approx(case.sigma_y / 2)
    assert c["peak_tension_from_softening_line_MPa"] == pytest.approx(
        0.5 * c["sigma_c_MPa"], rel=0.02
    )
    assert c["peak_tension_MPa"] == pytest.approx(0.5 * c["sigma_c_MPa"], rel=0.02)
    assert c["zero_crossing_of_softening_mm"] == pytest.approx(case.delta_max, rel=0.02)
    assert c["max_abs_T1_beyond_delta_max"] == 0.0
    assert c["alpha_beyond_delta_max"] == 0.0  # memory erased


def test_implicit_newton_through_an_adhesive_snap(tmp_path):
    """A tall block (h = 2 mm) is softer than the adhesive softening: E' / h < peak / (delta_max -
    delta_1), so no static state exists on the softening branch and the contact must snap from
    the peak tension straight to separation. Newton converges through it (the erased memory stays
    erased within the increment; a point cycling back from softening gets a zero-slope tangent);
    before, it cycled adhered <-> separated until dt_min (NonConvergence at the peak)."""
    case = FlatContactCase(height=2.0)
    law = case.law()
    M = case.E * (1 - case.nu) / ((1 + case.nu) * (1 - 2 * case.nu))
    peak = 0.5 * law.sigma_c  # alpha = 0.5
    d1 = peak / law.penalty
    assert M / case.height < peak / (case.delta_max - d1)  # the premise: unstable softening
    rows = run_normal(case, tmp_path, MPI.COMM_SELF).array()
    delta, T1 = rows[:, 0], rows[:, 1]
    assert -T1.min() == pytest.approx(peak, rel=2e-3)  # snap at the peak tension
    # no converged state on the (unstable) softening branch: every tensile state is on the
    # adhesive loading line T1 = -k delta, and the next one after the peak is separated
    tension = T1 < 0
    assert np.allclose(T1[tension], -law.penalty * delta[tension], rtol=1e-6)
    after = int(np.argmin(T1)) + 1
    assert T1[after] == 0.0 and delta[after] > case.delta_max


def test_friction_slip_onset_and_dissipation(checks):
    case, c = checks
    assert c["tau_plateau_MPa"] == pytest.approx(c["tau_c_MPa"], rel=0.01)
    assert c["u3c_from_stick_slope_mm"] == pytest.approx(c["u3c_expected_mm"], rel=0.02)
    assert c["W_f_mJ_per_mm2"] == pytest.approx(c["W_f_expected_mJ_per_mm2"], rel=0.02)


def test_explicit_contact_reaches_the_same_state(tmp_path):
    """Explicit central differences with the same contact model: slow smooth-step compression
    to T1 = 3 sigma_y gives the implicit end state, and the energy balance closes with the
    contact work equal to the penalty energy 1/2 T1^2 / k per unit area."""
    from mpfem_fenicsx.workflows.flat_contact import run_normal_explicit

    case = FlatContactCase()
    history, energies = run_normal_explicit(case, tmp_path, MPI.COMM_SELF, steps=2000)
    gap, T1, alpha = history.array()[-1, 1:]
    assert T1 == pytest.approx(3 * case.sigma_y, rel=1e-3)
    assert alpha == pytest.approx(0.5, rel=1e-3)
    assert gap == pytest.approx(-T1 / case.penalty, rel=1e-3)
    e = energies
    assert e.balance_error() < 1e-6 * e.external
    assert e.contact == pytest.approx(0.5 * T1**2 / case.penalty * 1.0, rel=1e-2)
    assert e.internal == pytest.approx(e.elastic, rel=1e-3)
    assert e.kinetic < 1e-6 * e.external


def test_contact_history_survives_a_restart(tmp_path):
    """Adhesive memory (alpha, sigma_max) and frictional history saved after compression and
    loaded into a fresh model give the same tractions on the next evaluation."""
    from mpfem_fenicsx.loading import PrescribedDisplacements
    from mpfem_fenicsx.solvers import ImplicitSolver, StepControl
    from mpfem_fenicsx.workflows.flat_contact import _compression, _setup

    case = FlatContactCase()
    models = []
    for _ in range(2):
        problem, contact, base, block_dofs = _setup(case, 0.0, MPI.COMM_SELF)
        models.append((problem, contact))
    (p1, c1), (p2, c2) = models
    u_c = _compression(case, case.E, 3.0 * case.sigma_y)
    bcs = PrescribedDisplacements(p1.V).add(base)
    top = block_dofs(lambda x: x[2] > 0.5 * case.height, 2)
    bcs.add(block_dofs(lambda x: x[2] > 0.5 * case.height, 0)).add(
        block_dofs(lambda x: x[2] > 0.5 * case.height, 1)
    ).add(top, lambda t: u_c * t)
    ImplicitSolver(p1, bcs, contact=c1).run(StepControl(t_end=1.0, dt=0.25, dt_max=0.25))
    np.savez(
        tmp_path / "state.npz",
        u=p1.u.x.array,
        **{f"c_{k}": v for k, v in c1.state_dict().items()},
        **{f"m_{k}": v for k, v in p1.material.state_dict().items()},
    )
    data = np.load(tmp_path / "state.npz")
    p2.u.x.array[:] = data["u"]
    c2.load_state({k[2:]: data[k] for k in data.files if k.startswith("c_")})
    p2.material.load_state({k[2:]: data[k] for k in data.files if k.startswith("m_")})
    assert np.allclose(c2.state.alpha, 0.5, rtol=1e-6)  # alpha survived
    block_z = block_dofs(lambda x: x[2] >= -1e-12, 2)
    for p, c in ((p1, c1), (p2, c2)):
        p.u.x.array[block_z] += 1e-4  # lift the block: adhesive softening branch, needs alpha
        c.evaluate(p.u)
    assert np.all(c2.evaluation.T1 < 0)
    assert np.allclose(c1.evaluation.T1, c2.evaluation.T1, rtol=1e-12)
