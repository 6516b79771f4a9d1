"""Constitutive law of the particles (thesis §2.1, eq. 2.1)."""

from .hencky_j2 import HenckyJ2, eig_sym3, return_mapping
from .parameters import LEAD, STEEL_LINEAR, ElastoPlastic

__all__ = ["ElastoPlastic", "HenckyJ2", "LEAD", "STEEL_LINEAR", "eig_sym3", "return_mapping"]
