"""The compaction history: its column schema and the measurements of one row (thesis chapter 2
and appendix C). Sign convention: reported stresses are positive in compression (sigma_m > 0 in
compaction); strains keep their sign (h_v < 0 in compaction). Units mm, N, MPa, s, mJ.

History columns (one row per output; thesis §2.3, §4.2, appendix C):
- time (s); rho = V_p / (V0 det F) (eq. 2.4-2.5: V_p = 4/3 pi sum r^3 of the particles' initial,
  meshed radii; F the least-squares gradient of the VEP centroids, eq. 2.2, C.3-C.6);
  rho_imposed (same with F0, the auxiliary-node gradient); rho_fe (the finite-element particle
  volumes / V0 det F: rho at the start for volume-exact particles, the default; less with
  ``exact_volume = false``, whose faceted particles hold less solid than their spheres; it
  follows the particles' elastic volume change);
- h_v, h_d, h_tilde_d: Hencky strain invariants of F (eq. 2.3, 2.8-2.9, 4.3-4.4; natural sign,
  h_v < 0 in compaction; Rendulic axis I = z, the die axis); nonaffine: rms distance of the
  volume's centroids from the fitted affine motion F X + c, over the mean radius (-);
- sigma_m, sigma_d, sigma_tilde_d: Love-Weber invariants (eq. 2.6, 2.10-2.11, 4.1-4.2; compression
  > 0); F11..F33 (least squares), sigma11..sigma33 (Love-Weber tensor, compression > 0, counted
  by the appendix-C rules), sigma_schmidt_11..33 (CLP/CLPS: from the auxiliary nodes' reactions,
  the forces through the ties / couplings and the periodic images times the lattice vectors,
  P = R / V0, sigma = P F0^T / det F0, eq. 2.14, 2.19, compression > 0; explicit: the medium's
  forces f_int + f_bv - f_c on the copies, without the relaxation damping and inertia; empty
  otherwise); sigma_vol_11..33, sigma_vol_m: the volume average (1/V) sum int sigma dv of the
  Cauchy stress of the volume's particles (eq. C.7, ``SolidProblem.cell_stress_integrals``;
  compression > 0). In static equilibrium the three stresses agree (CLP); they are independent
  measures (contact forces and centroids; boundary reactions; the particles' stress field). CLPS:
  the reactions also load the solid copies, which deform outside the volume, so sigma_schmidt is
  the whole model's over V0, not the volume's (a 24-particle die volume, copies at 1.5 r_max:
  2.7x Love-Weber where E_p_model / E_p = 2.8, bench/README.md);
- n_contacts: force-carrying contacts of the periodic volume (pairs with a loaded point, in
  compression or adhesive tension; appendix-C weights: one per physical contact), Z = 2 n_contacts
  / N the mean coordination number, rattlers the particles of the volume with fewer than 4
  (homogenization.coordination); Gamma = S / (V0 det F) (mm^-1, eq. 4.13, S the contact
  area of the volume, one per pair, appendix-C weights); Gamma_model: the same with S summed over
  every contact of the model (GDH / GDF / CLPS: the copies' contacts too), still over the volume's
  V, the reading of the thesis' footnote 4 of §4.4.1 ("each contact of the MPFEM model");
  Gamma_closed: Gamma over the compressive (overlapping, closed) contact points only, without the
  adhesive points in tension (Abaqus' CAREA counts the closed part of a contact; unloading an
  adhesive compact leaves Gamma nearly unchanged and lowers Gamma_closed, as the thesis' fig. 4.11
  lowers its S);
- energies (mJ): E_p plastic work of the volume's particles (eq. 4.11; GDH / GDF / CLPS copies
  deform too, outside the volume), E_f frictional (eq. 4.12; every modelled contact), E_d = E_p +
  E_f (eq. 4.10, the chapter-4 iso-dissipation criterion), E_p_model and E_d_model the same over
  the whole model (copies included; = E_p, E_d for CLP, whose copies are stiffless shells),
  E_c kinetic (of the motion relative to the imposed flow), E_int internal work, E_el stored
  elastic, E_contact work absorbed by contact, E_visc bulk viscosity, E_damp relaxation damping
  (implicit: the pseudo-time drag's work), E_mass kinetic energy added by variable mass scaling
  (mass raised at an unchanged velocity; since 2026-11-28, NaN in older histories), W_ext
  external work;
- unbalanced: out-of-balance ratio ||P^T (f_int + f_bv - f_c)|| / ||P^T f_int|| over the free dofs
  (ExplicitSolver.unbalanced_ratio: 0 in static equilibrium; implicit rows: the pseudo-time
  drag's share ||P^T f_reg|| / ||P^T f_int||, the force the converged residual holds that is not
  the medium's); E_c_over_E_int = E_c / E_int (kinetic over internal energy, -): the two
  quasi-static measures of an explicit row;
- newton_iterations and linear_iterations (of the row's increment; the linear ones include its
  predictor, 1 per solve for the direct solver), cutbacks (failed attempts so far): implicit
  rows (NaN for explicit ones);
- wall_time (s).

Quasi-static check of an explicit run (:func:`quasi_static_check`, logged at its end): the
explicit energy balance is exact, W_ext + E_mass = E_int + E_visc + E_contact + E_c + E_damp +
E_carrier, where E_carrier is the work of the damping and of the particles' inertia through the
imposed flow's offsets (``solvers.explicit``). On a quasi-static path it vanishes and a path brought
to rest leaves the volume in balance; a share of the work through the carrier or an out-of-balance
volume at rest means the stress still depends on the loading rate (more increments move it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from ..boundary import boundary_kind
from ..homogenization import (
    branch_vectors,
    contact_weights,
    coordination,
    dissipated_energy,
    hencky_strain,
    least_squares_gradient,
    love_weber_stress,
    piola_to_cauchy,
    relative_density,
    rendulic_strain,
    rendulic_stress,
    specific_contact_surface,
    strain_invariants,
    stress_invariants,
)
from ..io.history import tensor_columns, tensor_values
from ..meshes import ParticleCentroids

#: the history's columns, in file order, by group
KINEMATICS = ["time", "rho", "rho_imposed", "rho_fe", "h_v", "h_d", "h_tilde_d", "nonaffine"]
STRESS_INVARIANTS = ["sigma_m", "sigma_d", "sigma_tilde_d"]
TENSORS = {
    "F": "least-squares gradient of the centroids",
    "sigma": "Love-Weber stress",
    "sigma_schmidt_": "Schmidt stress (periodic conditions)",
    "sigma_vol_": "volume-averaged stress",
}
CONTACTS = ["n_contacts", "Z", "rattlers", "Gamma", "Gamma_model", "Gamma_closed"]
ENERGIES = [
    "E_p",
    "E_f",
    "E_d",
    "E_p_model",
    "E_d_model",
    "E_c",
    "E_int",
    "E_el",
    "E_contact",
    "E_visc",
    "E_damp",
    "E_mass",
    "W_ext",
]
QUASI_STATIC = ["unbalanced", "E_c_over_E_int"]
NONLINEAR = ["newton_iterations", "linear_iterations", "cutbacks"]
COLUMNS = (
    KINEMATICS
    + STRESS_INVARIANTS
    + [c for prefix in TENSORS for c in tensor_columns(prefix)]
    + ["sigma_vol_m"]
    + CONTACTS
    + ENERGIES
    + QUASI_STATIC
    + NONLINEAR
    + ["wall_time"]
)

#: limits of the quasi-static check: the share of the work through the comoving carrier at the end
#: (cumulative), and the out-of-balance ratio of the last row with the path at rest. They separate
#: the validation runs whose curves hold at twice the increments (CLP: 1 % and 0.007; CLPS on 24
#: particles at 12 000 increments: 0 and 0.017) from those that relax at the end (CLPS on 24
#: particles at 3000 increments: 12 % and 0.19; 50 particles at 6000: 31 % / 0.28 damped, 2 % /
#: 0.18 without damping); validation/README.md, the energy balance.
CARRIER_SHARE_LIMIT = 0.1
UNBALANCED_AT_REST_LIMIT = 0.05
#: the history columns the check reads (the energy balance's and the out-of-balance ratio)
QUASI_STATIC_CHECK_COLUMNS = (
    "W_ext",
    "E_int",
    "E_visc",
    "E_contact",
    "E_c",
    "E_damp",
    "E_mass",
    "unbalanced",
)


def carrier_share(history) -> np.ndarray:
    """Per row, the share of the work done on the model that entered through the comoving carrier
    rather than through the boundary: E_carrier / W_ext with E_carrier = E_int + E_visc + E_contact
    + E_c + E_damp - W_ext - E_mass (-; NaN where W_ext = 0; E_mass counted as 0 where unknown: a
    history written before the column, or rows before a restart that added it). ``history``:
    column name -> array (a ``read_csv`` dict, or ``{c: History.column(c)}``)."""
    h = history
    mass_scaling = np.nan_to_num(h["E_mass"], nan=0.0) if "E_mass" in h else 0.0
    carrier = (
        h["E_int"]
        + h["E_visc"]
        + h["E_contact"]
        + h["E_c"]
        + h["E_damp"]
        - h["W_ext"]
        - mass_scaling
    )
    with np.errstate(divide="ignore", invalid="ignore"):  # W_ext = 0 before the first contact
        return carrier / h["W_ext"]


@dataclass(frozen=True)
class QuasiStaticCheck:
    """The quasi-static check of an explicit run (:func:`quasi_static_check`)."""

    carrier_share: float  # E_carrier / W_ext at the end (cumulative, -)
    # out-of-balance ratio of the last row (-), NaN when the path ends in motion
    unbalanced_at_rest: float

    @property
    def passed(self) -> bool:
        """Both measures within their limits (a NaN out-of-balance ratio passes)."""
        return bool(
            abs(self.carrier_share) <= CARRIER_SHARE_LIMIT
            and not self.unbalanced_at_rest > UNBALANCED_AT_REST_LIMIT
        )

    def summary(self, increments: int) -> str:
        """One line for the run's log."""
        found = (
            f"{100 * self.carrier_share:.1f} % of the work through the comoving carrier "
            f"(limit {100 * CARRIER_SHARE_LIMIT:.0f} %)"
        )
        if np.isfinite(self.unbalanced_at_rest):
            found += (
                f", out of balance {self.unbalanced_at_rest:.2g} at rest "
                f"(limit {UNBALANCED_AT_REST_LIMIT:g})"
            )
        if self.passed:
            return f"quasi-static check passed: {found}"
        return (
            f"quasi-static check FAILED: {found}: the stress depends on the loading rate; "
            f"compare a run with more increments (this one: {increments})"
        )


