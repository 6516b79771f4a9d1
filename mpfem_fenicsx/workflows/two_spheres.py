"""Two elastoplastic spheres with adhesion (thesis §3.4.2) against Mesarovic-Johnson.

Identical spheres of radius r (linear-hardening steel, thesis table 3.2) centred at (0, 0, -r)
and (0, 0, r), frictionless, degree of contact forced to alpha = 1 where contact was made. Two
models (``meshes.sphere_pair``): the 3-D quarter (symmetry planes x = 0 and y = 0: u_x = 0, resp.
u_y = 0 there; hexahedra refined at the contact), or a one-cell wedge of a few degrees whose
second plane follows the first rotated (cyclic-symmetry rows ``_wedge_couplings``: the
axisymmetric problem, which resolves the contact at the thesis' 0.00125 r mesh for the cost of a
2-D model). Rigid cores (nodes within ``core`` r of the centres) press the spheres to a centre
approach of 0.02 r, then pull them apart to ``unload_to`` r, or until the pull-off ends the
static path (the last contact disc snaps off: ``pull_off``).

Unloading branch: force F against contact radius a = sqrt(A / pi), A = area of the loaded contact
points (T1 != 0: compression or adhesive tension, the thesis' "non-zero nodal force"
definition), both x ``symmetry_factor`` (4, or 360 / angle). Reference, the singular solution of
Mesarovic & Johnson (thesis eq. 3.8):
    F_MJ(a) = 2 p0 a0^2 [asin(a/a0) - (a/a0) sqrt(1 - (a/a0)^2)] - 2 a sqrt(2 pi a gamma E*),
with a0, F0 at the end of loading, p0 = F0 / (pi a0^2), E* = E / (2 (1 - nu^2)). Error (thesis
eq. 3.21): e = sqrt(sum_a ((F - F_MJ) / (pi a0^2 p0))^2) on a / a0 = 0.1, ..., 0.9 (``eq_3_21``:
the thesis leaves the sampling implicit; summed over all unloading increments it grows as the
square root of their number, reported as ``error_samples`` beside the per-sample rms).

Newton on these faceted, non-matching models needs the contact model's guards (smoothed master
normals, the penetration step limit, peeling and snap-in: ``contact.guards``); the history of
those fixes and the measured errors per ratio are in ``bench/README.md`` ("Single contacts").

Mesh: ``grading`` refines the contact cap only (size_min on the sphere surface within
refine_radius of the axis, growing by ``grading`` per unit distance from it), so that the contact
can be resolved at h = size_min / 2 = 0.01 mm (size_min 0.02, grading 0.5: 58 902 dofs).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..constraints import CouplingRows
from ..contact import ContactLaw, ContactModel
from ..contact.laws import default_penalty
from ..io import History
from ..loading import PrescribedDisplacements, component_dofs
from ..material import STEEL_LINEAR, ElastoPlastic
from ..meshes import node_particles
from ..meshes.sphere_pair import quarter_sphere_pair, wedge_sphere_pair
from ..parameters import check_parameters, parameter
from ..problem import SolidProblem
from ..solvers import ImplicitSolver, NonConvergence, StepControl


@dataclass(frozen=True)
class TwoSphereCase:
    """The two-sphere case: material, adhesion ratio, mesh and load steps (MPa, mm)."""

    ratio: float = parameter(
        1.0, "sigma_c / sigma_y: adhesive strength over the yield stress (-)", low=0, open_low=True
    )
    gamma: float = 1e-3  # mJ/mm^2
    approach: float = 0.02  # maximum centre approach / r
    radius: float = 1.0
    size_min: float = parameter(
        0.03,
        "element size at the contact / r (tetrahedra; hexahedra about half) (-)",
        low=0,
        high=0.2,
        open_low=True,
    )
    refine_radius: float = parameter(
        0.2,
        "refined zone: size_min within this distance of the contact point (of "
        "the axis with grading) / r (-)",
        low=0,
        open_low=True,
    )
    #: None: ball refinement around the contact point; a number: size_min on the contact cap,
    #: growing by ``grading`` per unit distance from it (``meshes.sphere_pair``), for fine contact
    #: meshes
    grading: float | None = parameter(
        None,
        "refine the contact cap only: element size grows by this per unit "
        "distance from it (default: a refined ball) (-)",
        kind=float,
        low=0,
        open_low=True,
    )
    core: float = 0.3
    #: "quarter" (3-D quarter, symmetry planes x = 0, y = 0) or "wedge" (a one-cell wedge of
    #: ``wedge_angle`` degrees whose second plane follows the first rotated (cyclic symmetry):
    #: the axisymmetric problem, resolved at
    #: the thesis' contact mesh size for the cost of a 2-D model; ``meshes.sphere_pair``)
    model: str = parameter(
        "quarter",
        "3-D quarter model, or one-cell wedge (axisymmetric by cyclic symmetry)",
        choices=("quarter", "wedge"),
    )
    wedge_angle: float = parameter(2.0, "wedge angle (degrees)", low=0, high=45, open_low=True)
    #: N/mm^3; default 10 E / h with h = size_min r / 2 the hexahedra's size at the contact (the
    #: thesis' 1e9 with these meshes makes Newton cut back whenever a ring of nodes enters contact)
    penalty: float | None = None
    load_steps: int = parameter(10, "implicit steps of the loading", low=1)
    unload_steps: int = parameter(40, "implicit steps of the unloading (0: loading only)", low=0)
    # final centre approach / r (past separation: elastic recovery ~1.5e-3 r)
    unload_to: float = 0.016
    material: ElastoPlastic = STEEL_LINEAR

    def __post_init__(self):
        check_parameters(self, prefix="TwoSphereCase.")
        self.law()  # the contact law's own ranges (gamma >= 0, ...), before any mesh

    @property
    def symmetry_factor(self) -> float:
        """Whole pair / modelled part: 4 for the quarter, 360 / angle for the wedge."""
        return 4.0 if self.model == "quarter" else 360.0 / self.wedge_angle

    @property
    def sigma_c(self) -> float:
        """Adhesive strength sigma_c = ratio sigma_0 (MPa)."""
        return self.ratio * self.material.sigma_0

    @property
    def delta_max(self) -> float:
        """Separation length delta_max = 2 gamma / sigma_c (mm)."""
        return 2.0 * self.gamma / self.sigma_c

    @property
    def e_star(self) -> float:
        """E* = E / (2 (1 - nu^2)) of two identical spheres (MPa)."""
        return self.material.E / (2.0 * (1.0 - self.material.nu**2))

    def law(self) -> ContactLaw:
        """The contact law: no friction, alpha forced to 1."""
        penalty = self.penalty or default_penalty(
            self.material.E, 0.5 * self.size_min * self.radius
        )
        return ContactLaw(
            penalty=penalty,
            friction=0.0,
            gamma=self.gamma,
            delta_max=self.delta_max,
            alpha_forced=1.0,
        )

    def mesarovic_johnson(self, a, a0, F0):
        """Mesarovic-Johnson unloading force (N) at contact radius ``a`` (mm) from the
        loaded state (a0 mm, F0 N)."""
        a = np.asarray(a, dtype=float)
        p0 = F0 / (np.pi * a0**2)
        s = np.clip(a / a0, 0.0, 1.0)
        return 2 * p0 * a0**2 * (np.arcsin(s) - s * np.sqrt(1 - s**2)) - 2 * a * np.sqrt(
            2 * np.pi * a * self.gamma * self.e_star
        )


@dataclass
class TwoSphereResult:
    """The two-sphere run's history and its unloading branch."""

    history: History
    branch: UnloadingBranch  # unloading branch and its deviations from Mesarovic-Johnson
    pull_off: float | None  # approach (mm) where the static path ended in a pull-off, or None
    num_dofs: int
    wall_time: float
    newton_iterations: list  # per converged increment
    residual_norms: list  # per converged increment: Newton residual norms (N), initial first

    # the branch's figures, by their names in the result
    a0 = property(lambda self: self.branch.a0)
    F0 = property(lambda self: self.branch.F0)
    error = property(lambda self: self.branch.error)
    error_rms = property(lambda self: self.branch.error_rms)
    grid_points = property(lambda self: self.branch.grid_points)
    error_samples = property(lambda self: self.branch.error_samples)
    a_unload = property(lambda self: self.branch.a)
    F_unload = property(lambda self: self.branch.F)
    F_mj = property(lambda self: self.branch.F_mj)


