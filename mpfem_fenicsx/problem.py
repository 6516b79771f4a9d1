"""The particles' bulk problem: displacement space, quadrature-point state and compiled forms.

Data flow per evaluation: u -> F at quadrature points (numba kernel ``forms.kinematics``, checked
against ``fem.Expression``) -> vectorized
return mapping (``material.hencky_j2``) writing P_dev (and A_dev) straight into quadrature
Functions -> residual / Jacobian assembled by DOLFINx from the UFL forms in ``forms/``
(``mpfem_fenicsx.forms``)
(the residual's deviatoric part by a numba loop of ``forms.kinematics`` when it reproduces the
compiled form, checked at construction).
"""

from __future__ import annotations

import warnings

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import basix
import basix.ufl
import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import ufl

from . import forms
from .forms.kinematics import (
    DeformationGradients,
    DeviatoricForces,
    TangentStiffness,
    VolumetricForces,
)
from .material import ElastoPlastic, HenckyJ2

#: the Q1 hexahedron's vertices in dolfinx's lexicographic order (x fastest) on the unit cube
HEX_VERTICES = np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)])


def _hex_reference_gradients(xi: np.ndarray) -> np.ndarray:
    """(8, 3) gradients of the Q1 shape functions on the unit cube at the point ``xi`` (3,)."""
    factors = np.where(HEX_VERTICES == 1, xi, 1.0 - xi)  # the 1D shape functions at xi
    signs = np.where(HEX_VERTICES == 1, 1.0, -1.0)
    return np.stack(
        [
            signs[:, 0] * factors[:, 1] * factors[:, 2],
            factors[:, 0] * signs[:, 1] * factors[:, 2],
            factors[:, 0] * factors[:, 1] * signs[:, 2],
        ],
        axis=1,
    )


_GAUSS_1D = (0.5 - 0.5 / np.sqrt(3.0), 0.5 + 0.5 / np.sqrt(3.0))
#: (8, 8, 3) the Q1 reference gradients at the 2x2x2 Gauss points of the unit cube (weights 1/8
#: each)
HEX_GAUSS_GRADIENTS = np.array(
    [
        _hex_reference_gradients(np.array(xi))
        for xi in np.array(np.meshgrid(*[_GAUSS_1D] * 3, indexing="ij")).reshape(3, -1).T
    ]
)
#: (8, 3) the Q1 reference gradients at the centre, the point of the volumetric part
#: (forms.QuadratureRules)
HEX_CENTRE_GRADIENTS = _hex_reference_gradients(np.full(3, 0.5))


