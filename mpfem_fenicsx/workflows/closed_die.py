"""Closed-die compaction of a poured powder between rigid punches: pressing, hold, unloading
(springback) and ejection.

The set-up of the field's die simulations (Procopio & Zavaliangos, Harthong et al., Güner et
al.): spheres poured into a cylindrical die (:func:`~mpfem_fenicsx.meshes.container.
generate_container_packing` with ``target_fraction=None``), three rigid tools, the particles
moved by contact only (no periodic cell, no carrier):

- ``upper``: the upper punch, the plane z = H0 (the poured column's top) facing down;
- ``lower``: the lower punch, the plane z = 0 facing up;
- ``die``: the die's wall, the inside of the cylinder of the container's radius, from z = 0 to
  its top z = H0 (an ejected compact leaves it).

The punches follow a :class:`~mpfem_fenicsx.tools.KeyframePath` of four stages, each a smooth
step in time (durations in units of the pressing time T):

1. **pressing** (T): the upper punch (single action) or both punches (double action, half the
   travel each) move until the green density reaches ``target_density``;
2. **hold** (``hold`` T): the punches stay; the compact relaxes to rest (the quasi-static check);
3. **unloading** (``unload`` T): the upper punch retreats by ``lift`` of the compact's height;
   the compact springs back axially (its height measured from its particles' surface nodes);
4. **ejection** (``eject`` T): the lower punch pushes the compact up and out of the die (the upper
   punch moves away faster); the ejection force is the lower punch's largest while it moves at
   constant speed, over the increments where the tools' axial forces balance within
   ``BALANCE_LIMIT`` of it (the compact's mass-scaled inertia, which peaks just after the ramp,
   left out; NaN if none does).

Each stage's motion is at constant speed between smooth ramps (``ramp`` of its time): the
homogeneous flow a punch drives at constant speed has no acceleration, so the particles'
(mass-scaled) inertia loads the tools only in the ramps and while the particles rearrange.

History (``history.csv``, one row per output; :class:`~.tooled.ToolHistory` columns, compression
> 0): ``stage`` (1-4), ``green_density`` = the particles' volume at the start over the volume
between the punches in the die, pi R^2 (z_upper - z_lower) (thesis eq. 2.5's rho with the tools'
volume), ``compact_height`` and ``compact_bottom`` (mm, from the particles' nodes: the
highest less the lowest, the lowest), ``upper_pressure`` /
``lower_pressure`` (MPa, the punches' axial force over pi R^2), ``die_normal`` (N, the sum of
the wall's normal forces), ``die_friction`` (N, the axial force the wall exerts on the compact:
> 0 upwards, holding it against the upper punch), ``tools_balance`` (the tools' axial forces'
sum over the upper punch's: the particles' inertia; 0 at rest), and per tool its translation
and force.

Quasi-static check (:meth:`ClosedDieResult.quasi_static`): while the punch moves at constant
speed and presses with more than ``CHECKED_FROM`` of its final force, the tools' forces balance
within ``BALANCE_LIMIT`` of the punch force (the pressing curve is free of inertia; the summary's
``balanced_from`` is the green density from which every constant-speed row balances), the upper
punch still presses at the end of the hold, and the out-of-balance ratio there is below the
explicit runs' limit.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx
import ufl

from ..material import LEAD
from ..meshes.container import CylinderContainer, Spheres, generate_container_packing
from ..parameters import check_parameters, parameter
from ..solvers.explicit import ExplicitSettings
from ..tools import CylinderInside, KeyframePath, Plane, RigidTool
from .compaction import RunFailure
from .history_recorder import UNBALANCED_AT_REST_LIMIT
from .tooled import (
    ToolHistory,
    build_tooled,
    flow_between_tools,
    mesh_radii,
    particle_law,
    tool_law,
    tooled_solver,
)

#: the four stages, in order
STAGES = ("pressing", "hold", "unloading", "ejection")
#: the history's own columns (module docstring), before the tools' (:class:`~.tooled.ToolHistory`)
COLUMNS = (
    "stage",
    "green_density",
    "compact_height",
    "compact_bottom",
    "upper_pressure",
    "lower_pressure",
    "die_normal",
    "die_friction",
    "tools_balance",
)
#: largest sum of the tools' axial forces over the upper punch's, while the punch presses at
#: constant speed with at least CHECKED_FROM of its final force, that the quasi-static check
#: accepts (below it the loose fill rearranges: that part of the curve is reported, not checked)
BALANCE_LIMIT = 0.05
CHECKED_FROM = 0.25


@dataclass(frozen=True)
class ClosedDieCase:
    """A closed-die compaction (module docstring). Lengths mm, times s, stresses MPa; lead
    particles (thesis table 2.1)."""

    particles: int = parameter(12, "particles poured into the die", low=1)
    radius: float = parameter(0.1, "mean particle radius (mm)", low=0, open_low=True)
    spread: float = parameter(
        0.2, "radii uniform within radius x (1 +/- spread) (-)", low=0, high=1, open_high=True
    )
    seed: int = parameter(1, "seed of the poured packing", low=0)
    aspect: float = parameter(
        1.0, "poured column's height / diameter, about (-)", low=0, open_low=True
    )
    target_density: float = parameter(
        0.85,
        "green density at the end of pressing (-)",
        low=0,
        high=1,
        open_low=True,
        open_high=True,
    )
    action: str = parameter(
        "single", "pressing by the upper punch or by both punches", choices=("single", "double")
    )
    wall_friction: float = parameter(0.1, "die-wall Coulomb coefficient (-)", low=0)
    punch_friction: float = parameter(0.1, "punches' Coulomb coefficient (-)", low=0)
    friction: float = parameter(0.1, "particle-particle Coulomb coefficient (-)", low=0)
    penalty_factor: float = parameter(
        10.0, "contact penalty / (E / h_contact) (-, thesis §3.3)", low=0, open_low=True
    )
    resolution: str = parameter(
        "chapter2", "particle mesh", choices=("chapter2", "chapter4", "coarse")
    )
    pressing_time: float = parameter(1e-3, "pressing time T (s)", low=0, open_low=True)
    increments: int = parameter(
        32000, "explicit increments of the pressing time T (the other stages alike)", low=1
    )
    hold: float = parameter(0.2, "hold after pressing (T)", low=0, open_low=True)
    unload: float = parameter(0.2, "upper punch's retreat time (T)", low=0, open_low=True)
    lift: float = parameter(
        0.05, "upper punch's retreat (pressed compact heights)", low=0, high=1, open_low=True
    )
    eject: float = parameter(1.0, "ejection time (T)", low=0, open_low=True)
    ramp: float = parameter(
        0.1,
        "share of a stage's time the punches accelerate and decelerate; constant speed between",
        low=0,
        high=0.5,
        open_low=True,
    )
    local_damping: float = parameter(
        0.7, "local damping coefficient (-)", low=0, high=1, open_high=True
    )
    damping: str = parameter("node", "what the local damping acts on", choices=("node", "particle"))
    damping_frame: str = parameter(
        "flow",
        "node-wise damping resists the motion relative to the homogeneous flow between the "
        "punches, or to rest",
        choices=("flow", "rest"),
    )
    outputs: int = parameter(60, "history rows", low=4)
    out_dir: str = parameter("results/closed_die", "results folder")
    bins: int = parameter(5, "axial and radial bins of the green density", low=1)

    def __post_init__(self):
        check_parameters(self, prefix="closed die: ")

    @property
    def stage_ends(self) -> np.ndarray:
        """The end times (s) of the four stages."""
        T = self.pressing_time
        return T * np.cumsum([1.0, self.hold, self.unload, self.eject])


def pour(case: ClosedDieCase) -> Spheres:
    """The case's spheres poured into a die (seeded): every sphere rests on others."""
    r = case.radius
    return generate_container_packing(
        case.particles,
        r * (1 - case.spread),
        r * (1 + case.spread),
        case.seed,
        None,
        shape="cylinder",
        aspect=case.aspect,
    )