def run_two_spheres(
    case: TwoSphereCase = TwoSphereCase(),
    out_dir: str | Path = "results/two_spheres",
    comm: MPI.Comm = MPI.COMM_WORLD,
    petsc_options: dict | None = None,
    log=print,
) -> TwoSphereResult:
    """Run the two-sphere case (load, then unload); the history is written to ``out_dir``."""
    r = case.radius
    if case.model == "wedge":
        assembly = wedge_sphere_pair(
            r,
            comm,
            angle=case.wedge_angle,
            size_min=case.size_min,
            cap_radius=case.refine_radius,
            grading=case.grading or 0.3,
        )
    else:
        assembly = quarter_sphere_pair(
            r, comm, size_min=case.size_min, refine_radius=case.refine_radius, grading=case.grading
        )
    problem = SolidProblem(assembly.mesh, case.material)
    V = problem.V
    contact = ContactModel(
        V, assembly.facet_tags, 2, case.law(), search_distance=max(0.02 * r, 2 * case.delta_max)
    )

    def in_core(sign):
        return lambda x: (x[0] ** 2 + x[1] ** 2 + (x[2] - sign * r) ** 2) <= (case.core * r) ** 2

    t_load, t_end = 1.0, 1.0 + case.unload_steps / case.load_steps

    def approach(t):
        if t <= t_load:
            return r * case.approach * t / t_load
        return r * float(np.interp(t, [t_load, t_end], [case.approach, case.unload_to]))

    bcs = PrescribedDisplacements(V)
    tol = 1e-9 * r
    if case.model == "quarter":
        bcs.add(component_dofs(V, lambda x: np.abs(x[0]) < tol, 0))  # symmetry planes
    else:
        on_axis = lambda x: x[0] ** 2 + x[1] ** 2 < tol**2  # noqa: E731
        bcs.add(component_dofs(V, on_axis, 0))
        bcs.add(component_dofs(V, on_axis, 1))
    bcs.add(component_dofs(V, lambda x: np.abs(x[1]) < tol, 1))
    for sign in (-1.0, 1.0):
        for c in (0, 1):
            bcs.add(component_dofs(V, in_core(sign), c))
    upper = component_dofs(V, in_core(1.0), 2)
    bcs.add(component_dofs(V, in_core(-1.0), 2), lambda t: 0.5 * approach(t))
    bcs.add(upper, lambda t: -0.5 * approach(t))
    if case.model == "wedge":
        bcs.couplings = _wedge_couplings(
            V, assembly.cell_tags, bcs.prescribed_dofs, np.radians(case.wedge_angle), tol
        )
    factor = case.symmetry_factor
    history = History(
        Path(out_dir) / f"history_{case.ratio:g}.csv",
        ["time", "approach_mm", "force_N", "contact_radius_mm", "loaded_points"],
        comm,
        flush_every_row=True,
    )  # a long run keeps its history if stopped

    newton_iterations, residual_norms = [], []

    def record(s):
        newton_iterations.append(s.snes.getIterationNumber())
        residual_norms.append(s.residual_norms)
        pairs = contact.pair_forces()
        area = factor * float(pairs["area"].sum())
        history.append(
            time=s.t,
            approach_mm=approach(s.t),
            force_N=-factor * s.reactions(upper),
            contact_radius_mm=np.sqrt(area / np.pi),
            loaded_points=float(pairs["points"].sum()),
        )
        log(
            f"  t={s.t:.3f} approach/r={approach(s.t) / r:.5f} F={history.rows[-1][2]:.4f} N "
            f"a={history.rows[-1][3]:.4f} mm points={history.rows[-1][4]:.0f} "
            f"its={s.snes.getIterationNumber()}"
        )

    start = time.perf_counter()
    solver = ImplicitSolver(problem, bcs, contact=contact, petsc_options=petsc_options)
    dt = 1.0 / case.load_steps
    control = StepControl(
        t_end=t_end,
        dt=dt,
        dt_max=dt,
        dt_min=dt / 1024,
        breakpoints=(t_load,) if t_end > t_load else (),
    )
    pull_off = None
    try:
        solver.run(control, on_step=record, log=log)
    except NonConvergence:
        # Under prescribed approach the adhesive unloading path ends where the last contact disc
        # pulls off at once (the fixed-grip JKR / Mesarovic-Johnson instability): no static
        # state continues it. Anything else is a failure.
        last = history.rows[-1] if history.rows else None
        if last is None or last[0] <= t_load or last[2] >= 0.0 or case.gamma <= 0.0:
            raise
        pull_off = float(last[1])
        log(
            f"  pull-off: the static unloading path ends at approach {pull_off:.5g} mm, F = "
            f"{last[2]:.4g} N, "
            f"a = {last[3]:.4g} mm (the remaining contact snaps; a dynamic solver would follow the "
            "jump)"
        )
    history.write()
    return TwoSphereResult(
        history,
        unloading_branch(case, history.array(), t_load),
        pull_off,
        V.dofmap.index_map.size_global * 3,
        time.perf_counter() - start,
        newton_iterations,
        residual_norms,
    )


