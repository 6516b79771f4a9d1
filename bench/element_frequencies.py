r"""The explicit stable increment against each element's exact highest frequency.

    mpirun -n 2 python bench/element_frequencies.py --case isotropic_CLPS_n12000 \
        --checkpoint validation/runs/isotropic_CLPS_n12000/checkpoints/step0012000

The explicit solver mass-scales each hexahedron for its stable increment
dt_e = safety * L / c_d * (sqrt(1 + xi^2) - xi) (``solvers/mass_scaling.py``), L the smallest vertex
distance or volume / largest face area (``SolidProblem.min_cell_length``; since 2026-11-28 also the
Gauss-point bound ``problem.hexahedron_gauss_length``, so the ratio below reads the checkpoint with
the current estimate, whatever the run used). This script restores a
validation run's checkpoint (same number of ranks as the run) and computes, for every owned cell in
its current shape and with its scaled density, the exact highest frequency omega_e of the elastic
Q1 element (2x2x2 Gauss, element row-sum lumped mass rho V / 8, Lame constants of the material),
then prints omega_e dt (the element alone is stable for omega_e dt <= 2; an assembled mesh's highest
frequency is at most its elements' highest) and omega_e dt / (2 dt / dt_e), which an undistorted
cube gives as sqrt((1 + nu) / (1 - nu)) / (safety (sqrt(1 + xi^2) - xi)) (1.35 for lead,
nu = 0.435): a cell above that is stiffer than the estimate assumes. A last line gives omega_e dt
of the element the runs integrate (the volumetric part at the centre, ``forms.QuadratureRules``)
with the Hencky moduli per reference volume: the tangent of the runs (the cube's frequency is the
same). Reference printed first: the unit cube's omega_e h / c_d against its closed form
2 sqrt((1 + nu) / (1 - nu)) (the all-corners volumetric mode).
Results: bench/README.md, "The stable increment of distorted elements".
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

from mpfem_fenicsx.problem import (
    HEX_CENTRE_GRADIENTS,
    HEX_GAUSS_GRADIENTS,
    HEX_VERTICES,
    hexahedron_gradients,
)

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the repository: the validation package


def elasticity_matrix(E: float, nu: float) -> np.ndarray:
    """Isotropic D (6, 6), Voigt order xx, yy, zz, xy, yz, xz with engineering shears (MPa)."""
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    D = np.zeros((6, 6))
    D[:3, :3] = lam
    D[np.arange(3), np.arange(3)] += 2 * mu
    D[np.arange(3, 6), np.arange(3, 6)] = mu
    return D


def strain_displacement(grad: np.ndarray) -> np.ndarray:
    """B (n, 6, 24) of Q1 hexahedra from their shape-function gradients ``grad`` (n, 8, 3) (1/mm),
    Voigt order of :func:`elasticity_matrix`."""
    B = np.zeros((grad.shape[0], 6, 24))
    for i in range(3):
        B[:, i, i::3] = grad[:, :, i]
    for row, (i, j) in zip(range(3, 6), ((0, 1), (1, 2), (0, 2)), strict=True):
        B[:, row, i::3] = grad[:, :, j]
        B[:, row, j::3] = grad[:, :, i]
    return B


def element_highest_omega2(
    x: np.ndarray,
    D: np.ndarray,
    density: np.ndarray,
    volumetric: float | None = None,
    reference: np.ndarray | None = None,
) -> np.ndarray:
    """omega_e^2 (1/s^2) of Q1 hexahedra with nodes ``x`` (n, 8, 3) (mm), elasticity ``D`` and
    densities ``density`` (n,) (t/mm^3): the largest eigenvalue of K_e against the row-sum lumped
    mass rho V / 8 per node. K_e integrated at the 2x2x2 Gauss points, or, with the bulk modulus
    ``volumetric`` (MPa), as the runs do (``forms.QuadratureRules``: selective reduced integration):
    the deviatoric part D - K m m^T at the Gauss points, the volumetric part K m m^T at the centre.
    With the ``reference`` vertices (n, 8, 3) of deformed cells, the moduli act per reference volume
    (Hencky: on the Kirchhoff stress; the spatial modulus is D / J) and the mass is the reference
    one: the weights are the reference Jacobians, the gradients the current ones (stress terms left
    out; on the ringing copy cell this reproduces the run's own force increments to 1 %,
    bench/README.md)."""
    n = x.shape[0]
    m = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])
    D_gauss = D if volumetric is None else D - volumetric * np.outer(m, m)
    K = np.zeros((n, 24, 24))
    volume = np.zeros(n)
    for reference_gradients in HEX_GAUSS_GRADIENTS:
        det, grad = hexahedron_gradients(x, reference_gradients)  # (n,), (n, 8, 3)
        if reference is not None:
            det = np.linalg.det(np.einsum("cai,aj->cij", reference, reference_gradients))
        weight = det / 8.0  # Gauss weight 1/8 on the unit cube
        B = strain_displacement(grad)
        K += np.einsum("cki,kl,clj->cij", B, D_gauss, B) * weight[:, None, None]
        volume += weight
    if volumetric is not None:
        det, grad = hexahedron_gradients(x, HEX_CENTRE_GRADIENTS)
        if reference is not None:
            det = np.linalg.det(np.einsum("cai,aj->cij", reference, HEX_CENTRE_GRADIENTS))
        divergence = np.einsum("k,cki->ci", m, strain_displacement(grad))
        K += volumetric * np.einsum("ci,cj->cij", divergence, divergence) * det[:, None, None]
    return np.linalg.eigvalsh(K)[:, -1] / (density * volume / 8.0)


def cube_reference(E: float, nu: float, density: float) -> tuple[float, float]:
    """The unit cube's omega_e h / c_d, computed and in closed form."""
    c_d = np.sqrt(E * (1 - nu) / ((1 + nu) * (1 - 2 * nu)) / density)
    omega2 = element_highest_omega2(
        HEX_VERTICES[None].astype(float), elasticity_matrix(E, nu), np.array([density])
    )
    return float(np.sqrt(omega2[0]) / c_d), float(2.0 * np.sqrt((1 + nu) / (1 - nu)))


