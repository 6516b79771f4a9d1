"""Issue 23 validation: run the stages' compactions, then regenerate the report.

    python validation/run.py die            # the die stage's runs (hours on 2 cores), then the report
    python validation/run.py die gamma      # several stages
    python validation/run.py --report-only  # tables, figures and summary.csv from the finished runs
    python validation/run.py --case die_CLP_faceted   # one case (several: repeat the option)
    python validation/run.py --list         # the stages, their cases and which are done

``make validate`` runs every stage then the report. Runs go to ``validation/runs/<case>/`` (not
versioned; a case with a ``done`` file is not repeated, a killed one restarts from its newest
checkpoint); the report (``report.py``) rewrites ``validation/summary.csv``, the figures in
``validation/figures/`` and the generated tables of ``validation/README.md``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from mpi4py import MPI  # noqa: E402

import mpfem_fenicsx  # noqa: E402,F401  (mpi4py before dolfinx)
from cases import STAGES  # noqa: E402

RUNS = HERE / "runs"


def run_case(case, comm, say) -> None:
    """Run ``case`` into RUNS/<name> unless done; restart from its newest checkpoint if any."""
    from mpfem_fenicsx.workflows.compaction import run_compaction

    run_dir = RUNS / case.name
    if (run_dir / "done").exists():
        say(f"{case.name}: done")
        return
    from mpfem_fenicsx.io.checkpoint import CheckpointError, resolve_checkpoint

    try:
        restart = resolve_checkpoint(run_dir)
    except CheckpointError:
        restart = None
    say(f"{case.name}: running -> {run_dir}" + (f" (restart from {restart.name})" if restart else ""))
    start = time.perf_counter()
    run_compaction(case.compaction_case(str(run_dir)), comm, log=say, restart=restart)
    if comm.rank == 0:
        (run_dir / "done").write_text(f"{time.perf_counter() - start:.0f}\n")


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("stages", nargs="*", help=f"stages to run: {', '.join(STAGES)} (default: all)")
    p.add_argument("--report-only", action="store_true", help="run nothing, regenerate the report")
    p.add_argument("--case", action="append", default=[], help="run only this case (repeatable)")
    p.add_argument("--list", action="store_true", help="list the stages and their cases")
    args = p.parse_args(argv)
    unknown = [s for s in args.stages if s not in STAGES]
    if unknown:
        p.error(f"stage must be one of {', '.join(STAGES)}, got {', '.join(unknown)}")
    by_name = {c.name: c for cases in STAGES.values() for c in cases}
    unknown = [c for c in args.case if c not in by_name]
    if unknown:
        p.error(f"case must be one of {', '.join(by_name)}, got {', '.join(unknown)}")
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    if args.list:
        for stage, cases in STAGES.items():
            say(f"{stage}: " + ", ".join(f"{c.name} ({'done' if (RUNS / c.name / 'done').exists() else 'to run'})"
                                         for c in cases))
        return
    if args.case and not args.report_only:
        for name in args.case:
            run_case(by_name[name], comm, say)
    elif not args.report_only:
        for stage in args.stages or list(STAGES):
            for case in STAGES[stage]:
                run_case(case, comm, say)
    if comm.rank == 0:
        from report import write_report

        write_report(RUNS, HERE)


if __name__ == "__main__":
    main()
