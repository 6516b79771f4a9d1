"""Flat-contact check of the adhesive / frictional contact law (thesis §3.4.1, fig. 3.6-3.8).

A rigid base (all nodes fixed) and an elastic block of height h (one hexahedron, 1 x 1 mm^2
contact area) resting on it; the block's top face is driven.

Normal test: lateral faces on rollers (uniaxial strain), compress until T1 = 3 sigma_y (asperity
yield sigma_y, p0 = 3 sigma_y, so alpha = 0.5), unload, then pull apart beyond delta_max. Expected:
alpha = 0.5 at the end of compression, peak tension alpha sigma_c = 0.5 sigma_c, T1 = 0 from
delta_max.

Tangential test (block with nu = 0, so that compressing it does not pre-load the frictional
interface through Poisson's expansion): compress to T1 = 3 sigma_y, then drive the top face
tangentially to u3 = +3 u3c and back to -3 u3c. Stick while |tau| < tau_c = mu T1: the block
shears elastically, tau = G u3 / h, so slip starts at u3c = 2 (1 + nu) h tau_c / E (+ tau_c / k_t,
the penalty's own compliance); dissipation per area = tau_c x accumulated slip (6 u3c).

Outputs: normal.csv (delta_mm, T1_MPa, alpha), tangential.csv (u3_mm, tau_MPa, W_f_mJ_per_mm2).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..contact import ContactLaw, ContactModel
from ..io import History
from ..loading import PrescribedDisplacements, body_dofs, component_dofs
from ..material import ElastoPlastic
from ..meshes import box_bodies_mesh
from ..problem import SolidProblem
from ..solvers import ImplicitSolver, StepControl


@dataclass(frozen=True)
class FlatContactCase:
    """The flat-contact check's block, contact law and loads (MPa, mm, mJ/mm^2)."""

    E: float = 200000.0  # MPa
    nu: float = 0.3
    height: float = 0.1  # block height h, mm (thin: stiffer than the adhesive softening slope)
    sigma_y: float = 200.0  # asperity yield stress, MPa (p0 = 3 sigma_y)
    gamma: float = 1e-2  # mJ/mm^2
    mu: float = 0.1
    penalty: float = 1e9  # N/mm^3

    @property
    def delta_max(self) -> float:
        """Chosen so that sigma_c = 2 gamma / delta_max = sigma_y / 2 (thesis §3.4.1)."""
        return 4.0 * self.gamma / self.sigma_y

    def law(self) -> ContactLaw:
        """The contact law of the case."""
        return ContactLaw(
            penalty=self.penalty,
            friction=self.mu,
            gamma=self.gamma,
            delta_max=self.delta_max,
            asperity_yield=self.sigma_y,
        )


def _setup(case: FlatContactCase, nu: float, comm, tangent: bool = True):
    h = case.height
    assembly = box_bodies_mesh(
        [([0, 0, -0.1], [1, 1, 0], (1, 1, 1)), ([0, 0, 0], [1, 1, h], (1, 1, 1))], comm
    )
    material = ElastoPlastic(
        E=case.E, nu=nu, sigma_0=1e9, hardening="linear", K=0.0, H=0.0, density=7.8e-9
    )
    problem = SolidProblem(assembly.mesh, material, tangent=tangent)
    contact = ContactModel(
        problem.V, assembly.facet_tags, 2, case.law(), search_distance=2 * case.delta_max
    )
    base = body_dofs(problem.V, assembly.cell_tags, 0)
    block = set(body_dofs(problem.V, assembly.cell_tags, 1).tolist())

    def block_dofs(marker, component):
        dofs = component_dofs(problem.V, marker, component)
        return np.array([d for d in dofs if d in block], dtype=np.int32)  # setup only

    return problem, contact, base, block_dofs


def _compression(case: FlatContactCase, modulus: float, T1: float) -> float:
    """Top displacement (mm, < 0) giving the normal traction T1 on a block of uniaxial-strain
    modulus ``modulus``: Hencky, tau_zz = M ln(l), Cauchy = tau / l, plus the penalty overlap."""
    stretch = 1.0
    for _ in range(50):
        stretch = np.exp(-T1 * stretch / modulus)
    return (stretch - 1.0) * case.height - T1 / case.penalty


def _traction(contact: ContactModel) -> tuple[float, float, float]:
    """Mean normal gap (mm), T1 (MPa) and alpha over the contact points, over all ranks."""
    comm = contact.comm
    ev = contact.evaluation
    n = comm.allreduce(ev.size, op=MPI.SUM)
    if n == 0:
        return np.nan, 0.0, 0.0
    gap = comm.allreduce(float(ev.points.gap.sum()), op=MPI.SUM) / n
    t1 = comm.allreduce(float(ev.T1.sum()), op=MPI.SUM) / n
    alpha = comm.allreduce(float(contact.trial.alpha.sum()), op=MPI.SUM) / max(
        comm.allreduce(contact.trial.alpha.size, op=MPI.SUM), 1
    )
    return gap, t1, alpha


