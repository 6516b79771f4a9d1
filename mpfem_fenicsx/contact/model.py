"""Contact model: search + law + history + assembly into the PETSc residual and Jacobian.

Node-to-surface penalty contact, two-pass: every surface node of every body is a slave against
the facets of the other bodies, and each pass carries half of the force (weight 1/2), so the
treatment is symmetric. A contact point is identified by (slave node, master body, lattice
shift); its history (alpha, sigma_max, tangential traction T_t, frictional work W_f) is kept
per identifier from one converged increment to the next (``commit``).

Per contact point with nodes a = [slave, master facet vertices] and weights c_a = [1, -N_i]:
    force on node a:  F_a = c_a w A (T1 n + T_t)       (w = 1/2, A = slave tributary area)
    residual:         r_a -= F_a                         (contact forces are external)
    tangent:          K = d r / d u by central differences of the whole point evaluation
                      (projection, normal, gap, slip, law) over its 3 (1 + nv) nodal coordinates,
                      i.e. the full node-to-surface linearization (slave area held fixed).
Entries go into PETSc with global indices (``Vec.setValues``, COO ``Mat``), so forces on master
nodes owned by another rank reach their owner.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx

from .guards import AdhesiveGuards
from .history import ContactState
from .kernels import (
    contact_areas,
    coo_entries,
    point_tangents,
    point_weights,
    relative_motion,
    slip_reversal_limit,
    trial_shear,
)
from .laws import ContactLaw, evaluate_law
from .rigid import RigidContact
from .search import (
    ContactPoints,
    ContactSearch,
    boxes_hold_a_point,
    candidate_pairs,
    corner_normals,
    facet_areas,
    surface_normals,
)
from .surface import ContactSurface

PASS_WEIGHT = 0.5  # two-pass symmetric treatment


@dataclass
class ContactEvaluation:
    """The contact points at one displacement (a trial state, :meth:`ContactModel.evaluate`),
    arrays of this rank's n slave points."""

    points: ContactPoints  # slave node, master body / facet, gap (mm), normal, lattice shift (mm)
    nodes: np.ndarray  # (n, 5) surface nodes [slave, master facet vertices] (-1: unused)
    weights: np.ndarray  # (n, 5) c_a = [1, -N_i]: a point's force on each of its nodes
    T1: np.ndarray  # (n,) normal traction (MPa, compression > 0, adhesion < 0)
    Tt: np.ndarray  # (n, 3) tangential traction (MPa)
    area: np.ndarray  # (n,) slave tributary area (mm^2)
    branch: np.ndarray  # (n,) law branch codes (laws.normal_branch / tangent branch)
    point_force: np.ndarray  # (n, 3) force on the slave, both passes' weight included (N)
    dissipation: float  # frictional work of this trial increment on this rank (mJ)
    trial_shear: np.ndarray  # (n,) magnitude of the trial tangential traction (MPa)

    @property
    def size(self) -> int:
        """Number of contact points of this rank."""
        return self.points.size

    @staticmethod
    def empty() -> ContactEvaluation:
        """No contact points, zero forces."""
        n0 = np.zeros(0)
        return ContactEvaluation(
            ContactPoints.empty(),
            np.zeros((0, 5), np.int64),
            np.zeros((0, 5)),
            n0,
            np.zeros((0, 3)),
            n0,
            np.zeros(0, np.int64),
            np.zeros((0, 3)),
            0.0,
            n0,
        )