def quasi_static_check(history, at_rest: bool = True) -> QuasiStaticCheck:
    """Quasi-static check of an explicit compaction from its history (column name -> array): the
    last row's :func:`carrier_share` (the whole run's work) and, when the path ends at rest
    (``at_rest``: every smooth profile of ``loading``), the last row's ``unbalanced``."""
    share = (
        float(carrier_share(history)[-1])
        if len(history["W_ext"]) and history["W_ext"][-1] > 0
        else 0.0
    )
    unbalanced = (
        float(history["unbalanced"][-1]) if at_rest and len(history["unbalanced"]) else float("nan")
    )
    return QuasiStaticCheck(share, unbalanced)


#: the static check's limit: at the end of a Newton run, the share of the particles' mean stress
#: that their contacts do not carry (the pseudo-time drag's, Newton's tolerance aside); the
#: default runs end at 0.01-0.6 % (flagship, 16-particle random volume, 50-particle die), a
#: drag-held state (particles squashed along the drag's frame, contacts unloaded) at 30 %
DRAG_SHARE_LIMIT = 0.01
#: the history columns the static check reads
STATIC_CHECK_COLUMNS = ("sigma_m", "sigma_vol_m", "rho")


def drag_share(history) -> np.ndarray:
    """Per row of a Newton run, |sigma_vol_m - sigma_m| / |sigma_vol_m| (-): how much of the
    particles' volume-averaged mean stress (eq. C.7) the contact forces' Love-Weber stress
    (eq. 2.6) does not carry. Without inertia the two differ only by the forces that are not
    contacts', the pseudo-time drag's (NaN where sigma_vol_m = 0)."""
    contact, volume = np.asarray(history["sigma_m"]), np.asarray(history["sigma_vol_m"])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.abs(volume - contact) / np.abs(volume)


