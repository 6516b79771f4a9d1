"""Loading: amplitudes and prescribed motions."""

from .amplitude import Ramp, SmoothStep
from .prescribed import PrescribedDisplacements, component_dofs

__all__ = ["PrescribedDisplacements", "Ramp", "SmoothStep", "component_dofs"]
