"""SPEC §9 case 3 / thesis §3.4.1: the adhesive and frictional contact law on a flat contact."""

import sys
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from mpfem_fenicsx.workflows.flat_contact import FlatContactCase, run_flat_contact

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
    assert c["peak_tension_from_softening_line_MPa"] == pytest.approx(0.5 * c["sigma_c_MPa"], rel=0.02)
    assert c["peak_tension_MPa"] == pytest.approx(0.5 * c["sigma_c_MPa"], rel=0.02)
    assert c["zero_crossing_of_softening_mm"] == pytest.approx(case.delta_max, rel=0.02)
    assert c["max_abs_T1_beyond_delta_max"] == 0.0
    assert c["alpha_beyond_delta_max"] == 0.0  # memory erased


def test_friction_slip_onset_and_dissipation(checks):
    case, c = checks
    assert c["tau_plateau_MPa"] == pytest.approx(c["tau_c_MPa"], rel=0.01)
    assert c["u3c_from_stick_slope_mm"] == pytest.approx(c["u3c_expected_mm"], rel=0.02)
    assert c["W_f_mJ_per_mm2"] == pytest.approx(c["W_f_expected_mJ_per_mm2"], rel=0.02)
