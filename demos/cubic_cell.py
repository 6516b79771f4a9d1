# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
# ---

# %% [markdown]
# # The simple cubic cell, step by step
#
# This demo builds a multi-particle finite element (MPFEM) compaction from its parts, with the
# library's public functions only, and checks what it measures against exact answers.
#
# The cell is the ordered packing of the thesis' section 2.6: eight lead spheres of radius
# $r$ at the centres $r + 2r\{0, 1\}^3$ of a periodic cube of side $4r$. Each sphere touches
# its six neighbours, and the solid fraction is
#
# $$\rho_0 = \frac{8 \cdot \tfrac{4}{3}\pi r^3}{(4r)^3} = \frac{\pi}{6} \approx 0.5236.$$
#
# We compact the cell isotropically by 7 % of its size (to $\rho = 0.65$), with fully periodic
# boundary conditions (CLP) and the explicit solver, and then measure the stress in three
# ways:
#
# - **Love-Weber** (thesis eq. 2.6): contact forces times branch vectors between centroids;
# - **Schmidt** (eq. 2.19): the reactions of the "auxiliary nodes" that drive the cell;
# - **volume average** (eq. C.7): the particles' own stress field integrated over them.
#
# The first two read the contact forces, the third reads the finite elements' stress field;
# in static equilibrium the three agree. Every particle is an exact translate of the others,
# so the motion stays affine and the relative density is known exactly:
# $\rho = \pi / (6 \det F)$ (eq. 2.17), with $F$ the gradient fitted to the centroids.
#
# Run it with
#
#     python demos/cubic_cell.py                 # a minute or two on one core
#     mpirun -n 2 python demos/cubic_cell.py
#
# Units are mm, N, MPa, s and mJ. Reported stresses are positive in compression. It writes
# `history.csv` (one row per output) and `stresses.png` into `results/cubic_cell/`.

# %%
from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np
from mpfem_fenicsx.meshes import ParticleCentroids, node_particles, particle_mesh
from mpfem_fenicsx.meshes.packing import (
    assembly_particles,
    duplicate_particles,
    periodic_pair_realizations,
    simple_cubic_packing,
)
from mpi4py import MPI
from scipy.spatial.transform import Rotation

from mpfem_fenicsx.constraints.granular import GranularBoundaryConditions
from mpfem_fenicsx.contact import ContactLaw, ContactModel
from mpfem_fenicsx.contact.laws import default_penalty
from mpfem_fenicsx.homogenization import (
    branch_vectors,
    contact_weights,
    least_squares_gradient,
    love_weber_stress,
    piola_to_cauchy,
    relative_density,
    reported_stress,
    solid_volume,
    stress_invariants,
)
from mpfem_fenicsx.loading import GradientPath, compaction_gradient
from mpfem_fenicsx.material import LEAD
from mpfem_fenicsx.problem import SolidProblem
from mpfem_fenicsx.solvers import create_solver
from mpfem_fenicsx.solvers.explicit import ExplicitSettings

# %% [markdown]
# ## Options
#
# Three options only: how far to compact, in how many explicit increments, and where to
# write. The defaults pass the check at the end; the tests run it with fewer increments (a
# smoke run, which says so).

# %%
DEFAULT_INCREMENTS = 1200
parser = argparse.ArgumentParser(description="The simple cubic cell (thesis §2.6), step by step.")
parser.add_argument(
    "--target-density",
    type=float,
    default=0.65,
    help="relative density to reach, in (pi/6, 0.7) (default 0.65)",
)
parser.add_argument(
    "--increments",
    type=int,
    default=DEFAULT_INCREMENTS,
    help=f"explicit increments of the compaction, >= 100 (default "
    f"{DEFAULT_INCREMENTS}; fewer: a smoke run, not quasi-static)",
)
parser.add_argument("--out", default="results/cubic_cell", help="output folder")
args = parser.parse_args()
if not np.pi / 6 < args.target_density < 0.7:
    parser.error(f"--target-density must be in ({np.pi / 6:.4f}, 0.7), got {args.target_density}")
if args.increments < 100:
    parser.error(f"--increments must be >= 100, got {args.increments}")

comm = MPI.COMM_WORLD
out = Path(args.out)
start = time.perf_counter()