def hexahedron_gradients(
    x: np.ndarray, reference_gradients: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """det J (n,) and the physical shape-function gradients (n, 8, 3) (1/mm) of Q1 hexahedra with
    vertices ``x`` (n, 8, 3) (mm, lexicographic) at one point given by its ``reference_gradients``
    (8, 3); cells with det J = 0 there get zero gradients."""
    J = np.einsum("cai,aj->cij", x, reference_gradients)
    det = np.linalg.det(J)
    inverse = np.zeros_like(J)
    good = det != 0.0
    inverse[good] = np.linalg.inv(J[good])
    return det, np.einsum("aj,cji->cai", reference_gradients, inverse)


def hexahedron_gauss_length(x: np.ndarray, reference: np.ndarray | None = None) -> np.ndarray:
    """A stable-increment length of Q1 hexahedra with vertices ``x`` (n, 8, 3) (mm, lexicographic
    order) from the Flanagan-Belytschko bound over the 2x2x2 Gauss points: with lumped mass
    rho V / 8 the element's highest frequency satisfies
    omega^2 <= (lambda + 2 mu) / rho * 8 / V * sum_g w_g det J_g sum_a |grad N_a(g)|^2 = omega_FB^2,
    returned as L = (8 / sqrt(3)) c_d / omega_FB: the undistorted cube of edge h (omega_FB = 8 c_d /
    (sqrt(3) h)) gets exactly h, the length L / c_d of a regular grid. It bounds omega_e L / c_d by
    8 / sqrt(3) = 4.62 for every valid cell (the cube: 3.19 at nu = 0.435), where the vertex
    distances and volume / face area let a folded cell reach 8.7 (measured, bench/README.md).
    With the ``reference`` vertices (n, 8, 3) of deformed cells, the weights det J_g and V are the
    reference ones: the Hencky moduli act on the Kirchhoff stress, so the tangent per current
    volume grows as 1 / J at a Gauss point (the spatial modulus c_tau / J), and the mass is
    the reference one; a cell squeezed at one Gauss point (J ~ 0.02 there, its centre intact,
    which the centre-point volume of the selective reduced integration does not resist) gets the
    stiffness it has. Cells whose Jacobian vanishes at a Gauss point get length 0."""
    n = x.shape[0]
    gradient_sum = np.zeros(n)
    volume = np.zeros(n)
    for reference_gradients in HEX_GAUSS_GRADIENTS:
        det, grad = hexahedron_gradients(x, reference_gradients)
        weight = np.abs(
            det
            if reference is None
            else np.linalg.det(np.einsum("cai,aj->cij", reference, reference_gradients))
        )
        gradient_sum += weight / 8.0 * np.sum(grad * grad, axis=(1, 2))  # Gauss weight 1/8
        gradient_sum[det == 0.0] = np.inf
        volume += weight / 8.0
    # omega_FB^2 / c_d^2 = 8 gradient_sum / volume; L = (8 / sqrt(3)) / sqrt(that)
    return 8.0 / np.sqrt(3.0) / np.sqrt(8.0 * gradient_sum / np.where(volume > 0.0, volume, np.inf))


class SolidProblem:
    """Finite-strain elastoplastic bulk on a (multi-particle) mesh.

    Args:
        mesh: DOLFINx mesh (mm); hexahedra (Q1 + SRI) or tetrahedra (P1/P2).
        material: particle material (MPa, t/mm^3).
        degree: displacement degree (default: the geometry degree).
        tangent: also compute the consistent tangent and compile the Jacobian (implicit solver).
        active_cells: cells carrying material (default all; CLP copies are stiffless shells).
        full_integration: integrate the volumetric part with the deviatoric rule (no SRI): the
            locking element, kept to show what the reduced rule avoids.
    """

    def __init__(
        self,
        mesh: dolfinx.mesh.Mesh,
        material: ElastoPlastic,
        *,
        degree: int | None = None,
        tangent: bool = True,
        active_cells: np.ndarray | None = None,
        full_integration: bool = False,
    ):
        self.mesh = mesh
        self.params = material
        self.comm = mesh.comm
        cell_name = mesh.topology.cell_name()
        degree = degree or mesh.geometry.cmaps[0].degree
        self.V = dolfinx.fem.functionspace(mesh, ("Lagrange", degree, (3,)))
        self.u = dolfinx.fem.Function(self.V, name="displacement")
        self.rules = forms.QuadratureRules.for_cell(cell_name, degree)
        if (
            full_integration
        ):  # the volumetric part on the deviatoric rule too (locks: for comparisons)
            self.rules = forms.QuadratureRules(self.rules.deviatoric, self.rules.deviatoric)
        if cell_name == "tetrahedron" and degree == 1:
            warnings.warn(
                "P1 tetrahedra lock under isochoric plastic flow (one constraint per "
                "cell, no reduced rule): use hexahedra (SRI) or tet_order=2",
                stacklevel=2,
            )

        tdim = mesh.topology.dim
        self.num_cells = mesh.topology.index_map(tdim).size_local
        self.cells = np.arange(self.num_cells, dtype=np.int32)
        cell_type = getattr(basix.CellType, cell_name)
        self.points, self.weights = basix.make_quadrature(cell_type, self.rules.deviatoric)
        self.points_per_cell = self.weights.size
        nq = self.num_cells * self.points_per_cell

        def quadrature_function(shape, name):
            element = basix.ufl.quadrature_element(
                cell_name, value_shape=shape, degree=self.rules.deviatoric
            )
            fn = dolfinx.fem.Function(dolfinx.fem.functionspace(mesh, element), name=name)
            # the kernel writes (cell, point, component) in order: check the dof layout is that
            dofs = fn.function_space.dofmap.list[: self.num_cells]
            if not np.array_equal(dofs.ravel(), np.arange(dofs.size)):
                raise RuntimeError("unexpected quadrature dof layout; cannot write state in place")
            return fn

        self.active = np.ones(self.num_cells, dtype=bool)
        if active_cells is not None:
            self.active[:] = False
            self.active[np.asarray(active_cells, dtype=np.int64)] = True
        #: cells whose quadrature points carry material state (all, or the active ones)
        self.material_cells = np.flatnonzero(self.active).astype(np.int32)
        self._all_active = self.material_cells.size == self.num_cells
        nq_mat = self.material_cells.size * self.points_per_cell

        self.P_dev = quadrature_function((3, 3), "P_dev")
        self.A_dev = quadrature_function((3, 3, 3, 3), "A_dev") if tangent else None
        size = nq * 9
        # all cells active: the kernel writes straight into the quadrature Functions; otherwise it
        # works on the active points and update_material scatters the result
        self.material = HenckyJ2(
            material,
            nq_mat,
            tangent,
            P_dev=self.P_dev.x.array[:size].reshape(nq, 3, 3) if self._all_active else None,
            A_dev=self.A_dev.x.array[: size * 9].reshape(nq, 3, 3, 3, 3)
            if tangent and self._all_active
            else None,
        )

        F = forms.deformation_gradient(self.u)
        self._F_expr = dolfinx.fem.Expression(F, self.points)
        # threaded numba evaluation of the same F when it reproduces the Expression (Q1, P1, P2)
        self._F_kernel = DeformationGradients(self.u, self.points, self.material_cells)
        if not self._F_kernel.matches():
            self._F_kernel = None
        detJ = dolfinx.fem.Expression(abs(ufl.JacobianDeterminant(mesh)), self.points)
        jac = detJ.eval(mesh, self.material_cells).reshape(-1, self.points_per_cell)
        #: reference volume (mm^3) carried by each material point
        self.point_volumes = (jac * self.weights[None, :]).ravel()

        marker = dolfinx.mesh.meshtags(mesh, tdim, self.cells, self.active.astype(np.int32))
        self.dx = ufl.Measure("dx", domain=mesh, subdomain_data=marker)

        def measure(degree):
            return self.dx(1, metadata={"quadrature_degree": degree})

        self._measure = measure
        self.dx_dev = measure(self.rules.deviatoric)
        self.dx_vol = measure(self.rules.volumetric)
        v = ufl.TestFunction(self.V)
        du = ufl.TrialFunction(self.V)
        bulk = dolfinx.fem.Constant(mesh, float(material.bulk))
        J = ufl.det(forms.deformation_gradient(self.u))
        self._volumetric_energy = dolfinx.fem.form(0.5 * bulk * ufl.ln(J) ** 2 * self.dx_vol)
        #: residual / Jacobian parts (deviatoric, volumetric), assembled one after the other
        self.residual_ufl = forms.internal_work(
            self.u, v, self.P_dev, bulk, self.dx_dev, self.dx_vol
        )
        self.residual_forms = [dolfinx.fem.form(f) for f in self.residual_ufl]
        self.jacobian_forms = None
        if tangent:
            self.jacobian_forms = [
                dolfinx.fem.form(f)
                for f in forms.internal_work_tangent(
                    self.u, du, v, self.A_dev, bulk, self.dx_dev, self.dx_vol
                )
            ]
        # The deviatoric forms' only coefficient is the kernel's output, whose (point, component)
        # layout per material cell is exactly DOLFINx's packed layout: hand it over as the packed
        # coefficients instead of letting every assembly gather it again (a copy of 72 (P_dev) or
        # 648 (A_dev) values per cell, ~10 % of an explicit step).
        self._residual_key = self._packed_key(self.residual_forms[0], 9)
        # the same deviatoric force by a numba loop with the inverse Jacobians stored (35-40 %
        # less time than the FFCx assembly on hexahedra), when it reproduces the form
        self._deviatoric_forces = DeviatoricForces(
            self.V, self.points, self.material_cells, self.point_volumes
        )
        if not self._deviatoric_forces.matches(
            self.residual_forms[0], self.P_dev, self.material.P_dev
        ):
            self._deviatoric_forces = None
        # the volumetric (SRI) force likewise; its points serve the explicit solver's bulk viscosity
        self._bulk = float(material.bulk)
        self.volumetric_forces = VolumetricForces(
            self.V, *basix.make_quadrature(cell_type, self.rules.volumetric), self.material_cells
        )
        self._volumetric_loop = self.volumetric_forces.reproduces(
            self.residual_forms[1],
            lambda array: self.volumetric_forces.add_volumetric(self.u, self._bulk, array),
            [(self.u, 1.0)],
        )
        self._jacobian_key = self._packed_key(self.jacobian_forms[0], 81) if tangent else None
        # the tangent stiffness likewise (half the time of the FFCx assembly on hexahedra)
        self._tangent_loop = None
        if tangent:
            self._tangent_loop = TangentStiffness(
                self.V, self.points, self.material_cells, self.point_volumes, self.volumetric_forces
            )
            if not self._tangent_loop.matches(
                self.jacobian_forms, self.A_dev, self.material.A_dev, self.u, self._bulk
            ):
                self._tangent_loop = None
        # per-cell integrals of the Kirchhoff stress, on the residual's own quadrature rules
        self._cell_tensors = dolfinx.fem.functionspace(mesh, ("DG", 0, (3, 3)))
        w = ufl.TestFunction(self._cell_tensors)
        self._stress_integral_forms = [
            dolfinx.fem.form(f)
            for f in forms.kirchhoff_stress_integrals(
                self.u, w, self.P_dev, bulk, self.dx_dev, self.dx_vol
            )
        ]

    def _packed_key(self, form, width: int):
        """Key of the form's packed coefficients if they are exactly the material array with
        ``width`` values per point (one cell integral, one coefficient), else None."""
        packed = dolfinx.fem.pack_coefficients(form)
        rows = self.material_cells.size
        if len(packed) != 1:
            return None
        ((key, array),) = packed.items()
        return key if array.shape == (rows, self.points_per_cell * width) else None

    def _material_coefficients(self, key, values: np.ndarray):
        """The material array as a deviatoric form's packed coefficients (None: let DOLFINx
        pack)."""
        return None if key is None else {key: values.reshape(self.material_cells.size, -1)}

    # -- assembly -----------------------------------------------------------------------------
    def create_vector(self) -> PETSc.Vec:
        """A new PETSc vector on the displacement space (with ghosts), for residuals (N)."""
        return dolfinx.fem.petsc.create_vector(self.V)

    def create_matrix(self) -> PETSc.Mat:
        """A new PETSc matrix with the Jacobian's sparsity pattern (N/mm)."""
        return dolfinx.fem.petsc.create_matrix(self.jacobian_forms[0])

    def assemble_residual(self, b: PETSc.Vec) -> None:
        """b = internal force (N) at the current material state, ghost contributions summed."""
        with b.localForm() as loc:
            loc.set(0.0)
        for k, form in enumerate(self.residual_forms):
            if k == 0 and self._deviatoric_forces is not None:
                with b.localForm() as loc:
                    self._deviatoric_forces.add_to(self.material.P_dev, loc.array)
                continue
            if k == 1 and self._volumetric_loop:
                with b.localForm() as loc:
                    self.volumetric_forces.add_volumetric(self.u, self._bulk, loc.array)
                continue
            coeffs = (
                self._material_coefficients(self._residual_key, self.material.P_dev)
                if k == 0
                else None
            )
            dolfinx.fem.petsc.assemble_vector(b, form, coeffs=coeffs)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)

    def assemble_jacobian(self, K: PETSc.Mat) -> None:
        """K = consistent tangent stiffness (N/mm) at the current material state."""
        K.zeroEntries()
        if self._tangent_loop is not None:
            self._tangent_loop.add_to(self.material.A_dev, self.u, self._bulk, K)
            K.assemble()
            return
        for k, form in enumerate(self.jacobian_forms):
            coeffs = (
                self._material_coefficients(self._jacobian_key, self.material.A_dev)
                if k == 0
                else None
            )
            dolfinx.fem.petsc.assemble_matrix(K, form, coeffs=coeffs)
            K.assemble(PETSc.Mat.AssemblyType.FLUSH)
        K.assemble()

    # -- material --------------------------------------------------------------------------
    def deformation_gradients(self) -> np.ndarray:
        """F (n, 3, 3) at the material points, in (cell, point) order (a reused buffer)."""
        if self._F_kernel is not None:
            return self._F_kernel()
        return self._F_expr.eval(self.mesh, self.material_cells).reshape(-1, 3, 3)

    def update_material(self, tangent: bool = False) -> None:
        """Return mapping at the current u (trial state; call :meth:`commit` when converged)."""
        self.material.update(self.deformation_gradients(), tangent)
        if not self._all_active:
            width = self.points_per_cell * 9
            cells = self.material_cells
            self.P_dev.x.array[: self.num_cells * width].reshape(self.num_cells, width)[cells] = (
                self.material.P_dev.reshape(cells.size, width)
            )
            if tangent:
                self.A_dev.x.array[: self.num_cells * width * 9].reshape(self.num_cells, width * 9)[
                    cells
                ] = self.material.A_dev.reshape(cells.size, width * 9)

    def commit(self) -> None:
        """Accept the material's trial state (and its plastic work increment) as converged."""
        self.material.commit()

    # -- integrals over the particles (summed over ranks) -------------------------------------
    def integrate_points(self, values: np.ndarray) -> float:
        """sum_q values_q dV_q over all points of all ranks (reference volume weights)."""
        return self.comm.allreduce(float(self.point_volumes @ values), op=MPI.SUM)

    def cell_stress_integrals(self) -> np.ndarray:
        """int_cell sigma dv (N mm, (num owned cells, 3, 3), mechanics sign, tension > 0) of every
        owned cell at the current trial state; zero on inactive cells.

        The Cauchy stress integrated over the deformed cell equals the Kirchhoff stress
        tau = P F^T integrated over the reference cell (dv = J dV), here with the quadrature rules
        of the internal force (deviatoric part at the 8 points, K ln J I at the SRI point), so that
        the sum over a particle is sum_nodes f_int (x) x, the stress its internal forces carry."""
        values = np.zeros(self._cell_tensors.dofmap.index_map.size_local * 9)
        for form in self._stress_integral_forms:
            vec = dolfinx.fem.assemble_vector(form)
            values += vec.array[: values.size]
        cells = self._cell_tensors.dofmap.list[: self.num_cells, 0]
        return values.reshape(-1, 3, 3)[cells]

    def plastic_work(self, cells: np.ndarray | None = None) -> float:
        """Committed plastic work (mJ) of the given owned cells (boolean mask over the owned cells,
        default all), summed over ranks: the material points' tallies of :meth:`commit`."""
        work = self.material.plastic_work.reshape(self.material_cells.size, -1)
        if cells is not None:
            work = work * np.asarray(cells, dtype=bool)[self.material_cells, None]
        return self.integrate_points(work.ravel())

    def plastic_dissipation_increment(self) -> float:
        """Plastic work of the current (trial) increment, mJ = N mm."""
        return self.integrate_points(self.material.dissipation)

    def stored_energy(self) -> float:
        """Hencky elastic energy of the current trial state, mJ: deviatoric part at the
        quadrature points + volumetric part 1/2 K ln(J)^2 with the volumetric (SRI) rule, i.e.
        the energy whose derivative is the internal force actually assembled."""
        volumetric = self.comm.allreduce(
            dolfinx.fem.assemble_scalar(self._volumetric_energy), op=MPI.SUM
        )
        return self.integrate_points(self.material.psi) + volumetric

    def lumped_mass(self, density) -> dolfinx.fem.Function:
        """Row-sum lumped mass per dof (t) as a Function (ghosts updated); ``density`` (t/mm^3)
        is a number or a (e.g. mass-scaled, cell-wise) Function."""
        v = ufl.TestFunction(self.V)
        dx = self._measure(2 * self.V.element.basix_element.degree)
        m = dolfinx.fem.Function(self.V, name="lumped_mass")
        vec = dolfinx.fem.petsc.assemble_vector(
            dolfinx.fem.form(forms.lumped_mass_action(density, v, dx))
        )
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        m.x.petsc_vec.array[:] = vec.array_r
        m.x.scatter_forward()
        vec.destroy()
        return m

    def min_cell_length(self, deformed: bool = False) -> np.ndarray:
        """Characteristic length of each owned cell (mm) for the explicit stable increment, in the
        reference configuration or (``deformed``) at the current displacement (P1/Q1 nodes): the
        smallest vertex-to-vertex distance, and for hexahedra also the volume / largest face area,
        which catches flattened (sheared) cells whose edges keep their lengths, and
        :func:`hexahedron_gauss_length`, which catches folded cells (a corner pushed inside) that
        both miss (bench/README.md, ``element_frequencies.py``)."""
        geom = self.mesh.geometry
        reference = None
        if deformed:
            nodes = self.V.tabulate_dof_coordinates()
            reference = nodes[self.V.dofmap.list[: self.num_cells]]
            x = (nodes + self.u.x.array.reshape(-1, 3))[self.V.dofmap.list[: self.num_cells]]
        else:
            x = geom.x[geom.dofmaps[0][: self.num_cells]]
        nv = x.shape[1]
        i, j = np.triu_indices(nv, 1)
        d = np.linalg.norm(x[:, i] - x[:, j], axis=-1).min(axis=1)
        if nv == 8 and self.mesh.topology.cell_name() == "hexahedron":  # lexicographic vertices
            jac = (
                np.stack(
                    [
                        (
                            x[:, 1]
                            - x[:, 0]
                            + x[:, 3]
                            - x[:, 2]
                            + x[:, 5]
                            - x[:, 4]
                            + x[:, 7]
                            - x[:, 6]
                        ),
                        (
                            x[:, 2]
                            - x[:, 0]
                            + x[:, 3]
                            - x[:, 1]
                            + x[:, 6]
                            - x[:, 4]
                            + x[:, 7]
                            - x[:, 5]
                        ),
                        (
                            x[:, 4]
                            - x[:, 0]
                            + x[:, 5]
                            - x[:, 1]
                            + x[:, 6]
                            - x[:, 2]
                            + x[:, 7]
                            - x[:, 3]
                        ),
                    ],
                    axis=-1,
                )
                / 4.0
            )
            volume = np.abs(np.linalg.det(jac))  # centre-point volume
            faces = np.array(
                [[0, 1, 2, 3], [4, 5, 6, 7], [0, 1, 4, 5], [2, 3, 6, 7], [0, 2, 4, 6], [1, 3, 5, 7]]
            )
            area = 0.5 * np.linalg.norm(
                np.cross(
                    x[:, faces[:, 3]] - x[:, faces[:, 0]], x[:, faces[:, 2]] - x[:, faces[:, 1]]
                ),
                axis=-1,
            ).max(axis=1)
            d = np.minimum(np.minimum(d, volume / area), hexahedron_gauss_length(x, reference))
        return d
