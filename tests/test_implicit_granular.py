"""The implicit solver on granular volumes: the AMG preconditioner's rigid-body modes, the
iterative linear solver against the direct one, the pseudo-time drag on the particles' cores."""

from pathlib import Path

import numpy as np
import pytest
from mpfem_fenicsx.meshes import node_particles, particle_mesh
from mpi4py import MPI
from petsc4py import PETSc

from mpfem_fenicsx.case import CompactionCase
from mpfem_fenicsx.constraints.affine import AffineConstraint
from mpfem_fenicsx.material import ElastoPlastic
from mpfem_fenicsx.problem import SolidProblem
from mpfem_fenicsx.solvers.implicit import DEFAULT_OPTIONS, FORCE_RTOL, rigid_body_modes
from mpfem_fenicsx.workflows import compaction
from mpfem_fenicsx.workflows.compaction import (
    DRAG_CORE_RADIUS,
    build_compaction,
    core_drag,
    held_drag,
    run_compaction,
)
from test_granular import quiet, small_case


def first_contacts_case(path, **kw):
    """The simple cubic cell (CLP by images) compacted by Newton to its first contacts: 24
    contacts form in one load step."""
    return small_case(
        path, condition="CLP", kind="implicit", images=True, target_density=0.5245, steps=1, **kw
    )


def tight_newton(patch: pytest.MonkeyPatch) -> None:
    """Newton to the absolute residual tolerance (1e-9 N) rather than 1e-9 of the first residual
    (~3e-8 N) or the granular volumes' tolerance on the forces (FORCE_RTOL): two linear solvers
    then give one solution to round-off, not to Newton's tolerance."""
    patch.setitem(DEFAULT_OPTIONS, "snes_rtol", 1e-12)
    patch.setattr(compaction, "FORCE_RTOL", 0.0)


@pytest.fixture(scope="module")
def first_contacts(tmp_path_factory):
    """:func:`first_contacts_case` run by Newton (:func:`tight_newton`) with the direct linear
    solver."""
    case = first_contacts_case(tmp_path_factory.mktemp("direct"), linear_solver="direct")
    with pytest.MonkeyPatch.context() as patch:
        tight_newton(patch)
        return run_compaction(case, MPI.COMM_SELF, log=quiet)