def say(*text) -> None:
    """Print on the first rank only (every rank runs this whole script)."""
    if comm.rank == 0:
        print(*text, flush=True)


# %% [markdown]
# ## 1. The packing
#
# `simple_cubic_packing` returns the eight spheres in their periodic cell: `cell` (the sizes
# $L = (4r, 4r, 4r)$), `centres` and `radii`. The solid volume $V_p = \frac{4}{3}\pi\sum r^3$
# (eq. 2.5) over the reference cell volume $V_0$ is the initial relative density.

# %%
radius = 0.1  # mm
packing = simple_cubic_packing(radius)
n = packing.num_particles
cell_volume0 = float(np.prod(packing.cell))  # V0 (mm^3)
solid0 = solid_volume(packing.radii)  # V_p (mm^3), eq. 2.5
rho0 = solid0 / cell_volume0
say(
    f"packing: {n} spheres of radius {radius} mm in a cube of side {packing.cell[0]:g} mm, "
    f"rho0 = {rho0:.4f} (pi/6 = {np.pi / 6:.4f})"
)

# %% [markdown]
# ## 2. Duplicated particles for the periodic conditions
#
# The fully periodic condition CLP (thesis §2.5.3, eq. 2.14) is realized here by *tied copies*
# (thesis §2.2.1, fig. 2.2): the spheres near the low faces of the cell are copied across
# them, and every node of a copy will be tied to the same node of its original, shifted by the
# deformed cell vector. A copy is stiffless: it only carries its original's surface to where
# the neighbours across the face can touch it.
#
# `duplicate_particles` copies every sphere whose centre lies within `d_bc` of a low face
# (`faces="half"`: CLP needs one side only). As in the thesis, the copies are made across the
# faces only (`corners=False`: 12 copies); the spheres would need the edge copies too only
# beyond $\rho \approx 0.9$, where they start to touch their diagonal neighbours.
# `assembly_particles` lists the originals first, then the copies, with the index of the
# original and the integer lattice shift $s$ of each body.

# %%
copies = duplicate_particles(packing, d_bc=radius, faces="half", corners=False)
centres, radii, original, shift = assembly_particles(packing, copies)
is_copy = np.any(shift != 0, axis=1)
say(f"assembly: {n} particles + {copies.num_copies} tied copies = {radii.size} bodies")

# %% [markdown]
# ## 3. The particle mesh
#
# Every body is meshed as a cube-sphere: an inner cube of $6^3$ hexahedra and one shell
# layer, the thesis' appendix-A particle (561 nodes). The meshes are *inscribed* in their
# spheres (`exact_volume=False`), so touching spheres start just touching.
#
# All particles get one common, generic rotation (0.3 rad about the axis (1, 2, 3)). They stay
# exact translates of each other, which keeps the motion affine, while their contact points
# fall inside surface facets instead of on nodes. `particle_mesh` builds one distributed DOLFINx
# mesh whose cells are tagged with their body and whose surface facets with their body too.

# %%
rotation = Rotation.from_rotvec(0.3 * np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)).as_matrix()
divisions = 6  # hexahedra per edge of the inner cube (the thesis' particle)
assembly = particle_mesh(
    centres,
    radii,
    comm,
    divisions=divisions,
    layers=1,
    exact_volume=False,
    rotations=np.broadcast_to(rotation, (radii.size, 3, 3)),
)
mesh = assembly.mesh
num_cells = mesh.topology.index_map(3).size_local  # cells owned by this rank
cell_body = assembly.cell_tags.values[:num_cells]  # body of every owned cell

# %% [markdown]
# ## 4. The bulk problem
#
# `SolidProblem` holds the displacement $u$ (Q1 hexahedra with selective reduced integration)
# and the lead's finite-strain law: Hencky elasticity and von Mises plasticity with the
# power-law hardening $\sigma_y = \sigma_0 + K \varepsilon_p^n$ of eq. 2.1 (`LEAD`: E = 10 GPa,
# nu = 0.435, sigma_0 = 5 MPa, K = 15.5 MPa, n = 0.35). Only the originals carry material
# (`active_cells`); the tied copies are stiffless shells. The explicit solver needs no
# tangent.

