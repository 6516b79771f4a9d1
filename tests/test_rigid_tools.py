"""Rigid tools: a particle pressed between two punches inside a die, by a prescribed motion
and by a force servo; restart with the tools' contact history; the tools' forces against the
particles' own balance; Newton on a tool-driven volume against the explicit state at rest."""

import shutil
from dataclasses import replace

import numpy as np
import pytest
from mpi4py import MPI

from mpfem_fenicsx.contact import ContactLaw
from mpfem_fenicsx.io.checkpoint import CheckpointError
from mpfem_fenicsx.material import LEAD
from mpfem_fenicsx.solvers.explicit import ExplicitSettings
from mpfem_fenicsx.tools import CylinderInside, ForceServo, KeyframePath, Plane, RigidTool
from mpfem_fenicsx.workflows.tooled import (
    ToolCheckpoints,
    ToolHistory,
    build_tooled,
    flow_displacement,
    mesh_radii,
    run_tooled,
    tool_law,
    tooled_newton,
    tooled_solver,
)

R = 0.1  # particle radius, mm
T = 1e-3  # pressing time, s


def _pressed(upper_motion=None, servo=None, die_friction=0.3, increments=4000, hold=0.5):
    """One lead particle on a lower punch at z = 0, in a die of radius 1.02 r with friction,
    pressed by an upper punch from z = 2 r over T (``increments``), then held for ``hold`` T."""
    law = ContactLaw(penalty=10 * LEAD.E / (R * np.pi / 12), friction=0.1)
    radius = mesh_radii([R], "coarse")
    tools = [
        RigidTool(
            "upper",
            Plane((0, 0, 2 * R), (0, 0, -1)),
            tool_law(law, 0.1),
            upper_motion or (lambda t: np.zeros(3)),
            servo,
        ),
        RigidTool("lower", Plane((0, 0, 0), (0, 0, 1)), tool_law(law, 0.1)),
        RigidTool("die", CylinderInside(1.02 * R), tool_law(law, die_friction)),
    ]
    model = build_tooled(
        [[0.0, 0.0, R]], radius, tools, law, LEAD, MPI.COMM_SELF, resolution="coarse"
    )
    solver = tooled_solver(
        model,
        ExplicitSettings(t_end=(1 + hold) * T, target_dt=T / increments, local_damping=0.7),
    )
    return model, solver


def test_pressed_particle_balances_the_punches_and_the_die():
    """At rest after a smooth-step squeeze of 25 % of its height into a die whose wall it
    presses (friction 0.3): the tools' forces sum to zero (the particle is in equilibrium), the
    upper punch carries the lower one's force plus the die's friction, which Coulomb bounds.

    At 20 % the bulge only grazes the die (normal force 0.6 % of the punch's): the friction's
    sign there is round-off. At 25 % the die carries 0.26 N normal, 0.076 N friction (0.31 N
    upper punch)."""
    path = KeyframePath((0.0, T), ((0, 0, 0), (0, 0, -0.5 * R)))
    model, solver = _pressed(path)
    run_tooled(model, solver, lambda s: None, outputs=2)
    f = model.tools.tool_forces()
    upper, lower, die = f["force"][:, 2]  # the particle's forces on the tools, along z
    assert upper > 0.05 and lower < 0.0  # N: it pushes the upper punch up, the lower one down
    assert f["normal"][2] > 0.3 * upper  # it has spread onto the die's wall
    assert abs(upper + lower + die) < 0.01 * upper  # equilibrium of the particle at rest
    # the die's friction holds the particle up: the lower punch carries less than the upper,
    # by a friction force within Coulomb's bound 0.3 x the die's normal force
    assert die < -0.1 * upper and -lower < upper
    assert abs(die) <= 0.3 * f["normal"][2] * (1 + 1e-9)
    assert solver.unbalanced_ratio() < 0.02
    # the tools' work on the particle (their forces along their motion, trapezoidal) against
    # what the particle absorbed, tallied separately: internal work, bulk viscosity, kinetic,
    # damping, the tools' friction and the penalty springs' energy 1/2 T1^2 / k A
    tools, e = model.tools, solver.energy_record()
    ev = tools.evaluation
    k = np.array([t.law.penalty for t in tools.tools])[ev.tool]
    springs = float(np.sum(0.5 * np.maximum(ev.T1, 0.0) ** 2 / k * ev.area))
    absorbed = e["E_int"] + e["E_visc"] + e["E_c"] + e["E_damp"] - e["E_mass"]
    absorbed += tools.frictional_work + springs
    assert tools.tool_work.sum() == pytest.approx(absorbed, rel=0.02)
    assert e["W_ext"] == pytest.approx(tools.tool_work.sum())  # the tools' work is W_ext


