"""The validation campaign: run the stages' compactions, then regenerate the report.

    python validation/run.py die
        # the die stage's runs (hours on 2 cores), then the report
    python validation/run.py die gamma      # several stages
    python validation/run.py --report-only  # tables, figures and summary.csv from the finished runs
    python validation/run.py --case die_CLP_faceted   # one case (several: repeat the option)
    python validation/run.py --list
        # the stages, their cases: done, to run or where they resume
    python validation/run.py --jobs 2 die
        # two cases at a time, one core each (logs in runs/<case>/log.txt)

``make validate`` runs every stage then the report. Runs go to ``validation/runs/<case>/`` (not
versioned; a case with a ``done`` file is not repeated, a killed one restarts from its newest
checkpoint); the report (``report.py``) rewrites ``validation/summary.csv``, the figures in
``validation/figures/`` and the generated tables of ``validation/README.md``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # the repository: the validation package

from mpi4py import MPI  # noqa: E402

from validation.cases import CASES, STAGES, FanCase  # noqa: E402

RUNS = HERE / "runs"
POLL_S = 30.0  # how often a fan waiting for another's unload looks for it (s)


def run_case(case, comm, say) -> None:
    """Run ``case`` into RUNS/<name> unless done; restart from its newest checkpoint if any (a
    fan resumes: its finished stages and reloads are kept)."""
    from mpfem_fenicsx.workflows.compaction import run_compaction

    run_dir = RUNS / case.name
    if (run_dir / "done").exists():
        say(f"{case.name}: done")
        return
    if isinstance(case, FanCase):
        from mpfem_fenicsx.workflows.yield_surface import run_yield_surface

        say(f"{case.name}: running -> {run_dir}")
        if comm.rank == 0 and case.shares_loading_with:
            share_loading(RUNS / case.shares_loading_with, run_dir, say, required=bool(case.shares))
        comm.barrier()
        clock = FanClock(run_dir, writes=comm.rank == 0)
        run_yield_surface(
            case.yield_surface_case(str(run_dir)), comm, log=clock.wrap(say), resume=True
        )
        if comm.rank == 0:
            (run_dir / "done").write_text(f"{clock.total():.0f}\n")
        return
    from mpfem_fenicsx.io.checkpoint import CheckpointError, resolve_checkpoint

    try:
        restart = resolve_checkpoint(run_dir)
    except CheckpointError:
        restart = None
    say(
        f"{case.name}: running -> {run_dir}"
        + (f" (restart from {restart.name})" if restart else "")
    )
    result = run_compaction(case.compaction_case(str(run_dir)), comm, log=say, restart=restart)
    if (
        comm.rank == 0
    ):  # a restarted run's wall time includes the killed runs' (up to their checkpoint)
        (run_dir / "done").write_text(f"{result.wall_time:.0f}\n")


def run_state(case) -> str:
    """The case's state: "done", "to run", or where a killed compaction resumes ("resumes at step
    N of M")."""
    run_dir = RUNS / case.name
    if (run_dir / "done").exists():
        return "done"
    if isinstance(case, FanCase):
        return "to run" if not run_dir.exists() else "started: resumes"
    from mpfem_fenicsx.io.checkpoint import CheckpointError, read_meta, resolve_checkpoint

    try:
        step = read_meta(resolve_checkpoint(run_dir))["step"]
    except CheckpointError:
        return "to run"
    return f"resumes at step {step} of {case.increments}"


class FanClock:
    """A fan's wall time over every process that worked on it: each log line records the time so
    far in <run_dir>/wall_s, which a resumed process starts from (a killed process loses at most
    the time since its last log line)."""

    def __init__(self, run_dir: Path, writes: bool = True):
        self.path, self.writes = run_dir / "wall_s", writes  # one rank writes
        self.before = float(self.path.read_text()) if self.path.exists() else 0.0
        self.start = time.perf_counter()

    def total(self) -> float:
        """The fan's wall time so far (s), the earlier processes' included."""
        return self.before + time.perf_counter() - self.start

    def wrap(self, say):
        """``say`` that first records the wall time so far in <run_dir>/wall_s (one rank writes)."""

        def timed(message):
            if self.writes:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                self.path.write_text(f"{self.total():.1f}\n")
            say(message)

        return timed


def share_loading(source: Path, run_dir: Path, say, required: bool = False) -> None:
    """Start a fan from the finished load and unload of ``source`` (the same path, other reloads):
    its packing, unload checkpoint and ``unloaded.json`` are copied (the fan then resumes at its
    reloads). Nothing is copied if ``run_dir`` has its own unloaded state. If ``source`` has
    none, or its checkpoint is gone (a fresh clone keeps most fans' summaries only), the fan
    loads and unloads itself, unless the sharing is ``required`` (a fan that names the one it
    shares): then a ``RuntimeError`` says which fan to run first."""
    import json
    import shutil

    if (run_dir / "unloaded.json").exists():
        return
    checkpoint = None
    if (source / "unloaded.json").exists():
        state = json.loads((source / "unloaded.json").read_text())
        checkpoint = Path(state["checkpoint"])
        # <fan>/<stage>/checkpoints/stepN: found under ``source`` if the runs have moved
        moved = source / checkpoint.parent.parent.name / "checkpoints" / checkpoint.name
        checkpoint = checkpoint if checkpoint.exists() else moved
    there = checkpoint is not None and checkpoint.exists()
    if not there or not (source / "load" / "packing.txt").exists():
        if required:
            raise RuntimeError(
                f"{run_dir.name} reloads from {source.name}'s unload, which is not in "
                f"{source}: run {source.name} first"
            )
        if checkpoint is not None:
            say(f"{run_dir.name}: {source.name}'s unload checkpoint is gone, loading afresh")
        return
    stage = checkpoint.parent.parent.name  # <fan>/<stage>/checkpoints/stepN: unload (or settle)
    (run_dir / "load").mkdir(parents=True, exist_ok=True)
    shutil.copy2(source / "load" / "packing.txt", run_dir / "load" / "packing.txt")
    for part in ("history.csv", "packing.txt"):
        if (source / stage / part).exists():
            (run_dir / stage).mkdir(exist_ok=True)
            shutil.copy2(source / stage / part, run_dir / stage / part)
    target = run_dir / stage / "checkpoints" / checkpoint.name
    shutil.copytree(checkpoint, target, dirs_exist_ok=True)
    state["checkpoint"] = str(target)
    (run_dir / "unloaded.json").write_text(json.dumps(state, indent=1))
    say(f"{run_dir.name}: load and unload shared with {source.name}")