# %%
volume_cells = ~is_copy[cell_body]  # owned cells of the eight particles of the cell
problem = SolidProblem(mesh, LEAD, tangent=False, active_cells=np.flatnonzero(volume_cells))
V = problem.V
say(
    f"mesh: {mesh.topology.index_map(3).size_global} hexahedra, "
    f"{3 * V.dofmap.index_map.size_global} displacement dofs, material {LEAD.E:g} MPa"
)

# %% [markdown]
# ## 5. The loading path and the periodic constraints
#
# The cell is driven by a macroscopic gradient $F_0(t)$. For an isotropic compaction from
# $\rho_0$ to $\rho$ the cell volume shrinks by $\rho_0 / \rho$, so
# $F_0 = (\rho_0 / \rho)^{1/3} I$ (`compaction_gradient`). `GradientPath` reaches it over the
# loading time with smooth ramps at both ends (a constant strain rate in between, at rest at
# the end), then holds it for a quarter of that time, so that the last oscillations die out
# before we measure. Explicit time is mass-scaled: 1 ms here stands for a slow loading.
#
# `GranularBoundaryConditions` turns CLP into multipoint constraints: each copy node follows
# its original, $u_{copy} = u_{orig} + (F_0 - I)(L \circ s)$ (eq. 2.14). The auxiliary nodes'
# reactions $R$, the forces through the ties times the lattice vectors, are work-conjugate
# to $F_0$: they give the Schmidt stress below. `comoving=True` carries each particle with the
# homogeneous flow at its centre; the unknowns are the motions relative to it. An explicit
# run conserves momentum, so no node is anchored.

# %%
duration = 1e-3  # s, mass-scaled loading time
target = compaction_gradient("isotropic", rho0, args.target_density)
hold = (0.25 * duration, np.eye(3))  # a segment whose increment gradient is I: F0 stays
path = GradientPath([(duration, target), hold], profiles=("smooth-ramps", "smooth-step"))
bcs = GranularBoundaryConditions(
    V,
    cell_body,
    centres,
    radii,
    original,
    shift,
    packing.cell,
    "CLP",
    path,
    anchor=False,
    comoving=True,
)
say(f"loading: F0 = {target[0, 0]:.4f} I, rho {rho0:.4f} -> {args.target_density}")

# %% [markdown]
# ## 6. The contact model
#
# Contacts are penalty contacts with Coulomb friction (thesis §2.2.2.2): the normal pressure is
# $k\,\delta$ for an overlap $\delta$, with $k = 10\,E/h$ (`default_penalty`, $h$ the
# surface element size $\pi r / (2 \cdot 6)$), and the tangential force is bounded by
# $\mu = 0.1$ times the normal one. Adhesion is off ($\gamma = 0$).
#
# With tied copies a periodic pair of particles may appear twice in the assembly (an original
# against a copy, and the copies of both); `periodic_pair_realizations` keeps one body pair per
# physical contact, so that each is modelled once. Points are searched within 5 % of a radius.

# %%
h_contact = radius * np.pi / (2 * divisions)  # mm, edge of a surface facet
law = ContactLaw(penalty=default_penalty(LEAD.E, h_contact, 10.0), friction=0.1, gamma=0.0)
contact = ContactModel(
    V,
    assembly.facet_tags,
    radii.size,
    law,
    search_distance=0.05 * radius,
    allowed=periodic_pair_realizations(original, shift),
)
say(f"contact: penalty {law.penalty:.3g} N/mm^3, friction {law.friction}")

# %% [markdown]
# ## 7. The explicit solver
#
# Central differences with a lumped mass, as Abaqus/Explicit in the thesis (§2.2.2.2): every
# increment computes the internal and contact forces, the accelerations of the free (reduced)
# dofs, then the new displacements. The stable increment of lead at the particles' size is a
# few nanoseconds, so the mass is scaled element by element until the increment is
# `duration / increments` (`target_dt`); the hold runs at the same increment. The loading
# stays slow next to the scaled waves: the path is quasi-static.
#
# Local non-viscous damping (`local_damping = 0.7`, as in DEM codes) takes energy out of each
# body's rigid oscillations without resisting a steady motion; `damped_bodies` names the body
# of every node (a copy moves with its original: the same body).