def test_force_servo_holds_the_punch_force():
    """A force-controlled upper punch: the particle's force on it reaches the target."""
    target = 2.0  # N
    servo = ForceServo(lambda t: target, (0, 0, -1), rate=0.5 * R / T, band=0.5, filter_time=T / 50)
    model, solver = _pressed(servo=servo, die_friction=0.0, increments=2000, hold=1.0)
    forces = []
    run_tooled(model, solver, lambda s: forces.append(model.tools.tool_forces()["force"][0, 2]), 20)
    assert forces[-1] == pytest.approx(target, rel=0.05)
    assert model.tools.translation[0, 2] < 0  # the servo moved the punch down


def test_restart_continues_the_tool_contact_history_bit_for_bit():
    path = KeyframePath((0.0, T), ((0, 0, 0), (0, 0, -0.3 * R)))
    model, solver = _pressed(path, increments=300, hold=0.0)
    run_tooled(model, solver, lambda s: None, outputs=2)
    whole = model.problem.u.x.array.copy()
    # the same run stopped half-way, its state restored on a new model, continued
    first, s1 = _pressed(path, increments=300, hold=0.0)
    s1.run_path(None, max_steps=s1.total_steps // 2)
    state = s1.state_dict()
    assert any(k.startswith("contact/tools/") for k in state)
    assert state["contact/tools/keys"].size > 0  # the tools' contact points have a history
    second, s2 = _pressed(path, increments=300, hold=0.0)
    s2.load_state(state)
    run_tooled(second, s2, lambda s: None, outputs=2)
    assert np.array_equal(second.problem.u.x.array, whole)
    assert np.array_equal(second.tools.translation, model.tools.translation)
    assert second.tools.tool_work == pytest.approx(model.tools.tool_work, rel=1e-12)


def test_a_killed_tool_run_continues_from_its_checkpoint(tmp_path):
    """The history and state of a pressed particle written every 4 rows; the run killed after
    its checkpoint at row 4 (the later ones removed), a new model resumes from it and ends with
    the uninterrupted run's rows and displacement, bit for bit (explicit)."""
    path = KeyframePath((0.0, T), ((0, 0, 0), (0, 0, -0.3 * R)))

    def run(folder):
        model, solver = _pressed(path, increments=300, hold=0.0)
        history = ToolHistory(model, folder / "history.csv")
        checkpoints = ToolCheckpoints(folder / "checkpoints", history, every=4, keep=0)
        resumed = checkpoints.restore(solver)

        def record(s):
            history.row(s)
            checkpoints.after_row(s)

        run_tooled(model, solver, record, outputs=12)
        return model, history, resumed

    whole, history, resumed = run(tmp_path)
    assert not resumed and len(history.history.rows) == 12
    steps = sorted((tmp_path / "checkpoints").glob("step*"))
    assert len(steps) == 3  # rows 4, 8, 12
    for later in steps[1:]:
        shutil.rmtree(later)
    again, continued, resumed = run(tmp_path)
    assert resumed
    assert np.array_equal(continued.history.array(), history.history.array())
    assert np.array_equal(again.problem.u.x.array, whole.problem.u.x.array)
    # a checkpoint of another model is refused
    wall = [RigidTool("wall", Plane())]
    other = build_tooled([[0, 0, R]], [R], wall, ContactLaw(penalty=1e6), LEAD, MPI.COMM_SELF)
    with pytest.raises(CheckpointError, match="another tool-driven model"):
        ToolCheckpoints(
            tmp_path / "checkpoints", ToolHistory(other, tmp_path / "h.csv"), 4
        ).restore(tooled_solver(other, ExplicitSettings(t_end=T, target_dt=T / 10)))


def test_tool_names_and_delta_max_are_checked():
    law = ContactLaw(penalty=1e6, gamma=1e-3, delta_max=1e-3)
    tools = [RigidTool("a", Plane()), RigidTool("a", Plane((0, 0, 1), (0, 0, -1)))]
    with pytest.raises(ValueError, match="unique"):
        build_tooled([[0, 0, R]], [R], tools, law, LEAD, MPI.COMM_SELF, resolution="coarse")
    adhesive = [RigidTool("wall", Plane(), law)]
    from mpfem_fenicsx.contact.rigid import RigidContact

    with pytest.raises(ValueError, match="delta_max"):
        RigidContact(None, adhesive, search_distance=1e-4)


def test_the_particle_resolution_is_checked_and_refined():
    """``refinement`` multiplies the cube-sphere's subdivisions: the chapter-2 particle has 561
    nodes, refined twice 3 929 (the mesh section's documented counts)."""
    law = ContactLaw(penalty=1e6)
    wall = [RigidTool("wall", Plane())]
    for refinement, nodes in ((1, 561), (2, 3929)):
        model = build_tooled(
            [[0, 0, R]], [R], wall, law, LEAD, MPI.COMM_SELF, refinement=refinement
        )
        assert model.num_dofs == 3 * nodes
    with pytest.raises(ValueError, match=r"refinement = 5 must be an integer in \[1, 4\]"):
        build_tooled([[0, 0, R]], [R], wall, law, LEAD, MPI.COMM_SELF, refinement=5)
    with pytest.raises(ValueError, match="resolution = 'fine' must be one of"):
        build_tooled([[0, 0, R]], [R], wall, law, LEAD, MPI.COMM_SELF, resolution="fine")


def test_the_user_guide_example_runs(tmp_path, monkeypatch):
    """The user guide's rigid-tools example, with fewer increments (it runs, the tools' history
    is written)."""
    import re
    from pathlib import Path

    guide = (Path(__file__).resolve().parents[1] / "docs" / "user-guide.md").read_text()
    section = guide.split("## Rigid tools", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    assert "T / 4000" in code
    monkeypatch.chdir(tmp_path)
    exec(compile(code.replace("T / 4000", "T / 300"), "user-guide", "exec"), {})
    assert (tmp_path / "results" / "pressed" / "history.csv").is_file()


@pytest.mark.heavy
def test_simple_cubic_cell_between_walls_ends_at_the_periodic_cells_stresses(tmp_path):
    """Six frictionless walls on the cell's contact planes are its symmetry planes: the die
    compaction between them ends at the periodic cell's stresses (measured: 0.2 / 0.2 / 1.3 %
    at 16 000 increments; ~10 min)."""
    from mpfem_fenicsx.workflows.compaction import run_compaction
    from mpfem_fenicsx.workflows.simple_cubic import between_walls, simple_cubic_case

    walls = between_walls(increments=16000, out_dir=str(tmp_path / "walls"), outputs=10)
    case = simple_cubic_case("die", increments=4000, out_dir=str(tmp_path), visual=False)
    periodic = run_compaction(case, MPI.COMM_SELF, log=lambda *a: None).history
    for wall, cell in (("zz", "33"), ("xx", "11"), ("yy", "22")):
        assert walls.column(f"sigma_{wall}_walls")[-1] == pytest.approx(
            periodic.column(f"sigma{cell}")[-1], rel=0.02
        )
    assert walls.column("rho")[-1] == pytest.approx(0.95, rel=1e-6)


def _squeezed(static: bool, squeeze: float = 0.2):
    """An elastic lead particle (no yield) between two frictionless planes z = 0 and 2 r, the
    upper one moved down by ``squeeze`` r over T (smooth step): by Newton in 8 load steps (the
    drag's frame the flow between the planes) or explicit (4000 increments, held T to rest)."""
    law = ContactLaw(penalty=10 * LEAD.E / (R * np.pi / 12))
    path = KeyframePath((0.0, T), ((0, 0, 0), (0, 0, -squeeze * R)))
    tools = [
        RigidTool("upper", Plane((0, 0, 2 * R), (0, 0, -1)), tool_law(law, 0.0), path),
        RigidTool("lower", Plane((0, 0, 0), (0, 0, 1)), tool_law(law, 0.0)),
    ]
    radius = mesh_radii([R], "coarse")
    elastic = replace(LEAD, sigma_0=1e5)
    model = build_tooled(
        [[0.0, 0.0, R]],
        radius,
        tools,
        law,
        elastic,
        MPI.COMM_SELF,
        resolution="coarse",
        tangent=static,
    )
    if static:
        frame = flow_displacement(model, [(2, 1, 0, 0.0, 2 * R)])
        solver = tooled_newton(model, T, 8, R * np.pi / 8, frame=frame)
    else:
        solver = tooled_solver(
            model, ExplicitSettings(t_end=2 * T, target_dt=T / 4000, local_damping=0.7)
        )
    return model, solver


def test_newton_between_two_planes_gives_the_explicit_state_at_rest():
    """Two realizations of one static squeeze (an elastic particle between two frictionless
    planes, 20 % of its height): Newton's end state carries the explicit run's force at rest
    (within 2e-3), both planes the same force; Newton converges quadratically from a
    predictor that moves the planes (12 iterations in its 8 steps measured; 23 when the
    predictor left the planes' motion out)."""
    forces, rows, its = {}, {True: [], False: []}, []
    for static in (True, False):
        model, solver = _squeezed(static)

        def record(s, mine=rows[static], static=static):
            mine.append(s.t)
            its.append(s.last_iterations if static else 0)

        run_tooled(model, solver, record, outputs=2)
        forces[static] = model.tools.tool_forces()["force"][:, 2]  # upper, lower (N)
        if static:
            assert len(rows[True]) >= 8  # every converged step is an output
            assert sum(its) <= 16
            assert solver.iteration_record()["newton_iterations"] <= 6
            assert solver.energy_record()["E_damp"] < 0.05 * solver.energy_record()["E_el"]
    newton, explicit = forces[True], forces[False]
    assert newton[0] > 1.0  # N: the particle pushes the upper plane up
    assert abs(newton[0] + newton[1]) < 1e-6 * newton[0]  # the planes balance
    assert newton[0] == pytest.approx(explicit[0], rel=2e-3)
