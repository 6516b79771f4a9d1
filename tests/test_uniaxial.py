"""Homogeneous uniaxial tension to log strain 0.5 with the lead parameters."""

import numpy as np
import pytest
from mpi4py import MPI

from mpfem_fenicsx.io import read_csv
from mpfem_fenicsx.material import LEAD
from mpfem_fenicsx.workflows.foundation import UniaxialCase, run_uniaxial


@pytest.fixture(scope="module", params=["implicit", "explicit"])
def uniaxial(request, tmp_path_factory):
    out = tmp_path_factory.mktemp(request.param)
    return request.param, run_uniaxial(
        UniaxialCase(solver=request.param, log_strain=0.5),
        out_dir=out,
        comm=MPI.COMM_SELF,
        log=lambda *a: None,
    )


def test_true_stress_follows_hardening_law(uniaxial):
    solver, res = uniaxial
    assert res.log_strain[-1] == pytest.approx(0.5, abs=1e-12)
    plastic = res.eps_p > 1e-3  # the whole plastic curve (elastic strain at yield is 5e-4)
    assert plastic.sum() > 0.8 * plastic.size
    expected = LEAD.sigma_0 + LEAD.K * res.eps_p[plastic] ** LEAD.n
    assert np.abs(res.true_stress[plastic] / expected - 1.0).max() < 0.01
    # eps_p ~ log strain - sigma/E at large strain (plastic incompressibility)
    assert res.eps_p[-1] == pytest.approx(0.5 - res.true_stress[-1] / LEAD.E, abs=2e-3)


def test_solver_tallies_the_plastic_work(uniaxial):
    """Both solvers' plastic dissipation = integral of sigma_y d eps_p over the 1 mm^3 block
    (the implicit tally is taken before each commit, after which the trial increment is zero)."""
    _, res = uniaxial
    eps = np.linspace(0.0, res.eps_p[-1], 2001)
    assert res.plastic_work == pytest.approx(np.trapezoid(LEAD.yield_stress(eps), eps), rel=0.01)


def test_csv_contract(uniaxial):
    _, res = uniaxial
    data = read_csv(res.csv)
    assert list(data) == ["log_strain", "true_stress_MPa", "eps_p"]
    assert np.all(np.diff(data["log_strain"]) > 0)
    assert np.allclose(data["true_stress_MPa"], res.true_stress)


@pytest.fixture(scope="module")
def explicit_run(tmp_path_factory):
    return run_uniaxial(
        UniaxialCase(solver="explicit", log_strain=0.5),
        out_dir=tmp_path_factory.mktemp("energy"),
        comm=MPI.COMM_SELF,
        log=lambda *a: None,
    )


def test_explicit_energy_balance(explicit_run):
    res = explicit_run
    e = dict(zip(res.energies.columns, res.energies.array()[-1], strict=True))
    w_ext = e["W_ext"]
    assert w_ext > 0
    assert abs(w_ext - (e["E_int"] + e["E_kin"] + e["E_visc"])) < 0.01 * w_ext
    # the internal work from nodal forces equals the material's stored + dissipated energy
    assert abs(e["E_int"] - (e["E_el"] + e["E_p"])) < 0.01 * w_ext
    # and the plastic work is the integral of sigma_y d eps_p over the 1 mm^3 block
    eps = np.linspace(0.0, res.eps_p[-1], 2001)
    plastic_work = np.trapezoid(LEAD.yield_stress(eps), eps)
    assert e["E_p"] == pytest.approx(plastic_work, rel=0.01)
