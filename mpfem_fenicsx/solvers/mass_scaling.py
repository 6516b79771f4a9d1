"""Element-wise mass scaling of the explicit solver (Abaqus "fixed mass scaling to a target
increment", then variable re-checks): rho_e = rho * max(1, (dt_target / (margin dt_e))^2) with
the element stable increment dt_e = safety * L_e / c_d * (sqrt(1 + xi^2) - xi) (c_d the
dilatational wave speed, xi the linear bulk-viscosity fraction, L_e the element's stable length,
``SolidProblem.min_cell_length``: the smallest of the smallest vertex distance, for hexahedra
the centre-point volume over the largest face area, and the Gauss-point bound of
``problem.hexahedron_gauss_length``). The scaled density and wave speed and the element lengths
are cell functions the bulk-viscosity form reads."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

import dolfinx
import dolfinx.fem


@dataclass
class ElementMassScaling:
    """The element mass scaling of a mesh: density factor per owned cell and the cell functions
    (scaled density t/mm^3, wave speed mm/s, stable length mm) the bulk-viscosity form reads."""

    scale: np.ndarray  # density factor (>= 1) of every owned cell
    cell_dofs: np.ndarray  # DG0 dof of every owned cell
    density: dolfinx.fem.Function  # scaled density (t / mm^3) per cell
    wave_speed: (
        dolfinx.fem.Function
    )  # scaled dilatational wave speed c_d / sqrt(scale) (mm / s) per cell
    cell_length: dolfinx.fem.Function  # stable length L_e (mm) per cell (min_cell_length)
    material_density: float  # unscaled (t / mm^3)
    dilatational_speed: float  # unscaled c_d (mm / s)
    bulk_viscosity_linear: float  # xi (-)
    safety: float  # stable-increment safety factor (-)

    @classmethod
    def build(cls, problem, settings) -> tuple[ElementMassScaling, np.ndarray]:
        """The scaling of ``problem``'s cells for ``settings.target_dt`` (none: unscaled), and
        the unscaled element stable increments dt_e (s)."""
        mat = problem.params
        c_d, xi = mat.dilatational_wave_speed, settings.bulk_viscosity_linear
        length = problem.min_cell_length()
        dt_e = settings.safety * length / c_d * (np.sqrt(1.0 + xi * xi) - xi)
        scale = np.ones_like(dt_e)
        if settings.target_dt is not None:
            scale = np.maximum(
                1.0, (settings.target_dt / (settings.deformation_margin * dt_e)) ** 2
            )
        DG0 = dolfinx.fem.functionspace(problem.mesh, ("DG", 0))
        cell_dofs = DG0.dofmap.list[: problem.num_cells, 0]

        def cell_function(values, name):
            fn = dolfinx.fem.Function(DG0, name=name)
            fn.x.array[cell_dofs] = values
            fn.x.scatter_forward()
            return fn

        scaling = cls(
            scale,
            cell_dofs,
            cell_function(mat.density * scale, "density"),
            cell_function(c_d / np.sqrt(scale), "wave_speed"),
            cell_function(length, "cell_length"),
            mat.density,
            c_d,
            xi,
            settings.safety,
        )
        return scaling, dt_e

    def stable_increments(self, length: np.ndarray) -> np.ndarray:
        """Unscaled element stable increments (s) for the element lengths ``length`` (mm)."""
        xi = self.bulk_viscosity_linear
        return self.safety * length / self.dilatational_speed * (np.sqrt(1.0 + xi * xi) - xi)

    def set_lengths(self, length: np.ndarray) -> None:
        """Set the stable length L_e (mm) of every owned cell (ghosts updated)."""
        self.cell_length.x.array[self.cell_dofs] = length
        self.cell_length.x.scatter_forward()

    def apply(self) -> None:
        """The density and wave speed of the current :attr:`scale`."""
        self.density.x.array[self.cell_dofs] = self.material_density * self.scale
        self.density.x.scatter_forward()
        self.wave_speed.x.array[self.cell_dofs] = self.dilatational_speed / np.sqrt(self.scale)
        self.wave_speed.x.scatter_forward()

    def largest(self, comm: MPI.Comm) -> float:
        """The largest density factor over the ranks."""
        return comm.allreduce(float(self.scale.max()), op=MPI.MAX)