@dataclass
class UnloadingBranch:
    """The unloading branch against Mesarovic-Johnson (mm, N) and its errors (eq. 3.21)."""

    a0: float  # contact radius (mm) at the end of loading
    F0: float  # force (N) there
    a: np.ndarray  # contact radius (mm) of the unloading samples with 0 < a < a0
    F: np.ndarray  # their force (N)
    F_mj: np.ndarray  # Mesarovic-Johnson at the same radii (N)
    error: float  # eq. 3.21 on the a / a0 grid
    grid_points: int
    error_rms: float
    error_samples: float


def unloading_branch(case: TwoSphereCase, data: np.ndarray, t_load: float = 1.0) -> UnloadingBranch:
    """The unloading branch of a two-sphere history (rows time, approach_mm, force_N,
    contact_radius_mm, ...) and its deviation from Mesarovic-Johnson (thesis eq. 3.8, 3.21)."""
    t, F, a = data[:, 0], data[:, 2], data[:, 3]
    i0 = int(np.argmin(np.abs(t - t_load)))
    a0, F0 = a[i0], F[i0]
    unloading = (t > t_load + 1e-9) & (a < a0) & (a > 0)
    F_mj = case.mesarovic_johnson(a[unloading], a0, F0)
    error, grid = eq_3_21(case, a[unloading], F[unloading], a0, F0)
    deviation = (F[unloading] - F_mj) / F0
    error_rms = float(np.sqrt(np.mean(deviation**2))) if deviation.size else float("nan")
    return UnloadingBranch(
        a0,
        F0,
        a[unloading],
        F[unloading],
        F_mj,
        error,
        int(grid.sum()),
        error_rms,
        float(np.sqrt(np.sum(deviation**2))),
    )


