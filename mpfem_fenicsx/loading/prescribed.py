"""Prescribed displacements (mm) on groups of dofs, as the affine constraint's offset g(t)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

import dolfinx
import dolfinx.fem

from ..constraints import AffineConstraint, CouplingRows


def component_dofs(V: dolfinx.fem.FunctionSpace, marker: Callable, component: int) -> np.ndarray:
    """Local unrolled dofs (block * 3 + component) of the nodes where ``marker(x)`` is True."""
    if component not in (0, 1, 2):
        raise ValueError(f"component must be 0, 1 or 2, got {component}")
    blocks = dolfinx.fem.locate_dofs_geometrical(V, marker)
    return (blocks.astype(np.int64) * V.dofmap.index_map_bs + component).astype(np.int32)


def body_dofs(
    V: dolfinx.fem.FunctionSpace,
    cell_tags: dolfinx.mesh.MeshTags,
    body: int,
    component: int | None = None,
) -> np.ndarray:
    """Local unrolled dofs of all nodes of the cells tagged ``body`` (all 3 components, or one)."""
    cells = cell_tags.indices[cell_tags.values == body]
    blocks = np.unique(V.dofmap.list[cells].ravel()).astype(np.int64)
    bs = V.dofmap.index_map_bs
    comps = range(bs) if component is None else [component]
    return np.sort(np.concatenate([blocks * bs + c for c in comps])).astype(np.int32)


class PrescribedDisplacements:
    """Groups of dofs with a prescribed displacement value(t) (mm).

    ``value`` is a float (fixed) or a callable ``t -> float`` or ``t -> array`` (one value per dof
    of the group, in the order given). A dof listed in several groups takes the last one.
    """

    def __init__(self, V: dolfinx.fem.FunctionSpace):
        self.V = V
        self._groups: list[tuple[np.ndarray, Callable | float]] = []
        self.constraint: AffineConstraint | None = None
        #: fixed multipoint rows (e.g. cyclic symmetry), built with the prescribed dofs
        self.couplings: CouplingRows | None = None
        #: callables ``t -> None`` placed with the prescribed values (e.g. rigid tools' motion)
        self.followers: list[Callable[[float], None]] = []

    def add(self, dofs: np.ndarray, value: Callable | float = 0.0) -> PrescribedDisplacements:
        """Prescribe ``dofs`` to ``value`` (mm): a number, an array, or t -> either."""
        self._groups.append((np.asarray(dofs, dtype=np.int32), value))
        return self

    @property
    def prescribed_dofs(self) -> np.ndarray:
        """All dofs of the groups added so far (local unrolled indices)."""
        return (
            np.concatenate([d for d, _ in self._groups]) if self._groups else np.zeros(0, np.int32)
        )

    def build(self) -> AffineConstraint:
        """The affine constraint of the prescribed dofs and the couplings."""
        self.constraint = AffineConstraint(self.V, self.prescribed_dofs, self.couplings)
        prescribed = self.constraint.prescribed
        self._positions = []
        for dofs, _ in self._groups:
            keep = dofs < self.constraint.num_owned
            self._positions.append((np.searchsorted(prescribed, dofs[keep]), keep))
        return self.constraint

    def values(self, t: float) -> np.ndarray:
        """Values (mm) of the constraint's prescribed dofs at time ``t`` (s)."""
        out = np.zeros(self.constraint.prescribed.size)
        for (_, value), (pos, keep) in zip(self._groups, self._positions, strict=True):
            v = value(t) if callable(value) else value
            out[pos] = v[keep] if np.ndim(v) else v
        return out

    def apply(self, t: float) -> None:
        """Set the prescribed values of time ``t`` (s) in the constraint and move the
        followers (rigid tools) to ``t``."""
        self.constraint.set_prescribed(self.values(t))
        for follow in self.followers:
            follow(t)
