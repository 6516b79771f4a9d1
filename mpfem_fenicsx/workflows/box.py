"""A box of six independently driven rigid planes: hydrostatic and true-triaxial compaction.

Spheres packed in a box [0, Lx] x [0, Ly] x [0, Lz] (:func:`~mpfem_fenicsx.meshes.container.
generate_container_packing`, ``shape="box"``), six frictionless (or frictional) planes on its
faces, ``x0``, ``x1``, ``y0``, ``y1``, ``z0``, ``z1``, each following its own
:class:`~mpfem_fenicsx.tools.KeyframePath` along its normal. The particles are moved by contact
only (no periodic cell, no carrier).

The path: the box's side a ends at L_a0 exp(-c r_a), ``ratios`` r = (r_x, r_y, r_z) the
relative logarithmic strains (1, 1, 1: hydrostatic; (0, 0, 1): a die between two planes;
anything else: true triaxial), c such that the solid fraction reaches ``target_density``; each
side's two planes move by half its shortening, at constant speed between smooth ramps over the
pressing time (:class:`~mpfem_fenicsx.tools.KeyframePath` with ``ramp``). Then a hold.

History (:class:`~.tooled.ToolHistory` columns, compression > 0): ``rho`` (the particles' volume
at the start over the box's, eq. 2.5 with the walls' volume), ``L_x/L_y/L_z`` (mm), and the wall
stresses ``sigma_xx/yy/zz_walls`` (MPa): each the mean normal force of the two opposite planes
over the current face area, ``sigma_m_walls`` their mean.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..material import LEAD
from ..meshes.container import BoxContainer, Spheres, generate_container_packing
from ..parameters import check_parameters, parameter, parameter_of
from ..solvers.explicit import ExplicitSettings
from ..tools import KeyframePath, Plane, RigidTool
from .closed_die import ClosedDieCase
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

#: the planes: name, axis, side (0: at 0 facing +, 1: at L facing -)
PLANES = (("x0", 0, 0), ("x1", 0, 1), ("y0", 1, 0), ("y1", 1, 1), ("z0", 2, 0), ("z1", 2, 1))


@dataclass(frozen=True)
class BoxCase:
    """A box compaction (module docstring). Lengths mm, times s; lead particles."""

    particles: int = parameter(12, "particles in the box", low=1)
    radius: float = parameter_of(ClosedDieCase, "radius")
    spread: float = parameter_of(ClosedDieCase, "spread")
    seed: int = parameter(1, "seed of the packing", low=0)
    fill: float = parameter(
        0.4, "solid fraction of the generated packing (-)", low=0, high=0.6, open_low=True
    )
    ratios: tuple = (1.0, 1.0, 1.0)  # relative shortening rates of x, y, z (>= 0, not all 0)
    target_density: float = parameter(
        0.75,
        "solid fraction at the end of pressing (-)",
        low=0,
        high=1,
        open_low=True,
        open_high=True,
    )
    wall_friction: float = parameter(0.0, "walls' Coulomb coefficient (-)", low=0)
    friction: float = parameter_of(ClosedDieCase, "friction")
    penalty_factor: float = parameter_of(ClosedDieCase, "penalty_factor")
    resolution: str = parameter_of(ClosedDieCase, "resolution")
    pressing_time: float = parameter_of(ClosedDieCase, "pressing_time")
    increments: int = parameter(16000, "explicit increments of the pressing time T", low=1)
    hold: float = parameter(0.3, "hold after pressing (T)", low=0, open_low=True)
    ramp: float = parameter(
        0.1,
        "share of the pressing time the planes accelerate and decelerate; constant speed between",
        low=0,
        high=0.5,
        open_low=True,
    )
    local_damping: float = parameter_of(ClosedDieCase, "local_damping")
    outputs: int = parameter(40, "history rows", low=2)
    out_dir: str = parameter("results/triaxial_box", "results folder")

    def __post_init__(self):
        check_parameters(self, prefix="box: ")
        r = np.asarray(self.ratios, dtype=float)
        if r.shape != (3,) or not np.all(np.isfinite(r) & (r >= 0)) or r.sum() == 0:
            raise ValueError(f"box: ratios = {self.ratios!r} must be 3 numbers >= 0, not all 0")
        if not self.fill < self.target_density:
            raise ValueError(
                f"box: target_density = {self.target_density!r} must be > fill = {self.fill}"
            )


def wall_paths(
    lengths, ratios, rho0: float, target: float, t_press: float, t_end: float, ramp: float = 0.1
):
    """The six planes' keyframe paths (:data:`PLANES` order) and the final lengths (mm)."""
    lengths, r = np.asarray(lengths, dtype=float), np.asarray(ratios, dtype=float)
    c = np.log(target / rho0) / r.sum()
    final = lengths * np.exp(-c * r)
    paths = []
    for _, axis, side in PLANES:
        move = np.zeros(3)
        move[axis] = 0.5 * (lengths[axis] - final[axis]) * (1 if side == 0 else -1)
        paths.append(
            KeyframePath((0.0, t_press, t_end), ((0, 0, 0), tuple(move), tuple(move)), ramp=ramp)
        )
    return paths, final