def test_rigid_body_modes_span_the_stiffness_nullspace_of_a_free_particle():
    """The six modes are orthonormal and the assembled tangent of an unconstrained particle maps
    each to zero (round-off of K's entries), while a deformation mode is not in its nullspace."""
    mesh = particle_mesh([[0.0, 0.0, 0.0]], [1.0], MPI.COMM_SELF).mesh
    problem = SolidProblem(mesh, ElastoPlastic(), tangent=True)
    constraint = AffineConstraint(problem.V, np.zeros(0, np.int64))
    K = problem.create_matrix()
    problem.update_material(tangent=True)
    problem.assemble_jacobian(K)
    n = problem.V.dofmap.index_map.size_local
    X = problem.V.tabulate_dof_coordinates()[:n]
    modes = rigid_body_modes(constraint, X + np.array([0.3, -0.2, 0.1]))
    gram = np.array([[a.dot(b) for b in modes] for a in modes])
    assert np.abs(gram - np.eye(6)).max() < 1e-12
    scale = K.norm(PETSc.NormType.INFINITY)
    y = modes[0].duplicate()
    for v in modes:
        K.mult(v, y)
        assert y.norm(PETSc.NormType.INFINITY) < 1e-10 * scale
    stretch = modes[0].duplicate()  # u = (x, 0, 0): a uniaxial strain
    stretch.array_w[:] = np.where(constraint.free % 3 == 0, X[constraint.free // 3, 0], 0.0)
    K.mult(stretch, y)
    assert y.norm(PETSc.NormType.INFINITY) > 1e-3 * scale * stretch.norm(PETSc.NormType.INFINITY)


def test_drag_rides_on_the_particle_cores_with_its_total_per_particle(tmp_path):
    """The drag stiffness sits on the nodes within the core radius only, and each particle's
    sum is factor x E V_p / h^2 with V_p its finite-element volume (the nodal volumes' sum)."""
    model = build_compaction(small_case(tmp_path, kind="implicit"), MPI.COMM_SELF, log=quiet)
    k = core_drag(model, 0.05).reshape(-1, 3)[:, 0]
    problem = model.problem
    X = problem.V.tabulate_dof_coordinates()[: k.size]
    particle = node_particles(problem.V, model.assembly.cell_tags.values[: problem.num_cells])
    distance = np.linalg.norm(X - model.centres[particle], axis=1)
    volume = problem.lumped_mass(1.0).x.array[: 3 * k.size : 3]
    solid = np.bincount(particle, weights=volume)
    assert np.count_nonzero(solid) == 8  # the cell's particles (the copies: massless shells)
    inner = distance < DRAG_CORE_RADIUS * model.radii[particle]
    assert np.all(k[~inner] == 0.0)
    assert np.all(k[inner & (solid[particle] > 0)] > 0.0)
    expected = 0.05 * problem.params.E / model.contact_length**2
    totals = np.bincount(particle, weights=k)[solid > 0] / solid[solid > 0]
    assert totals == pytest.approx(np.full(totals.size, expected), rel=1e-12)


def test_drag_weakens_on_the_particles_their_contacts_hold(tmp_path, first_contacts):
    """held_drag: the core drag at ``regularization`` on a particle with fewer than 4
    force-carrying contacts, at ``held_regularization`` on the others. Before contact every
    particle has the full drag; the simple cubic cell compacted by Newton (6 contacts each)
    ends with every particle held, and the solver carries that drag; on a contact list given
    by hand, a particle with 3 loaded pairs and one with its own image (counted twice) is held,
    one with 3 loaded pairs and an unloaded fourth is not."""
    case = first_contacts_case(tmp_path)
    section = case.solver
    ratio = section.held_regularization / section.regularization
    assert ratio < 0.1
    model = build_compaction(case, MPI.COMM_SELF, log=quiet)
    full = core_drag(model, section.regularization)
    assert np.array_equal(held_drag(model, section)(), full)  # no contact yet
    result = first_contacts
    update = held_drag(result.model, section)
    assert update() == pytest.approx(full * ratio, rel=1e-12)
    assert result.solver.regularization.array_r == pytest.approx(full * ratio, rel=1e-12)
    # by hand: bodies 0 (pairs with 1, 2, 3 and its own image), 1 (0, 2, 4 loaded, 5 unloaded)
    pairs = np.array([[0, 1], [0, 2], [0, 3], [0, 0], [1, 2], [1, 4], [1, 5]])
    points = np.array([3, 1, 2, 5, 1, 1, 0])
    model.contact.pair_forces = lambda: {"pairs": pairs, "points": points}
    k = held_drag(model, section)().reshape(-1, 3)[:, 0]
    particle = node_particles(model.problem.V, model.assembly.cell_tags.values)[: k.size]
    expected = full.reshape(-1, 3)[:, 0] * np.where(particle == 0, ratio, 1.0)
    assert k == pytest.approx(expected, rel=1e-12)


def test_iterative_linear_solver_gives_the_direct_solution(tmp_path, first_contacts, monkeypatch):
    """The simple cubic cell compacted by Newton to its first contacts (24 in one load
    step) with GMRES + smoothed-aggregation AMG (the rigid-body near-nullspace) and with
    MUMPS: the same displacements to 1e-8 of their size (2.9e-12 measured), the same stresses;
    the iterative run reports its Krylov iterations (~60 per Newton iteration)."""
    tight_newton(monkeypatch)
    case = first_contacts_case(tmp_path, linear_solver="iterative")
    runs = {"direct": first_contacts, "iterative": run_compaction(case, MPI.COMM_SELF, log=quiet)}
    u = {s: r.model.problem.u.x.array for s, r in runs.items()}
    assert np.abs(u["iterative"] - u["direct"]).max() < 1e-8 * np.abs(u["direct"]).max()
    sigma = {s: r.history.column("sigma_m") for s, r in runs.items()}
    assert sigma["iterative"] == pytest.approx(sigma["direct"], rel=1e-7, abs=1e-9)
    assert sigma["direct"][-1] > 0.01  # MPa: the cell was compacted
    linear = runs["iterative"].history.column("linear_iterations")
    assert np.all(linear > runs["iterative"].history.column("newton_iterations"))


def test_newton_stops_at_the_force_tolerance(tmp_path, monkeypatch):
    """The granular volumes' step control ends Newton once its residual is at most FORCE_RTOL of
    the internal forces' norm at the step's start: the simple cubic cell pressed past its first
    contacts in four steps (the last two start loaded) ends its last step in fewer iterations than
    to the absolute tolerance, at a residual between 1e-9 N and that bound, and in the same state
    to that accuracy (displacements within 1e-4 of their size, sigma_m within 1e-4)."""
    runs = {}
    for name in ("loose", "tight"):
        if name == "tight":
            tight_newton(monkeypatch)
        case = first_contacts_case(tmp_path / name, linear_solver="direct")
        runs[name] = run_compaction(
            case.updated(target_density=0.53, steps=4), MPI.COMM_SELF, log=quiet
        )
    result, tight = runs["loose"], runs["tight"]
    assert result.history.column("n_contacts")[-2] > 0  # the last step starts loaded
    solver = result.solver
    bound = FORCE_RTOL * solver._internal_force_norm()  # the end's: above the start's
    norms = solver.residual_norms
    assert 1e-9 < norms[-1] <= bound, (norms, bound)
    its = result.history.column("newton_iterations")[-1]
    assert its < tight.history.column("newton_iterations")[-1]
    u, u_tight = result.model.problem.u.x.array, tight.model.problem.u.x.array
    assert np.abs(u - u_tight).max() < 1e-4 * np.abs(u_tight).max()
    sigma = result.history.column("sigma_m")[-1]
    assert sigma == pytest.approx(tight.history.column("sigma_m")[-1], rel=1e-4)


def test_newton_converges_superlinearly_through_the_first_contacts(first_contacts):
    """Newton's iterations per load step are bounded, and the contact tangent (normal penalty,
    stick and slip, thesis eq. 3.14-3.17) keeps it superlinear: the simple cubic cell's 24 first
    contacts form in one load step within 8 iterations (4 measured; 15 when the predictor
    loaded the drag with the offsets' motion), and the last iterations converge at an order
    above 1.5 (the residual 2e-2 -> 8e-5 -> 8e-9 N: ~1.6 measured) to the absolute tolerance."""
    its = first_contacts.history.column("newton_iterations")
    assert its.size == 1 and 1 <= its[0] <= 8
    norms = first_contacts.solver.residual_norms
    assert norms.size == its[0] + 1 and norms[-1] < 1e-9  # N: converged to snes_atol
    # the order of the iterate that first brings the residual below 1e-6 of its start (the
    # next one reaches round-off, ~1e-12 of the contact forces)
    k = np.flatnonzero(norms < 1e-6 * norms[0])[0]
    order = np.log(norms[k] / norms[k - 1]) / np.log(norms[k - 1] / norms[k - 2])
    assert order > 1.5, (order, norms)


#: the random volume's explicit compaction at the slowest loading rate measured (central
#: differences, 96 000 increments; its rho and sigma_m; ``python bench/implicit_vs_explicit.py
#: --case random16 --run explicit --increments 96000`` recomputes it in 45 min)
SLOW_EXPLICIT = Path(__file__).parent / "data" / "random16_explicit_n96000.csv"


def newton_against_slow_explicit(rho, sigma_m, Z):
    """(rows compared, relative differences) of a Newton history of the random volume against
    :data:`SLOW_EXPLICIT`: the rows past the first contacts (Z > 6) and before the explicit
    loading decelerates (rho < 0.650), the explicit curve interpolated at Newton's densities."""
    reference = np.loadtxt(SLOW_EXPLICIT, delimiter=",", skiprows=1)
    rows = (Z > 6.0) & (rho < 0.650)
    return rho[rows], sigma_m[rows] / np.interp(rho[rows], *reference.T) - 1.0


@pytest.mark.heavy  # ~15 min on a shared core: pytest -m heavy tests/test_implicit_granular.py
def test_random_volume_by_newton_follows_its_slow_explicit_compaction(tmp_path):
    """A random granular volume (16 generated lead particles, radii 0.09-0.11 mm, the coarse
    particle, CLP by images) compacted from rho 0.556 to 0.66 by Newton (30 nominal steps, the
    solver section's drags) against its compaction by central differences at 96 000 increments
    (kept: :data:`SLOW_EXPLICIT`): rearrangements, rattlers and first contacts on both paths.
    The explicit curve moves with the loading rate on so few particles (rearrangements come
    at other densities): 24 000 and 48 000 increments lie up to 6.8 % and 4.9 % from 96 000
    in these rows, so the reference is the slowest run. Past the first contacts (Z > 6) and
    before the explicit loading decelerates (rho < 0.650), the two sigma_m agree within 6 % in
    every row (4.1 % measured, at rho 0.636) and within 4 % past rho 0.638 (3.7 %; with the
    held drag doubled, 4.0 % and 2.2 %); Newton's median is at most 16 iterations per step (9).
    The 24 000-increment explicit run, checked as if it were Newton's, fails both bounds (6.8 %,
    4.8 %)."""
    case = CompactionCase.build(
        particles=16, r_min=0.09, r_max=0.11, seed=1, resolution="coarse", exact_volume=False,
        condition="CLP", images=True, target_density=0.66, outputs=40, visual=False,
        directory=str(tmp_path), kind="implicit", steps=30,
    )  # fmt: skip
    result = run_compaction(case, MPI.COMM_SELF, log=quiet)
    history = result.history
    assert result.quasi_static.passed, result.quasi_static.summary()  # the contacts carry it
    rho, difference = newton_against_slow_explicit(
        history.column("rho"), history.column("sigma_m"), history.column("Z")
    )
    assert difference.size >= 10 and rho.min() < 0.63 and rho.max() > 0.645, rho
    assert np.abs(difference).max() < 0.06, np.c_[rho, difference]
    assert np.abs(difference[rho > 0.638]).max() < 0.04, np.c_[rho, difference]
    assert np.nanmedian(history.column("newton_iterations")) <= 16


def test_the_static_check_tells_a_drag_held_state_from_a_static_one():
    """Newton's static check compares the contacts' Love-Weber stress with the particles'
    volume average: the flagship by Newton (kept: its rho, sigma_m and sigma_vol_m) passes,
    0.01 % apart at the end; a drag-held run (the simple cubic cell by Newton with gaps to
    curved master surfaces, an experiment not kept: particles squashed along the drag's frame,
    contacts tangent and unloaded) fails, 30 % at the end and 100 % at rho 0.539."""
    from mpfem_fenicsx.io.history import read_csv
    from mpfem_fenicsx.workflows.history_recorder import static_check

    data = Path(__file__).resolve().parent / "data"
    static = static_check(read_csv(data / "newton_flagship.csv"))
    assert static.passed and static.drag_share < 1e-3 and static.worst < 0.005
    held = static_check(read_csv(data / "newton_drag_held.csv"))
    assert not held.passed and held.drag_share > 0.2 and held.worst_rho < 0.55
    assert "FAILED" in held.summary() and "passed" in static.summary()


@pytest.mark.parametrize("images", [True, False])
def test_the_predictor_carries_free_particles_with_their_offsets(tmp_path, images):
    """Before any contact the particles only ride on their comoving carriers, which the drag
    lets pass (it acts on u - g): the predictor's load is then zero and it solves each step, so
    Newton has nothing left to do (0 iterations in 4 steps measured; 15-20 when the predictor
    loaded the drag with the offsets' motion)."""
    case = small_case(
        tmp_path, condition="CLP", kind="implicit", images=images, target_density=0.515, steps=4
    )
    result = run_compaction(case, MPI.COMM_SELF, log=quiet)
    assert result.history.column("n_contacts")[-1] == 0
    assert len(result.history.column("newton_iterations")) >= 4
    assert result.solver.iterations_total == 0
