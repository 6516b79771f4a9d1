"""The four boundary conditions of the thesis (table 2.2) and the rules each one carries: one
definition, read by the constraints, the homogenization, the workflows and the command line.

    GDH   duplicated particles, homogeneous: every particle's reference point follows F0
    GDF   duplicated particles, free: the copies' reference points follow F0, the volume is free
    CLPS  periodic, by reference points: each copy's reference point follows its original's
          plus the cell's shift (eq. 2.15; equal rotations, eq. 2.16)
    CLP   fully periodic: each copy node tied to its original's node (eq. 2.14), or contact with
          periodic images (no copies)

Pure Python (no DOLFINx), like ``homogenization/``.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class BoundaryKind:
    """The rules of one boundary condition.

    Attributes:
        name: thesis name (table 2.2).
        periodic: the copies follow their originals: the cell's gradient F0 has reactions (the
            auxiliary nodes, Schmidt's eq. 2.19), stress control applies, and one node anchors
            the rigid translation.
        tied_nodes: every node of a copy is its original's node shifted (eq. 2.14; or periodic
            images): a copy is its original, so each physical contact is modelled once (weights
            1 in Love-Weber) and the copies need only half of the faces.
        driven: which particles' reference points F0 drives: "all", "copies", or "none" (the
            periodic kinds: F0 enters through the periodic shifts).
        default_d_bc: duplication distance / r_max of thesis table 2.3 (§2.5).
    """

    name: str
    periodic: bool
    tied_nodes: bool
    driven: str
    default_d_bc: float

    @property
    def copy_faces(self) -> str:
        """Faces duplicated (meshes.packing.duplicate_particles): "half" for tied copies (a
        contact across a face is already the original's with the opposite copy), else "all"."""
        return "half" if self.tied_nodes else "all"


BOUNDARY_KINDS = {
    k.name: k
    for k in (
        BoundaryKind("GDH", periodic=False, tied_nodes=False, driven="all", default_d_bc=2.5),
        BoundaryKind("GDF", periodic=False, tied_nodes=False, driven="copies", default_d_bc=2.5),
        BoundaryKind("CLPS", periodic=True, tied_nodes=False, driven="none", default_d_bc=2.5),
        BoundaryKind("CLP", periodic=True, tied_nodes=True, driven="none", default_d_bc=1.8),
    )
}
#: the names, in the thesis' order
KINDS = tuple(BOUNDARY_KINDS)


def boundary_kind(name: str) -> BoundaryKind:
    """The :class:`BoundaryKind` of a name (case-insensitive); ValueError naming the allowed
    ones."""
    kind = BOUNDARY_KINDS.get(str(name).upper())
    if kind is None:
        raise ValueError(f"bc must be one of {', '.join(KINDS)}, got {name!r}")
    return kind
