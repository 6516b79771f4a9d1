"""Time of the material update and of the residual / Jacobian assembly on a 50-particle mesh.

    python bench/material_assembly.py [--particles 50] [--refinement 1] [--repeat 5]
    mpirun -n 2 python bench/material_assembly.py

Prints one JSON object: mesh size, and for each phase the median wall time (s) and the time per
quadrature point (us/qp, wall time x ranks / global points, i.e. the cost of one point on one
core). Particles are cube-sphere hexahedra (default 517 nodes, 448 cells, 8 points per cell),
placed on a 5 x 5 x 2 grid, deformed by a homogeneous compression with plastic flow.
"""

import argparse
import json
import platform
import time

import numpy as np
from mpfem_fenicsx.meshes import particle_mesh
from mpi4py import MPI
from petsc4py import PETSc
from timing import median_time

import dolfinx.fem.petsc

import mpfem_fenicsx  # noqa: F401
from mpfem_fenicsx.material import LEAD
from mpfem_fenicsx.problem import SolidProblem


def main():
    """Print one JSON object: mesh size and the median wall time (s) and us/qp of each phase."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--particles", type=int, default=50)
    parser.add_argument("--refinement", type=int, default=1)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    n = args.particles
    grid = np.array([(i, j, k) for k in range(10) for j in range(10) for i in range(10)])[:n]
    centres = 2.2 * grid.astype(float)
    radii = np.ones(n)
    t0 = time.perf_counter()
    assembly = particle_mesh(centres, radii, comm, refinement=args.refinement)
    problem = SolidProblem(assembly.mesh, LEAD, tangent=True)
    setup = time.perf_counter() - t0
    u = problem.u
    u.interpolate(lambda x: np.array([-0.05 * x[0], -0.03 * x[1], 0.02 * x[2] + 0.01 * x[0]]))
    b = problem.create_vector()
    K = problem.create_matrix()

    problem.update_material(tangent=True)  # JIT warm-up
    problem.assemble_residual(b)
    problem.assemble_jacobian(K)

    def compiled_jacobian():
        """The Jacobian by FFCx's compiled forms alone (the deviatoric loop's reference)."""
        K.zeroEntries()
        for form in problem.jacobian_forms:
            dolfinx.fem.petsc.assemble_matrix(K, form)
            K.assemble(PETSc.Mat.AssemblyType.FLUSH)
        K.assemble()

    phases = {
        "deformation_gradient_expression": lambda: problem._F_expr.eval(
            problem.mesh, problem.material_cells
        ),
        "deformation_gradient_eval": problem.deformation_gradients,
        "material_update_stress": lambda: problem.update_material(tangent=False),
        "material_update_stress_tangent": lambda: problem.update_material(tangent=True),
        "residual_assembly": lambda: problem.assemble_residual(b),
        "jacobian_assembly": lambda: problem.assemble_jacobian(K),
        "jacobian_assembly_compiled_forms": compiled_jacobian,
    }
    qp_global = comm.allreduce(problem.material.num_points, op=MPI.SUM)
    result = {
        "case": f"{n} cube-sphere particles, refinement {args.refinement}",
        "ranks": comm.size,
        "numba_threads": __import__("numba").get_num_threads(),
        "cells": assembly.mesh.topology.index_map(3).size_global,
        "nodes_per_particle": assembly.mesh.geometry.index_map().size_global // n,
        "dofs": problem.V.dofmap.index_map.size_global * 3,
        "quadrature_points": qp_global,
        "setup_s": setup,
        "machine": platform.processor() or platform.machine(),
        "phases": {},
    }
    for name, fn in phases.items():
        wall = median_time(fn, args.repeat, comm)
        result["phases"][name] = {"wall_s": wall, "us_per_qp": 1e6 * wall * comm.size / qp_global}
    if comm.rank == 0:
        print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