def punch_paths(case: ClosedDieCase, height: float, solid: float, die_radius: float):
    """The upper and lower punches' keyframe paths (translations along z, mm) for a poured
    column of ``height`` (mm) and particles' volume ``solid`` (mm^3) in a die of ``die_radius``;
    returns (upper, lower, pressed height)."""
    pressed = solid / (case.target_density * np.pi * die_radius**2)
    if pressed >= height:
        raise ValueError(
            f"closed die: target_density = {case.target_density} is below the poured density "
            f"{solid / (np.pi * die_radius**2 * height):.3f}"
        )
    travel = height - pressed
    up_travel, low_travel = (travel, 0.0) if case.action == "single" else (travel / 2, travel / 2)
    t1, t2, t3, t4 = case.stage_ends
    lift = case.lift * pressed
    # the lower punch's face ends at the die's top (z = height): the compact is out
    eject = height - low_travel
    # the upper punch moves a compact's height further than the lower one: clear of the
    # compact as it springs back out of the die
    z_up = [0.0, -up_travel, -up_travel, -up_travel + lift, -up_travel + lift + eject + pressed]
    z_low = [0.0, low_travel, low_travel, low_travel, low_travel + eject]
    times = (0.0, t1, t2, t3, t4)
    upper = KeyframePath(times, tuple((0.0, 0.0, z) for z in z_up), ramp=case.ramp)
    lower = KeyframePath(times, tuple((0.0, 0.0, z) for z in z_low), ramp=case.ramp)
    return upper, lower, pressed


