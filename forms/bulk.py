"""UFL forms of the particles' bulk: finite-strain internal virtual work, its linearization,
lumped mass and bulk viscosity (importable as ``mpfem_fenicsx.forms``).

Total Lagrangian, reference configuration X (mm), displacement u (mm), F = I + Grad u.
Internal virtual work (N mm):
    W_int = int_Omega0 P : Grad v dX,    P = tau F^-T  (first Piola, MPa)
with the Kirchhoff stress split exactly (Hencky + isochoric plastic flow, see
``mpfem_fenicsx.material.hencky_j2``) into
    tau = dev(tau)(F_bar, state)  +  K ln(J) I.

Volumetric locking: Q1 hexahedra use *selective reduced integration* — the deviatoric part,
computed at the 2x2x2 Gauss points by the return-mapping kernel, is integrated with 8 points;
the volumetric part K ln J F^-T is integrated with a single point per cell, so each element
carries one incompressibility constraint instead of eight and isochoric plastic flow does not
lock (Hughes 1980; the finite-strain analogue of Abaqus C3D8 SRI). The deviatoric part is fully
integrated, so there are no hourglass modes. P2 tetrahedra (gmsh option) need no reduced rule.
"""

from __future__ import annotations

from dataclasses import dataclass

import ufl


@dataclass(frozen=True)
class QuadratureRules:
    """Quadrature degrees of the deviatoric and volumetric parts for a cell type / degree."""

    deviatoric: int
    volumetric: int

    @staticmethod
    def for_cell(cell_name: str, degree: int) -> QuadratureRules:
        """The rules for Lagrange elements of ``degree`` on ``cell_name`` cells."""
        if cell_name == "hexahedron" and degree == 1:
            return QuadratureRules(deviatoric=2, volumetric=1)  # 8 points + 1 point (SRI)
        if cell_name == "tetrahedron":
            return QuadratureRules(deviatoric=2, volumetric=2 if degree >= 2 else 1)
        return QuadratureRules(deviatoric=2 * degree, volumetric=2 * degree)


def deformation_gradient(u):
    """F = I + Grad u (dimensionless) of the displacement ``u`` (mm)."""
    return ufl.Identity(len(u)) + ufl.grad(u)


def volumetric_piola(u, bulk):
    """P_vol = K ln(J) F^-T (MPa): Hencky volumetric Kirchhoff stress pulled back."""
    F = deformation_gradient(u)
    return bulk * ufl.ln(ufl.det(F)) * ufl.inv(F).T


def internal_work(u, v, P_dev, bulk, dx_dev, dx_vol):
    """Residual int P : Grad v dX as two forms: (deviatoric, 8 points; volumetric, 1 point).

    The two parts must be compiled as *separate* forms and their assembled tensors added:
    FFCx 0.11 mis-evaluates a single form mixing quadrature degrees on non-affine hexahedra
    (checked by ``tests/test_material.py::test_tangent_matches_finite_differences``).
    """
    deviatoric = ufl.inner(P_dev, ufl.grad(v)) * dx_dev
    volumetric = ufl.inner(volumetric_piola(u, bulk), ufl.grad(v)) * dx_vol
    return deviatoric, volumetric


def internal_work_tangent(u, du, v, A_dev, bulk, dx_dev, dx_vol):
    """Consistent linearization of :func:`internal_work` in the direction du, same two parts.

    Deviatoric part: A_dev = dP_dev/dF from the kernel; volumetric part: exact UFL derivative.
    """
    i, j, k, m = ufl.indices(4)
    dP_dev = ufl.as_tensor(A_dev[i, j, k, m] * ufl.grad(du)[k, m], (i, j))
    volumetric = ufl.inner(volumetric_piola(u, bulk), ufl.grad(v)) * dx_vol
    return ufl.inner(dP_dev, ufl.grad(v)) * dx_dev, ufl.derivative(volumetric, u, du)


def kirchhoff_stress_integrals(u, w, P_dev, bulk, dx_dev, dx_vol):
    """int tau : w dX as two forms (deviatoric, volumetric; same rules as :func:`internal_work`),
    tau = P F^T = dev(tau) + K ln(J) I the Kirchhoff stress (MPa). With w a test function of
    piecewise-constant tensors, the assembled vector holds each cell's int tau dX = int sigma dx
    (N mm), the cell's share of the volume-averaged stress (thesis eq. C.7)."""
    F = deformation_gradient(u)
    deviatoric = ufl.inner(ufl.dot(P_dev, F.T), w) * dx_dev
    volumetric = bulk * ufl.ln(ufl.det(F)) * ufl.tr(w) * dx_vol
    return deviatoric, volumetric


def lumped_mass_action(density, v, dx):
    """Row-sum lumped mass: assembling this linear form gives M_i = rho int N_i dX (t)."""
    return density * ufl.dot(ufl.as_vector([1.0, 1.0, 1.0]), v) * dx


def bulk_viscosity_work(
    u, velocity, v, density, wave_speed, cell_length, linear, quadratic, dx_vol
):
    """Abaqus-style bulk viscosity (explicit dynamics): a volumetric viscous Cauchy stress

        sigma_bv = [ b1 rho c_d L_e eps_dot_v  -  rho (b2 L_e eps_dot_v)^2 H(-eps_dot_v) ] I

    with eps_dot_v = tr(grad_x velocity) (1/s), L_e the element length (mm), rho the (mass-scaled)
    density, c_d the dilatational wave speed; b1 = 0.06, b2 = 1.2 by default. The quadratic term
    acts in compression only. Virtual work int J sigma_bv : grad_x v dX (one point per cell).
    """
    F = deformation_gradient(u)
    Finv = ufl.inv(F)
    J = ufl.det(F)
    rate = ufl.tr(ufl.grad(velocity) * Finv)
    compression = ufl.conditional(ufl.lt(rate, 0.0), 1.0, 0.0)
    pressure = (
        linear * density * wave_speed * cell_length * rate
        - density * (quadratic * cell_length * rate) ** 2 * compression
    )
    return J * pressure * ufl.tr(ufl.grad(v) * Finv) * dx_vol
