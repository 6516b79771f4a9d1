"""Rigid tools: planes, the inside of a cylinder (a die) and triangulated (STL) surfaces, each a
contact master with its own contact law and motion (dies, punches, walls).

A :class:`RigidTool` is what a case declares; the contact of the particles' surface nodes
against the tools is :class:`mpfem_fenicsx.contact.rigid.RigidContact`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..contact.laws import ContactLaw
from .motion import KeyframePath, fixed
from .servo import ForceServo
from .shapes import CylinderInside, Plane, TriangulatedSurface, read_stl, write_stl


@dataclass(frozen=True, eq=False)
class RigidTool:
    """A rigid tool: its ``shape`` (reference placement, mm), its contact ``law`` with the
    particles (own penalty, friction, adhesion) and its ``motion`` (t -> translation (3,) mm;
    a force-controlled tool is moved by its ``servo`` instead, :class:`ForceServo`)."""

    name: str
    shape: Plane | CylinderInside | TriangulatedSurface
    law: ContactLaw = field(default_factory=ContactLaw)
    motion: Callable[[float], np.ndarray] = fixed
    servo: ForceServo | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"tool name = {self.name!r} must be a non-empty string")
        if not hasattr(self.shape, "gap_normal"):
            raise ValueError(f"tool {self.name}: shape must be a Plane, CylinderInside or mesh")


__all__ = [
    "CylinderInside",
    "ForceServo",
    "KeyframePath",
    "Plane",
    "RigidTool",
    "TriangulatedSurface",
    "fixed",
    "read_stl",
    "write_stl",
]
