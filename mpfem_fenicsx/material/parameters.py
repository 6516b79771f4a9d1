"""Material parameters of the particles (units: MPa, t/mm^3)."""

from __future__ import annotations

from dataclasses import dataclass

from ..parameters import check_parameters, parameter


@dataclass(frozen=True)
class ElastoPlastic:
    """Hencky elasticity + von Mises plasticity with isotropic hardening.

    Yield stress (Kirchhoff, MPa) as a function of the equivalent plastic strain eps_p:
    - ``hardening="power"``: sigma_y = sigma_0 + K * eps_p**n  (thesis eq. 2.1, table 2.1)
    - ``hardening="linear"``: sigma_y = sigma_0 + H * eps_p    (thesis table 3.2)
    """

    E: float = parameter(10000.0, "Young's modulus (MPa)", low=0, open_low=True)
    nu: float = parameter(
        0.435, "Poisson's ratio (-)", low=-1, high=0.5, open_low=True, open_high=True
    )
    sigma_0: float = parameter(5.0, "initial yield stress (MPa)", low=0, open_low=True)
    hardening: str = parameter(
        "power",
        "sigma_y = sigma_0 + K eps_p^n (power, eq. 2.1) or sigma_0 + H eps_p (linear)",
        choices=("power", "linear"),
    )
    K: float = parameter(15.5, "power-law hardening modulus (MPa)", low=0)
    n: float = parameter(0.35, "power-law hardening exponent (-)", low=0, high=1, open_low=True)
    H: float = parameter(0.0, "linear hardening modulus (MPa)", low=0)
    density: float = parameter(1e-8, "mass density (t/mm^3)", low=0, open_low=True)

    def __post_init__(self):
        check_parameters(self, prefix="material.")

    @property
    def mu(self) -> float:
        """Shear modulus (MPa)."""
        return self.E / (2.0 * (1.0 + self.nu))

    @property
    def lmbda(self) -> float:
        """Lame's first parameter (MPa)."""
        return self.E * self.nu / ((1.0 + self.nu) * (1.0 - 2.0 * self.nu))

    @property
    def bulk(self) -> float:
        """Bulk modulus (MPa)."""
        return self.E / (3.0 * (1.0 - 2.0 * self.nu))

    @property
    def dilatational_wave_speed(self) -> float:
        """c_d = sqrt((lambda + 2 mu) / rho), mm/s."""
        return ((self.lmbda + 2.0 * self.mu) / self.density) ** 0.5

    def yield_stress(self, eps_p):
        """sigma_y(eps_p), MPa (numpy-friendly)."""
        if self.hardening == "power":
            return self.sigma_0 + self.K * eps_p**self.n
        return self.sigma_0 + self.H * eps_p

    def kernel_parameters(self) -> tuple[float, float, float, float, float, int]:
        """(mu, bulk, sigma_0, modulus, exponent, law) as passed to the numba kernels."""
        if self.hardening == "power":
            return (self.mu, self.bulk, self.sigma_0, self.K, self.n, 0)
        return (self.mu, self.bulk, self.sigma_0, self.H, 1.0, 1)


#: Lead-like reference particles of the thesis (table 2.1)
LEAD = ElastoPlastic()

#: Linear-hardening steel of the contact validation (thesis table 3.2)
STEEL_LINEAR = ElastoPlastic(
    E=200000.0, nu=0.3, sigma_0=200.0, hardening="linear", K=0.0, H=100.0, density=7.8e-9
)