class ContactModel:
    """Penalty / adhesive / frictional contact between the bodies tagged in ``facet_tags``.

    ``search_distance`` (mm): slave nodes within it of a master facet are contact points;
    ``shifts`` (m, 3): lattice shifts of the periodic images (mm, the zero shift first);
    ``allowed``: (bodies, bodies) pairs that may touch; ``skin`` (mm, > 0): the held facets'
    margin beyond the search distance on each rank (default: the search distance); ``tools``:
    rigid tools (:class:`~mpfem_fenicsx.tools.RigidTool`) whose contact with the surface nodes
    (:class:`~.rigid.RigidContact`, :attr:`tools`) joins the forces, tangent and history."""

    def __init__(
        self,
        V: dolfinx.fem.FunctionSpace,
        facet_tags: dolfinx.mesh.MeshTags,
        num_bodies: int,
        law: ContactLaw,
        search_distance: float,
        *,
        shifts: np.ndarray | None = None,
        allowed: np.ndarray | None = None,
        skin: float | None = None,
        tools=None,
    ):
        self.law = law
        if skin is not None and not skin > 0:
            raise ValueError(f"contact skin must be > 0 mm, got {skin}")
        self.surface = ContactSurface(V, facet_tags, num_bodies)
        if search_distance < law.delta_max and law.gamma > 0:
            raise ValueError(
                f"contact search distance ({search_distance} mm) must be >= delta_max "
                f"({law.delta_max} mm) so that adhesive points are tracked"
            )
        self.search = ContactSearch(self.surface, search_distance, shifts, allowed)
        #: the contact with rigid tools (None without tools)
        self.tools = RigidContact(self.surface, tools, search_distance) if tools else None
        self.comm = V.mesh.comm
        #: margin (mm) of the held facets beyond the search distance (default: the search
        #: distance): the held set is rebuilt when surfaces may have approached by more than it
        #: (a Verlet list; the flagship at 6000 increments rebuilds every ~150 steps)
        self.skin = float(skin) if skin is not None else float(search_distance)
        self.halo_builds = 0
        self.state = ContactState.empty()
        self.trial = ContactState.empty()
        #: committed displacement of this rank's owned dofs (the held nodes' values scatter
        #: from it whenever the held set changes)
        self._owned_committed = np.zeros(self.surface.num_owned_values)
        self.shifts_committed = self.search.shifts.copy()
        self._size_floor = 1e-12 * self._model_extent()
        self._build_halo(self._owned_committed)
        self.U_committed = np.zeros((self.surface.num_nodes, 3))
        #: the last :meth:`evaluate` (empty before the first)
        self.evaluation = ContactEvaluation.empty()
        self._geometry: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self.guards = AdhesiveGuards()  # the adhesive law's iterates within an increment
        self._coo = (np.zeros(0, PETSc.IntType), np.zeros(0, PETSc.IntType), np.zeros(0))
        #: the last tangent evaluation's point tangents, nodes, image indices and shifts (mm)
        self._point_tangents: tuple | None = None
        self.frictional_work = 0.0  # committed, summed over ranks, mJ
        self.search_time = 0.0  # accumulated wall time of the search (s), for benchmarks
        self.halo_time = 0.0  # accumulated wall time of the halo builds after the first (s)
        self._V = V

    def set_periodic_images(self, lattice: np.ndarray, cell_vectors: np.ndarray) -> None:
        """Images of the masters shifted by ``lattice @ cell_vectors`` (lattice (m, 3) integers,
        the zero shift first; cell_vectors (3, 3), rows = current cell vectors F0 (L_i e_i), mm).
        Called whenever the macroscopic gradient changes (periodic conditions by images)."""
        self.search.shifts = np.asarray(lattice, dtype=float) @ np.asarray(
            cell_vectors, dtype=float
        )

    def image_moment(self) -> np.ndarray:
        """sum over the points whose master is a periodic image of (force on the slave) x (image
        shift) (N mm, (3, 3), summed over ranks): the work-conjugate of the shifts, i.e. what the
        copies' ties transmit in fully periodic conditions (Schmidt stress by images)."""
        local = np.zeros((3, 3))
        if self.evaluation.size:
            local = self.evaluation.point_force.T @ self.evaluation.points.shift
        return self.comm.allreduce(local, op=MPI.SUM)

    # -- the held bodies (halo) -----------------------------------------------------------------
    def _model_extent(self) -> float:
        """Largest extent (mm) of the reference surface (one reduction of 6 numbers)."""
        X = self.surface.X[self.surface.owned_nodes]
        lo = X.min(axis=0) if X.size else np.full(3, np.inf)
        hi = X.max(axis=0) if X.size else np.full(3, -np.inf)
        glo, ghi = np.empty(3), np.empty(3)
        self.comm.Allreduce(lo, glo, op=MPI.MIN)
        self.comm.Allreduce(hi, ghi, op=MPI.MAX)
        return float(np.max(ghi - glo))

    def _build_halo(self, owned_u: np.ndarray) -> None:
        """Hold what this rank's slave nodes may touch before the next build, at displacement
        ``owned_u`` (this rank's owned dof values): their own bodies whole, and of every body
        that may come within reach (the search distance + skin) of one of them (periodic images
        and ``allowed`` pairs included) the facets within that reach, with their rings; remember
        the configuration for :meth:`_refresh_halo`. Collective.

        Distances are per coordinate (the narrow phase tests facet boxes inflated by the search
        distance in each coordinate): a facet is held when its box, inflated by the reach,
        holds a slave node; a body is fetched when its bounding sphere comes within sqrt(3)
        (reach + half the largest facet side) of a slave body's, so that no such facet is
        missed."""
        s = self.surface
        owned = s.owned_nodes
        x = s.X.copy()  # only the owned (slave) nodes are current: all that the boxes read
        x[owned] += owned_u.reshape(-1, 3)[s.owned_local_blocks]
        facet_size = self.comm.allreduce(self._largest_facet_side(x), op=MPI.MAX)
        body_reach = self.search.distance + self.skin + 0.5 * facet_size
        boxes = s.owned_body_boxes(x)
        present = np.flatnonzero(np.all(np.isfinite(boxes), axis=(1, 2)))
        allowed = self.search.allowed
        slaves = np.searchsorted(present, s.slave_bodies)
        pairs, shift_index = candidate_pairs(
            boxes[present],
            body_reach,
            self.search.shifts,
            None if allowed is None else allowed[np.ix_(present, present)],
            slaves=slaves,
        )
        # bounding spheres are much tighter than boxes for round particles
        centre, radius = s.owned_body_spheres(x, boxes)
        centre, radius = centre[present], radius[present]
        gap = np.linalg.norm(
            centre[pairs[:, 0]] - centre[pairs[:, 1]] - self.search.shifts[shift_index], axis=1
        )
        near = gap <= radius[pairs[:, 0]] + radius[pairs[:, 1]] + np.sqrt(3.0) * body_reach
        pairs, shift_index = pairs[near], shift_index[near]
        masters = present[pairs[:, 1]] if len(pairs) else np.zeros(0, np.int64)
        # the configuration of the build, for the rebuild criterion (owned nodes: the same
        # nodes in the same order for any held set)
        self._built_x = x[owned]
        self._built_u = owned_u.reshape(-1, 3)[s.owned_local_blocks]
        s.hold(
            masters,
            owned_u,
            select=lambda xf, body: self._within_reach(xf, body, x[owned], masters, shift_index),
        )
        moment = np.zeros((4, 4))
        if owned.size:
            xb1 = np.column_stack([self._built_x, np.ones(owned.size)])
            moment = xb1.T @ xb1
        self._built_moment = self.comm.allreduce(moment, op=MPI.SUM)
        self._built_facet_size = facet_size
        # every rank holds the whole surface (one rank, or a few particles cut over every rank):
        # no later build can change the held set
        whole = bool(np.all(np.isin(np.flatnonzero(s.home >= 0), s.slave_bodies)))
        self._holds_all = self.comm.allreduce(whole, op=MPI.LAND)
        self.halo_builds += 1
        self._built_shifts = self.search.shifts.copy()

    def _largest_facet_side(self, x: np.ndarray) -> float:
        """Largest side of the boxes of this rank's slave bodies' facets at positions x (only
        the owned nodes of x need be current: a facet's box from the owned among its nodes)."""
        s = self.surface
        mine = np.isin(s.facet_body, s.slave_bodies)
        facets = s.facets[mine, : s.vertices_per_facet]
        if facets.size == 0:
            return 0.0
        owned = np.zeros(s.num_nodes, dtype=bool)
        owned[s.owned_nodes] = True
        xf = np.where(owned[facets][..., None], x[facets], np.nan)
        return float(np.nan_to_num(np.nanmax(xf, axis=1) - np.nanmin(xf, axis=1)).max())

    def _within_reach(self, xf, body, slave_x, masters, shift_index) -> np.ndarray:
        """Facets (vertex positions xf (m, 4, 3), bodies (m,)) the narrow phase can test before
        the next build: those whose box, inflated by the search distance + skin, holds a slave
        node (``slave_x``) in one of the lattice shifts by which their body is a candidate
        master (``masters``, ``shift_index``)."""
        chosen = np.zeros(len(body), dtype=bool)
        if slave_x.shape[0] == 0 or len(body) == 0:
            return chosen
        reach = self.search.distance + self.skin
        lo, hi = xf.min(axis=1) - reach, xf.max(axis=1) + reach
        # every (facet, shift) of its body's candidate shifts, without a loop over the facets
        ns = len(self.search.shifts)
        combos = np.unique(masters * ns + shift_index)
        order = np.argsort(body, kind="stable")
        ptr = np.searchsorted(body[order], np.stack([combos // ns, combos // ns + 1]))
        count = ptr[1] - ptr[0]
        first = np.repeat(ptr[0] - np.cumsum(count) + count, count)
        rows = order[np.arange(count.sum(), dtype=np.int64) + first]
        shift = self.search.shifts[np.repeat(combos % ns, count)]
        hit = boxes_hold_a_point(lo[rows] + shift, hi[rows] + shift, slave_x)
        chosen[rows[hit]] = True
        return chosen

    def _approach_bound(self, U: np.ndarray) -> float:
        """Upper bound (mm, per coordinate) of how much closer than at the last build any slave
        node and any master facet (images included) have come, from the held displacement U.

        The motion since the build is split into the affine map that fits it best over every
        slave node (A x_b + c, least squares: one reduction of 12 numbers) and the rest w. Two
        points d apart at the build (per coordinate) have approached by at most
        2 max|w| + |A|_inf d, and an image also by its shift's departure from the affine map,
        |A s_b - (s - s_b)|_inf. A facet not held was farther than the reach r from every slave
        node (in its box's coordinate farthest from it), with its vertices within r + h (h: the
        largest facet side at the build); so the bound is
            2 max|w| + |A|_inf (r + h) + max_k |A s_k,b - (s_k - s_k,b)|_inf,
        and nothing the narrow phase would test is missed while it stays below the skin. Under
        a uniform strain (periodic images, a carrier) w stays small: the held set follows the
        flow without rebuilds. Collective (two reductions)."""
        s = self.surface
        owned = s.owned_nodes
        du = U[owned] - self._built_u
        rhs = np.zeros((4, 3))
        if owned.size:
            rhs = np.column_stack([self._built_x, np.ones(owned.size)]).T @ du
        rhs = self.comm.allreduce(rhs, op=MPI.SUM)
        fit = np.linalg.lstsq(self._built_moment, rhs, rcond=None)[0]  # (4, 3): [A^T; c]
        A, c = fit[:3].T, fit[3]
        local = float(np.abs(du - self._built_x @ A.T - c).max()) if owned.size else 0.0
        w = self.comm.allreduce(local, op=MPI.MAX)
        if self.search.shifts.shape != self._built_shifts.shape:
            return np.inf
        moved = self.search.shifts - self._built_shifts
        images = float(np.abs(self._built_shifts @ A.T - moved).max())
        reach = self.search.distance + self.skin
        norm = float(np.abs(A).sum(axis=1).max())
        return 2.0 * w + norm * (reach + self._built_facet_size) + images

    def _refresh_halo(self, U: np.ndarray) -> np.ndarray:
        """Rebuild the held set if surfaces may have approached by more than the skin since the
        last build (:meth:`_approach_bound`), unless every rank holds the whole surface; returns
        U on the (possibly new) held set. Collective."""
        s = self.surface
        if self._holds_all or self._approach_bound(U) <= self.skin:
            return U
        start = time.perf_counter()
        owned_now = np.zeros_like(self._owned_committed)
        owned_now.reshape(-1, 3)[s.owned_local_blocks] = U[s.owned_nodes]
        self._build_halo(owned_now)
        self.U_committed = s.gather_owned_array(self._owned_committed)
        self._geometry = None
        U = s.gather_owned_array(owned_now)
        self.halo_time += time.perf_counter() - start
        return U

    # -- evaluation ------------------------------------------------------------------------------
    def _keys(self, pts: ContactPoints) -> tuple[np.ndarray, np.ndarray]:
        """History keys (slave's global dof block, master body, shift id) of the points (the
        same for every partition), and their shift ids."""
        nb = self.surface.num_bodies
        ns = len(self.search.shifts)
        shift_id = pts.shift_index
        slave = self.surface.blocks[pts.slave]
        return (slave * nb + pts.master_body) * ns + shift_id, shift_id

    def evaluate(self, u: dolfinx.fem.Function, tangent: bool = False) -> ContactEvaluation:
        """Search, law and forces at displacement u (trial state; see :meth:`commit`); with
        ``tangent`` also the contact tangent (:meth:`tangent_matrix`)."""
        s = self.surface
        U = self._refresh_halo(s.gather(u))
        x = s.X + U
        start = time.perf_counter()
        pts = self.search(x, self.corner_normals())
        pts.master_body = s.bodies[pts.master_body]  # held index -> body id
        self.search_time += time.perf_counter() - start
        keys, shift_id = self._keys(pts)
        # image shifts at the last converged state: a deforming periodic cell moves the images
        shift_n = (
            self.shifts_committed[shift_id]
            if self.shifts_committed.shape == self.search.shifts.shape
            else pts.shift
        )
        # history of the points already in contact at the last converged state
        alpha_n, smax_n, tt_n, work_n = self.state.history_of(keys)
        self.guards.adjust_history(keys, alpha_n, smax_n)

        n = pts.size
        nodes = np.empty((n, 5), np.int64)
        weights = np.empty((n, 5))
        point_weights(s.facets, s.vertices_per_facet, pts.slave, pts.facet, pts.xi, nodes, weights)
        jump = relative_motion(nodes, weights, U - self.U_committed)
        jump -= pts.shift - shift_n  # relative motion includes the image's displacement
        _, facet_normal, facet_area = self.committed_geometry()
        area = np.empty(n)
        if n:
            contact_areas(
                pts.slave,
                pts.normal,
                s.node_facet_ptr,
                s.node_facets,
                facet_area,
                facet_normal,
                s.vertices_per_facet,
                area,
            )

        T1 = np.empty(n)
        Tt = np.empty((n, 3))
        alpha = np.empty(n)
        smax = np.empty(n)
        dissipation = np.empty(n)
        branch = np.empty(n, np.int64)
        params = self.law.kernel_parameters()
        if n:
            evaluate_law(
                pts.gap,
                jump,
                pts.normal,
                alpha_n,
                smax_n,
                tt_n,
                *params,
                T1,
                Tt,
                alpha,
                smax,
                dissipation,
                branch,
            )
        adhesive = n and self.law.gamma > 0
        held = np.zeros(n, np.bool_)
        if adhesive:
            held = self.guards.track(keys, branch, smax_n, T1)
        scale = PASS_WEIGHT * area
        self.evaluation = ContactEvaluation(
            pts,
            nodes,
            weights,
            T1,
            Tt,
            area,
            branch,
            scale[:, None] * (T1[:, None] * pts.normal + Tt),
            float(np.sum(scale * dissipation)),
            trial_shear(Tt, dissipation, params[1]),
        )
        order = np.argsort(keys)
        self.guards.remember(keys[order], branch[order])
        self.trial = ContactState(
            keys[order], alpha[order], smax[order], Tt[order], (work_n + scale * dissipation)[order]
        )
        if self.tools is not None:
            self.tools.evaluate(x, U - self.U_committed, facet_normal, facet_area, tangent)
        if tangent:
            nn = 1 + s.vertices_per_facet
            K = np.empty((n, 3 * nn, 3 * nn))
            x_n = s.X + self.U_committed
            if n:
                point_tangents(
                    x,
                    x_n,
                    s.facets,
                    s.vertices_per_facet,
                    self.corner_normals(),
                    pts.slave,
                    pts.facet,
                    branch,
                    held,
                    T1,
                    pts.shift,
                    shift_n,
                    alpha_n,
                    smax_n,
                    tt_n,
                    scale,
                    *params,
                    K,
                )
            size = n * 9 * nn * nn
            rows = np.empty(size, PETSc.IntType)
            cols = np.empty(size, PETSc.IntType)
            vals = np.empty(size)
            k = coo_entries(nodes[:, :nn], s.blocks, K, rows, cols, vals) if n else 0
            self._coo = (rows[:k], cols[:k], vals[:k])
            self._point_tangents = (K, nodes[:, :nn], shift_id, pts.shift)
            if self.tools is not None:
                self._coo = tuple(
                    np.concatenate([a, b]) for a, b in zip(self._coo, self.tools.coo, strict=True)
                )
        return self.evaluation

    def step_limit(self, direction: dolfinx.fem.Function, slip: bool = True) -> float:
        """Largest fraction (0, 1] of a displacement update ``direction`` that Newton may take
        at the last evaluation, on the linearized gaps and slips (same on all ranks): the
        smaller of two limits, on each point's relative motion along the update
        (:func:`~.kernels.relative_motion`; a tool point's own, the tools standing still within
        an increment).

        Penetration: no open point (gap >= 0) goes deeper than the deepest current penetration.
        Newton's linearization gives an open point no contact stiffness, so on a soft (plastic)
        substrate one iteration can drive it far into the master, the next pushes it back out:
        the period-2 open / closed cycles at the rim of a growing contact. Limiting the step to
        the scale of the existing penetrations lets the point enter the contact gently and carry
        its stiffness into the next iteration (a penetration-controlled step, not a change of
        the solution).

        Slip reversal (``slip``): no slipping point goes back past the centre of its Coulomb
        cone (:func:`~.kernels.slip_reversal_limit`). Collective."""
        lam = 1.0
        pts = self.evaluation.points
        moved = self.surface.gather(direction)  # collective: on every rank, points or not
        if pts.size:
            ev = self.evaluation
            jump = relative_motion(ev.nodes, ev.weights, moved)
            lam = self._penetration_limit(pts.gap, np.einsum("pd,pd->p", jump, pts.normal))
            if slip:
                kt = self.law.kernel_parameters()[1]
                lam = min(
                    lam, slip_reversal_limit(jump, pts.normal, ev.Tt, ev.trial_shear, ev.branch, kt)
                )
        if self.tools is not None:
            ev = self.tools.evaluation
            if ev.size:
                jump = moved[ev.slave]
                dgap = np.einsum("pd,pd->p", jump, ev.normal)
                lam = min(lam, self._penetration_limit(ev.gap, dgap))
                if slip:
                    kt = self.tools.tangential_penalties(ev.tool)
                    lam = min(
                        lam,
                        slip_reversal_limit(jump, ev.normal, ev.Tt, ev.trial_shear, ev.branch, kt),
                    )
        return self.comm.allreduce(lam, op=MPI.MIN)

    def _penetration_limit(self, gap: np.ndarray, dgap: np.ndarray) -> float:
        """The penetration part of :meth:`step_limit` for points of gaps ``gap`` (mm) moving by
        ``dgap`` (mm) along the update."""
        closed = gap < 0
        depth = max(-gap[closed].min(), 0.0) if closed.any() else 0.0
        depth = max(depth, self._size_floor)
        limited = (gap >= 0) & (gap + dgap < -depth)
        return float(np.min((gap[limited] + depth) / -dgap[limited])) if limited.any() else 1.0

    def nodal_forces(self) -> tuple[np.ndarray, np.ndarray]:
        """Global dof indices and values of the contact forces on the bodies (N)."""
        nodes, weights = self.evaluation.nodes, self.evaluation.weights
        used = nodes >= 0
        f = weights[:, :, None] * self.evaluation.point_force[:, None, :]  # (n, 5, 3)
        dofs = self.surface.blocks[np.where(used, nodes, 0)][:, :, None] * 3 + np.arange(3)
        dofs, values = dofs[used].ravel().astype(PETSc.IntType), f[used].ravel()
        if self.tools is not None:
            tool_dofs, tool_values = self.tools.nodal_forces()
            dofs, values = np.concatenate([dofs, tool_dofs]), np.concatenate([values, tool_values])
        return dofs, values

    def nodal_stiffness(self) -> np.ndarray:
        """Gershgorin row sums (N/mm) of the contact stiffness at the last evaluation, at this
        rank's owned surface nodes (``surface.owned_nodes`` order), summed over the ranks whose
        points load them (zero before the first evaluation): the penalty k of the law times each
        point's loaded tributary area, spread on its nodes by |c_a|."""
        rows = np.zeros(self.surface.num_nodes)
        ev = self.evaluation
        if ev.size:
            k = max(self.law.kernel_parameters()[:2])
            used = ev.nodes >= 0
            point = 2.0 * k * PASS_WEIGHT * ev.area  # sum_b |c_b| = 2
            rows = np.bincount(
                ev.nodes[used],
                weights=(np.abs(ev.weights) * point[:, None])[used],
                minlength=self.surface.num_nodes,
            )
        if self.tools is not None:
            rows = rows + self.tools.nodal_stiffness()
        return self.surface.sum_to_owners(rows)

    def add_residual(self, r: PETSc.Vec) -> None:
        """r -= contact forces (r is the assembled internal-force vector)."""
        dofs, values = self.nodal_forces()
        r.setValues(dofs, -values, addv=PETSc.InsertMode.ADD_VALUES)
        r.assemblyBegin()
        r.assemblyEnd()

    def add_master_motion(self, r: PETSc.Vec) -> None:
        """r += the linearized change of the contact residual as the masters that the
        prescribed offsets do not carry move from their place at the last evaluation with
        tangent to the current one: the periodic images (:meth:`set_periodic_images`; a point
        whose master is an image shifted further by dS sees its slave moved by -dS, so
        dr = -K_p[:, slave] dS on the point's nodes, K_p its point tangent) and the rigid tools
        (:meth:`~.rigid.RigidContact.motion_residual`). It is their part of a load increment's
        linearization (tied copies carry it in their offsets); zero without images and tools.
        Collective."""
        dofs, values = np.zeros(0, PETSc.IntType), np.zeros(0)
        if self._point_tangents is not None and self._point_tangents[0].shape[0]:
            K, nodes, shift_id, shift = self._point_tangents
            dS = self.search.shifts[shift_id] - shift  # (n, 3) mm
            moved = np.flatnonzero(np.any(dS != 0.0, axis=1))
            dr = -np.einsum("pij,pj->pi", K[moved][:, :, :3], dS[moved])  # (m, 3 nn)
            blocks = self.surface.blocks[nodes[moved]]  # (m, nn)
            dofs = (blocks[:, :, None] * 3 + np.arange(3)).ravel().astype(PETSc.IntType)
            values = dr.ravel()
        if self.tools is not None:
            tool_dofs, tool_values = self.tools.motion_residual()
            dofs = np.concatenate([dofs, tool_dofs]).astype(PETSc.IntType)
            values = np.concatenate([values, tool_values])
        r.setValues(dofs, values, addv=PETSc.InsertMode.ADD_VALUES)
        r.assemblyBegin()
        r.assemblyEnd()

    @property
    def tangent_pattern(self) -> tuple[np.ndarray, np.ndarray]:
        """Rows and columns (local dof indices, COO) of the last :meth:`evaluate` with ``tangent``:
        the sparsity of :meth:`tangent_matrix` (a solver rebuilds its summed matrix when it
        changes)."""
        rows, cols, _ = self._coo
        return rows, cols

    def tangent_matrix(self, template: PETSc.Mat) -> PETSc.Mat:
        """Contact tangent as a new AIJ matrix with the layout of ``template`` (any number of
        times per evaluation: PETSc sorts the COO indices it is given in place, so it gets
        copies and the entries stay paired with their values)."""
        rows, cols, vals = self._coo
        K = PETSc.Mat().create(comm=self.comm)
        K.setSizes(template.getSizes())
        K.setType(PETSc.Mat.Type.AIJ)
        K.setPreallocationCOO(rows.copy(), cols.copy())
        K.setValuesCOO(vals, addv=PETSc.InsertMode.ADD_VALUES)
        K.assemble()
        return K

    def committed_geometry(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The surface at the last converged configuration, held over an increment: the
        masters' corner normals (:func:`~mpfem_fenicsx.contact.search.corner_normals`), the
        facets' normals and areas. A point's force is its traction times its slave node's
        tributary area on that configuration, so that the residual is a function of the
        point's own nodes only and the point tangent (:func:`~.kernels.point_tangents`) is its
        exact derivative (quadratic Newton); the area lags the current one by an increment's
        surface strain."""
        if self._geometry is None:
            s = self.surface
            x_n = s.X + self.U_committed
            normals, _ = surface_normals(x_n, s.facets, s.vertices_per_facet)
            areas = facet_areas(x_n, s.facets, s.vertices_per_facet)
            self._geometry = (corner_normals(x_n, s), normals, areas)
        return self._geometry

    def corner_normals(self) -> np.ndarray:
        """Masters' corner normals at the last converged configuration
        (:meth:`committed_geometry`)."""
        return self.committed_geometry()[0]

    # -- history -------------------------------------------------------------------------------
    def begin_increment(self) -> None:
        """Start (or restart after a cut-back) an increment from the committed state.

        An adhesive point that an iterate pulls beyond delta_max loses its memory for the rest of
        the increment, as the law's erasure is irreversible (alpha reset to 0). Without this, a node
        peeling off a soft substrate re-adheres at the next iterate (the reversible trial law
        sees the committed memory again) and Newton cycles between adhered and separated: when
        the softening slope sigma_c / (delta_max - delta_1) exceeds a surface node's stiffness the
        node snaps, and the adhered branch ends at a fold. The points held at zero softening slope
        (:meth:`evaluate`) are released too."""
        self.guards.reset()

    def commit(self, u: dolfinx.fem.Function) -> None:
        """End of an increment at ``u``: the trial history becomes the committed one, the
        frictional work of the increment is added (summed over ranks)."""
        self.state = self.trial
        self.begin_increment()
        self._owned_committed = u.x.array[: self._owned_committed.size].copy()
        self.U_committed = self.surface.gather(u)
        self._geometry = None
        self.shifts_committed = self.search.shifts.copy()
        self.frictional_work += self.comm.allreduce(self.evaluation.dissipation, op=MPI.SUM)
        if self.tools is not None:
            self.tools.commit()

    def state_dict(self) -> dict[str, np.ndarray]:
        """Committed contact history of this rank's slave points, as arrays (for checkpoints):
        keys, alpha, sigma_max, tangential traction, frictional work per point, committed
        displacement of the owned surface nodes and the total frictional work."""
        st = self.state
        tools = {} if self.tools is None else self.tools.state_dict()
        return {
            **{f"tools/{k}": v for k, v in tools.items()},
            "keys": st.keys,
            "alpha": st.alpha,
            "sigma_max": st.smax,
            "tangential_traction": st.tt,
            "frictional_work": st.work,
            "surface_displacement": self.U_committed[self.surface.owned_nodes],
            "image_shifts": self.shifts_committed,
            "total_frictional_work": np.array(self.frictional_work),
        }

    def load_state(self, data: dict[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict` (same mesh and partition). Collective: the held bodies
        are rebuilt at the restored configuration."""
        s = self.surface
        if data["surface_displacement"].shape != (s.num_owned, 3):
            raise ValueError("contact state: surface size differs from this model's")
        self.state = ContactState(
            np.asarray(data["keys"], np.int64),
            np.asarray(data["alpha"]),
            np.asarray(data["sigma_max"]),
            np.asarray(data["tangential_traction"]),
            np.asarray(data["frictional_work"]),
        )
        self.trial = self.state
        self.begin_increment()
        if "image_shifts" in data:
            self.shifts_committed = np.asarray(data["image_shifts"], dtype=float).copy()
            self.search.shifts = self.shifts_committed.copy()
        self._owned_committed[:] = 0.0
        self._owned_committed.reshape(-1, 3)[s.owned_local_blocks] = data["surface_displacement"]
        self._build_halo(self._owned_committed)
        self.U_committed = s.gather_owned_array(self._owned_committed)
        self._geometry = None
        self.frictional_work = float(data["total_frictional_work"])
        if self.tools is not None:
            self.tools.load_state({k[6:]: v for k, v in data.items() if k.startswith("tools/")})

    # -- results -------------------------------------------------------------------------------
    def count(self, compressive_only: bool = False) -> int:
        """Number of contact points carrying load (summed over ranks)."""
        T1 = self.evaluation.T1
        active = T1 > 0 if compressive_only else T1 != 0
        return self.comm.allreduce(int(active.sum()), op=MPI.SUM)

    def pair_forces(self) -> dict[str, np.ndarray]:
        """Per contacting pair of bodies (and lattice shift), summed over ranks:
        ``pairs`` (m, 2) body ids (i, j) with i < j or a non-zero shift; ``shift`` (m, 3) lattice
        vector of j's image (mm); ``force`` (m, 3) force exerted by j (its image) on i (N);
        ``area`` (m,) contact area carried by the pair (mm^2, mean of both passes' loaded
        tributary areas: compressive and adhesive points); ``area_closed`` (m,) the same over its
        compressive points only (T1 > 0: the overlapping, closed part of the contact);
        ``points`` (m,) number of loaded contact points. The branch vector for
        the Love-Weber stress is centroid(j) + shift - centroid(i).
        """
        ev = self.evaluation
        if ev.size == 0:
            local = (
                np.zeros((0, 2), np.int64),
                np.zeros((0, 3)),
                np.zeros((0, 3)),
                np.zeros(0),
                np.zeros(0),
                np.zeros(0),
            )
        else:
            loaded = ev.T1 != 0.0
            slave = self.surface.node_body[ev.points.slave]
            master = ev.points.master_body
            shift = ev.points.shift
            # orient every point as (i, j, shift): the pass with slave j becomes (i, j) with -shift
            flip = (slave > master) | ((slave == master) & (shift[:, 0] < 0))
            i = np.where(flip, master, slave)
            j = np.where(flip, slave, master)
            sh = np.where(flip[:, None], -shift, shift)
            f = np.where(flip[:, None], -ev.point_force, ev.point_force)
            key = np.round(sh, 9)
            table, inverse = np.unique(np.column_stack([i, j, key]), axis=0, return_inverse=True)
            inverse = inverse.ravel()
            force = np.zeros((table.shape[0], 3))
            np.add.at(force, inverse, f)
            area = np.bincount(
                inverse, weights=PASS_WEIGHT * ev.area * loaded, minlength=table.shape[0]
            )
            closed = np.bincount(
                inverse, weights=PASS_WEIGHT * ev.area * (ev.T1 > 0.0), minlength=table.shape[0]
            )
            count = np.bincount(inverse, weights=loaded.astype(float), minlength=table.shape[0])
            local = (table[:, :2].astype(np.int64), table[:, 2:], force, area, count, closed)
        parts = self.comm.allgather(local)
        pairs = np.concatenate([p[0] for p in parts])
        shifts = np.concatenate([p[1] for p in parts])
        if pairs.shape[0] == 0:
            return {
                "pairs": pairs,
                "shift": shifts,
                "force": np.zeros((0, 3)),
                "area": np.zeros(0),
                "area_closed": np.zeros(0),
                "points": np.zeros(0),
            }
        table, inverse = np.unique(np.column_stack([pairs, shifts]), axis=0, return_inverse=True)
        inverse = inverse.ravel()
        m = table.shape[0]
        force = np.zeros((m, 3))
        np.add.at(force, inverse, np.concatenate([p[2] for p in parts]))
        area = np.bincount(inverse, weights=np.concatenate([p[3] for p in parts]), minlength=m)
        count = np.bincount(inverse, weights=np.concatenate([p[4] for p in parts]), minlength=m)
        closed = np.bincount(inverse, weights=np.concatenate([p[5] for p in parts]), minlength=m)
        return {
            "pairs": table[:, :2].astype(np.int64),
            "shift": table[:, 2:],
            "force": force,
            "area": area,
            "area_closed": closed,
            "points": count,
        }

    def body_forces(self) -> np.ndarray:
        """(num_bodies, num_bodies, 3): force (N) exerted by body j on body i, summed over ranks."""
        nb = self.surface.num_bodies
        out = np.zeros((nb, nb, 3))
        ev = self.evaluation
        if ev.size:
            slave_body = self.surface.node_body[ev.points.slave]
            np.add.at(out, (slave_body, ev.points.master_body), ev.point_force)
            np.add.at(out, (ev.points.master_body, slave_body), -ev.point_force)
        return self.comm.allreduce(out, op=MPI.SUM)
