"""Contact of the particles' surface nodes against rigid tools (planes, a die's cylinder, STL).

One-pass node-to-surface penalty contact: every surface node this rank owns is a slave against
every tool (the tool is rigid: no master nodes, weight 1), with the tool's own contact law (the
particles' law of thesis §3.3, eq. 3.11-3.19: penalty, adhesion, Coulomb friction) and a history
per identifier (slave's global dof block, tool) kept from one converged increment to the next.

Per point (slave node s, tool i at translation c_i):
    gap g and outward normal n of the tool at x_s - c_i (mm, g < 0: penetration);
    slip increment  = (u_s - u_s,n) - (c_i - c_i,n)   (motion relative to the tool);
    force on the slave F = A (T1 n + T_t) (A the slave's tributary area projected on the tool's
    tangent plane, N);
    residual r_s -= F; tangent d r / d u_s = -dF/dx_s by central differences of the whole point
    evaluation (gap, normal, slip, law on its branches), 3 x 3 per point.
The tool's reaction is minus the sum of its points' forces (the force the particles exert on it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .history import ContactState
from .kernels import trial_shear
from .laws import evaluate_law, law_point

#: relative size of the central-difference step of the tangent (times the point's sqrt(area))
_FD_STEP = 1e-6


@numba.njit(parallel=True, cache=True)
def _law_on_branches(
    gap, slip, normal, alpha_n, smax_n, tt_n, k, kt, mu, sigma_c, delta_max, p0, forced, branch, out
):
    """Tractions (n, 4) = [T1, T_t] at every point with the law held on the given branches
    (``law_point``): the differences of the tangent never straddle a kink of the law."""
    for i in numba.prange(gap.shape[0]):
        res = np.empty(9)
        law_point(
            gap[i],
            slip[i, 0],
            slip[i, 1],
            slip[i, 2],
            normal[i, 0],
            normal[i, 1],
            normal[i, 2],
            alpha_n[i],
            smax_n[i],
            tt_n[i, 0],
            tt_n[i, 1],
            tt_n[i, 2],
            k,
            kt,
            mu,
            sigma_c,
            delta_max,
            p0,
            forced,
            branch[i],
            np.nan,
            res,
        )
        out[i, :] = res


@dataclass
class RigidEvaluation:
    """The tool contact points of this rank at one displacement (arrays of n points)."""

    slave: np.ndarray  # (n,) surface node (held numbering of the surface)
    tool: np.ndarray  # (n,) tool index
    gap: np.ndarray  # (n,) mm
    normal: np.ndarray  # (n, 3) the tool's outward normal
    T1: np.ndarray  # (n,) MPa, compression > 0
    Tt: np.ndarray  # (n, 3) MPa
    area: np.ndarray  # (n,) mm^2
    branch: np.ndarray  # (n,) law branch codes
    force: np.ndarray  # (n, 3) force on the slave node (N)
    dissipation: float  # frictional work of this trial increment on this rank (mJ)
    reference: np.ndarray  # (n, 3) the slave node's reference (undeformed) position (mm)
    trial_shear: np.ndarray  # (n,) magnitude of the trial tangential traction (MPa)

    @property
    def size(self) -> int:
        """Number of tool contact points of this rank."""
        return self.slave.size

    @staticmethod
    def empty() -> RigidEvaluation:
        """No points."""
        z = np.zeros(0)
        return RigidEvaluation(
            np.zeros(0, np.int64),
            np.zeros(0, np.int64),
            z,
            np.zeros((0, 3)),
            z,
            np.zeros((0, 3)),
            z,
            np.zeros(0, np.int64),
            np.zeros((0, 3)),
            0.0,
            np.zeros((0, 3)),
            z,
        )


class RigidContact:
    """Contact of the surface nodes of ``surface`` (a :class:`ContactSurface`) against ``tools``
    (objects with ``name``, ``shape``, ``law``, ``motion``, ``servo``: the
    :class:`~mpfem_fenicsx.tools.RigidTool`) within ``search_distance`` (mm). A servo-driven
    tool moves by :meth:`servo_step` (a workflow calls it after every explicit increment), the
    others follow their motion (:meth:`move`, called with the prescribed displacements)."""

    def __init__(self, surface, tools, search_distance: float):
        names = [t.name for t in tools]
        if len(set(names)) != len(names):
            raise ValueError(f"tool names must be unique, got {names}")
        if not tools:
            raise ValueError("rigid contact needs at least one tool")
        for tool in tools:
            if tool.law.gamma > 0 and search_distance < tool.law.delta_max:
                raise ValueError(
                    f"tool {tool.name}: contact search distance ({search_distance} mm) must be "
                    f">= its delta_max ({tool.law.delta_max} mm)"
                )
        self.surface = surface
        self.tools = list(tools)
        self.names = names
        self.distance = float(search_distance)
        self.comm = surface.comm
        nt = len(tools)
        #: current and committed translations of the tools (mm)
        self.translation = np.zeros((nt, 3))
        self.translation_committed = np.zeros((nt, 3))
        self.state = ContactState.empty()
        self.trial = ContactState.empty()
        self.evaluation = RigidEvaluation.empty()
        #: committed: work done by each tool on the particles (mJ, summed over ranks), the
        #: frictional work of the tool contacts (mJ) and each tool's force at the last commit
        self.tool_work = np.zeros(nt)
        self.frictional_work = 0.0
        self._force_committed = np.zeros((nt, 3))
        self._coo = (np.zeros(0, PETSc.IntType), np.zeros(0, PETSc.IntType), np.zeros(0))
        #: the last tangent's point tangents (n, 3, 3), dofs (n, 3), tools (n,) and translations
        none = np.zeros(0, np.int64)
        self._point_tangents = (np.zeros((0, 3, 3)), none.reshape(0, 3), none, np.zeros((nt, 3)))

    # -- motion --------------------------------------------------------------------------------
    def move(self, t: float) -> None:
        """Place the displacement-driven tools at time ``t`` (s); servo-driven tools keep the
        translation their servo set."""
        for i, tool in enumerate(self.tools):
            if tool.servo is None:
                self.translation[i] = tool.motion(t)

    def servo_step(self, t: float, dt: float) -> None:
        """Move the force-controlled tools by their servos over the next increment, from the
        particles' forces on them at time ``t`` (collective: one reduction)."""
        if all(tool.servo is None for tool in self.tools):
            return
        force = self.tool_forces()["force"]
        for i, tool in enumerate(self.tools):
            if tool.servo is not None:
                self.translation[i] += tool.servo.step(t, dt, force[i])

    # -- evaluation ----------------------------------------------------------------------------
    def _query(self, tool: int, x: np.ndarray, reach: float):
        """Indices, gaps and normals of the points ``x`` within ``reach`` of tool ``tool``."""
        return self.tools[tool].shape.gap_normal(x - self.translation[tool], reach)

    def tangential_penalties(self, tool: np.ndarray) -> np.ndarray:
        """The tangential penalty k_t (N/mm^3) of each point's tool (``tool``: tool indices)."""
        kt = np.array([t.law.kernel_parameters()[1] for t in self.tools])
        return kt[np.asarray(tool, dtype=np.int64)]

    def _law(self, tool: np.ndarray, gap, slip, normal, history, branch=None):
        """Law per tool (a loop over the few tools): T1 (n,), Tt (n, 3), alpha, smax,
        dissipation per area, branch codes; on fixed ``branch`` only [T1, Tt]."""
        n = gap.size
        alpha_n, smax_n, tt_n = history
        T1, Tt = np.zeros(n), np.zeros((n, 3))
        alpha, smax, diss, br = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n, np.int64)
        for i, t in enumerate(self.tools):
            rows = np.flatnonzero(tool == i)
            if rows.size == 0:
                continue
            params = t.law.kernel_parameters()
            args = (gap[rows], slip[rows], normal[rows], alpha_n[rows], smax_n[rows], tt_n[rows])
            if branch is None:
                out = [np.empty(rows.size), np.empty((rows.size, 3))]
                out += [np.empty(rows.size) for _ in range(3)] + [np.empty(rows.size, np.int64)]
                evaluate_law(*args, *params, *out)
                T1[rows], Tt[rows], alpha[rows], smax[rows], diss[rows], br[rows] = out
            else:
                out = np.empty((rows.size, 9))
                _law_on_branches(*args, *params, branch[rows], out)
                T1[rows], Tt[rows] = out[:, 0], out[:, 1:4]
        if branch is not None:
            return T1, Tt
        return T1, Tt, alpha, smax, diss, br

    def evaluate(
        self,
        x: np.ndarray,
        dU: np.ndarray,
        facet_normal: np.ndarray,
        facet_area: np.ndarray,
        tangent: bool = False,
    ) -> RigidEvaluation:
        """Points, law and forces at the surface positions ``x`` (held nodes, mm) with the
        displacement since the last commit ``dU`` (held nodes, mm) and the surface's facet
        normals and areas on the last converged configuration (held over an increment, so that
        the 3 x 3 tangents are the forces' whole derivative); with ``tangent`` also those
        tangents (:meth:`coo`)."""
        s = self.surface
        owned = s.owned_nodes
        found = [self._query(i, x[owned], self.distance) for i in range(len(self.tools))]
        slave = np.concatenate([owned[f[0]] for f in found]).astype(np.int64)
        tool = np.concatenate([np.full(f[0].size, i, np.int64) for i, f in enumerate(found)])
        gap = np.concatenate([f[1] for f in found])
        normal = np.concatenate([f[2] for f in found]).reshape(-1, 3)
        keys = s.blocks[slave].astype(np.int64) * len(self.tools) + tool
        alpha_n, smax_n, tt_n, work_n = self.state.history_of(keys)
        moved = self.translation - self.translation_committed
        slip = dU[slave] - moved[tool]
        area = self._projected_areas(slave, normal, facet_area, facet_normal)
        history = (alpha_n, smax_n, tt_n)
        T1, Tt, alpha, smax, diss, branch = self._law(tool, gap, slip, normal, history)
        force = area[:, None] * (T1[:, None] * normal + Tt)
        self.evaluation = RigidEvaluation(
            slave,
            tool,
            gap,
            normal,
            T1,
            Tt,
            area,
            branch,
            force,
            float(np.sum(area * diss)),
            s.X[slave],
            trial_shear(Tt, diss, self.tangential_penalties(tool)),
        )
        order = np.argsort(keys)
        self.trial = ContactState(
            keys[order], alpha[order], smax[order], Tt[order], (work_n + area * diss)[order]
        )
        if tangent:
            K = self._tangents(x, slip, history)
            dofs = s.blocks[slave][:, None] * 3 + np.arange(3)  # (n, 3)
            rows = np.repeat(dofs, 3, axis=1).ravel()
            cols = np.tile(dofs, (1, 3)).ravel()
            self._coo = (rows.astype(PETSc.IntType), cols.astype(PETSc.IntType), K.ravel())
            self._point_tangents = (K, dofs, tool, self.translation.copy())
        return self.evaluation

    def motion_residual(self) -> tuple[np.ndarray, np.ndarray]:
        """Global dof indices and values of the linearized change of the tool contacts' residual
        as the tools move from their translations at the last tangent to the current ones:
        a point's tool moved by dc sees its slave moved by -dc, so dr = -K_p dc (K_p the point's
        3 x 3 tangent). A Newton predictor adds it to the prescribed motion's load, as the
        periodic images' motion (the tools are not in the prescribed displacements)."""
        K, dofs, tool, translation = self._point_tangents
        if not K.shape[0]:
            return np.zeros(0, PETSc.IntType), np.zeros(0)
        dc = (self.translation - translation)[tool]  # (n, 3) mm
        dr = -np.einsum("pij,pj->pi", K, dc)
        return dofs.ravel().astype(PETSc.IntType), dr.ravel()

    def _projected_areas(self, slave, normal, facet_area, facet_normal) -> np.ndarray:
        """Tributary area of each point's slave node projected on the tool's tangent plane
        (mm^2): sum over the node's facets of area / nv x max(0, -n_facet . n_tool). A pressure
        on a tool carries the force pressure x projected area; the projection lets a facet that
        turns towards the tool (a particle bulging under a punch) take load gradually."""
        s = self.surface
        ptr = s.node_facet_ptr
        count = ptr[slave + 1] - ptr[slave]
        point = np.repeat(np.arange(slave.size), count)
        first = np.repeat(ptr[slave] - np.cumsum(count) + count, count)
        facets = s.node_facets[np.arange(count.sum()) + first]
        facing = np.maximum(-np.einsum("ij,ij->i", facet_normal[facets], normal[point]), 0.0)
        return np.bincount(
            point,
            weights=facet_area[facets] / s.vertices_per_facet * facing,
            minlength=slave.size,
        )

    def _tangents(self, x: np.ndarray, slip: np.ndarray, history) -> np.ndarray:
        """K (n, 3, 3) = d r / d u_s = -dF / dx_s by central differences over the slave's
        position (gap, normal, slip and the law on its current branches; area held)."""
        ev = self.evaluation
        n = ev.size
        K = np.zeros((n, 3, 3))
        if n == 0:
            return K
        h = _FD_STEP * np.sqrt(np.maximum(ev.area, 1e-30))
        xs = x[ev.slave]
        for j in range(3):
            forces = []
            for sign in (1.0, -1.0):
                step = np.zeros((n, 3))
                step[:, j] = sign * h
                gap, normal = np.empty(n), np.empty((n, 3))
                for i in range(len(self.tools)):
                    rows = np.flatnonzero(ev.tool == i)
                    if rows.size:
                        reach = self.distance + 2.0 * float(h[rows].max())
                        idx, g, nn = self._query(i, xs[rows] + step[rows], reach)
                        gap[rows], normal[rows] = np.nan, np.nan
                        gap[rows[idx]], normal[rows[idx]] = g, nn
                T1, Tt = self._law(ev.tool, gap, slip + step, normal, history, ev.branch)
                forces.append(ev.area[:, None] * (T1[:, None] * normal + Tt))
            K[:, :, j] = -(forces[0] - forces[1]) / (2.0 * h[:, None])
        return np.nan_to_num(K)

    # -- assembly ------------------------------------------------------------------------------
    def nodal_forces(self) -> tuple[np.ndarray, np.ndarray]:
        """Global dof indices and values of the tool contact forces on the bodies (N)."""
        ev = self.evaluation
        dofs = self.surface.blocks[ev.slave][:, None] * 3 + np.arange(3)
        return dofs.ravel().astype(PETSc.IntType), ev.force.ravel()

    def nodal_stiffness(self) -> np.ndarray:
        """Penalty x area of every point at its slave (held numbering, N/mm): the Gershgorin row
        sums of the tool contacts' stiffness."""
        ev = self.evaluation
        k = np.array([max(t.law.kernel_parameters()[:2]) for t in self.tools])
        return np.bincount(ev.slave, weights=k[ev.tool] * ev.area, minlength=self.surface.num_nodes)

    @property
    def coo(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rows, columns, values of the last tangent (COO, global dof indices)."""
        return self._coo

    # -- results -------------------------------------------------------------------------------
    def tool_forces(self) -> dict[str, np.ndarray]:
        """Per tool, summed over ranks: ``force`` (nt, 3) the particles exert on the tool (N);
        ``normal`` (nt,) the sum of the normal forces pressing on it (N, compression > 0);
        ``friction`` (nt, 3) the tangential forces on it (N); ``points`` (nt,) loaded points."""
        ev = self.evaluation
        nt = len(self.tools)
        local = np.zeros((nt, 8))
        if ev.size:
            np.add.at(local[:, :3], ev.tool, -ev.force)
            local[:, 3] = np.bincount(ev.tool, weights=ev.area * ev.T1, minlength=nt)
            np.add.at(local[:, 4:7], ev.tool, -ev.area[:, None] * ev.Tt)
            local[:, 7] = np.bincount(ev.tool, weights=(ev.T1 != 0.0) * 1.0, minlength=nt)
        total = self.comm.allreduce(local, op=MPI.SUM)
        return {
            "force": total[:, :3],
            "normal": total[:, 3],
            "friction": total[:, 4:7],
            "points": total[:, 7],
        }

    def tools_touched(self, num_bodies: int) -> np.ndarray:
        """(num_bodies,) the number of tools each body has loaded points on (pressing or
        adhering, T1 != 0), summed over ranks: a particle's contacts with the tools."""
        ev = self.evaluation
        local = np.zeros((num_bodies, len(self.tools)))
        loaded = ev.T1 != 0.0
        np.add.at(local, (self.surface.node_body[ev.slave[loaded]], ev.tool[loaded]), 1.0)
        return np.count_nonzero(self.comm.allreduce(local, op=MPI.SUM), axis=1)

    # -- history -------------------------------------------------------------------------------
    def commit(self) -> None:
        """End of an increment: the trial history becomes the committed one; the tools' work
        on the particles (trapezoidal over the increment) and the frictional work are added
        (collective)."""
        force = self.tool_forces()["force"]
        moved = self.translation - self.translation_committed
        # work of the tool on the particles: minus the particles' force on it, along its motion
        self.tool_work -= np.einsum("ij,ij->i", 0.5 * (force + self._force_committed), moved)
        self._force_committed = force
        self.frictional_work += self.comm.allreduce(self.evaluation.dissipation, op=MPI.SUM)
        self.state = self.trial
        self.translation_committed = self.translation.copy()

    def state_dict(self) -> dict[str, np.ndarray]:
        """This rank's committed tool-contact history and the tools' placements (checkpoints)."""
        st = self.state
        return {
            "keys": st.keys,
            "alpha": st.alpha,
            "sigma_max": st.smax,
            "tangential_traction": st.tt,
            "frictional_work": st.work,
            "translation": self.translation_committed.copy(),
            "tool_work": self.tool_work.copy(),
            "tool_force": self._force_committed.copy(),
            "total_frictional_work": np.array(self.frictional_work),
            "servo_state": np.array(
                [t.servo.state if t.servo is not None else [np.nan, 0.0] for t in self.tools]
            ),
        }

    def load_state(self, data: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict` (same tools, mesh and partition)."""
        if np.shape(data["translation"]) != self.translation.shape:
            raise ValueError(
                f"tool contact state: {np.shape(data['translation'])[0]} tools saved, "
                f"{len(self.tools)} in the model"
            )
        self.state = ContactState(
            np.asarray(data["keys"], np.int64),
            np.asarray(data["alpha"]),
            np.asarray(data["sigma_max"]),
            np.asarray(data["tangential_traction"]),
            np.asarray(data["frictional_work"]),
        )
        self.trial = self.state
        self.translation_committed = np.array(data["translation"], dtype=float)
        self.translation = self.translation_committed.copy()
        self.tool_work = np.array(data["tool_work"], dtype=float)
        self._force_committed = np.array(data["tool_force"], dtype=float)
        self.frictional_work = float(data["total_frictional_work"])
        for tool, state in zip(self.tools, data["servo_state"], strict=True):
            if tool.servo is not None:
                tool.servo.state = np.array(state, dtype=float)
