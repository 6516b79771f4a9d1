"""Energy bookkeeping of the explicit solver: the cumulated energies and their tallies.

Energy balance (mJ = N mm), all with forces at integer steps n times the centred displacement
increment du_n = (u_{n+1} - u_{n-1}) / 2 = dw_n + dg_n (peculiar part dw = P dx, offset part dg),
which makes the discrete balance exact for central differences (the first step is one-sided,
du_0 = (u_1 - u_0) / 2; started out of equilibrium, f_0 != 0, e.g. from overlapping particles, the
balance then misses the start-up term 1/2 (dt/2 a_0)^T M (dt/2 a_0), a discretization term that
no later step changes; from rest in equilibrium it is zero):
    W_ext = sum R_n . du_n,   R_n = f_int + f_bv - f_c + f_d + M a_w  (a_w = P a_red)
    E_int = sum f_int,n . du_n (elastic + plastic),  E_visc = sum f_bv,n . du_n,
    E_contact = -sum f_c,n . du_n (penalty energy + friction + adhesion work),
    E_damp = sum f_d,n . dw_n (dissipation of the relaxation damping, >= 0),
    E_kin = 1/2 w'^T M w' (peculiar velocity w' = P v_red at the step),
    E_carrier = sum (f_d + M a_w)_n . dg_n (work of damping and peculiar inertia through the
    moving offsets; zero without a comoving carrier, small when quasi-static),
    E_mass = sum 1/2 w'^T dM w' (the kinetic energy variable mass scaling adds: mass raised at an
    unchanged velocity; zero at rest), so that W_ext + E_mass = E_int + E_visc + E_contact + E_kin
    + E_damp + E_carrier.
Periodic images whose shifts S = F0 (L o s) move (a granular cell's contacts across the cell)
add their work sum f_slave . dS to W_ext and to E_contact. The material's own energies (Hencky
stored energy and accumulated plastic work) are reported next to E_int as an independent check
of the internal work.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI


@dataclass
class Energies:
    """Cumulated energies (mJ), over the whole model."""

    external: float = 0.0
    internal: float = 0.0
    viscous: float = 0.0
    contact: float = 0.0  # work absorbed by contact (penalty energy + friction + adhesion)
    kinetic: float = 0.0
    plastic: float = 0.0  # accumulated plastic work from the material
    elastic: float = 0.0  # current Hencky stored energy from the material
    damping: float = 0.0  # dissipated by the relaxation damping (>= 0)
    carrier: float = 0.0  # work of damping and peculiar inertia through the moving offsets
    mass_scaling: float = 0.0  # kinetic energy added by mass raised at an unchanged velocity

    def balance_error(self) -> float:
        """|W_ext + E_mass - (E_int + E_visc + E_contact + E_kin + E_damp + E_carrier)| (mJ): zero
        to round-off from an equilibrium start, else the start-up term of the module docstring."""
        absorbed = (
            self.internal + self.viscous + self.contact + self.kinetic + self.damping + self.carrier
        )
        return abs(self.external + self.mass_scaling - absorbed)

    def record(self) -> dict[str, float]:
        """The energies of a history row (mJ): E_int, E_el, E_p (the whole model), E_contact,
        E_c (kinetic), E_visc, E_damp, E_mass (added by mass scaling), W_ext."""
        return dict(
            E_int=self.internal,
            E_el=self.elastic,
            E_p=self.plastic,
            E_contact=self.contact,
            E_c=self.kinetic,
            E_visc=self.viscous,
            E_damp=self.damping,
            E_mass=self.mass_scaling,
            W_ext=self.external,
        )

    def to_array(self) -> np.ndarray:
        """The fields in :data:`ENERGY_FIELDS` order (a checkpoint's array)."""
        return np.array([getattr(self, name) for name in ENERGY_FIELDS])

    def load_array(self, values: np.ndarray) -> None:
        """Restore :meth:`to_array`."""
        for name, value in zip(ENERGY_FIELDS, values, strict=False):
            setattr(self, name, float(value))


#: the fields of :class:`Energies`, in a checkpoint's order
ENERGY_FIELDS = tuple(Energies.__dataclass_fields__)


class EnergyTally:
    """The increments of :attr:`energies` over the ranks of ``comm`` (the balance of the module
    docstring). Forces in N and displacements in mm on this rank's owned unrolled dofs, masses
    in t, velocities in mm/s: energies in mJ."""

    def __init__(self, comm: MPI.Comm):
        self.comm = comm
        self.energies = Energies()
        #: H = F0 - I at the previous step, for the centred increment of the images' shifts
        self.H_prev = np.zeros((3, 3))

    def dot(self, a: np.ndarray, b: np.ndarray) -> float:
        """a . b summed over the ranks."""
        return self.comm.allreduce(float(a @ b), op=MPI.SUM)

    def add_step_work(
        self,
        inertia: np.ndarray,
        du: np.ndarray,
        dg: np.ndarray,
        forces: tuple[np.ndarray, np.ndarray, np.ndarray],
        damping: np.ndarray | None,
    ) -> None:
        """The work around step n of the internal, viscous and contact ``forces`` (f_int, f_bv
        and minus the contact forces f_c) over the centred displacement increment ``du``, the
        relaxation ``damping`` force (None: none) over its peculiar part du - dg, and the
        damping's and peculiar ``inertia``'s over the offsets' part ``dg`` (E_carrier)."""
        e = self.energies
        f_int, f_visc, f_cont = forces
        e.internal += self.dot(f_int, du)
        e.viscous += self.dot(f_visc, du)
        e.contact += self.dot(f_cont, du)
        carrier = inertia
        if damping is not None:
            e.damping += self.dot(damping, du - dg)
            carrier = carrier + damping
        e.carrier += self.dot(carrier, dg)

    def add_external_work(self, reaction: np.ndarray, du: np.ndarray) -> None:
        """W_ext += R_n . du_n."""
        self.energies.external += self.dot(reaction, du)

    def add_image_work(
        self, image_force: np.ndarray, H_n: np.ndarray, H_new: np.ndarray, first: bool
    ) -> None:
        """The periodic images' work through their moving shifts, sum f_slave . dS with the
        centred increment of H = F0 - I around step n (one-sided at the ``first`` step):
        ``image_force`` (N mm, 3 x 3) the images' force moment, done by the loading (W_ext) and
        absorbed by the contacts (E_contact), which -f_c . du alone misses."""
        image_work = float(np.sum(image_force * 0.5 * (H_new - (H_n if first else self.H_prev))))
        self.energies.external += image_work
        self.energies.contact += image_work
        self.H_prev = H_n

    def set_kinetic(self, mass: np.ndarray, velocity: np.ndarray) -> None:
        """E_kin = 1/2 w'^T M w' (lumped ``mass`` per dof)."""
        self.energies.kinetic = 0.5 * self.dot(mass, velocity * velocity)

    def add_mass_scaling(self, added_mass: np.ndarray, velocity: np.ndarray) -> None:
        """E_mass += 1/2 w'^T dM w': mass ``added_mass`` raised at an unchanged velocity."""
        self.energies.mass_scaling += 0.5 * self.dot(added_mass, velocity * velocity)
