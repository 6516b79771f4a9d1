"""From particles to a continuum model: the Drucker-Prager Cap surface in Abaqus' form, its fit
to the yield points of the computed fans, the Abaqus fragment of the fitted model and a
material-point driver that replays the particle model's paths with it. Pure
numpy / scipy: plain arrays in, plain arrays out. Stresses in MPa, compression > 0."""

from .abaqus import (
    CalibratedDensity,
    cap_fragment,
    clay_fragment,
    elastic_constants,
    hardening_table,
    read_keywords,
    surfaces_from_fragment,
)
from .cap import CapSurface
from .clay import ClaySurface
from .driver import ContinuumModel, PointState, drive, return_map
from .fit import (
    SurfaceFit,
    deviatoric_misfit,
    die_cap,
    die_point,
    die_ratio,
    fit_cap,
    fit_clay,
    isotropic_hardening,
    paths_cap,
    radial_residuals,
    reload_moduli,
)

__all__ = [
    "CalibratedDensity",
    "SurfaceFit",
    "ContinuumModel",
    "CapSurface",
    "ClaySurface",
    "PointState",
    "cap_fragment",
    "clay_fragment",
    "deviatoric_misfit",
    "die_cap",
    "die_point",
    "die_ratio",
    "drive",
    "elastic_constants",
    "fit_cap",
    "fit_clay",
    "hardening_table",
    "isotropic_hardening",
    "paths_cap",
    "radial_residuals",
    "read_keywords",
    "reload_moduli",
    "return_map",
    "surfaces_from_fragment",
]