#: a / a0 where eq. 3.21 compares the unloading branch with Mesarovic-Johnson
ERROR_GRID = np.round(np.linspace(0.1, 0.9, 9), 12)


def eq_3_21(
    case: TwoSphereCase, a: np.ndarray, F: np.ndarray, a0: float, F0: float
) -> tuple[float, np.ndarray]:
    """Thesis eq. 3.21, e = sqrt(sum_a ((F(a) - F_MJ(a)) / (pi a0^2 p0))^2) with pi a0^2 p0 = F0,
    summed over a / a0 = 0.1, 0.2, ..., 0.9 (``ERROR_GRID``).

    The thesis leaves the sampling of a implicit, and a sum over all unloading increments grows
    with their number (x sqrt(N)): a fixed grid in a / a0 makes e a property of the curve. F(a)
    between samples: linear in a (samples at the same radius averaged). Grid points outside the
    radii the branch reached (e.g. below a pull-off radius) are left out; returns (e, mask of the
    grid points used)."""
    if a.size < 2:
        return float("nan"), np.zeros(ERROR_GRID.size, bool)
    radii, inverse = np.unique(a / a0, return_inverse=True)
    force = np.bincount(inverse, weights=F) / np.bincount(inverse)
    used = (ERROR_GRID >= radii[0]) & (ERROR_GRID <= radii[-1])
    s = ERROR_GRID[used]
    deviation = (np.interp(s, radii, force) - case.mesarovic_johnson(s * a0, a0, F0)) / F0
    return float(np.sqrt(np.sum(deviation**2))), used