def run_box(
    case: BoxCase,
    comm: MPI.Comm = MPI.COMM_WORLD,
    spheres: Spheres | None = None,
    log=print,
    render: bool = True,
) -> tuple[ToolHistory, dict]:
    """Pack (or take ``spheres`` in a :class:`BoxContainer`), press and hold (module docstring);
    writes ``history.csv``, ``summary.json`` and ``box.png`` in ``case.out_dir``."""
    start = time.perf_counter()
    out = Path(case.out_dir)
    if comm.rank == 0:
        out.mkdir(parents=True, exist_ok=True)
    r = case.radius
    if spheres is None:
        spheres = generate_container_packing(
            case.particles,
            r * (1 - case.spread),
            r * (1 + case.spread),
            case.seed,
            case.fill,
            shape="box",
            aspect=(1.0, 1.0, 1.0),
        )
    if not isinstance(spheres.container, BoxContainer):
        raise ValueError("box: the spheres must come in a box container")
    L0 = np.asarray(spheres.container.lengths)
    radii = mesh_radii(spheres.radii, case.resolution)
    law = particle_law(spheres.radii, case.resolution, case.penalty_factor, case.friction)
    solid = float(np.sum(4.0 / 3.0 * np.pi * radii**3))
    rho0 = solid / float(np.prod(L0))
    t_press = case.pressing_time
    t_end = t_press * (1 + case.hold)
    paths, final = wall_paths(L0, case.ratios, rho0, case.target_density, t_press, t_end, case.ramp)
    wall = tool_law(law, case.wall_friction)
    tools = []
    for (name, axis, side), path in zip(PLANES, paths, strict=True):
        point, normal = np.zeros(3), np.zeros(3)
        point[axis] = L0[axis] * side
        normal[axis] = 1.0 if side == 0 else -1.0
        tools.append(RigidTool(name, Plane(tuple(point), tuple(normal)), wall, path))
    model = build_tooled(spheres.centres, radii, tools, law, LEAD, comm, resolution=case.resolution)
    solver = tooled_solver(
        model,
        ExplicitSettings(
            t_end=t_end, target_dt=t_press / case.increments, local_damping=case.local_damping
        ),
    )
    # the node-wise damping resists the motion relative to the homogeneous flow between the planes
    solver.damping_reference = flow_between_tools(
        model,
        [(a, 2 * a, 2 * a + 1, 0.0, float(L0[a])) for a in range(3)],
        0.5 * t_press / case.increments,
    )
    extra = (
        "rho",
        "L_x",
        "L_y",
        "L_z",
        "sigma_xx_walls",
        "sigma_yy_walls",
        "sigma_zz_walls",
        "sigma_m_walls",
    )
    history = ToolHistory(model, out / "history.csv", extra=extra)
    log(
        f"box: {spheres.num_particles} particles in {L0.round(4).tolist()} mm (rho {rho0:.3f}), "
        f"ratios {list(case.ratios)} to rho {case.target_density}; {model.num_dofs} dofs, "
        f"{solver.total_steps} increments"
    )

    def record(s):
        tr = model.tools.translation
        L = L0 + tr[1::2].diagonal() - tr[0::2].diagonal()
        f = model.tools.tool_forces()["normal"]
        sig = [
            0.5 * (f[2 * a] + f[2 * a + 1]) / (L[(a + 1) % 3] * L[(a + 2) % 3]) for a in range(3)
        ]
        history.row(
            s,
            rho=solid / float(np.prod(L)),
            L_x=L[0],
            L_y=L[1],
            L_z=L[2],
            sigma_xx_walls=sig[0],
            sigma_yy_walls=sig[1],
            sigma_zz_walls=sig[2],
            sigma_m_walls=float(np.mean(sig)),
        )
        if comm.rank == 0:
            print(
                f"  t/T {s.t / t_press:.3f}, rho {solid / float(np.prod(L)):.4f}, wall stresses "
                + " ".join(f"{v:.3f}" for v in sig)
                + f" MPa, unbalanced {history.column('unbalanced')[-1]:.3g}",
                flush=True,
            )

    try:
        solver.run_path(
            record, outputs=case.outputs, on_step=lambda s: model.tools.servo_step(s.t, s.dt)
        )
    except FloatingPointError as err:  # the history so far is kept; exit 3 in the demos
        path = history.write()
        raise RunFailure(
            f"{err} (history so far: {path})", solver.step, solver.t, path, None
        ) from None
    history.write()
    col = history.column
    summary = {
        "case": asdict(case),
        "rho0": rho0,
        "lengths0": L0.tolist(),
        "lengths": final.tolist(),
        "rho": float(col("rho")[-1]),
        **{f"sigma_{a}_walls": float(col(f"sigma_{a}_walls")[-1]) for a in ("xx", "yy", "zz")},
        **{f"{n}_N": float(col(f"{n}_N")[-1]) for n, _, _ in PLANES},
        "unbalanced_at_rest": float(col("unbalanced")[-1]),
        "quasi_static": bool(col("unbalanced")[-1] <= UNBALANCED_AT_REST_LIMIT),
        "wall_time_s": time.perf_counter() - start,
        "ranks": comm.size,
        "dofs": model.num_dofs,
    }
    if render:
        from ..io.fields import CellFields
        from ..io.render import render_deformed

        fields = CellFields(model.problem, model.assembly.cell_tags)
        fields.update()
        render_deformed(model.problem.u, fields.von_mises, out / "box.png", title="box compaction")
    if comm.rank == 0:
        out.mkdir(parents=True, exist_ok=True)
        (out / "summary.json").write_text(json.dumps(summary, indent=1))
    return history, summary
