"""Yield, damage and rupture surfaces of a compacted periodic volume (thesis chapter 4).

    python demos/yield_surface.py
        # small default (~15 min on 2 cores)
    mpirun -n 2 python demos/yield_surface.py                      # two reloads at a time
    python demos/yield_surface.py --loading die --target-density 0.85 --gamma 1e-3 --nphi 24

Load (isotropic or die) to --target-density, unload isotropically until the mean stress is a
small fraction of its loaded value, checkpoint, then reload in --nphi directions phi of the
Rendulic strain plane (h_v = A cos phi, h~_d = A sin phi, compression > 0, A = 1.5 |h_v(unload)|,
thesis eq. 4.7-4.9), each reload restarted from the checkpoint with its contact history
(adhesion alpha, stick anchors) intact. Thresholds along each reload give the yield surface
(E_d = E_0 (1 + 0.3 %)), iso-Gamma damage curves and Hill's W2 <= 0 rupture points.

Outputs in --out (default results/yield_surface/): fan.csv (phi, sigma_m, sigma_tilde_d, h_v,
h_tilde_d, E_d, Gamma, W2 per reload output), surfaces.csv (kind, phi, sigma_m, sigma_tilde_d;
kind = yield | gamma_<value> | w2), uniaxial.csv (uniaxial compressive / tensile strength of
each closed surface), yield_surface.png, and load/, unload/, reload_<k>/ with their histories.
summary.json (E_0, Gamma_l, points per surface, raw W2 sign changes per reload). --resume
continues a killed fan (finished reloads are not repeated; a Newton reload on its way continues
from its checkpoint, written every 5 steps). --solver
implicit runs the reloads with Newton (the loading and unload stay explicit; the unloaded state
is first relaxed to static equilibrium): W2 then needs no filter, at ~10x the cost of a reload.
An explicit reload lasts --reload-increments (default: the compaction's strain rate slowed 4x,
at least 400): a fan counts once its yield points no longer move when the reloads are slowed
(bench/implicit_fan.py compares the rates and the reloads by Newton).
Stresses in MPa, compression > 0.
"""

from mpi4py import MPI

from mpfem_fenicsx.exits import RUN_FAILED, bad_input_exits, fail
from mpfem_fenicsx.options import add_parameter_option, compaction_case, compaction_parser
from mpfem_fenicsx.workflows.compaction import RunFailure
from mpfem_fenicsx.workflows.yield_surface import YieldSurfaceCase, run_yield_surface, surfaces

# the small default: 24 particles compacted to rho = 0.80 slowly enough to pass the loading's
# quasi-static check (4000 increments: out of balance 0.014 at rest; 2000 failed it, 0.059), 16
# reloads
DEFAULTS = dict(particles=24, target_density=0.80, increments=4000, gamma=1e-2, outputs=20)


def main(argv=None) -> None:
    p = compaction_parser("isotropic", __doc__)
    p.set_defaults(out="results/yield_surface", **DEFAULTS)
    p.add_argument(
        "--loading", choices=("isotropic", "die"), default="isotropic", help="initial loading path"
    )
    # meaning, unit, default and range of the fan's options from YieldSurfaceCase's declarations
    add_parameter_option(p, YieldSurfaceCase, "nphi")
    add_parameter_option(p, YieldSurfaceCase, "unload_stress_ratio", flag="--unload-ratio")
    add_parameter_option(p, YieldSurfaceCase, "amplitude_factor")
    add_parameter_option(p, YieldSurfaceCase, "dissipation_threshold", flag="--threshold")
    p.add_argument(
        "--gamma-thresholds",
        type=float,
        nargs="*",
        default=(),
        help="iso-Gamma levels (1/mm; default: 0.25..1 x Gamma after the unload)",
    )
    add_parameter_option(p, YieldSurfaceCase, "reload_increments")
    add_parameter_option(p, YieldSurfaceCase, "reload_steps")
    add_parameter_option(p, YieldSurfaceCase, "reload_extension")
    add_parameter_option(p, YieldSurfaceCase, "reload_profile")
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue a killed fan in --out (same options): "
        "the loading and a Newton reload from their newest checkpoints, "
        "finished stages and reloads not repeated",
    )
    p.add_argument(
        "--surfaces-only",
        action="store_true",
        help="recompute fan.csv, surfaces.csv, uniaxial.csv and the PNG "
        "from a finished fan in --out "
        "(e.g. with another --threshold or --gamma-thresholds)",
    )
    args = p.parse_args(argv)
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    args.no_visual = True  # the stages write histories, the fan its own figure
    reload_solver, args.solver = (
        args.solver,
        "explicit",
    )  # --solver: the reloads' (loading: explicit)
    base = compaction_case(args, args.loading)
    with bad_input_exits():
        case = YieldSurfaceCase(
            base=base,
            solver=reload_solver,
            reload_increments=args.reload_increments,
            reload_steps=args.reload_steps,
            reload_extension=args.reload_extension,
            nphi=args.nphi,
            unload_stress_ratio=args.unload_ratio,
            amplitude_factor=args.amplitude_factor,
            reload_profile=args.reload_profile,
            dissipation_threshold=args.threshold,
            gamma_thresholds=tuple(args.gamma_thresholds),
            out_dir=args.out,
        )
    if args.surfaces_only:
        if comm.rank == 0:
            surfaces(case, log=say)
        return
    try:
        result = run_yield_surface(case, comm, log=say, resume=args.resume)
    except RunFailure as err:
        fail(RUN_FAILED, str(err))
    say(
        f"done in {result['wall_time']:.0f} s: {args.out}/fan.csv, "
        "surfaces.csv, uniaxial.csv, yield_surface.png"
    )


if __name__ == "__main__":
    main()