# %%
settings = ExplicitSettings(
    t_end=path.duration, target_dt=duration / args.increments, local_damping=0.7
)
solver = create_solver(
    "explicit",
    problem,
    bcs,
    contact=contact,
    settings=settings,
    damped_bodies=original[node_particles(V, cell_body)],
)
say(
    f"solver: explicit, dt = {solver.dt:.3g} s (unscaled {solver.dt_stable_unscaled:.3g} s), "
    f"{solver.total_steps} increments"
)

# %% [markdown]
# ## 8. What we measure
#
# **Kinematics.** The centroid $x^a$ of each particle (an integral over its deformed cells)
# is fitted by an affine motion $x^a \approx F X^a + c$ in the least-squares sense (eq. 2.2,
# C.3-C.6). The relative density is $\rho = V_p / (V_0 \det F)$, eq. 2.17: $\pi / (6 \det F)$.
#
# **Love-Weber** (eq. 2.6): $\sigma = \frac{1}{V} \sum_k w_k\, f^k \otimes l^k$ over the
# contacts, $f^k$ the force on particle $i$ by $j$, $l^k = x_j - x_i$ the branch vector and
# $V = V_0 \det F$. With CLP every modelled contact counts once (`contact_weights`: $w = 1$).
#
# **Schmidt** (eq. 2.19): the auxiliary nodes' generalized force $R$ gives the first Piola
# stress $P = R / V_0$ and the Cauchy stress $\sigma = P F_0^T / \det F_0$.
#
# **Volume average** (eq. C.7): $\sigma = \frac{1}{V} \sum_p \int_p \sigma\, dv$ over the eight
# particles, from the stress field of the finite elements.
#
# The library's tensors use the mechanics sign (tension > 0); `reported_stress` flips them to
# compression > 0, and `stress_invariants` returns the mean stress $\sigma_m = -\mathrm{tr}\,
# \sigma / 3$ already compression-positive.

# %%
centroids = ParticleCentroids(assembly, problem.u)
X0 = centroids()[:n]  # reference centroids of the eight particles (mm)


def measure() -> dict:
    """The state of the cell now: rho (eq. 2.17) and the three stresses (MPa, compression > 0)."""
    x = centroids()  # current centroids of every body (copies too: the branch vectors need them)
    F, _ = least_squares_gradient(X0, x[:n])  # eq. 2.2
    volume = cell_volume0 * np.linalg.det(F)  # V = V0 det F
    F0 = path(solver.t)
    # Love-Weber, eq. 2.6: one row per contacting body pair, force on i by j
    pairs = contact.pair_forces()
    i, j = pairs["pairs"][:, 0], pairs["pairs"][:, 1]
    weights = contact_weights(i, j, original, shift, "CLP")
    love_weber = love_weber_stress(
        pairs["force"], branch_vectors(x, i, j, pairs["shift"]), volume, weights
    )
    # Schmidt, eq. 2.19: P = R / V0 from the forces the medium exerts on the constrained dofs
    reaction = bcs.macroscopic_force(solver.macroscopic_reaction)
    schmidt = piola_to_cauchy(reaction / cell_volume0, F0)
    # volume average, eq. C.7: sum over the particles' cells of int sigma dv (N mm)
    integral = problem.cell_stress_integrals()[volume_cells].sum(axis=0)
    averaged = comm.allreduce(integral, op=MPI.SUM) / volume
    stresses = {"Love-Weber": love_weber, "Schmidt": schmidt, "volume average": averaged}
    return {
        "time": solver.t,
        "rho": float(relative_density(solid0, cell_volume0, F)),
        "rho_imposed": float(relative_density(solid0, cell_volume0, F0)),
        "stress": {name: reported_stress(s) for name, s in stresses.items()},
        "sigma_m": {name: float(stress_invariants(s)[0]) for name, s in stresses.items()},
        "contacts": int(np.sum(pairs["points"] > 0)),
        "unbalanced": solver.unbalanced_ratio(),
    }


# %% [markdown]
# ## 9. The loop
#
# `run_path` advances the solver increment by increment to the end of the path and calls our
# function about `outputs` times on the way. Each call measures the cell and keeps one history
# row: the density and the mean stress of each measure.