class CellVolumes:
    """Current volume (mm^3) and centroid (mm) of every owned cell (DG0 forms compiled once)."""

    def __init__(self, u: dolfinx.fem.Function):
        mesh = u.function_space.mesh
        DG0 = dolfinx.fem.functionspace(mesh, ("DG", 0))
        v = ufl.TestFunction(DG0)
        J = ufl.det(ufl.Identity(3) + ufl.grad(u))
        x = ufl.SpatialCoordinate(mesh) + u
        self._forms = [dolfinx.fem.form(J * v * ufl.dx)]
        self._forms += [dolfinx.fem.form(x[i] * J * v * ufl.dx) for i in range(3)]
        self._n = mesh.topology.index_map(3).size_local
        self._dofs = DG0.dofmap.list[: self._n, 0]

    def __call__(self) -> tuple[np.ndarray, np.ndarray]:
        """(volumes (n,), centroids (n, 3)) of the owned cells."""
        values = [dolfinx.fem.assemble_vector(f).array[self._dofs] for f in self._forms]
        volume = values[0]
        return volume, np.column_stack(values[1:]) / volume[:, None]


def density_bins(volume, centroid, radius, z_low, z_high, bins, comm) -> dict[str, np.ndarray]:
    """The green density's distribution: the particles' volume in ``bins`` axial slices of
    [z_low, z_high] and ``bins`` annuli of equal area of the die of ``radius`` (mm), over the
    slice's or annulus' volume (cells counted where their centroid lies; -)."""
    height = z_high - z_low
    axial = np.clip(((centroid[:, 2] - z_low) / height * bins).astype(int), 0, bins - 1)
    rho = np.hypot(centroid[:, 0], centroid[:, 1])
    radial = np.clip(((rho / radius) ** 2 * bins).astype(int), 0, bins - 1)
    local = np.stack([np.bincount(axial, volume, bins), np.bincount(radial, volume, bins)])
    total = comm.allreduce(local, op=MPI.SUM)
    slice_volume = np.pi * radius**2 * height / bins
    return {
        "z_mid": z_low + (np.arange(bins) + 0.5) * height / bins,
        "axial": total[0] / slice_volume,
        "r_mid": radius * np.sqrt((np.arange(bins) + 0.5) / bins),
        "radial": total[1] / slice_volume,
    }


