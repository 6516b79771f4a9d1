"""mpfem: the command line of mpfem-fenicsx (multi-particle finite elements on DOLFINx).

    mpfem run CASE.toml [--out DIR] [--restart CHECKPOINT]   compaction of a periodic volume
    mpfem pack --particles N --out FILE | --input FILE --out FILE   make or check a packing file
    mpfem plot DIR                                            figures again from a results folder
    mpfem init CASE.toml                                      a commented case file with
                                                              the defaults
    mpfem calibrate --fan RHO DIR ... --isotropic HISTORY [--die HISTORY] --out DIR
                                                              continuum models (Drucker-
                                                              Prager Cap, Cam-clay) from fans

Exit codes: 0 done; 2 bad input (one line naming the field and the allowed range); 3 the run
diverged or did not converge (history so far and the last good checkpoint are kept).
Parallel: ``mpirun -n P mpfem run CASE.toml`` (progress and messages on rank 0 only).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from mpi4py import MPI

from ..exits import BAD_INPUT, RUN_FAILED
from ..runtime import configure_runtime


class _Exit(Exception):
    def __init__(self, code: int, message: str):
        super().__init__(message)
        self.code = code


def _say(comm):
    return print if comm.rank == 0 else (lambda *a, **k: None)


def _parser() -> argparse.ArgumentParser:
    from .casefile import documentation

    p = argparse.ArgumentParser(
        prog="mpfem",
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="Run 'mpfem <command> --help' for a command's options.",
    )
    sub = p.add_subparsers(dest="command", required=True, metavar="command")

    run = sub.add_parser(
        "run",
        help="compact a periodic volume described by a TOML case file",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Compaction of a periodic volume of elastoplastic particles "
        "(thesis chapter 2): packing -> meshed particles -> contact + periodic constraints -> "
        "explicit/implicit solver -> history.",
        epilog="Outputs in the results folder: history.csv (one row per output; columns in "
        "README), "
        "packing.txt, particles.xdmf (ParaView: displacement, von_mises_MPa, eps_p, particle, "
        "contact_pressure_MPa), particles.png, loading_path.png, checkpoints/.\n\n"
        "Case file keys (section, key, type, default, allowed, meaning):\n" + documentation(),
    )
    run.add_argument("case", help="TOML case file (see below; 'mpfem init' writes one)")
    run.add_argument("--out", default=None, help="results folder (overrides [output] directory)")
    run.add_argument(
        "--restart",
        default=None,
        metavar="CHECKPOINT",
        help="continue from a checkpoint directory (or a results folder: its newest checkpoint); "
        "same case file and number of MPI ranks",
    )
    run.add_argument("--check", action="store_true", help="validate the case file and stop")

    pack = sub.add_parser(
        "pack",
        help="generate a packing file, or check and convert one",
        description="Generate a seeded frictionless periodic packing (--particles), or read "
        "a packing file as a DEM code left it (--input: ours, 'dx dy dz' then 'x y z r' "
        "lines; a YADE export.text, '#format x_y_z_r', its cell in a '# dx dy dz = ...' "
        "header or --cell; a LAMMPS / LIGGGHTS dump with box bounds and x y z radius "
        "columns), check it as a run at the default mesh would "
        "(spheres in the cell, contact overlaps: the radius "
        "reduction that removes them is reported) and write it in "
        "our format.",
    )
    src = pack.add_mutually_exclusive_group(required=True)
    src.add_argument(
        "--particles", type=int, help="number of spheres to generate (>= ~20 for a periodic cell)"
    )
    src.add_argument("--input", help="packing file to check / convert")
    pack.add_argument("--r-min", type=float, default=0.082, help="smallest radius, mm (generator)")
    pack.add_argument("--r-max", type=float, default=0.147, help="largest radius, mm (generator)")
    pack.add_argument("--seed", type=int, default=1, help="generator seed")
    pack.add_argument(
        "--fraction",
        type=float,
        default=None,
        help="stop the generator at this solid fraction (default: jammed)",
    )
    pack.add_argument(
        "--scale",
        type=float,
        default=1.0,
        help="multiply the input's radii by this factor (a run reduces them "
        "itself to remove a DEM export's contact overlaps)",
    )
    pack.add_argument(
        "--cell",
        type=float,
        nargs=3,
        default=None,
        metavar=("DX", "DY", "DZ"),
        help="periodic cell of the input (mm; e.g. a YADE export without a cell header)",
    )
    pack.add_argument(
        "--length-scale",
        type=float,
        default=1.0,
        help="multiply the input's lengths by this (e.g. 1000 for a DEM file in metres)",
    )
    pack.add_argument("--out", required=True, help="packing file to write")

    plot = sub.add_parser(
        "plot",
        help="draw the figures of a results folder again",
        description="Re-render loading_path.png from history.csv and particles.png from "
        "particles.vtu (saved by every run with visual output).",
    )
    plot.add_argument("directory", help="results folder of a run")

    init = sub.add_parser("init", help="write a commented case file with every default")
    init.add_argument("case", help="file to write (refuses to overwrite)")

    cal = sub.add_parser(
        "calibrate",
        help="fit continuum models (Drucker-Prager Cap, Cam-clay) to computed yield fans",
        description="Fit the Drucker-Prager Cap surface and the critical-state (Cam-clay) "
        "ellipse (Abaqus' forms) to each fan's yield points, take the elastic moduli from its "
        "reloads and the hardening from the isotropic compaction curve, write each model "
        "(cap_model.json / .csv, clay_model.json / .csv), its Abaqus fragment (cap_model.inp: "
        "*ELASTIC, *CAP PLASTICITY, *CAP HARDENING; clay_model.inp: *ELASTIC, *CLAY PLASTICITY, "
        "*CLAY HARDENING in compression and tension; field variable 1 = relative density) and "
        "calibration.png, and replay the isotropic (and die, triaxial) paths with a "
        "material-point driver of each model against the particles (round_trip.csv).",
    )
    cal.add_argument(
        "--fan",
        nargs=2,
        action="append",
        required=True,
        metavar=("RHO", "DIR"),
        help="a fan's relative density and its results folder (surfaces.csv, fan.csv of "
        "demos/yield_surface.py); repeat for each density",
    )
    cal.add_argument(
        "--isotropic", required=True, help="history.csv of the isotropic compaction (hardening)"
    )
    cal.add_argument("--die", default=None, help="history.csv of a die compaction (round trip)")
    cal.add_argument(
        "--triaxial",
        default=None,
        help="history.csv of a triaxial test (demos/triaxial.py; round trip of its axial stress)",
    )
    cal.add_argument(
        "--axial-start",
        type=float,
        default=None,
        help="time (s) at which the triaxial test's axial compression starts (default: after "
        "the default consolidation ramp and hold, 1.3e-3 s)",
    )
    cal.add_argument("--alpha", type=float, default=0.01, help="transition parameter alpha")
    cal.add_argument("--out", required=True, help="folder for the model and the figures")
    return p


def _run(args, comm) -> None:
    from ..io.checkpoint import CheckpointError
    from ..io.progress import Progress
    from ..workflows.compaction import RunFailure, initial_packing, run_compaction
    from .casefile import CaseError, load_case, load_tool_case

    say = _say(comm)
    try:
        tooled = load_tool_case(args.case, out_dir=args.out)
        if tooled is not None:
            return _run_tooled(tooled, args, comm)
        case = load_case(args.case, out_dir=args.out)
    except CaseError as err:
        raise _Exit(BAD_INPUT, str(err)) from None
    if args.check:
        try:  # the packing as `run` admits it while building, before any mesh (same message)
            admitted = initial_packing(
                case.packing, case.mesh, case.loading.target_density, log=say
            )
        except (ValueError, OSError) as err:
            raise _Exit(BAD_INPUT, f"{args.case}: {err}") from None
        source = (
            f"from {case.packing.file}"
            if case.packing.file
            else f"generated (seed {case.packing.seed})"
        )
        say(
            f"{args.case}: valid: {admitted.packing.num_particles} particles {source}, "
            f"rho0 {admitted.rho0:.4f} (radius reduction x{admitted.radius_factor:g}), "
            f"{case.boundary.condition}, {case.loading.path} to {case.loading.target_density}, "
            f"{case.solver.kind}"
        )
        return
    start = time.perf_counter()
    try:
        res = run_compaction(case, comm, log=say, restart=args.restart, progress=Progress(comm))
    except CheckpointError as err:
        raise _Exit(BAD_INPUT, str(err)) from None
    except RunFailure as err:
        raise _Exit(RUN_FAILED, str(err)) from None
    except ValueError as err:  # bad input found while building: packing file, unreachable density
        raise _Exit(BAD_INPUT, f"{args.case}: {err}") from None
    h = res.history
    say(
        f"done: rho = {h.column('rho')[-1]:.4f} (imposed {h.column('rho_imposed')[-1]:.4f}), "
        f"sigma_m = {h.column('sigma_m')[-1]:.3f} MPa, "
        f"{round(h.column('n_contacts')[-1])} contacts (Z {h.column('Z')[-1]:.2f}); "
        f"{res.num_particles_model} particles in the model, {res.num_dofs} dofs, "
        f"wall {time.perf_counter() - start:.0f} s"
    )
    say(
        f"outputs in {res.out_dir}/: history.csv, packing.txt, checkpoints/"
        + (
            ", particles.xdmf (ParaView), particles.png, loading_path.png"
            if case.output.visual
            else ""
        )
    )


def _run_tooled(case, args, comm) -> None:
    """A ``[die]`` or ``[box]`` case: pour or pack, press by the rigid tools, report."""
    from ..workflows.box import BoxCase, run_box
    from ..workflows.closed_die import run_closed_die
    from ..workflows.compaction import RunFailure

    say = _say(comm)
    if args.check:
        say(f"{args.case}: valid: {type(case).__name__} of {case.particles} particles")
        return
    if args.restart:
        raise _Exit(BAD_INPUT, f"{args.case}: --restart is for periodic compaction cases")
    try:
        if isinstance(case, BoxCase):
            _, summary = run_box(case, comm, log=say)
            say(
                f"done: rho = {summary['rho']:.4f}, wall stresses xx / yy / zz = "
                f"{summary['sigma_xx_walls']:.3f} / {summary['sigma_yy_walls']:.3f} / "
                f"{summary['sigma_zz_walls']:.3f} MPa; outputs in {case.out_dir}/"
            )
        else:
            result = run_closed_die(case, comm, log=say)
            for line in result.report():
                say(line)
            say(f"outputs in {case.out_dir}/")
    except RunFailure as err:
        raise _Exit(RUN_FAILED, str(err)) from None
    except ValueError as err:
        raise _Exit(BAD_INPUT, f"{args.case}: {err}") from None


def _pack(args, comm) -> None:
    from ..case import MeshSection
    from ..meshes.admission import admit_packing
    from ..meshes.cubesphere import unit_ball_hex
    from ..meshes.packing import generate_packing, packing_format, read_packing, write_packing

    say = _say(comm)
    try:
        if args.input is not None:
            if not 0.5 <= args.scale <= 1.5:
                raise ValueError(f"--scale = {args.scale} is out of range: must be in [0.5, 1.5]")
            if not 1e-6 <= args.length_scale <= 1e6:
                raise ValueError(
                    f"--length-scale = {args.length_scale} is out of range: must be in [1e-6, 1e6]"
                )
            packing = read_packing(
                args.input, validate=False, cell=args.cell, length_scale=args.length_scale
            )
            say(f"{args.input}: read as {packing_format(args.input)}")
            if args.scale != 1.0:
                packing = packing.scaled(args.scale)
            run = MeshSection()  # the run's defaults: radius reduction, particle mesh
            particle = unit_ball_hex(
                *run.subdivisions, run.refinement, exact_volume=run.exact_volume
            )
            admitted = admit_packing(
                packing, run.radius_factor, particle.radius_scale, automatic=True
            )
            for note in admitted.notes:
                say(f"{args.input}: {note}")
        else:
            if not 0 < args.r_min <= args.r_max:
                raise ValueError(
                    f"--r-min = {args.r_min}, --r-max = {args.r_max}: "
                    "must be 0 < r_min <= r_max (mm)"
                )
            packing = generate_packing(
                args.particles,
                args.r_min,
                args.r_max,
                seed=args.seed,
                target_fraction=args.fraction,
            )
    except (ValueError, OSError) as err:
        raise _Exit(BAD_INPUT, f"{args.input or 'pack'}: {err}") from None
    if comm.rank == 0:
        write_packing(packing, args.out)
    say(
        f"{args.out}: {packing.num_particles} spheres, "
        f"cell {' x '.join(f'{d:.6g}' for d in packing.cell)} mm, "
        f"radii {packing.radii.min():.4g}-{packing.radii.max():.4g} mm, "
        f"solid fraction {packing.solid_fraction:.4f}"
    )


def _plot(args, comm) -> None:
    from ..io.plots import plot_loading_path
    from ..io.render import render_grid_file

    say = _say(comm)
    folder = Path(args.directory)
    history = folder / "history.csv"
    if not history.is_file():
        raise _Exit(BAD_INPUT, f"{folder}: no history.csv (not a results folder of 'mpfem run')")
    if comm.rank != 0:
        return
    try:
        made = [plot_loading_path(history, folder / "loading_path.png", title=str(folder))]
    except ValueError as err:
        raise _Exit(BAD_INPUT, str(err)) from None
    if (folder / "particles.vtu").is_file():
        made.append(render_grid_file(folder / "particles.vtu", folder / "particles.png"))
    say("wrote " + ", ".join(str(m) for m in made))


def _init(args, comm) -> None:
    from .casefile import example_case

    path = Path(args.case)
    if path.exists():
        raise _Exit(BAD_INPUT, f"{path}: exists already (not overwritten)")
    if comm.rank == 0:
        path.write_text(example_case())
    _say(comm)(f"wrote {path}; edit it, then: mpfem run {path}")


def _calibrate(args, comm) -> None:
    from ..workflows.calibration import calibrate

    say = _say(comm)
    fans = {}
    for rho, folder in args.fan:
        try:
            density = float(rho)
        except ValueError:
            raise _Exit(BAD_INPUT, f"--fan {rho} {folder}: RHO must be a number") from None
        if not 0.0 < density < 1.0:
            raise _Exit(BAD_INPUT, f"--fan {rho}: RHO is out of range: must be > 0 and < 1")
        for needed in ("surfaces.csv", "fan.csv"):
            if not (Path(folder) / needed).is_file():
                raise _Exit(BAD_INPUT, f"--fan {folder}: no {needed} (not a fan's results folder)")
        fans[density] = Path(folder)
    if args.axial_start is not None and not args.axial_start > 0.0:
        raise _Exit(BAD_INPUT, f"--axial-start {args.axial_start:g}: must be > 0 (s)")
    for name in ("isotropic", "die", "triaxial"):
        path = getattr(args, name)
        if path is not None and not Path(path).is_file():
            raise _Exit(BAD_INPUT, f"--{name} {path}: no such history file")
    if comm.rank != 0:
        return
    try:
        calibrate(
            fans,
            Path(args.isotropic),
            Path(args.out),
            die=None if args.die is None else Path(args.die),
            alpha=args.alpha,
            log=say,
            triaxial=None if args.triaxial is None else Path(args.triaxial),
            axial_start=args.axial_start,
        )
    except ValueError as err:
        raise _Exit(BAD_INPUT, str(err)) from None
    say(
        f"outputs in {args.out}/: cap_model.json / .csv / .inp, clay_model.json / .csv / .inp, "
        "round_trip.csv, summary.csv, calibration.png"
    )


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``mpfem`` console script; returns the exit code."""
    comm = MPI.COMM_WORLD
    configure_runtime(comm)  # thread rules before numpy and PETSc load their BLAS
    args = _parser().parse_args(argv)
    try:
        commands = {
            "run": _run,
            "pack": _pack,
            "plot": _plot,
            "init": _init,
            "calibrate": _calibrate,
        }
        commands[args.command](args, comm)
    except _Exit as err:
        if comm.rank == 0:
            print(f"mpfem: error: {err}", file=sys.stderr)
        return err.code
    return 0


def console() -> None:
    """Console-script wrapper: exit the process with the code returned by main()."""
    sys.exit(main())
