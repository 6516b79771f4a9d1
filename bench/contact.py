"""Cost of contact search + contact forces (and tangent) versus the number of particles.

    python bench/contact.py [--particles 50 150 350] [--repeat 5]

Particles (default cube-sphere mesh, radius 1 +/- 10 %) sit on a jittered cubic lattice of
spacing 1.95 so that each one overlaps its neighbours slightly, as in a lightly compressed
packing (the packing generator arrives with the granular-volume capability). Prints one JSON
object per size: surface nodes, contact points, and the median time (s) of the search, of the
forces (law + assembly into a PETSc vector) and of the tangent, with the time per surface node.
"""

import argparse
import json

import numpy as np
from mpfem_fenicsx.meshes import particle_mesh
from mpi4py import MPI
from timing import median_time

from mpfem_fenicsx.contact import ContactLaw, ContactModel
from mpfem_fenicsx.material import LEAD
from mpfem_fenicsx.problem import SolidProblem


def lattice(n: int, seed: int = 0):
    """Centres (n, 3) on a jittered cubic lattice of spacing 1.95 and radii in [0.95, 1.05]."""
    side = int(np.ceil(n ** (1 / 3)))
    grid = np.array([(i, j, k) for k in range(side) for j in range(side) for i in range(side)])[:n]
    rng = np.random.default_rng(seed)
    centres = 1.95 * grid + rng.uniform(-0.02, 0.02, (n, 3))
    radii = rng.uniform(0.95, 1.05, n)
    return centres, radii


def main():
    """Print one JSON object of contact search, force and tangent times (s) per particle count."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--particles", type=int, nargs="+", default=[50, 150, 350])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    for n in args.particles:
        centres, radii = lattice(n)
        assembly = particle_mesh(centres, radii, comm)
        problem = SolidProblem(assembly.mesh, LEAD, tangent=False)
        law = ContactLaw(penalty=1e6, friction=0.1, gamma=1e-3, delta_max=5e-4)
        contact = ContactModel(problem.V, assembly.facet_tags, n, law, search_distance=0.05)
        surface = contact.surface
        x = surface.X + surface.gather(problem.u)
        vec = problem.create_vector()
        contact.evaluate(problem.u, tangent=True)  # JIT warm-up

        def forces(contact=contact, problem=problem, vec=vec):
            contact.evaluate(problem.u, tangent=False)
            contact.add_residual(vec)

        t_search = median_time(lambda contact=contact, x=x: contact.search(x), args.repeat, comm)
        t_forces = median_time(forces, args.repeat, comm)
        template = _template(problem)
        t_tangent = median_time(
            lambda contact=contact, problem=problem, template=template: (
                contact.evaluate(problem.u, tangent=True),
                contact.tangent_matrix(template),
            ),
            args.repeat,
            comm,
        )
        points = comm.allreduce(contact.evaluation.size, op=MPI.SUM)
        nodes = comm.allreduce(surface.num_owned, op=MPI.SUM)  # the whole surface
        result = {
            "particles": n,
            "ranks": comm.size,
            "surface_nodes": int(nodes),
            "contact_points": int(points),
            "search_s": t_search,
            "forces_s": t_forces,
            "forces_and_tangent_s": t_tangent,
            "search_us_per_surface_node": 1e6 * t_search / nodes,
            "forces_us_per_surface_node": 1e6 * t_forces / nodes,
        }
        if comm.rank == 0:
            print(json.dumps(result))


def _template(problem):
    """A matrix with the layout of the displacement space."""
    import dolfinx.fem.petsc
    import ufl

    u, v = ufl.TrialFunction(problem.V), ufl.TestFunction(problem.V)
    return dolfinx.fem.petsc.create_matrix(dolfinx.fem.form(ufl.inner(u, v) * ufl.dx))


if __name__ == "__main__":
    main()
