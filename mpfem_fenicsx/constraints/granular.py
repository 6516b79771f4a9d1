"""Boundary conditions of a granular volume as multipoint constraints (thesis §2.5, table 2.2).

A macroscopic gradient F0(t) is imposed on a periodic cell of sizes L = (dx, dy, dz) (mm) with
the origin at a corner; H = F0 - I. Every constrained dof gets an offset linear in H,
g = G vec(H) (vec(H)[3 i + j] = H_ij), so that

    u_full = P u_red + G vec(H(t))    (``AffineConstraint`` + the basis G of this module)

and the generalized force conjugate to H (the "auxiliary nodes" reactions of the thesis) is
R = G^T r_full (N mm) over the constraint rows: W_ext = R : dH, hence the Schmidt first Piola
stress P = R / V0 with V0 the reference cell volume (eq. 2.14 and the virtual-work argument of
§2.3).

Kinds (``kind``):
- ``GDH`` (eq. 2.12-2.13): the reference point (centre X_c) of every particle, originals and
  copies, follows u_ref = H (X_c - L/2) through a *distributing* coupling: the weighted mean of
  the nodes within 0.5 r of the centre (cubic weights w = 1 - 3 (d/R)^2 + 2 (d/R)^3, R = 0.5 r,
  normalized) equals u_ref; the nodes keep deforming. Eliminated through the node of largest
  weight: u_s = (u_ref - sum_{k != s} w_k u_k) / w_s.
- ``GDF``: the same coupling on the duplicated particles only; the particles of the volume
  (VEP) are free to rearrange.
- ``CLPS`` (Loidolt, eq. 2.15-2.16): the reference point of each copy follows the one of its
  original shifted by the deformed cell vector, sum w u(copy) - sum w u(orig) = H (L o s), and
  turns with it (eq. 2.16, ``equal_rotations``): the coupling's rotation, the weighted first moment
  theta = A^-1 sum w r x u about the coupling's weighted centroid (A = sum w (|r|^2 I - r r^T),
  the distributing coupling's rotation), is the same for copy and original. Copies are meshed as
  translates of their originals, so an exactly periodic motion satisfies both at any
  deformation. The 3 (or 6) rows of a copy are eliminated jointly through the copy's coupling dofs
  picked by a pivoted QR of its rows.
- ``CLP`` (Schmidt, eq. 2.14): every node of a copy is tied to its original,
  u(n, copy) = u(n, orig) + H (L o s); copies are stiffless and massless
  (``SolidProblem(active_cells=...)``), placed on half of the faces.
For CLP and CLPS the whole assembly may translate freely: for static solvers one surface node of a
particle of the volume is held at u = 0 (its reaction vanishes by periodicity); explicit runs
conserve momentum and keep no anchor.

Comoving carrier (``comoving=True``, default): every particle is carried, rigidly, by the
homogeneous flow at its centre X_c: u = H (X_c - L/2) + w for each of its nodes, and the unknowns
are the motions w relative to it (free nodes: offset H (X_c - L/2); slaves: their own offset plus
the masters' carriers). The particle's shape is not imposed: it deforms through contacts only.
For a static solver this is only a change of variables (and a better predictor); for explicit
dynamics the offsets carry no inertia (``ExplicitSolver``), so the imposed flow is not resisted
by the scaled masses, only the particles' motion relative to it (periodic "SLLOD" dynamics).
The auxiliary-node reactions (``macroscopic_force``) take the constraint rows without their
carriers: the forces through the copies (ties, couplings) times the lattice vectors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from scipy.spatial import cKDTree

import dolfinx

from ..boundary import boundary_kind
from ..exchange import KeyedRows
from ..meshes import node_particles
from .affine import AffineConstraint, CouplingRows


def periodic_lattice() -> np.ndarray:
    """The 27 integer shifts {-1, 0, 1}^3, zero first (periodic images of a cell)."""
    grid = np.array(np.meshgrid(*[[0, -1, 1]] * 3, indexing="ij")).reshape(3, -1).T
    return grid.astype(np.int64)


def cubic_weights(distance: np.ndarray, reach: float) -> np.ndarray:
    """Abaqus distributing-coupling cubic weights 1 - 3 (d/R)^2 + 2 (d/R)^3, normalized to sum 1."""
    s = np.clip(distance / reach, 0.0, 1.0)
    w = 1.0 - 3.0 * s**2 + 2.0 * s**3
    return w / w.sum()


@dataclass
class _Nodes:
    """The mesh nodes of the particles this rank needs (whole particles, fetched from their home
    ranks): reference coordinates X, the assembly particle they belong to and their global block
    index, sorted by particle, then block (the order of the global numbering, whatever the
    partition)."""

    X: np.ndarray
    particle: np.ndarray
    block: np.ndarray

    def carrier(self, blocks: np.ndarray, centres: np.ndarray, cell: np.ndarray) -> np.ndarray:
        """X_c - L/2 of the particle of each of ``blocks`` (global, among these nodes), mm."""
        order = np.argsort(self.block)
        pos = order[np.searchsorted(self.block[order], blocks)]
        return centres[self.particle[pos]] - 0.5 * cell


def _particle_nodes(V: dolfinx.fem.FunctionSpace, cell_particle: np.ndarray, num_particles: int):
    """Each particle's owned nodes kept whole at the particle's home rank (``KeyedRows``), and
    the particles of this rank's owned nodes."""
    imap = V.dofmap.index_map
    n_owned = imap.size_local
    particle = node_particles(V, cell_particle)
    X = V.tabulate_dof_coordinates()[:n_owned]
    block = imap.local_range[0] + np.arange(n_owned, dtype=np.int64)
    return KeyedRows(V.mesh.comm, particle, (X, block), num_particles), np.unique(particle)


