"""Quasi-static explicit compaction (issue 21) on a CI-sized random volume: the particle meshes hold
their spheres' volume in every row, the loading curve does not move when the number of increments
doubles, it carries no end-of-load hook, and the last row is in equilibrium.

Case: 12 equal spheres (r = 0.1 mm, a seeded jammed periodic packing), CLP (periodic images), the
default mesh and damping, compacted from rho 0.616 to 0.70 in N = 1000 and 2N increments."""

import numpy as np
import pytest
from mpi4py import MPI

from mpfem_fenicsx.workflows.compaction import CompactionCase, build_compaction, run_compaction

CASE = dict(particles=12, r_min=0.1, r_max=0.1, target_density=0.70, outputs=20, visual=False, checkpoint_every=0)
DENSITIES = (0.66, 0.68)


def quiet(*args, **kwargs):
    pass


def sigma_at(h, rho):
    """sigma_m (MPa) where the history first reaches ``rho`` (linear interpolation)."""
    r, s = h.column("rho"), h.column("sigma_m")
    k = int(np.flatnonzero(r >= rho)[0])
    return s[k - 1] + (s[k] - s[k - 1]) * (rho - r[k - 1]) / (r[k] - r[k - 1])


@pytest.fixture(scope="module")
def histories(tmp_path_factory):
    out = tmp_path_factory.mktemp("quasi_static")
    return {n: run_compaction(CompactionCase(increments=n, out_dir=str(out / f"n{n}"), **CASE), MPI.COMM_SELF,
                              quiet).history for n in (1000, 2000)}


def test_model_solid_fraction_is_the_spheres(tmp_path):
    """Finite-element volumes (DOLFINx integral over the deformed particles) = the spheres' volumes
    the relative density counts (thesis eq. 2.4-2.5), on the flagship packing with its two radii."""
    model = build_compaction(CompactionCase(visual=False, out_dir=str(tmp_path)), MPI.COMM_SELF, log=quiet)
    assert model.rho0_fe == pytest.approx(model.rho0, rel=1e-9)


def test_rho_and_rho_fe_agree_in_every_row(histories):
    for h in histories.values():
        rho, rho_fe = h.column("rho"), h.column("rho_fe")
        assert np.all(np.abs(rho - rho_fe) / rho < 0.005)


def test_loading_curve_converged_in_the_number_of_increments(histories):
    coarse, fine = histories[1000], histories[2000]
    for rho in DENSITIES:
        assert sigma_at(coarse, rho) == pytest.approx(sigma_at(fine, rho), rel=0.03), rho


def test_no_end_of_load_hook_and_equilibrium_at_the_end(histories):
    for n, h in histories.items():
        sigma_m = h.column("sigma_m")
        assert sigma_m[-1] >= 0.98 * sigma_m.max(), n
        assert h.column("unbalanced")[-1] < 0.01, n
        assert h.column("E_c_over_E_int")[-1] < 1e-3, n
