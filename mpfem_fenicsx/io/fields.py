"""Output fields: per-cell von Mises stress, equivalent plastic strain, particle id; nodal contact
pressure on the particle surfaces; ParaView time series (XDMF) of the displacement and these
fields."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import dolfinx
import dolfinx.io

from ..problem import SolidProblem


class CellFields:
    """DG0 fields averaged over the quadrature points of each cell.

    - ``von_mises``: Cauchy von Mises stress sqrt(3/2) |dev sigma| (MPa), sigma = tau / J;
    - ``eps_p``: equivalent plastic strain (-);
    - ``particle``: particle id (cell tag), when tags are given.
    """

    def __init__(self, problem: SolidProblem, cell_tags: dolfinx.mesh.MeshTags | None = None):
        self.problem = problem
        DG0 = dolfinx.fem.functionspace(problem.mesh, ("DG", 0))
        self._dofs = DG0.dofmap.list[problem.material_cells, 0]  # cells carrying material points
        self.von_mises = dolfinx.fem.Function(DG0, name="von_mises_MPa")
        self.eps_p = dolfinx.fem.Function(DG0, name="eps_p")
        self.particle = None
        if cell_tags is not None:
            self.particle = dolfinx.fem.Function(DG0, name="particle")
            owned = cell_tags.values[: problem.num_cells]
            self.particle.x.array[DG0.dofmap.list[: problem.num_cells, 0]] = owned
            self.particle.x.scatter_forward()

    def _cell_average(self, values: np.ndarray) -> np.ndarray:
        return values.reshape(self.problem.material_cells.size, -1).mean(axis=1)

    def update(self) -> None:
        """Recompute the cell fields from the material's current state."""
        m = self.problem.material
        tau = m.tau
        # J = exp(tr eps_e) and tr tau = 3 K tr eps_e (plastic flow is isochoric)
        J = np.exp((tau[:, 0] + tau[:, 1] + tau[:, 2]) / (3.0 * self.problem.params.bulk))
        self.von_mises.x.array[self._dofs] = self._cell_average(m.von_mises_kirchhoff() / J)
        self.eps_p.x.array[self._dofs] = self._cell_average(m.eps_p)
        self.von_mises.x.scatter_forward()
        self.eps_p.x.scatter_forward()

    def functions(self) -> list[dolfinx.fem.Function]:
        """The fields written with the displacement."""
        fields = [self.von_mises, self.eps_p]
        return fields + ([self.particle] if self.particle is not None else [])


class ContactPressure:
    """Nodal contact traction T1 (MPa, compression > 0, adhesion < 0) of the last contact
    evaluation, on the surface nodes (zero elsewhere and where nothing touches): the normal
    traction of each node's own slave points (two-pass contact, thesis §3.3), summed over the
    bodies it touches. A degree-1 scalar field on the particles' mesh (ParaView: colour the
    surface by ``contact_pressure_MPa``)."""

    def __init__(self, V: dolfinx.fem.FunctionSpace, contact):
        self.contact = contact
        Vs = dolfinx.fem.functionspace(V.mesh, ("Lagrange", 1))
        self.function = dolfinx.fem.Function(Vs, name="contact_pressure_MPa")

    def update(self) -> None:
        """Recompute the nodal contact pressure (MPa) from the last contact evaluation."""
        values = self.function.x.array
        values[:] = 0.0
        ev = self.contact.evaluation
        if ev.size:
            # held surface node -> local node of this rank (slave points live on owned nodes)
            surf = self.contact.surface
            local = np.full(surf.num_nodes, -1, dtype=np.int64)
            local[surf.owned_nodes] = surf.owned_local_blocks
            nodes = local[ev.points.slave]
            np.add.at(values, nodes[nodes >= 0], ev.T1[nodes >= 0])
        self.function.x.scatter_forward()


class ParaViewWriter:
    """XDMF time series: displacement (mm), the cell fields and, with a contact model, the nodal
    contact pressure; open ``<path>`` in ParaView."""

    def __init__(self, path: str | Path, problem: SolidProblem, fields: CellFields, contact=None):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.problem = problem
        self.fields = fields
        self.pressure = ContactPressure(problem.V, contact) if contact is not None else None
        self._file = dolfinx.io.XDMFFile(problem.comm, str(self.path), "w")
        self._file.write_mesh(problem.mesh)

    def write(self, t: float) -> None:
        """Write the displacement and the fields at time ``t`` (s)."""
        self.fields.update()
        self._file.write_function(self.problem.u, t)
        for fn in self.fields.functions():
            self._file.write_function(fn, t)
        if self.pressure is not None:
            self.pressure.update()
            self._file.write_function(self.pressure.function, t)

    def close(self) -> None:
        """Close the file."""
        self._file.close()
