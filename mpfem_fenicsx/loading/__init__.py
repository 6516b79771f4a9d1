"""Loading: amplitudes and prescribed motions."""

from .amplitude import Ramp, SmoothStep
from .prescribed import PrescribedDisplacements, body_dofs, component_dofs

__all__ = ["PrescribedDisplacements", "Ramp", "SmoothStep", "body_dofs", "component_dofs"]
