"""Chapter-4 workflow (thesis §4.2-4.5): reload gradients, threshold detection, uniaxial strengths
(plain arrays), and a small fan restarted from an unload checkpoint (finite elements)."""

import numpy as np
import pytest

from mpfem_fenicsx.homogenization import (first_crossing, hencky_strain, rendulic_strain, strain_invariants,
                                          uniaxial_strengths)
from mpfem_fenicsx.loading import reload_gradient, unload_gradient


@pytest.mark.parametrize("phi", np.linspace(0, 2 * np.pi, 9)[:-1])
def test_reload_gradient_follows_eq_4_8(phi):
    """h_v = -A cos phi and h~_d = -A sin phi (natural sign; A cos phi, A sin phi compression > 0)."""
    A = 0.012
    h = hencky_strain(reload_gradient(phi, A))
    h_v, _ = strain_invariants(h)
    assert h_v == pytest.approx(-A * np.cos(phi), abs=1e-14)
    assert rendulic_strain(h)[1] == pytest.approx(-A * np.sin(phi), abs=1e-14)


def test_reload_gradient_axis_and_unload():
    F = reload_gradient(np.pi / 2, 0.03, axis=2)  # axial compression at constant volume along z
    assert F[2, 2] < 1 < F[0, 0] and F[0, 0] == F[1, 1]
    assert np.linalg.det(F) == pytest.approx(1.0, abs=1e-14)
    assert np.log(np.linalg.det(unload_gradient(0.004))) == pytest.approx(0.004, rel=1e-12)
    with pytest.raises(ValueError, match="amplitude"):
        reload_gradient(0.0, -1.0)


def test_last_crossing_of_non_monotonic_indicator():
    """Gamma decreasing through a level and rising back: first and last crossings differ."""
    g = np.array([5.0, 4.0, 2.0, 1.0, 2.0, 4.0, 6.0])
    x = np.arange(7.0)
    pos, xf = first_crossing(g, 3.0, x, rising=False)
    assert pos == pytest.approx(1.5) and xf == pytest.approx(1.5)
    pos, xl = first_crossing(g, 3.0, x, rising=True, last=True)
    assert pos == pytest.approx(4.5) and xl == pytest.approx(4.5)


def test_uniaxial_strengths_of_an_ellipse():
    """Ellipse (sigma_m - c)^2 / a^2 + sigma~_d^2 / b^2 = 1 cut by sigma~_d = 3 sigma_m: solve the
    quadratic by hand and compare with the polygon intersection (fine polygon, 1e-4)."""
    a, b, c = 4.0, 6.0, 2.5
    t = np.linspace(0, 2 * np.pi, 4000, endpoint=False)
    sm, sd = c + a * np.cos(t), b * np.sin(t)
    # (m - c)^2 / a^2 + 9 m^2 / b^2 = 1
    roots = np.roots([1 / a ** 2 + 9 / b ** 2, -2 * c / a ** 2, c ** 2 / a ** 2 - 1])
    compressive, tensile = uniaxial_strengths(sm, sd)
    assert compressive == pytest.approx(3 * roots.max(), rel=1e-4)
    assert tensile == pytest.approx(-3 * roots.min(), rel=1e-4)
    # a surface entirely in compression has no tensile strength
    assert np.isnan(uniaxial_strengths(sm + 10.0, sd)[1])