@dataclass
class ClosedDieResult:
    """What a closed-die run measured (lengths mm, forces N, pressures MPa)."""

    history: ToolHistory
    summary: dict = field(default_factory=dict)
    bins: dict = field(default_factory=dict)

    def report(self) -> list[str]:
        """Lines for the run's log."""
        s = self.summary
        lines = [
            f"pressed: green density {s['green_density_pressed']:.4f}, upper punch "
            f"{s['upper_pressure_pressed']:.3f} MPa, lower punch {s['lower_pressure_pressed']:.3f}"
            f" MPa (lower / upper {s['transmission']:.3f}), die wall normal "
            f"{s['die_normal_pressed']:.4g} N, friction {s['die_friction_pressed']:.4g} N",
            f"springback: compact height {s['height_pressed']:.5f} -> {s['height_unloaded']:.5f}"
            f" mm ({100 * s['springback']:.2f} %)",
            f"ejection force: {s['ejection_force']:.4g} N (the lower punch's largest, pushing "
            "the compact out of the die at constant speed, where the tools balance within "
            f"{100 * BALANCE_LIMIT:.0f} %: {100 * s['ejection_balanced_share']:.0f} % of the "
            "increments)",
            "green density by height (bottom -> top): "
            + " ".join(f"{v:.3f}" for v in self.bins["axial"]),
            "green density by radius (axis -> wall): "
            + " ".join(f"{v:.3f}" for v in self.bins["radial"]),
            self.quasi_static_line(),
            f"wall time {s['wall_time_s']:.0f} s on {s['ranks']} rank(s), {s['dofs']} dofs",
        ]
        return lines

    @property
    def quasi_static(self) -> bool:
        """Out of balance at rest after the hold and the kinetic share during pressing within
        their limits."""
        s = self.summary
        return bool(
            s["upper_pressure_pressed"] > 0.0
            and s["unbalanced_hold"] <= UNBALANCED_AT_REST_LIMIT
            and s["tools_balance_pressing"] <= BALANCE_LIMIT
        )

    def quasi_static_line(self) -> str:
        """The quasi-static check's line."""
        s = self.summary
        found = (
            f"out of balance {s['unbalanced_hold']:.2g} at rest after the hold (limit "
            f"{UNBALANCED_AT_REST_LIMIT:g}), the tools' forces balance within "
            f"{100 * s['tools_balance_pressing']:.1f} % of the punch force while it presses at "
            f"constant speed past {100 * CHECKED_FROM:g} % of its final force (limit "
            f"{100 * BALANCE_LIMIT:g} %; within it from green density {s['balanced_from']:.3f})"
        )
        if not s["upper_pressure_pressed"] > 0.0:
            found = "the compact left the upper punch when it stopped (its momentum); " + found
        if self.quasi_static:
            return f"quasi-static check passed: {found}"
        return f"quasi-static check FAILED: {found}: run with more increments"


def _die_model(case: ClosedDieCase, spheres: Spheres, comm):
    """The meshed particles with the punches and the die's wall, the explicit solver (its
    node-wise damping in the flow frame: between the punches while pressing and holding, the
    lower punch's motion in unloading and ejection, when the compact rides on it and the upper
    punch leaves it), the punches' paths and the particles' volume (mm^3)."""
    R, H0 = spheres.container.radius, spheres.container.height
    radii = mesh_radii(spheres.radii, case.resolution)
    law = particle_law(spheres.radii, case.resolution, case.penalty_factor, case.friction)
    solid = float(np.sum(4.0 / 3.0 * np.pi * radii**3))
    upper_path, lower_path, _ = punch_paths(case, H0, solid, R)
    punch, wall = tool_law(law, case.punch_friction), tool_law(law, case.wall_friction)
    tools = [
        RigidTool("upper", Plane((0, 0, H0), (0, 0, -1)), punch, upper_path),
        RigidTool("lower", Plane((0, 0, 0), (0, 0, 1)), punch, lower_path),
        RigidTool("die", CylinderInside(R, extent=(-np.inf, H0)), wall),
    ]
    model = build_tooled(spheres.centres, radii, tools, law, LEAD, comm, resolution=case.resolution)
    dt = case.pressing_time / case.increments
    settings = ExplicitSettings(
        t_end=float(case.stage_ends[-1]), target_dt=dt, local_damping=case.local_damping
    )
    solver = tooled_solver(model, settings, damping=case.damping)
    if case.damping == "node" and case.damping_frame == "flow":
        between = flow_between_tools(model, [(2, 1, 0, 0.0, H0)], 0.5 * dt)
        t_hold_end = float(case.stage_ends[1])
        nodes = model.problem.V.dofmap.index_map.size_local

        def reference(t: float) -> np.ndarray:
            if t <= t_hold_end:
                return between(t)
            v = np.zeros((nodes, 3))
            v[:, 2] = (lower_path(t + 0.5 * dt)[2] - lower_path(t - 0.5 * dt)[2]) / dt
            return v.ravel()

        solver.damping_reference = reference
    return model, solver, (upper_path, lower_path), solid


