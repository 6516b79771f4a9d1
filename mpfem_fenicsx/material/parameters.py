"""Material parameters of the particles (units: MPa, t/mm^3)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ElastoPlastic:
    """Hencky elasticity + von Mises plasticity with isotropic hardening.

    Yield stress (Kirchhoff, MPa) as a function of the equivalent plastic strain eps_p:
    - ``hardening="power"``: sigma_y = sigma_0 + K * eps_p**n  (thesis eq. 2.1, table 2.1)
    - ``hardening="linear"``: sigma_y = sigma_0 + H * eps_p    (thesis table 3.2)
    """

    E: float = 10000.0  # Young's modulus, MPa
    nu: float = 0.435  # Poisson's ratio
    sigma_0: float = 5.0  # initial yield stress, MPa
    hardening: str = "power"
    K: float = 15.5  # power-law hardening modulus, MPa
    n: float = 0.35  # power-law hardening exponent
    H: float = 0.0  # linear hardening modulus, MPa
    density: float = 1e-8  # t/mm^3

    def __post_init__(self):
        checks = [
            ("E", self.E, self.E > 0, "> 0 MPa"),
            ("nu", self.nu, -1.0 < self.nu < 0.5, "in (-1, 0.5)"),
            ("sigma_0", self.sigma_0, self.sigma_0 > 0, "> 0 MPa"),
            ("K", self.K, self.K >= 0, ">= 0 MPa"),
            ("n", self.n, 0 < self.n <= 1, "in (0, 1]"),
            ("H", self.H, self.H >= 0, ">= 0 MPa"),
            ("density", self.density, self.density > 0, "> 0 t/mm^3"),
        ]
        for name, value, ok, allowed in checks:
            if not ok:
                raise ValueError(f"material.{name} = {value!r} is out of range: must be {allowed}")
        if self.hardening not in ("power", "linear"):
            raise ValueError(f"material.hardening = {self.hardening!r}: must be 'power' or 'linear'")

    @property
    def mu(self) -> float:
        return self.E / (2.0 * (1.0 + self.nu))

    @property
    def lmbda(self) -> float:
        return self.E * self.nu / ((1.0 + self.nu) * (1.0 - 2.0 * self.nu))

    @property
    def bulk(self) -> float:
        return self.E / (3.0 * (1.0 - 2.0 * self.nu))

    @property
    def dilatational_wave_speed(self) -> float:
        """c_d = sqrt((lambda + 2 mu) / rho), mm/s."""
        return ((self.lmbda + 2.0 * self.mu) / self.density) ** 0.5

    def yield_stress(self, eps_p):
        """sigma_y(eps_p), MPa (numpy-friendly)."""
        if self.hardening == "power":
            return self.sigma_0 + self.K * eps_p ** self.n
        return self.sigma_0 + self.H * eps_p

    def kernel_parameters(self) -> tuple[float, float, float, float, float, int]:
        """(mu, bulk, sigma_0, modulus, exponent, law) as passed to the numba kernels."""
        if self.hardening == "power":
            return (self.mu, self.bulk, self.sigma_0, self.K, self.n, 0)
        return (self.mu, self.bulk, self.sigma_0, self.H, 1.0, 1)


#: Lead-like reference particles of the thesis (table 2.1)
LEAD = ElastoPlastic()

#: Linear-hardening steel of the contact validation (thesis table 3.2)
STEEL_LINEAR = ElastoPlastic(E=200000.0, nu=0.3, sigma_0=200.0, hardening="linear", K=0.0, H=100.0,
                             density=7.8e-9)