# %%
columns = [
    "time",
    "rho",
    "rho_imposed",
    "sigma_m_love_weber",
    "sigma_m_schmidt",
    "sigma_m_volume",
    "contacts",
    "unbalanced",
]
history: list[list[float]] = []


def record(solver) -> None:
    """One history row (and a progress line) at an output of the solver's loop."""
    m = measure()
    history.append(
        [
            m["time"],
            m["rho"],
            m["rho_imposed"],
            *m["sigma_m"].values(),
            m["contacts"],
            m["unbalanced"],
        ]
    )
    say(
        f"  t = {m['time']:.2e} s  rho = {m['rho']:.4f}  "
        f"sigma_m = {m['sigma_m']['Love-Weber']:6.3f} MPa  contacts {m['contacts']}"
    )


solver.run_path(record, outputs=20)

# %% [markdown]
# ## 10. The three stresses at the end
#
# The path ends at rest, so the cell is in static equilibrium: the three measures must agree,
# and the density fitted to the centroids must equal the imposed one, $\pi / (6 \det F)$.
# The three diagonal components are close but not equal: the rotated particle meshes meet
# their x, y and z neighbours on different facets.
#
# Love-Weber and Schmidt agree all along the path, not only at rest: the tied copies are
# massless shells, so the forces through their ties are the contact forces across the cell's
# faces. The volume average is the measure that needs equilibrium (in a run with too few
# increments it is the one that departs).

# %%
final = measure()
wall = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
reference = final["sigma_m"]["Love-Weber"]
say(
    f"\nrho = {final['rho']:.5f} (pi / (6 det F); imposed {final['rho_imposed']:.5f}), "
    f"{final['contacts']} contacts, out of balance {final['unbalanced']:.2g}"
)
say("stress (MPa, compression > 0)  sigma_11  sigma_22  sigma_33   sigma_m  vs Love-Weber")
for name, sigma in final["stress"].items():
    sigma_m = final["sigma_m"][name]
    say(
        f"  {name:<27} {sigma[0, 0]:9.3f} {sigma[1, 1]:9.3f} {sigma[2, 2]:9.3f} {sigma_m:9.3f}"
        f"  {100 * (sigma_m - reference) / reference:+7.2f} %"
    )
say(f"wall time {wall:.1f} s on {comm.size} rank(s)")

# %% [markdown]
# The check: the three mean stresses within 3 % of each other, the fitted density within
# 1e-4 of the imposed one.

# %%
spread = max(abs(value - reference) for value in final["sigma_m"].values())
agree = reference > 0 and spread <= 0.03 * reference
affine = abs(final["rho"] - final["rho_imposed"]) <= 1e-4 * final["rho_imposed"]
say(
    f"check: stresses {'agree' if agree else 'DISAGREE'} (largest gap {spread:.3g} MPa), "
    f"density {'exact' if affine else 'NOT exact'}"
)

# %% [markdown]
# ## 11. Outputs
#
# `history.csv` holds the rows of the loop; `stresses.png` draws the three mean stresses
# against the density.

# %%
if comm.rank == 0:
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "history.csv", "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(columns)
        writer.writerows([[repr(float(v)) for v in row] for row in history])

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = np.array(history)
    fig, ax = plt.subplots(figsize=(5.5, 4))
    for k, label, style in (
        (3, "Love-Weber (eq. 2.6)", "-"),
        (4, "Schmidt (eq. 2.19)", "--"),
        (5, "volume average (eq. C.7)", ":"),
    ):
        ax.plot(rows[:, 1], rows[:, k], style, label=label)
    ax.set(
        xlabel="relative density rho",
        ylabel="mean stress sigma_m (MPa, compression > 0)",
        title="Simple cubic cell, 8 lead spheres, CLP",
    )
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "stresses.png", dpi=120)
    say(f"outputs in {out}/: history.csv, stresses.png")

if not (agree and affine):
    if args.increments < DEFAULT_INCREMENTS:
        say(
            f"(a smoke run: below the default {DEFAULT_INCREMENTS} increments the path is not "
            "quasi-static, and the check is not expected to pass)"
        )
    else:
        raise SystemExit(1)