def run_in_parallel(cases, jobs: int, say) -> None:
    """Run ``cases`` as ``jobs`` separate processes of this script, one numba / BLAS thread each
    (a 50-particle case keeps one core busy; two threads on one core only contend), each writing
    its progress to RUNS/<case>/log.txt. A failed case is reported and the others go on. A fan
    that reloads from another's unload (``FanCase.shares``) starts after it and waits for that
    unload while its fan runs."""
    cases = in_sharing_order(cases)
    running = {case.name: threading.Event() for case in cases}  # set when its process ends
    env = {
        **os.environ,
        "NUMBA_NUM_THREADS": "1",
        "OMP_NUM_THREADS": "1",
        "OPENBLAS_NUM_THREADS": "1",
    }

    def one(case) -> int:
        try:
            return launch(case)
        finally:
            running[case.name].set()

    def launch(case) -> int:
        if (RUNS / case.name / "done").exists():
            say(f"{case.name}: done")
            return 0
        source = getattr(case, "shares", None)
        unloaded = RUNS / str(source) / "unloaded.json"
        if source in running and not unloaded.exists():
            say(f"{case.name}: waiting for {source}'s unload")
            while not running[source].wait(POLL_S) and not unloaded.exists():
                pass
        (RUNS / case.name).mkdir(parents=True, exist_ok=True)
        say(f"{case.name}: started (log: {RUNS / case.name / 'log.txt'})")
        with open(RUNS / case.name / "log.txt", "a") as log:
            code = subprocess.call(
                [sys.executable, str(Path(__file__).resolve()), "--no-report", "--case", case.name],
                stdout=log,
                stderr=subprocess.STDOUT,
                env=env,
            )
        say(f"{case.name}: {'finished' if code == 0 else f'failed (exit {code}), see its log'}")
        return code

    with ThreadPoolExecutor(max_workers=jobs) as pool:
        codes = list(pool.map(one, cases))
    if any(codes):
        say(f"{sum(c != 0 for c in codes)} of {len(cases)} cases failed")


def in_sharing_order(cases: list) -> list:
    """``cases`` with every fan that reloads from another's unload (``FanCase.shares``) after
    all the others (kept in their order otherwise), so that a worker never waits on a fan that
    no worker has started."""
    names = {case.name for case in cases}

    def waits(case) -> bool:
        return getattr(case, "shares", None) in names

    return [c for c in cases if not waits(c)] + [c for c in cases if waits(c)]


def main(argv=None) -> None:
    """Run the chosen stages' or cases' missing runs (or list them), then regenerate the report."""
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("stages", nargs="*", help=f"stages to run: {', '.join(STAGES)} (default: all)")
    p.add_argument("--report-only", action="store_true", help="run nothing, regenerate the report")
    p.add_argument("--case", action="append", default=[], help="run only this case (repeatable)")
    p.add_argument("--list", action="store_true", help="list the stages and their cases")
    p.add_argument(
        "--jobs",
        type=int,
        default=1,
        help="cases run at a time, each in its own process on one core (default 1: in this "
        "process)",
    )
    p.add_argument("--no-report", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.jobs < 1:
        p.error(f"--jobs must be >= 1, got {args.jobs}")
    unknown = [s for s in args.stages if s not in STAGES]
    if unknown:
        p.error(f"stage must be one of {', '.join(STAGES)}, got {', '.join(unknown)}")
    unknown = [c for c in args.case if c not in CASES]
    if unknown:
        p.error(f"case must be one of {', '.join(CASES)}, got {', '.join(unknown)}")
    comm = MPI.COMM_WORLD
    if args.jobs > 1 and comm.size > 1:
        p.error("--jobs runs cases side by side in separate processes: use it without mpirun")
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    if args.list:
        for stage, cases in STAGES.items():
            say(f"{stage}: " + ", ".join(f"{c.name} ({run_state(c)})" for c in cases))
        return
    if not args.report_only:
        if args.case:
            cases = [CASES[name] for name in args.case]
        else:
            cases = [case for stage in args.stages or list(STAGES) for case in STAGES[stage]]
        if args.jobs > 1:
            run_in_parallel(cases, args.jobs, say)
        else:
            for case in in_sharing_order(cases):
                run_case(case, comm, say)
    if comm.rank == 0 and not args.no_report:
        from validation.report import write_report

        write_report(RUNS, HERE)


if __name__ == "__main__":
    main()