def run_normal(
    case: FlatContactCase, out_dir: Path, comm: MPI.Comm, steps_per_unit: int = 40
) -> History:
    """The normal test: its history (written to ``out_dir``)."""
    problem, contact, base, block_dofs = _setup(case, case.nu, comm)
    E, nu = case.E, case.nu
    M = E * (1 - nu) / ((1 + nu) * (1 - 2 * nu))
    u_c = _compression(case, M, 3.0 * case.sigma_y)
    u_open = 1.5 * case.delta_max
    h = case.height
    u_peak = 2.0 * (0.5 * case.law().sigma_c * h / M)  # past the tension peak (elastic block)

    # pseudo-time path: compress on [0, 1], unload on [1, 2], cross the peak on [2, 3],
    # open on [3, 4]
    def uz(t):
        return float(np.interp(t, [0.0, 1.0, 2.0, 3.0, 4.0], [0.0, u_c, 0.0, u_peak, u_open]))

    bcs = PrescribedDisplacements(problem.V).add(base)
    bcs.add(block_dofs(lambda x: np.isclose(x[0], 0.0) | np.isclose(x[0], 1.0), 0))
    bcs.add(block_dofs(lambda x: np.isclose(x[1], 0.0) | np.isclose(x[1], 1.0), 1))
    bcs.add(block_dofs(lambda x: np.isclose(x[2], h), 2), uz)
    history = History(out_dir / "normal.csv", ["delta_mm", "T1_MPa", "alpha"], comm)

    def record(s):
        gap, t1, alpha = _traction(contact)
        history.append(delta_mm=gap, T1_MPa=t1, alpha=alpha)

    solver = ImplicitSolver(problem, bcs, contact=contact)
    dt = 1.0 / steps_per_unit
    solver.run(StepControl(t_end=4.0, dt=dt, dt_max=dt, dt_min=dt / 64), on_step=record)
    history.write()
    return history


def run_tangential(case: FlatContactCase, out_dir: Path, comm: MPI.Comm, steps_per_unit: int = 40):
    """The tangential test: its history (written to ``out_dir``), the slip onset u3c (mm)
    and the friction limit tau_c (MPa)."""
    problem, contact, base, block_dofs = _setup(case, 0.0, comm)
    h = case.height
    u_c = _compression(case, case.E, 3.0 * case.sigma_y)
    tau_c = case.mu * 3.0 * case.sigma_y
    u3c = 2.0 * h * tau_c / case.E + tau_c / case.penalty

    # compress on [0, 1]; shear to +3 u3c on [1, 2], back to -3 u3c on [2, 4]
    def uz(t):
        return float(np.interp(t, [0.0, 1.0], [0.0, u_c]))

    def ux(t):
        return float(np.interp(t, [1.0, 2.0, 4.0], [0.0, 3.0 * u3c, -3.0 * u3c]))

    top = lambda x: np.isclose(x[2], h)  # noqa: E731
    top_x = block_dofs(top, 0)
    bcs = PrescribedDisplacements(problem.V).add(base)
    bcs.add(top_x, ux).add(block_dofs(top, 1)).add(block_dofs(top, 2), uz)
    history = History(out_dir / "tangential.csv", ["u3_mm", "tau_MPa", "W_f_mJ_per_mm2"], comm)

    def record(s):
        if s.t > 1.0 + 1e-12:
            history.append(
                u3_mm=ux(s.t),
                tau_MPa=s.reactions(top_x) / 1.0,
                W_f_mJ_per_mm2=contact.frictional_work / 1.0,
            )

    solver = ImplicitSolver(problem, bcs, contact=contact)
    dt = 1.0 / steps_per_unit
    solver.run(StepControl(t_end=4.0, dt=dt, dt_max=dt, dt_min=dt / 64), on_step=record)
    history.write()
    return history, u3c, tau_c


def run_normal_explicit(
    case: FlatContactCase, out_dir: Path, comm: MPI.Comm, duration: float = 2e-4, steps: int = 4000
):
    """Explicit counterpart of the compression half of :func:`run_normal` (smooth step to
    T1 = 3 sigma_y). Returns (history, energies)."""
    from ..loading import SmoothStep
    from ..solvers.explicit import ExplicitSettings, ExplicitSolver

    problem, contact, base, block_dofs = _setup(case, case.nu, comm, tangent=False)
    E, nu = case.E, case.nu
    M = E * (1 - nu) / ((1 + nu) * (1 - 2 * nu))
    u_c = _compression(case, M, 3.0 * case.sigma_y)
    amplitude = SmoothStep(duration)
    bcs = PrescribedDisplacements(problem.V).add(base)
    bcs.add(block_dofs(lambda x: np.isclose(x[0], 0.0) | np.isclose(x[0], 1.0), 0))
    bcs.add(block_dofs(lambda x: np.isclose(x[1], 0.0) | np.isclose(x[1], 1.0), 1))
    bcs.add(block_dofs(lambda x: np.isclose(x[2], case.height), 2), lambda t: u_c * amplitude(t))
    history = History(
        out_dir / "normal_explicit.csv", ["time", "delta_mm", "T1_MPa", "alpha"], comm
    )

    def record(s):
        gap, t1, alpha = _traction(contact)
        history.append(time=s.t, delta_mm=gap, T1_MPa=t1, alpha=alpha)

    solver = ExplicitSolver(
        problem, bcs, ExplicitSettings(t_end=duration, target_dt=duration / steps), contact=contact
    )
    solver.run(record, outputs=50)
    history.write()
    return history, solver.energies


def run_flat_contact(
    case: FlatContactCase = FlatContactCase(),
    out_dir: str | Path = "results/flat_contact",
    comm: MPI.Comm = MPI.COMM_WORLD,
):
    """Both tests: (normal history, tangential history, u3c, tau_c)."""
    out_dir = Path(out_dir)
    normal = run_normal(case, out_dir, comm)
    tangential, u3c, tau_c = run_tangential(case, out_dir, comm)
    return normal, tangential, u3c, tau_c