def run_closed_die(
    case: ClosedDieCase,
    comm: MPI.Comm = MPI.COMM_WORLD,
    spheres: Spheres | None = None,
    log=print,
    render: bool = True,
) -> ClosedDieResult:
    """Pour (or take ``spheres`` in a :class:`CylinderContainer` standing on z = 0), press,
    hold, unload and eject (module docstring); writes ``history.csv``, ``density_bins.csv``,
    ``summary.json``, ``pressing_curve.png`` and the compact's pictures in ``case.out_dir``."""
    start = time.perf_counter()
    out = Path(case.out_dir)
    if comm.rank == 0:
        out.mkdir(parents=True, exist_ok=True)
    if spheres is None:
        spheres = pour(case)
    container = spheres.container
    if not isinstance(container, CylinderContainer):
        raise ValueError("closed die: the spheres must come in a cylinder container")
    R, H0 = container.radius, container.height
    model, solver, (upper_path, lower_path), solid = _die_model(case, spheres, comm)
    t_end = float(case.stage_ends[-1])
    dt = case.pressing_time / case.increments
    history = ToolHistory(model, out / "history.csv", extra=COLUMNS)
    volumes = CellVolumes(model.problem.u)
    coords = model.problem.V.tabulate_dof_coordinates()[
        : model.problem.V.dofmap.index_map.size_local
    ]
    area = np.pi * R**2
    log(
        f"closed die: {spheres.num_particles} particles poured to {H0:.4f} mm in a die of radius "
        f"{R:.4f} mm (density {solid / (area * H0):.3f}), {case.action} action to "
        f"{case.target_density}; {model.num_dofs} dofs, {solver.total_steps} increments"
    )

    state = {"stage_rows": {}, "bins": None, "t0": time.perf_counter(), **EJECTION_START}
    ends = case.stage_ends

    starts = np.r_[0.0, ends[:-1]]

    def constant_speed(t: float, stage: int) -> bool:
        """Whether ``t`` lies in ``stage``'s constant-speed part (between its ramps)."""
        lo, hi = starts[stage - 1], ends[stage - 1]
        return lo + case.ramp * (hi - lo) <= t <= hi - case.ramp * (hi - lo)

    def stage_of(t: float) -> int:
        return min(int(np.searchsorted(ends, t - 0.5 * dt)) + 1, 4)

    def record(s, stage_end: bool = False):
        stage = stage_of(s.t)
        f = model.tools.tool_forces()
        z_up = H0 + model.tools.translation[0, 2]
        z_low = model.tools.translation[1, 2]
        lo, hi = _z_range(coords, model.problem.u, comm)
        F = f["force"]
        history.row(
            s,
            stage=stage,
            green_density=solid / (area * max(z_up - z_low, 1e-300)),
            compact_height=hi - lo,
            compact_bottom=lo,
            upper_pressure=F[0, 2] / area,
            lower_pressure=-F[1, 2] / area,
            die_normal=f["normal"][2],
            die_friction=-F[2, 2],
            tools_balance=(F[0, 2] + F[1, 2] + F[2, 2]) / max(abs(F[0, 2]), 1e-300),
        )
        if stage_end:  # the end state of a stage
            state["stage_rows"][STAGES[stage - 1]] = len(history.column("time")) - 1
            if stage == 2:
                vol, cen = volumes()
                state["bins"] = density_bins(vol, cen, R, z_low, z_up, case.bins, comm)
                if render:
                    _pictures(model, out / "pressed.png", "pressed compact (end of hold)")
        elif comm.rank == 0:
            elapsed = time.perf_counter() - state["t0"]
            frac = s.t / t_end
            eta = elapsed * (1 - frac) / max(frac, 1e-12)
            print(
                f"  [{STAGES[stage - 1]}] t/T {s.t / case.pressing_time:.3f}, green density "
                f"{solid / (area * (z_up - z_low)):.4f}, upper {F[0, 2] / area:.3f} MPa, "
                f"unbalanced {history.column('unbalanced')[-1]:.3g}, {100 * frac:.0f} %, "
                f"ETA {eta:.0f} s",
                flush=True,
            )

    def on_step(s):
        model.tools.servo_step(s.t, s.dt)
        stage = stage_of(s.t)
        if constant_speed(s.t, 4):  # the ejection force: the lower punch's largest, step by step
            _count_ejection(state, model.tools.tool_forces()["force"][:, 2])
        # the increment that ends a stage (the last one ends the run: recorded by run's output)
        if stage < 4 and abs(s.t - ends[stage - 1]) < 0.5 * dt:
            record(s, stage_end=True)

    def on_output(s):
        record(s, stage_end=s.t >= t_end - 0.5 * dt)

    try:
        solver.run_path(on_output, outputs=case.outputs, on_step=on_step)
    except FloatingPointError as err:  # the history so far is kept; exit 3 in the demos
        path = history.write()
        raise RunFailure(
            f"{err} (history so far: {path})", solver.step, solver.t, path, None
        ) from None
    history.write()
    if render:
        _pictures(model, out / "ejected.png", "ejected compact")
    summary = {
        "case": asdict(case),
        "particles": spheres.num_particles,
        "die_radius": R,
        "fill_height": H0,
        "poured_density": solid / (area * H0),
        **_pressing_figures(history, state, constant_speed),
        "wall_time_s": time.perf_counter() - start,
        "ranks": comm.size,
        "dofs": model.num_dofs,
        "increments_total": solver.total_steps,
    }
    if comm.rank == 0:
        _write_outputs(out, summary, state["bins"], history, render)
    return ClosedDieResult(history, summary, state["bins"])


