"""Triaxial compression of a periodic volume of lead particles under mixed control (
beyond the thesis, whose loading is strain-driven only).

    python demos/triaxial.py
        # flagship volume: consolidation to 2 MPa, then 10 % axial
    python demos/triaxial.py --confining 5 --axial-strain 0.15 --particles 50
    python demos/triaxial.py --restart results/triaxial  # continue a killed run (same options)

Pipeline: the flagship volume (24 particles, seed 1, CLP by periodic images, explicit) -> the
three normal stresses servo-controlled through the cell's gradient (the auxiliary nodes) on the
Schmidt stress (eq. 2.19; --measure volume: the particles' volume average, eq. C.7) up to the
confining pressure over 1e-3 s, held 0.3e-3 s -> axial compression along z (10 % over 1e-3 s)
with the lateral stresses held at the confining pressure (loading.stress_paths.StressPath, the
case file's [control] path = "triaxial"). The servo is a PI controller (rate 0.1 per duration,
i.e. 100 1/s; band 0.15 x the confining pressure; integral time 0.1 duration; the measure
low-passed over 0.01 duration; the duration is 1e-3 s): without the integral term the lateral
stresses lag behind what the axial compression adds to them. Every option's unit and range:
--help.

Outputs in --out (default results/triaxial/): history.csv with the columns of
demos/isotropic.py (sigma_schmidt_11..33: the auxiliary nodes' reactions; sigma11..33: Love-Weber;
sigma_vol_*: the volume average), packing.txt, loading_path.png.
"""

import argparse
import sys

import numpy as np
from mpi4py import MPI

from mpfem_fenicsx.case import CompactionCase, LoadingSection
from mpfem_fenicsx.exits import bad_input_exits
from mpfem_fenicsx.io.plots import plot_loading_path
from mpfem_fenicsx.loading.stress_paths import StressPath
from mpfem_fenicsx.options import add_case_option, add_parameter_option, run_exits
from mpfem_fenicsx.parameters import parameter_default
from mpfem_fenicsx.workflows.compaction import run_compaction

#: the demo's servo band / confining pressure (the paths' default is 0.25)
TRIAXIAL_BAND_FRACTION = 0.15


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_case_option(
        p, "packing", "particles"
    )  # type, default, range and help from the case declarations
    add_case_option(p, "packing", "seed")
    # the path's options (meaning, unit, default, range) from its declaration:
    # loading.stress_paths.StressPath
    add_parameter_option(p, StressPath, "pressure", flag="--confining", default=2.0)
    add_parameter_option(p, StressPath, "axial_strain")
    add_case_option(p, "solver", "increments", help="per 1e-3 s of loading")
    for name in ("rate", "band", "measure", "integral_time", "filter_time", "axial_ramp"):
        add_parameter_option(p, StressPath, name)
    # a narrower band than the paths' default: the lateral stresses' lag in the axial phase
    # (README, the triaxial servo study: 0.25 -> 0.15 took the largest Schmidt deviation from 2.14
    # to 1.85 %)
    add_parameter_option(
        p,
        StressPath,
        "band_fraction",
        default=TRIAXIAL_BAND_FRACTION,
        help=f"here {TRIAXIAL_BAND_FRACTION}",
    )
    add_case_option(p, "output", "outputs", default=60)
    p.add_argument("--out", default="results/triaxial")
    p.add_argument(
        "--restart",
        default=None,
        metavar="CHECKPOINT",
        help="continue a killed run from a checkpoint "
        "(directory, or its results folder: the newest "
        "one); give the same options as the run that wrote it",
    )
    args = p.parse_args(argv)
    with bad_input_exits():
        path = StressPath(
            path="triaxial",
            pressure=args.confining,
            axial_strain=args.axial_strain,
            rate=args.rate,
            band=args.band,
            band_fraction=args.band_fraction,
            measure=args.measure,
            integral_time=args.integral_time,
            filter_time=args.filter_time,
            axial_ramp=args.axial_ramp,
        )
        duration = parameter_default(LoadingSection, "duration")  # times above in units of it
        control = path.control(duration)
        case = CompactionCase.build(
            particles=args.particles,
            seed=args.seed,
            condition="CLP",
            control=control,
            duration=duration,
            increments=args.increments,
            outputs=args.outputs,
            visual=False,
            directory=args.out,
        )
    with run_exits():  # a refused checkpoint exits 2, a diverged run 3
        result = run_compaction(case, MPI.COMM_WORLD, restart=args.restart)
    h = result.history
    if MPI.COMM_WORLD.rank == 0:
        plot_loading_path(
            h.path,
            result.out_dir / "loading_path.png",
            title=f"{args.particles} particles, triaxial, confining {args.confining} MPa, CLP",
        )
        axial = h.column("time") > control.duration - path.axial_time * duration * (
            1 - 1e-9
        )  # the axial phase's rows
        for name, key in (("Schmidt", "sigma_schmidt_"), ("volume average", "sigma_vol_")):
            lateral = np.concatenate([h.column(key + "11")[axial], h.column(key + "22")[axial]])
            print(
                f"end: sigma_11 / 22 / 33 = {h.column(key + '11')[-1]:.3f} / "
                f"{h.column(key + '22')[-1]:.3f}"
                f" / {h.column(key + '33')[-1]:.3f} MPa ({name}), "
                f"rho {h.column('rho')[-1]:.4f}; axial phase: "
                f"lateral stresses within "
                f"{100 * np.abs(lateral / args.confining - 1).max():.2f} % of the "
                f"confining pressure"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