def main(argv=None) -> None:
    """Print omega_e dt of a checkpoint's cells (quantiles, worst particles) and the unit cube's."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", required=True, help="validation case name (validation/cases.py)")
    parser.add_argument(
        "--checkpoint", required=True, type=Path, help="a checkpoint directory of that case's run"
    )
    args = parser.parse_args(argv)
    from mpfem_fenicsx.workflows.compaction import CompactionRun
    from validation.cases import CASES

    comm = MPI.COMM_WORLD
    say = (lambda m: print(m, flush=True)) if comm.rank == 0 else (lambda m: None)
    if args.case not in CASES:
        raise SystemExit(
            f"--case: {args.case!r} is not a validation case (python validation/run.py --list)"
        )
    run = CompactionRun(
        CASES[args.case].compaction_case(f"/tmp/element_frequencies_{args.case}"),
        comm,
        log=say,
        restart=args.checkpoint,
    )
    solver, problem, model = run.solver, run.model.problem, run.model
    material = problem.params
    computed, closed = cube_reference(material.E, material.nu, material.density)
    say(
        f"unit cube: omega_e h / c_d = {computed:.4f} (closed form {closed:.4f}; the same with the "
        f"volumetric part at the centre)"
    )

    cells = problem.V.dofmap.list[: problem.num_cells]
    reference = problem.V.tabulate_dof_coordinates()[cells]
    x = (problem.V.tabulate_dof_coordinates() + problem.u.x.array.reshape(-1, 3))[cells]
    scale = solver.scaling.scale
    omega_dt = (
        np.sqrt(
            element_highest_omega2(
                x, elasticity_matrix(material.E, material.nu), material.density * scale
            )
        )
        * solver.dt
    )
    estimate = solver.scaling.stable_increments(problem.min_cell_length(deformed=True)) * np.sqrt(
        scale
    )
    ratio = omega_dt / (2.0 * solver.dt / estimate)
    run_element = (
        np.sqrt(
            element_highest_omega2(
                x,
                elasticity_matrix(material.E, material.nu),
                material.density * scale,
                volumetric=material.bulk,
                reference=reference,
            )
        )
        * solver.dt
    )
    particle = model.assembly.cell_tags.values[: problem.num_cells]
    gathered = comm.gather((omega_dt, ratio, run_element, particle))
    if comm.rank:
        return
    omega_dt, ratio, run_element, particle = (
        np.concatenate([g[k] for g in gathered]) for k in range(4)
    )
    say(
        f"{omega_dt.size} cells at step {solver.step}: omega_e dt max {omega_dt.max():.3f}, 99.9 % "
        f"{np.quantile(omega_dt, 0.999):.3f}, median {np.median(omega_dt):.3f} (an element alone "
        "is stable <= 2)"
    )
    say(
        "omega_e dt / (2 dt / dt_e): quantiles 1 / 50 / 99.9 % "
        f"{np.quantile(ratio, [0.01, 0.5, 0.999]).round(3)}, "
        f"max {ratio.max():.3f}"
    )
    worst = np.zeros(particle.max() + 1)
    np.maximum.at(worst, particle, omega_dt)
    top = np.argsort(worst)[::-1][:8]
    say(
        f"cells with omega_e dt > 2: {(omega_dt > 2).sum()}; particles with the highest omega_e "
        "dt: "
        + ", ".join(f"{p}{' (copy)' if model.is_copy[p] else ''} {worst[p]:.3f}" for p in top)
    )
    worst[:] = 0.0
    np.maximum.at(worst, particle, run_element)
    top = np.argsort(worst)[::-1][:4]
    say(
        "the runs' element (volumetric part at the centre, moduli per reference volume): omega_e "
        f"dt max {run_element.max():.3f}, median "
        f"{np.median(run_element):.3f}; highest in " + ", ".join(f"{p} {worst[p]:.3f}" for p in top)
    )


if __name__ == "__main__":
    main()