def _wedge_couplings(
    V, cell_tags, prescribed: np.ndarray, theta: float, tol: float
) -> CouplingRows:
    """Cyclic-symmetry rows of the one-cell wedge: every node of the plane at angle theta follows
    its partner in the plane y = 0 (same body, radius and height) rotated by theta,
    u' = (cos theta u_x, sin theta u_x, u_z): the displacement field is exactly axisymmetric and
    the thin cells have no hoop modes of their own (rollers on both planes left each cell free to
    shear across its width, a few 1e-5 mm near the axis: Newton inverted those cells). Of the two
    copies of an axis node, the one with the larger global index follows the other (its x, y are
    prescribed to zero, so only z is tied). Slave dofs that are prescribed are left out; their
    partner's are then prescribed too (cores and axis are symmetric about the z axis)."""
    imap = V.dofmap.index_map
    bs = V.dofmap.index_map_bs
    owned = np.arange(imap.size_local, dtype=np.int32)
    X = V.tabulate_dof_coordinates()[: imap.size_local]
    rho, z = np.hypot(X[:, 0], X[:, 1]), X[:, 2]
    body = node_particles(V, cell_tags.values[: V.mesh.topology.index_map(3).size_local])
    first = np.abs(X[:, 1]) < tol  # in the plane y = 0 (axis nodes: both copies)
    gid = imap.local_to_global(owned).astype(np.int64)
    comm = V.mesh.comm
    allb, allz, allr, allg, allf = (
        np.concatenate(comm.allgather(a)) for a in (body, z, rho, gid, first)
    )
    # partners are adjacent in (body, z, rho) order; within a pair the node of the plane y = 0
    # (or, on the axis, the smaller global index) comes first
    order = np.lexsort((allg, ~allf, np.round(allr / tol), np.round(allz / tol), allb))
    allb, allz, allr, allg, allf = allb[order], allz[order], allr[order], allg[order], allf[order]
    masters, slaves = allg[0::2], allg[1::2]
    if (
        allg.size % 2
        or np.any(allb[0::2] != allb[1::2])
        or np.any(np.abs(allz[0::2] - allz[1::2]) > tol)
        or np.any(np.abs(allr[0::2] - allr[1::2]) > tol)
        or not np.all(allf[0::2])
    ):
        raise RuntimeError(
            "wedge nodes do not come in pairs (one per plane) of the same body, radius and height"
        )
    lo, hi = imap.local_range
    mine = (slaves >= lo) & (slaves < hi)
    slave_blocks, master_blocks = slaves[mine] - lo, masters[mine]
    rows, cols, coefs = [], [], []
    for c, (mc, coef) in enumerate(((0, np.cos(theta)), (0, np.sin(theta)), (2, 1.0))):
        dof = slave_blocks * bs + c
        free = ~np.isin(dof, prescribed)
        rows.append(dof[free])
        cols.append(master_blocks[free] * bs + mc)
        coefs.append(np.full(free.sum(), coef))
    rows, cols, coefs = np.concatenate(rows), np.concatenate(cols), np.concatenate(coefs)
    order = np.argsort(rows)
    return CouplingRows(
        rows[order].astype(np.int32),
        np.arange(rows.size + 1, dtype=np.int64),
        cols[order],
        coefs[order],
    )
