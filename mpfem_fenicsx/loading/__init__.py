"""Loading: amplitudes, prescribed motions and macroscopic gradient paths."""

from .amplitude import PROFILES, Ramp, SmoothRamps, SmoothStep
from .macroscopic import GradientPath, compaction_gradient, reload_gradient, unload_gradient
from .prescribed import PrescribedDisplacements, body_dofs, component_dofs

__all__ = [
    "PROFILES",
    "GradientPath",
    "PrescribedDisplacements",
    "Ramp",
    "SmoothRamps",
    "SmoothStep",
    "body_dofs",
    "compaction_gradient",
    "component_dofs",
    "reload_gradient",
    "unload_gradient",
]