def _fetch_nodes(rows: KeyedRows, particles: np.ndarray) -> _Nodes:
    """The nodes of ``particles`` (point to point from their homes), sorted as in ``_Nodes``."""
    particle, X, block = rows.fetch(particles)
    order = np.lexsort((block, particle))
    return _Nodes(X[order], particle[order], block[order])


def _anchor_particle(kind: str, is_copy: np.ndarray, original: np.ndarray) -> int:
    """The particle whose outermost node holds the rigid translation (CLP / CLPS): the first
    particle of the volume that is neither a copy nor, for CLP, copied."""
    used = np.unique(original[is_copy]) if boundary_kind(kind).tied_nodes else np.zeros(0)
    candidates = np.flatnonzero(~is_copy & ~np.isin(np.arange(is_copy.size), used))
    if not candidates.size:
        raise ValueError(
            f"{kind}: every particle has a copy; no node left to anchor the rigid "
            "translation (use a larger cell)"
        )
    return int(candidates[0])


class GranularBoundaryConditions:
    """GDH / GDF / CLPS / CLP on a particle assembly, driven by ``gradient(t)`` -> F0 (3, 3).

    Args:
        V: displacement space of the assembly mesh.
        cell_particle: assembly particle index of every owned cell.
        centres, radii: (n, 3), (n,) reference centres and radii of the assembly particles,
            originals first.
        original, shift: (n,) original particle of each assembly particle and (n, 3) integer
            lattice shift (zero for the originals).
        cell: (3,) periodic cell sizes (mm).
        kind: one of GDH, GDF, CLPS, CLP.
        gradient: callable t -> F0(t) (3, 3).
        coupling_radius: reach of the distributing coupling as a fraction of r (thesis: 0.5).
        images: a ContactModel whose periodic images follow the deformed cell, shifts
            F0 (L o s) for the 26 neighbours s (CLP realized by contact with periodic images,
            beyond the thesis; then no copies are needed and only the rigid translation is
            fixed).
        anchor: CLP/CLPS only: hold one node against the free rigid translation (needed by a
            static solver; an explicit run conserves momentum and needs none).
        comoving: carry every particle with the homogeneous flow at its centre, H (X_c - L/2)
            (see the module notes).
        equal_rotations: CLPS only: impose eq. 2.16 (copy and original reference points turn
            alike) next to eq. 2.15; False leaves the copies' rotation free.
    """

    def __init__(
        self,
        V,
        cell_particle,
        centres,
        radii,
        original,
        shift,
        cell,
        kind: str,
        gradient,
        *,
        coupling_radius: float = 0.5,
        images=None,
        anchor: bool = True,
        comoving: bool = True,
        equal_rotations: bool = True,
    ):
        rules = boundary_kind(kind)
        if not 0.0 < coupling_radius < 1.0:
            raise ValueError(
                f"coupling_radius must be in (0, 1) (fraction of r), got {coupling_radius}"
            )
        self.V = V
        self.kind = kind
        self.images = images
        self.gradient = gradient
        self.cell = np.asarray(cell, dtype=float)
        centres = np.asarray(centres, dtype=float)
        radii = np.asarray(radii, dtype=float)
        original = np.asarray(original, dtype=np.int64)
        shift = np.asarray(shift, dtype=np.int64)
        is_copy = np.any(shift != 0, axis=1)
        # the particles this rank needs: those of its nodes, their copies' originals, and the
        # anchor's particle
        rows, local = _particle_nodes(V, np.asarray(cell_particle, dtype=np.int64), radii.size)
        needed = np.union1d(local, original[local])
        if rules.periodic and anchor:
            needed = np.union1d(needed, [_anchor_particle(kind, is_copy, original)])
        nodes = _fetch_nodes(rows, needed)
        #: bytes of particle nodes this rank received (setup: homes and fetch)
        self.bytes_received = rows.bytes_received
        self.num_particles = radii.size
        self.comoving = comoving
        self.anchor_block = None  # global dof block of the anchored node (CLP/CLPS with anchor)
        self.anchor_carrier = np.zeros(3)  # its prescribed displacement is H anchor_carrier (mm)
        self._nodes = nodes
        self._centres = centres
        # (slave blocks, masters (k, m) blocks, coeffs, G (k, 3, 9)): per component
        self._rows: list[tuple] = []
        # (slave dofs (k,), master dofs (k, m), coeffs, G (k, 9)): unrolled
        self._dof_rows: list[tuple] = []
        self._prescribed: list[tuple] = []  # (blocks, G (k, 9)) for all 3 components

        starts = np.searchsorted(nodes.particle, np.arange(radii.size + 1))
        self._members = {int(p): np.arange(starts[p], starts[p + 1]) for p in needed}

        # each rank builds the rows of its own particles (the owner of a row's slave keeps it)
        if rules.driven != "none":
            driven = np.arange(radii.size) if rules.driven == "all" else np.flatnonzero(is_copy)
            for p in np.intersect1d(driven, local):
                self._add_coupling(
                    nodes, p, centres[p], radii[p], coupling_radius, centres[p] - 0.5 * self.cell
                )
        elif not rules.tied_nodes:  # CLPS: reference points
            for p in np.intersect1d(np.flatnonzero(is_copy), local):
                self._add_periodic_coupling(
                    nodes,
                    p,
                    original[p],
                    centres,
                    radii[p],
                    coupling_radius,
                    shift[p] * self.cell,
                    equal_rotations,
                )
        else:
            self._add_ties(nodes, is_copy, original, shift)
        if rules.periodic and anchor:
            self._add_anchor(nodes, centres, radii, is_copy, original)
        self._build()

    # -- construction -------------------------------------------------------------------------
    def _coupling_nodes(self, nodes, p, centre, radius, fraction):
        members = self._members[p]
        d = np.linalg.norm(nodes.X[members] - centre, axis=1)
        inside = d <= fraction * radius
        if inside.sum() < 4:
            raise ValueError(
                f"particle {p}: fewer than 4 nodes within {fraction} r of the centre; "
                "refine the particle mesh or raise coupling_radius"
            )
        sel = members[inside]
        return sel, cubic_weights(d[inside], fraction * radius)

    def _add_coupling(self, nodes, p, centre, radius, fraction, offset):
        """Distributing coupling of particle p (GDH / GDF): sum w u(p) = H offset, eliminated
        through the node of largest weight."""
        sel, w = self._coupling_nodes(nodes, p, centre, radius, fraction)
        s = int(np.argmax(w))
        others = np.delete(np.arange(sel.size), s)
        G = np.zeros((3, 9))
        for i in range(3):
            G[i, 3 * i : 3 * i + 3] = offset / w[s]
        self._rows.append(
            (
                np.array([nodes.block[sel[s]]]),
                nodes.block[sel[others]][None, :],
                (-w[others] / w[s])[None, :],
                G[None],
            )
        )

    def _coupling_operator(self, nodes, p, centre, radius, fraction, rotations):
        """Rows C (3 or 6, 3 n) of particle p's coupling, on its n coupling nodes' unrolled dofs
        (returned, global): the weighted mean displacement sum w u (mm) and, with ``rotations``,
        r_p theta = r_p A^-1 sum w r x u (mm; r the offset from the weighted centroid)."""
        sel, w = self._coupling_nodes(nodes, p, centre, radius, fraction)
        dofs = (3 * nodes.block[sel][:, None] + np.arange(3)).ravel()
        C = np.zeros((6 if rotations else 3, sel.size, 3))
        for i in range(3):
            C[i, :, i] = w
        if rotations:
            r = nodes.X[sel] - w @ nodes.X[sel]
            A = (w * np.einsum("ki,ki->k", r, r)).sum() * np.eye(3) - np.einsum(
                "k,ki,kj->ij", w, r, r
            )
            # (r x u)_i = eps_ijk r_j u_k: the moment rows per node
            eps = np.zeros((3, 3, 3))
            eps[0, 1, 2] = eps[1, 2, 0] = eps[2, 0, 1] = 1.0
            eps[0, 2, 1] = eps[2, 1, 0] = eps[1, 0, 2] = -1.0
            moment = np.einsum("ijk,nj,n->ink", eps, r, w)
            C[3:] = radius * np.einsum("ij,jnk->ink", np.linalg.inv(A), moment)
        return C.reshape(C.shape[0], -1), dofs

    def _add_periodic_coupling(self, nodes, p, q, centres, radius, fraction, offset, rotations):
        """CLPS copy p of original q (eq. 2.15, and 2.16 with ``rotations``):
        C_p u_p - C_q u_q = [H offset; 0]. The copy's rows are solved for the dofs of the pivots
        of a column-pivoted QR of C_p (a well-conditioned square block), in terms of its other
        coupling dofs and the original's."""
        from scipy.linalg import qr

        C_p, dofs_p = self._coupling_operator(nodes, p, centres[p], radius, fraction, rotations)
        C_q, dofs_q = self._coupling_operator(nodes, q, centres[q], radius, fraction, rotations)
        m = C_p.shape[0]
        pivots = qr(C_p, mode="r", pivoting=True)[1][:m]
        rest = np.setdiff1d(np.arange(C_p.shape[1]), pivots)
        D = np.linalg.inv(C_p[:, pivots])
        coeffs = np.hstack([-D @ C_p[:, rest], D @ C_q])
        masters = np.concatenate([dofs_p[rest], dofs_q])
        E = np.zeros((m, 9))
        for i in range(3):
            E[i, 3 * i : 3 * i + 3] = offset
        self._dof_rows.append(
            (dofs_p[pivots], np.broadcast_to(masters, (m, masters.size)), coeffs, D @ E)
        )

    def _add_ties(self, nodes, is_copy, original, shift):
        """CLP: every node of every copy tied to the coincident node of its original."""
        orig_mask = ~is_copy[nodes.particle]
        if not orig_mask.any() or orig_mask.all():  # no copy (or no original) on this rank
            return
        tree = cKDTree(nodes.X[orig_mask])
        orig_index = np.flatnonzero(orig_mask)
        copy_nodes = np.flatnonzero(is_copy[nodes.particle])
        p = nodes.particle[copy_nodes]
        lattice = shift[p] * self.cell
        # several candidates: touching particles (e.g. the simple cubic cell) share contact nodes
        k = min(4, orig_index.size)
        dist, hit = tree.query(nodes.X[copy_nodes] - lattice, k=k)
        dist, hit = dist.reshape(-1, k), orig_index[hit.reshape(-1, k)]
        scale = float(np.max(self.cell))
        match = (dist <= 1e-9 * scale) & (nodes.particle[hit] == original[p][:, None])
        first = np.argmax(match, axis=1)
        hit = hit[np.arange(hit.shape[0]), first]
        bad = ~match[np.arange(hit.shape[0]), first]
        if np.any(bad):
            raise ValueError(
                f"CLP: {int(bad.sum())} copy nodes have no coincident node on their original "
                "(copies must be meshed exactly like their originals)"
            )
        G = np.zeros((copy_nodes.size, 3, 9))
        for i in range(3):
            G[:, i, 3 * i : 3 * i + 3] = lattice
        self._rows.append(
            (nodes.block[copy_nodes], nodes.block[hit][:, None], np.ones((copy_nodes.size, 1)), G)
        )

    def _add_anchor(self, nodes, centres, radii, is_copy, original):
        """Fix the rigid translation: the outermost node of a particle of the volume, which is
        never a coupling master (CLPS couples the central nodes); CLP ties every node of a copied
        particle, so there the particle must have no copy."""
        p = _anchor_particle(self.kind, is_copy, original)
        members = self._members[p]
        k = members[np.argmax(np.linalg.norm(nodes.X[members] - centres[p], axis=1))]
        # any translation of the whole is equivalent by periodicity; the node moves with its
        # particle's carrier H (X_c - L/2) (comoving), which the rest of the particle follows
        # too: held at u = 0, it would pull its particle back against the carrier and load the
        # implicit pseudo-time drag on that one node at every step
        self.anchor_carrier = (centres[p] - 0.5 * self.cell) if self.comoving else np.zeros(3)
        G = np.zeros((1, 3, 9))
        for i in range(3):
            G[0, i, 3 * i : 3 * i + 3] = self.anchor_carrier
        self._prescribed.append((np.array([nodes.block[k]]), G))
        self.anchor_block = int(nodes.block[k])

    def _build(self) -> None:
        """Keep the rows whose slave this rank owns; create the AffineConstraint."""
        V = self.V
        imap = V.dofmap.index_map
        lo, hi = imap.local_range
        rows = list(self._dof_rows)
        for blocks, mblocks, c, G in self._rows:  # per component, unrolled
            rows += [(3 * blocks + i, 3 * mblocks + i, c, G[:, i]) for i in range(3)]
        slave_dofs, indptr, masters, coeffs, g_rows = [], [0], [], [], []
        for dofs, mdofs, c, G in rows:
            owned = (dofs >= 3 * lo) & (dofs < 3 * hi)
            slave_dofs.append(dofs[owned] - 3 * lo)
            masters.append(mdofs[owned].ravel())
            coeffs.append(c[owned].ravel())
            indptr.append(np.full(owned.sum(), mdofs.shape[1], np.int64))
            g_rows.append(G[owned])
        pres_dofs, pres_G = [], []
        for blocks, G in self._prescribed:
            owned = (blocks >= lo) & (blocks < hi)
            for i in range(3):
                pres_dofs.append((blocks[owned] - lo) * 3 + i)
                pres_G.append(G[owned, i])
        slaves = np.concatenate(slave_dofs) if slave_dofs else np.zeros(0, np.int64)
        counts = np.concatenate(indptr[1:]) if len(indptr) > 1 else np.zeros(0, np.int64)
        couplings = CouplingRows(
            slaves.astype(np.int32),
            np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
            np.concatenate(masters) if masters else np.zeros(0, np.int64),
            np.concatenate(coeffs) if coeffs else np.zeros(0),
        )
        prescribed = np.concatenate(pres_dofs) if pres_dofs else np.zeros(0, np.int64)
        self.constraint = AffineConstraint(V, prescribed, couplings)
        order = np.argsort(prescribed)
        constrained = np.concatenate([slaves, prescribed[order]]).astype(np.int32)
        G_slaves = np.concatenate(g_rows) if g_rows else np.zeros((0, 9))
        blocks_G = [G_slaves] + ([np.concatenate(pres_G)[order]] if pres_G else [])
        G = np.concatenate(blocks_G)
        #: the auxiliary nodes' part of G (eq. 2.14 / 2.15, no carrier) on the constrained dofs
        self._G_auxiliary = G.copy()
        self._constrained = constrained
        #: owned dofs with an offset G vec(H) (constrained ones, and the free ones when comoving)
        self.offset_dofs = constrained
        if self.comoving:
            G[: slaves.size] += self._slave_carriers(slaves, couplings)
            free = self.constraint.free
            X = self._carrier(lo + free // 3)
            G_free = np.zeros((free.size, 9))
            for j in range(3):
                G_free[np.arange(free.size), 3 * (free % 3) + j] = X[:, j]
            self.offset_dofs = np.concatenate([constrained, free]).astype(np.int32)
            G = np.concatenate([G, G_free])
        self.G = G

    def _carrier(self, blocks: np.ndarray) -> np.ndarray:
        """X_c - L/2 of the particle of each node ``blocks`` (global), (n, 3) mm."""
        return self._nodes.carrier(blocks, self._centres, self.cell)

    def _slave_carriers(self, slaves, couplings) -> np.ndarray:
        """Carrier part of the slave offsets: u_s = sum_k c_k (w_k + [H (X_k - L/2)]_(i_k)) + g_s
        for master dof k of component i_k, i.e. sum_k c_k X_kj at H_(i_k j) in the G vec(H) form,
        (num slaves, 9), X_k - L/2 the carrier position of master k (``_carrier``)."""
        counts = np.diff(couplings.indptr)
        row = np.repeat(np.arange(slaves.size), counts)
        component = couplings.masters % 3
        X = self._carrier(couplings.masters // 3)
        G = np.zeros((slaves.size, 9))
        for j in range(3):
            np.add.at(G, (row, 3 * component + j), couplings.coefficients * X[:, j])
        return G

    # -- PrescribedDisplacements interface (used by the solvers) -------------------------------
    def build(self) -> AffineConstraint:
        """The affine constraint u = P u_red + g of these conditions."""
        return self.constraint

    def displacement_gradient(self, t: float) -> np.ndarray:
        """H(t) = F0(t) - I (3, 3) of the loading path at time t (s)."""
        F0 = np.asarray(self.gradient(t), dtype=float)
        return F0 - np.eye(3)

    def apply(self, t: float) -> None:
        """Offsets g = G vec(F0(t) - I) on every constrained dof."""
        H = self.displacement_gradient(t)
        self._H = H
        self.constraint.set_values(self.offset_dofs, self.G @ H.ravel())
        if self.images is not None:
            self.images.set_periodic_images(periodic_lattice(), ((H + np.eye(3)) * self.cell).T)

    def image_force(self) -> np.ndarray | None:
        """(3, 3) generalized force (N mm) of the periodic images at the current contact state,
        conjugate to H = F0 - I (the images' part of :meth:`macroscopic_force`): their work rate
        enters the external work, which the nodal reactions of a model without copies do not carry.
        None without images."""
        if self.images is None:
            return None
        return self.images.image_moment() @ np.linalg.inv(self._H + np.eye(3)).T

    # -- results --------------------------------------------------------------------------------
    def macroscopic_force(self, reaction: np.ndarray) -> np.ndarray:
        """Reactions of the thesis' auxiliary nodes (N mm, (3, 3), conjugate to H = F0 - I), from
        the full reaction vector's owned values (N), summed over ranks: the forces that cross the
        cell boundary, R = sum over the tie / coupling slaves of r (x) (L o s) (eq. 2.14, CLPS
        eq. 2.15), plus the periodic images' contacts. The Schmidt stress P = R / V0 (eq. 2.19).

        Only the constraint rows count, not the comoving carriers of the free nodes: summed over
        every row, R would be sum_k f_k (x) (X_j - X_i) over all contacts whatever the state -- an
        algebraic copy of Love-Weber with reference branch vectors. The boundary reactions equal
        the volume's stress only when every particle is in equilibrium, which is what a
        comparison with Love-Weber then verifies."""
        G = self._G_auxiliary
        local = G.T @ reaction[self._constrained] if G.size else np.zeros(9)
        R = self.V.mesh.comm.allreduce(local, op=MPI.SUM).reshape(3, 3)
        if self.images is not None:  # image shifts S = F0 (L o s): dW = pf . dH (L o s)
            R += self.image_force()
        return R
