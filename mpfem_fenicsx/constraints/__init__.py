"""Multipoint / Dirichlet constraints as PETSc matrices: u_full = P u_reduced + g."""

from .affine import AffineConstraint, CouplingRows

__all__ = ["AffineConstraint", "CouplingRows"]
