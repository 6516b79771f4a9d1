"""Triaxial compression of a periodic volume of lead particles under mixed control (issue 24;
beyond the thesis, whose loading is strain-driven only).

    python demos/triaxial.py                          # flagship volume: consolidation to 2 MPa, then 10 % axial
    python demos/triaxial.py --confining 5 --axial-strain 0.15 --particles 50
    python demos/triaxial.py --restart results/triaxial  # continue a killed run (same options)

Pipeline: the flagship volume (24 particles, seed 1, CLP by periodic images, explicit) -> the
three normal stresses servo-controlled through the cell's gradient (the auxiliary nodes) on the
Schmidt stress (eq. 2.19; --measure volume: the particles' volume average, eq. C.7) up to the
confining pressure over 1e-3 s, held 0.3e-3 s -> axial compression along z (10 % over 1e-3 s)
with the lateral stresses held at the confining pressure (loading.mixed.triaxial_control). The
servo is a PI controller (rate 100 1/s, band a quarter of the confining pressure, integral time
1e-4 s, the measure low-passed over 1e-5 s): without the integral term the lateral stresses lag
behind what the axial compression adds to them.

Outputs in --out (default results/triaxial/): history.csv with the columns of
demos/isotropic.py (sigma_schmidt_11..33: the auxiliary nodes' reactions; sigma11..33: Love-Weber;
sigma_vol_*: the volume average), packing.txt, loading_path.png.
"""

import argparse
import sys
from inspect import signature

import numpy as np
from mpi4py import MPI

from mpfem_fenicsx.io.plots import plot_loading_path
from mpfem_fenicsx.loading.mixed import triaxial_control
from mpfem_fenicsx.cli.casefile import add_schema_option
from mpfem_fenicsx.cli.compaction import run_exits
from mpfem_fenicsx.workflows.compaction import CompactionCase, run_compaction


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_schema_option(p, "packing", "particles")  # type, default, range and help from the case-file schema
    add_schema_option(p, "packing", "seed")
    p.add_argument("--confining", type=float, default=2.0, help="confining pressure (MPa, compression > 0)")
    p.add_argument("--axial-strain", type=float, default=0.10, help="axial Hencky shortening (-)")
    add_schema_option(p, "solver", "increments", help="per 1e-3 s of loading")
    p.add_argument("--rate", type=float, default=100.0, help="servo's largest strain rate (1/s of loading time)")
    p.add_argument("--band", type=float, default=None, help="stress error giving the servo's largest rate (MPa; "
                   "default: a quarter of the confining pressure. A narrow band makes the servo outrun the "
                   "volume's pseudo-dynamic response and oscillate)")
    p.add_argument("--measure", choices=("schmidt", "volume"), default="schmidt", help="the servo's stress")
    p.add_argument("--integral-time", type=float, default=1e-4, help="PI servo's integral time (s of loading time; "
                   "0: proportional only, which lags behind the lateral stress the axial compression adds)")
    p.add_argument("--filter-time", type=float, default=1e-5, help="low-pass filter of the measured stress (s)")
    p.add_argument("--axial-ramp", type=float, default=signature(triaxial_control).parameters["axial_ramp"].default,
                   help="fraction of the axial phase over which the axial strain rate rises from zero (a sudden "
                        "start jolts the lateral stresses) (default: %(default)s)")
    add_schema_option(p, "output", "outputs", default=60)
    p.add_argument("--out", default="results/triaxial")
    p.add_argument("--restart", default=None, metavar="CHECKPOINT",
                   help="continue a killed run from a checkpoint (directory, or its results folder: the newest "
                        "one); give the same options as the run that wrote it")
    args = p.parse_args(argv)
    if not 0 < args.confining <= 100:
        p.error(f"--confining must be in (0, 100] MPa, got {args.confining}")
    if not 0 < args.axial_strain <= 0.5:
        p.error(f"--axial-strain must be in (0, 0.5], got {args.axial_strain}")
    args.band = args.confining / 4 if args.band is None else args.band
    if not 0 < args.band <= args.confining:
        p.error(f"--band must be in (0, confining] MPa, got {args.band}")
    if not 0 < args.rate <= 1000:
        p.error(f"--rate must be in (0, 1000] 1/s, got {args.rate}")
    if not 0 <= args.integral_time <= 1:
        p.error(f"--integral-time must be in [0, 1] s (0: none), got {args.integral_time}")
    if not 0 <= args.filter_time <= 1e-3:
        p.error(f"--filter-time must be in [0, 1e-3] s, got {args.filter_time}")
    if not 0 <= args.axial_ramp < 1:
        p.error(f"--axial-ramp must be in [0, 1) (fraction of the axial phase), got {args.axial_ramp}")
    # loading time in units of the flagship's compaction (1e-3 s of mass-scaled time)
    control = triaxial_control(args.confining, consolidation=1e-3, hold=0.3e-3, axial_strain=args.axial_strain,
                               axial_time=1e-3, rate=args.rate, band=args.band, measure=args.measure,
                               integral_time=args.integral_time or None, filter_time=args.filter_time,
                               axial_ramp=args.axial_ramp)
    try:
        case = CompactionCase(particles=args.particles, seed=args.seed, bc="CLP", control=control,
                              increments=args.increments, outputs=args.outputs, visual=False, out_dir=args.out)
    except ValueError as err:
        p.error(str(err))
    with run_exits():  # a refused checkpoint exits 2, a diverged run 3
        result = run_compaction(case, MPI.COMM_WORLD, restart=args.restart)
    h = result.history
    if MPI.COMM_WORLD.rank == 0:
        plot_loading_path(h.path, result.out_dir / "loading_path.png",
                          title=f"{args.particles} particles, triaxial, confining {args.confining} MPa, CLP")
        axial = h.column("time") > control.duration - 1e-3 * (1 - 1e-9)  # the axial phase's rows
        for name, key in (("Schmidt", "sigma_schmidt_"), ("volume average", "sigma_vol_")):
            lateral = np.concatenate([h.column(key + "11")[axial], h.column(key + "22")[axial]])
            print(f"end: sigma_11 / 22 / 33 = {h.column(key + '11')[-1]:.3f} / {h.column(key + '22')[-1]:.3f}"
                  f" / {h.column(key + '33')[-1]:.3f} MPa ({name}), rho {h.column('rho')[-1]:.4f}; axial phase: "
                  f"lateral stresses within {100 * np.abs(lateral / args.confining - 1).max():.2f} % of the "
                  f"confining pressure")
    return 0


if __name__ == "__main__":
    sys.exit(main())
