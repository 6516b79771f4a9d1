"""From particles to a continuum model: the Drucker-Prager Cap surface in Abaqus' form, its fit
to the yield points of the computed fans, and the Abaqus fragment of the fitted model. Pure
numpy / scipy: plain arrays in, plain arrays out. Stresses in MPa, compression > 0."""

from .abaqus import (
    CalibratedDensity,
    cap_fragment,
    elastic_constants,
    hardening_table,
    read_keywords,
    surfaces_from_fragment,
)
from .cap import CapSurface
from .fit import CapFit, deviatoric_misfit, fit_cap, isotropic_hardening, radial_residuals

__all__ = [
    "CalibratedDensity",
    "CapFit",
    "CapSurface",
    "cap_fragment",
    "deviatoric_misfit",
    "elastic_constants",
    "fit_cap",
    "hardening_table",
    "isotropic_hardening",
    "radial_residuals",
    "read_keywords",
    "surfaces_from_fragment",
]