def _write_outputs(out: Path, summary: dict, bins: dict, history: ToolHistory, render: bool):
    """summary.json, density_bins.csv and the pressing curve (rank 0)."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    np.savetxt(
        out / "density_bins.csv",
        np.column_stack([bins["z_mid"], bins["axial"], bins["r_mid"], bins["radial"]]),
        delimiter=",",
        header="z_mid_mm,green_density_axial,r_mid_mm,green_density_radial",
        comments="",
    )
    if render:
        plot_pressing_curve(history, out / "pressing_curve.png")


def balanced_push(forces_z: np.ndarray, limit: float = BALANCE_LIMIT) -> float:
    """The lower punch's push (N, > 0 upward) from the tools' axial forces on them
    ``forces_z`` = (upper, lower, die), where the tools balance within ``limit`` of it; NaN
    where they do not (the compact's mass-scaled inertia carries the rest: it peaks after the
    ejection's ramp, with the mass scaling's (T / increments)^2) or the punch carries nothing."""
    lower = forces_z[1]
    if lower == 0.0 or abs(np.sum(forces_z)) > limit * abs(lower):
        return float("nan")
    return float(-lower)


#: the ejection's counters in a run's state: the force, increments at constant speed, balanced
EJECTION_START = {"ejection": float("nan"), "ejection_steps": 0, "ejection_balanced": 0}


def _count_ejection(state: dict, forces_z: np.ndarray) -> None:
    """One increment of the ejection at constant speed: its balanced push in ``state``."""
    push = balanced_push(forces_z)
    state["ejection_steps"] += 1
    state["ejection_balanced"] += int(np.isfinite(push))
    state["ejection"] = float(np.fmax(state["ejection"], push))


def _pressing_figures(history: ToolHistory, state: dict, constant_speed) -> dict:
    """The figures of a run's history (:class:`ClosedDieResult`'s summary): the end of the hold,
    the springback, the ejection force, the tools' balance and the quasi-static measures."""
    rows = state["stage_rows"]
    col = history.column
    press, hold, unload = rows["pressing"], rows["hold"], rows["unloading"]
    stage = col("stage")
    time_ = col("time")
    upper_force = col("upper_Fz")
    steady = np.array([constant_speed(t, 1) for t in time_]) & (stage == 1)
    steady &= np.abs(upper_force) > 0.0
    checked = steady & (np.abs(upper_force) >= CHECKED_FROM * abs(upper_force[hold]))
    balance = np.abs(col("tools_balance")[checked])
    unbalanced_rows = np.flatnonzero(steady & (np.abs(col("tools_balance")) > BALANCE_LIMIT))
    after = unbalanced_rows[-1] + 1 if unbalanced_rows.size else np.flatnonzero(steady)[0]
    balanced_from = float(col("green_density")[min(after, press)])
    return {
        "green_density_pressed": float(col("green_density")[hold]),
        "upper_pressure_pressed": float(col("upper_pressure")[hold]),
        "lower_pressure_pressed": float(col("lower_pressure")[hold]),
        "transmission": _ratio(col("lower_pressure")[hold], col("upper_pressure")[hold]),
        "die_normal_pressed": float(col("die_normal")[hold]),
        "die_friction_pressed": float(col("die_friction")[hold]),
        "tools_force_sum_pressed": _ratio(
            col("upper_Fz")[hold] + col("lower_Fz")[hold] + col("die_Fz")[hold],
            abs(col("upper_Fz")[hold]),
        ),
        "peak_upper_pressure": float(col("upper_pressure")[: press + 1].max()),
        "height_pressed": float(col("compact_height")[hold]),
        "height_unloaded": float(col("compact_height")[unload]),
        "springback": float(col("compact_height")[unload] / col("compact_height")[hold] - 1),
        "ejection_force": float(state["ejection"]),
        "ejection_balanced_share": state["ejection_balanced"] / max(state["ejection_steps"], 1),
        "unbalanced_hold": float(col("unbalanced")[hold]),
        "tools_balance_pressing": float(balance.max()) if balance.size else float("nan"),
        "balanced_from": balanced_from,
        "damping_work_share": float(col("E_damp")[hold] / col("W_ext")[hold]),
    }