@dataclass(frozen=True)
class StaticCheck:
    """The static check of a Newton run (:func:`static_check`)."""

    drag_share: float  # :func:`drag_share` of the last row (-)
    worst: float  # its largest over the rows past 5 % of the final mean stress (-)
    worst_rho: float  # where (-)

    @property
    def passed(self) -> bool:
        """The end state's stress carried by the contacts within :data:`DRAG_SHARE_LIMIT`."""
        return bool(self.drag_share <= DRAG_SHARE_LIMIT)

    def summary(self) -> str:
        """One line for the run's log."""
        found = (
            f"the contacts carry the particles' mean stress within "
            f"{100 * self.drag_share:.2f} % at the end (limit {100 * DRAG_SHARE_LIMIT:g} %), "
            f"{100 * self.worst:.2f} % at worst (rho {self.worst_rho:.3f})"
        )
        if self.passed:
            return f"static check passed: {found}"
        return (
            f"static check FAILED: {found}: the pseudo-time drag holds part of the load; "
            f"a weaker drag ([solver] regularization, held_regularization) or more load steps"
        )


def static_check(history) -> StaticCheck:
    """Static check of a Newton compaction from its history (column name -> array with
    ``sigma_m``, ``sigma_vol_m`` and ``rho``): :func:`drag_share` at the last row and its worst
    past 5 % of the final |sigma_vol_m|."""
    share = drag_share(history)
    volume = np.abs(np.asarray(history["sigma_vol_m"]))
    if not volume.size or not volume[-1] > 0:
        return StaticCheck(0.0, 0.0, float("nan"))
    past = np.flatnonzero(volume >= 0.05 * volume[-1])
    k = past[int(np.nanargmax(share[past]))]
    return StaticCheck(float(share[-1]), float(share[k]), float(history["rho"][k]))


