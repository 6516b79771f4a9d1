"""The simple cubic cell of thesis §2.6 as a compaction case, and its verification quantities.

Eight spheres of radius r in a periodic cube of side 4 r (``meshes.packing.simple_cubic_packing``),
CLP by tied copies, every particle mesh an exact translate of the others: the motion stays
affine, so rho = pi / (6 det F) (eq. 2.17), the least-squares Hencky strain equals the
auxiliary-node one, and Love-Weber (eq. 2.6) equals Schmidt (eq. 2.19) at rest. Used by
``demos/simple_cubic.py``, the tests and the benchmarks.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from mpi4py import MPI
from scipy.spatial.transform import Rotation

from ..homogenization import hencky_strain
from ..loading import GradientPath, compaction_gradient
from ..meshes.packing import simple_cubic_packing
from ..solvers import solver_kind
from ..solvers.explicit import ExplicitSettings
from ..tools import Plane, RigidTool
from .compaction import CompactionCase, contact_law
from .tooled import (
    ToolCheckpoints,
    ToolHistory,
    build_tooled,
    flow_between_tools,
    flow_displacement,
    run_tooled,
    tool_law,
    tooled_newton,
    tooled_solver,
)

__all__ = [
    "COMPONENTS",
    "MESH_ROTATION",
    "between_walls",
    "checks",
    "mirrored_rotations",
    "simple_cubic_case",
]

#: one generic orientation for every particle mesh (0.3 rad about (1, 2, 3)): identical particles
#: stay exact translates while their contact points are inside facets (no node-on-node contact)
MESH_ROTATION = Rotation.from_rotvec(0.3 * np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)).as_matrix()
COMPONENTS = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]


def mirrored_rotations(radius: float = 0.1, rotation: np.ndarray = MESH_ROTATION) -> np.ndarray:
    """(8, 3, 3) orientations of the cell's particle meshes mirrored across its contact planes:
    the sphere at r + 2 r (i, j, k) takes diag((-1)^i, (-1)^j, (-1)^k) ``rotation``. Two touching
    meshes are then mirror images of each other across their contact plane (in the periodic
    lattice too: the cell holds two spheres along each axis), so the planes x, y, z = 0, 2 r, 4 r
    are symmetry planes of the discrete problem, not only of the spheres, and a node meets its
    neighbour's surface where it meets the plane. Mirror images meet node on node (each slave
    node lands on a master vertex): the contact is rougher than with one generic orientation."""
    grid = np.rint((simple_cubic_packing(radius).centres - radius) / (2.0 * radius))
    mirrors = np.where(grid % 2 == 1, -1.0, 1.0)
    return mirrors[:, :, None] * np.asarray(rotation, dtype=float)[None]


def simple_cubic_case(
    loading: str,
    radius: float = 0.1,
    target_density: float = 0.95,
    increments: int = 4000,
    out_dir: str = "results/simple_cubic",
    visual: bool = True,
    outputs: int = 40,
    face_copies_only: bool = False,
    mirrored: bool = False,
    refinement: int = 1,
) -> CompactionCase:
    """The thesis §2.6 cell: CLP by copies, radii not shrunk (exact pi / 6; the particle meshes are
    inscribed in their touching spheres), all copies (or the 12 face copies of the thesis); the
    particle meshes (the chapter-2 particle, its subdivisions times ``refinement``) in one
    generic orientation or, ``mirrored``, mirror images of each other across the contact planes
    (:func:`mirrored_rotations`)."""
    return CompactionCase.build(
        spheres=simple_cubic_packing(radius),
        path=loading,
        condition="CLP",
        images=False,
        exact_volume=False,
        corners=not face_copies_only,
        d_bc=1.0,
        radius_factor=1.0,
        rotation=mirrored_rotations(radius) if mirrored else MESH_ROTATION,
        refinement=refinement,
        target_density=target_density,
        increments=increments,
        outputs=outputs,
        visual=visual,
        directory=str(Path(out_dir) / loading),
    )


def checks(result) -> dict[str, np.ndarray]:
    """The thesis §2.6 verification quantities along the history of a simple cubic run."""
    h = result.history
    path = result.model.path
    t = h.column("time")
    F = h.tensor("F")
    F0 = np.stack([path(ti) for ti in t])
    h_lsq, h_aux = hencky_strain(F), hencky_strain(F0)
    schmidt = np.stack([h.column(f"sigma_schmidt_{i}{i}") for i in (1, 2, 3)], axis=1).mean(axis=1)
    out = {"time": t, "rho": h.column("rho"), "rho_pi6": np.pi / (6.0 * np.linalg.det(F))}
    for a, b in COMPONENTS:
        out[f"h_lsq_{a + 1}{b + 1}"] = h_lsq[:, a, b]
        out[f"h_aux_{a + 1}{b + 1}"] = h_aux[:, a, b]
    out["sigma_m_love_weber"] = h.column("sigma_m")
    out["sigma_m_schmidt"] = schmidt
    return out


def between_walls(
    radius: float = 0.1,
    target_density: float = 0.95,
    increments: int = 4000,
    duration: float = 1e-3,
    out_dir: str = "results/simple_cubic/walls",
    outputs: int = 40,
    comm=None,
    log=print,
    damping_frame: str = "rest",
    solver: str = "explicit",
    steps: int = 100,
    regularization: float = 5e-4,
    mirrored: bool = False,
    refinement: int = 1,
    checkpoint_every: int = 0,
):
    """The cell's eight spheres in a box of six frictionless rigid planes on its contact planes
    x, y, z = 0 and 4 r (the periodic cell's symmetry planes), die-compacted by the top plane:
    its height follows the periodic die path's F0_zz(t) (the same smooth ramps over
    ``duration``), the other planes stay. The same particle meshes as :func:`simple_cubic_case`
    (its ``refinement``; inscribed, the generic rotation or, ``mirrored``, mirror images across
    the contact planes: then the planes are symmetry planes of the periodic cell's discrete
    problem), the same contact law between the spheres; the planes' penalty is twice it
    (:func:`~.tooled.tool_law`).
    The node-wise local damping resists the motion of every node (``damping_frame="rest"``) or
    its motion relative to the homogeneous flow between the bottom and top planes (``"flow"``,
    the periodic cell's comoving frame; its rows farther from the periodic cell's at 16 000 and
    32 000 increments: bench/README.md).
    ``solver="implicit"``: the static path by Newton in ``steps`` load steps instead
    (:func:`~.tooled.tooled_newton`; ``increments`` and the damping unused), the pseudo-time drag
    on the particles' cores at ``regularization`` x E V_p / h^2 whatever their contacts (the
    die's two axial contacts do not hold a particle laterally; a drag as strong as a free
    particle's carried up to 80 % of the forces before the lateral contacts engage) and
    relative to the homogeneous flow between the bottom and top planes.

    ``checkpoint_every``: a checkpoint in ``out_dir``/checkpoints after every that many history
    rows (0: none); a run that finds one there continues from it (:class:`~.tooled.
    ToolCheckpoints`).

    Returns the :class:`~.tooled.ToolHistory` with ``rho`` (the spheres' volume over the box's,
    eq. 2.5) and the stresses from the planes' forces (compression > 0, each the mean of the two
    opposite planes): ``sigma_zz_walls`` = force / (4 r)^2, ``sigma_xx_walls``,
    ``sigma_yy_walls`` = force / (4 r x the current height)."""
    if damping_frame not in ("flow", "rest"):
        raise ValueError(f"damping_frame = {damping_frame!r} must be 'flow' or 'rest'")
    comm = comm or MPI.COMM_WORLD
    periodic = simple_cubic_case(
        "die",
        radius,
        target_density,
        increments,
        visual=False,
        mirrored=mirrored,
        refinement=refinement,
    )
    packing, L = simple_cubic_packing(radius), 4.0 * radius
    divisions, _ = periodic.mesh.subdivisions
    h_contact = radius * np.pi / (2 * divisions * periodic.mesh.refinement)
    law = contact_law(periodic.contact, periodic.material, h_contact)
    # the periodic die path: F0_zz(t) from pi / 6 to the target density
    path = GradientPath(
        [(duration, compaction_gradient("die", np.pi / 6.0, target_density))],
        profiles=(periodic.loading.profile,),
    )

    def top(t):
        return np.array([0.0, 0.0, L * (path(t)[2, 2] - 1.0)])

    wall = tool_law(law, 0.0)
    planes = [
        RigidTool(name, Plane(point, normal), wall)
        for name, point, normal in [
            ("x0", (0, 0, 0), (1, 0, 0)),
            ("x1", (L, 0, 0), (-1, 0, 0)),
            ("y0", (0, 0, 0), (0, 1, 0)),
            ("y1", (0, L, 0), (0, -1, 0)),
            ("z0", (0, 0, 0), (0, 0, 1)),
        ]
    ]
    planes.append(RigidTool("z1", Plane((0, 0, L), (0, 0, -1)), wall, top))
    static = solver_kind(solver).static
    model = build_tooled(
        packing.centres,
        packing.radii,
        planes,
        law,
        periodic.material,
        comm,
        resolution=periodic.mesh.resolution,
        refinement=periodic.mesh.refinement,
        exact_volume=False,
        rotation=periodic.mesh.rotation,
        tangent=static,
    )
    if static:
        # the drag lets the homogeneous flow between the bottom and top planes pass (the
        # periodic cell's comoving offsets)
        flow = flow_displacement(model, [(2, 4, 5, 0.0, L)])
        integrator = tooled_newton(
            model,
            duration,
            steps,
            h_contact,
            frame=flow,
            regularization=regularization,
            held_regularization=regularization,
        )
    else:
        integrator = tooled_solver(
            model,
            ExplicitSettings(
                t_end=duration,
                target_dt=duration / increments,
                local_damping=periodic.solver.local_damping,
            ),
        )
    if damping_frame == "flow" and not static:  # planes z0 (index 4) at 0 and z1 (5) at L
        integrator.damping_reference = flow_between_tools(
            model, [(2, 4, 5, 0.0, L)], 0.5 * duration / increments
        )
    history = ToolHistory(
        model,
        f"{out_dir}/history.csv",
        extra=("rho", "sigma_xx_walls", "sigma_yy_walls", "sigma_zz_walls"),
    )

    spheres = float(np.sum(4.0 / 3.0 * np.pi * packing.radii**3))  # V_p of eq. 2.5
    checkpoints = ToolCheckpoints(f"{out_dir}/checkpoints", history, checkpoint_every)
    resumed = checkpoint_every > 0 and checkpoints.restore(integrator)

    def record(s):
        height = L * path(s.t)[2, 2]
        forces = model.tools.tool_forces()["force"]
        history.row(
            s,
            rho=spheres / (L * L * height),
            sigma_xx_walls=0.5 * (forces[1, 0] - forces[0, 0]) / (L * height),
            sigma_yy_walls=0.5 * (forces[3, 1] - forces[2, 1]) / (L * height),
            sigma_zz_walls=0.5 * (forces[5, 2] - forces[4, 2]) / (L * L),
        )
        checkpoints.after_row(s)

    log(
        f"simple cubic cell between walls: {model.num_dofs} dofs, "
        + (f"{steps} load steps (Newton)" if static else f"{increments} increments")
        + (f"; continued from t = {integrator.t:.6g} s" if resumed else "")
    )
    run_tooled(model, integrator, record, outputs=outputs)
    history.write()
    return history