def _z_range(coords: np.ndarray, u, comm) -> tuple[float, float]:
    """The lowest and highest current z of the nodes (mm; ``coords`` the owned nodes')."""
    z = coords[:, 2] + u.x.array.reshape(-1, 3)[: len(coords), 2]
    lo = comm.allreduce(float(z.min()) if z.size else np.inf, op=MPI.MIN)
    hi = comm.allreduce(float(z.max()) if z.size else -np.inf, op=MPI.MAX)
    return lo, hi


def _ratio(a: float, b: float) -> float:
    """a / b, NaN when b is 0 (a punch that carries nothing)."""
    return float(a / b) if b != 0 else float("nan")


def _pictures(model, path: Path, title: str) -> None:
    from ..io.fields import CellFields
    from ..io.render import render_deformed

    fields = CellFields(model.problem, model.assembly.cell_tags)
    fields.update()
    render_deformed(model.problem.u, fields.von_mises, path, title=title, save_grid=True)


def plot_pressing_curve(history: ToolHistory, png: Path) -> Path:
    """The pressing curve: the punches' pressures (MPa) against the green density."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    col = history.column
    stage = col("stage")
    fig, ax = plt.subplots(figsize=(5.5, 4))
    for name, style in (("upper", "-"), ("lower", "--")):
        for k, colour in ((1, "C0"), (2, "C1"), (3, "C2")):
            mask = stage == k
            if mask.any():
                ax.plot(
                    col("green_density")[mask],
                    col(f"{name}_pressure")[mask],
                    style,
                    color=colour,
                    label=f"{name} punch, {STAGES[k - 1]}",
                )
    ax.set_xlabel("green density (-)")
    ax.set_ylabel("punch pressure (MPa, compression > 0)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    plt.close(fig)
    return png