class HistoryRecorder:
    """Measures one history row of a compaction model from a solver's state (the solver
    interface: ``t``, ``macroscopic_reaction``, ``energy_record``, ``unbalanced_ratio``): the
    centroids' kinematics, the three stress measures (Love-Weber, Schmidt, volume average), the
    contact network and the energies. ``reference_centroids``: the volume's particle centroids at
    t = 0 (a restart passes the checkpoint's; default: measured now)."""

    def __init__(self, model, comm: MPI.Comm, reference_centroids: np.ndarray | None = None):
        self.model, self.comm = model, comm
        self.n = model.packing.num_particles
        self.cell_volume0 = float(np.prod(model.packing.cell))
        self.periodic = boundary_kind(model.boundary.condition).periodic  # Schmidt stress defined
        self.mean_radius = float(np.mean(model.radii[: self.n]))
        self.centroids = ParticleCentroids(model.assembly, model.problem.u)
        # one memory layout: a restart reproduces the BLAS round-off
        self.X0 = np.ascontiguousarray(
            self.centroids()[: self.n] if reference_centroids is None else reference_centroids,
            dtype=float,
        )
        # the particles of the volume (originals; CLP copies are stiffless, GDH/GDF/CLPS copies lie
        # outside)
        problem = model.problem
        self.volume_cells = model.assembly.cell_tags.values[: problem.num_cells] < self.n

    def volume_stress_integral(self) -> np.ndarray:
        """sum over the volume's particles of int sigma dv (N mm, (3, 3), tension > 0; eq. C.7)."""
        local = self.model.problem.cell_stress_integrals()[self.volume_cells].sum(axis=0)
        return self.comm.allreduce(local, op=MPI.SUM)

    def schmidt_stress(self, reaction: np.ndarray, F0: np.ndarray) -> np.ndarray:
        """Cauchy stress (MPa, tension > 0) of the auxiliary nodes' reactions (eq. 2.14, 2.19)."""
        return piola_to_cauchy(self.model.bcs.macroscopic_force(reaction) / self.cell_volume0, F0)

    def volume_stress(self, F: np.ndarray) -> np.ndarray:
        """The volume-averaged Cauchy stress (MPa, tension > 0) of eq. C.7, (1/V) sum int sigma dv
        over the volume's particles, V = V0 det F the volume of the VEP (eq. 2.4): ``F`` the
        least-squares gradient of the centroids, the volume of rho and of the Love-Weber stress."""
        return self.volume_stress_integral() / (np.linalg.det(F) * self.cell_volume0)

    def measured_stress(self, solver, measure: str) -> np.ndarray:
        """The Cauchy stress (MPa, tension > 0) a stress servo reads, the one the history reports
        for the same state: "schmidt" (the auxiliary nodes' reactions, eq. 2.19, the
        ``sigma_schmidt_*`` columns) or "volume" (:meth:`volume_stress`, the ``sigma_vol_*``
        columns; it measures the centroids for F)."""
        if measure == "schmidt":
            return self.schmidt_stress(solver.macroscopic_reaction, self.model.path(solver.t))
        F, _ = least_squares_gradient(self.X0, self.centroids()[: self.n])
        return self.volume_stress(F)

    def _kinematics(self, x: np.ndarray, F0: np.ndarray) -> tuple[dict, np.ndarray]:
        n = self.n
        F, c = least_squares_gradient(self.X0, x[:n])
        # rms distance of the centroids from the best affine motion, over the mean radius
        nonaffine = (
            float(np.sqrt(np.mean(np.sum((x[:n] - self.X0 @ F.T - c) ** 2, axis=1))))
            / self.mean_radius
        )
        h = hencky_strain(F)
        h_v, h_d = strain_invariants(h)
        volume = np.linalg.det(F) * self.cell_volume0
        solid0 = self.model.solid_volume0
        return dict(
            rho=relative_density(solid0, self.cell_volume0, F),
            rho_imposed=relative_density(solid0, self.cell_volume0, F0),
            rho_fe=float(self.centroids.volumes[:n].sum()) / volume,
            h_v=h_v,
            h_d=h_d,
            h_tilde_d=rendulic_strain(h)[1],
            nonaffine=nonaffine,
            **tensor_values("F", F),
        ), F

    def _contacts(self, x: np.ndarray, F: np.ndarray, F0: np.ndarray) -> tuple[dict, np.ndarray]:
        """Love-Weber over the model's contacts with the appendix-C counting weights, and the
        contact network."""
        model = self.model
        pf = model.contact.pair_forces()
        pairs = pf["pairs"]
        image = np.rint(np.linalg.solve(F0, pf["shift"].T).T / model.packing.cell).astype(np.int64)
        weights = contact_weights(
            pairs[:, 0], pairs[:, 1], model.original, model.shift, model.boundary.condition, image
        )
        volume = np.linalg.det(F) * self.cell_volume0
        sigma_lw = love_weber_stress(
            pf["force"], branch_vectors(x, pairs[:, 0], pairs[:, 1], pf["shift"]), volume, weights
        )  # tension > 0
        carrying = pf["points"] > 0  # pairs within the search distance may carry no force
        n_contacts, mean_z, rattlers = coordination(
            pairs[carrying, 0], pairs[carrying, 1], model.original, weights[carrying], self.n
        )
        return dict(
            n_contacts=n_contacts,
            Z=mean_z,
            rattlers=rattlers,
            Gamma=specific_contact_surface(pf["area"], self.cell_volume0, F, weights),
            Gamma_model=specific_contact_surface(pf["area"], self.cell_volume0, F),
            Gamma_closed=specific_contact_surface(pf["area_closed"], self.cell_volume0, F, weights),
        ), sigma_lw

    def _energies(self, solver) -> dict:
        """The solver's energies; E_p of the volume's particles (the solver tallies the whole
        model, copies outside the volume included), E_f of every contact, E_d = E_p + E_f."""
        energies = solver.energy_record()
        energies["E_p_model"] = energies["E_p"]
        energies["E_p"] = self.model.problem.plastic_work(self.volume_cells)
        energies["E_f"] = self.model.contact.frictional_work
        energies["E_d"] = float(dissipated_energy(energies["E_p"], energies["E_f"]))
        energies["E_d_model"] = float(dissipated_energy(energies["E_p_model"], energies["E_f"]))
        return energies

    def measure(self, solver, wall_time: float) -> dict[str, float]:
        """One history row (every column of :data:`COLUMNS`) of the current state.
        Raises FloatingPointError on a non-finite density, Love-Weber stress or plastic work."""
        F0 = self.model.path(solver.t)
        x = self.centroids()
        row, F = self._kinematics(x, F0)
        contacts, sigma_lw = self._contacts(x, F, F0)
        # third measure, from the particles' stress field: (1/V) sum int sigma dv (eq. C.7)
        sigma_vol = self.volume_stress(F)
        sigma_s = np.full((3, 3), np.nan)
        if self.periodic:  # Schmidt: reactions conjugate to F0 (auxiliary nodes), eq. 2.14
            sigma_s = self.schmidt_stress(solver.macroscopic_reaction, F0)
        energies = self._energies(solver)
        sigma_m, sigma_d = stress_invariants(sigma_lw)
        if not (
            np.isfinite(row["rho"])
            and np.isfinite(sigma_lw).all()
            and np.isfinite(energies["E_p_model"])
        ):
            raise FloatingPointError(
                f"non-finite state at step {solver.step} (t={solver.t:.4g} s): rho={row['rho']}, "
                f"sigma_m={sigma_m}"
            )
        row.update(
            time=solver.t,
            sigma_m=sigma_m,
            sigma_d=sigma_d,
            sigma_tilde_d=rendulic_stress(sigma_lw)[1],
            **tensor_values("sigma", -sigma_lw),
            **tensor_values("sigma_schmidt_", -sigma_s),
            **tensor_values("sigma_vol_", -sigma_vol),
            sigma_vol_m=stress_invariants(sigma_vol)[0],
            **contacts,
            **energies,
            unbalanced=solver.unbalanced_ratio(),
            E_c_over_E_int=energies["E_c"] / energies["E_int"] if energies["E_int"] > 0 else np.nan,
            **solver.iteration_record(),
            wall_time=wall_time,
        )
        return row
