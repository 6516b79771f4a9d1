"""UFL variational forms (importable as ``mpfem_fenicsx.forms``)."""

from .bulk import (
    QuadratureRules,
    bulk_viscosity_work,
    deformation_gradient,
    internal_work,
    internal_work_tangent,
    kirchhoff_stress_integrals,
    lumped_mass_action,
    volumetric_piola,
)

__all__ = [
    "QuadratureRules",
    "bulk_viscosity_work",
    "deformation_gradient",
    "internal_work",
    "internal_work_tangent",
    "kirchhoff_stress_integrals",
    "lumped_mass_action",
    "volumetric_piola",
]
