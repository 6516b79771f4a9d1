"""Output fields: per-cell von Mises stress, equivalent plastic strain, particle id; ParaView
time series (XDMF) of the displacement and these cell fields."""

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
        m = self.problem.material
        tau = m.tau
        # J = exp(tr eps_e) and tr tau = 3 K tr eps_e (plastic flow is isochoric)
        J = np.exp((tau[:, 0] + tau[:, 1] + tau[:, 2]) / (3.0 * self.problem.params.bulk))
        self.von_mises.x.array[self._dofs] = self._cell_average(m.von_mises_kirchhoff() / J)
        self.eps_p.x.array[self._dofs] = self._cell_average(m.eps_p)
        self.von_mises.x.scatter_forward()
        self.eps_p.x.scatter_forward()

    def functions(self) -> list[dolfinx.fem.Function]:
        fields = [self.von_mises, self.eps_p]
        return fields + ([self.particle] if self.particle is not None else [])


class ParaViewWriter:
    """XDMF time series: displacement (mm) and the cell fields; open ``<path>`` in ParaView."""

    def __init__(self, path: str | Path, problem: SolidProblem, fields: CellFields):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.problem = problem
        self.fields = fields
        self._file = dolfinx.io.XDMFFile(problem.comm, str(self.path), "w")
        self._file.write_mesh(problem.mesh)

    def write(self, t: float) -> None:
        self.fields.update()
        self._file.write_function(self.problem.u, t)
        for fn in self.fields.functions():
            self._file.write_function(fn, t)

    def close(self) -> None:
        self._file.close()
