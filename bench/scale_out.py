"""What a rank holds, receives and costs at 1, 2 and 4 ranks: the measurements of the scaling model.

    python bench/scale_out.py                      # 350 GDF and 1000 CLP: 1x1, 2x1, 1x2, 4x1
    python bench/scale_out.py --cases 50:CLP --runs 1x1 2x1
    python bench/scale_out.py --runs 1x1 2x1 1x2 --repeat 3   # three interleaved rounds

Runs ``bench/compaction.py`` (short mode: a few increments from the packing, already in contact)
under ``mpirun -n P`` with T numba threads per rank for every case and run ``PxT``, one run at a
time, and appends each run's JSON (with the case, P, T and the round) to ``--results`` (default
``bench/measured/scale_out.jsonl``, kept in the repository): time by phase (per rank too), peak
memory per rank, and per rank the contact surface held, the candidate pairs of the broad phase
and the bytes received per step. With ``--repeat`` the runs are made in interleaved rounds, so
that a slow spell of a shared machine hits every configuration alike; compare the fastest round
of each. Runs already in the file are skipped, so an interrupted series resumes where it
stopped. On a 2-core machine 4 ranks are oversubscribed: their bytes and memory are valid,
their times are not.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def _key(case: str, ranks: int, threads: int, repeat: int = 0) -> str:
    """``case/P{ranks}/T{threads}``, with ``#{repeat}`` for repeats after the first."""
    return f"{case}/P{ranks}/T{threads}" + (f"#{repeat}" if repeat else "")


def _run_spec(text: str) -> tuple[int, int]:
    """``"PxT"`` -> (ranks, numba threads per rank)."""
    ranks, _, threads = text.partition("x")
    try:
        out = int(ranks), int(threads or 1)
    except ValueError:
        raise argparse.ArgumentTypeError(f"run {text!r}: expected PxT, e.g. 2x1") from None
    if min(out) < 1:
        raise argparse.ArgumentTypeError(f"run {text!r}: ranks and threads must be >= 1")
    return out


def main(argv=None) -> None:
    """Run the missing (case, P, threads, repeat) runs and append their results."""
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--cases", nargs="+", default=["350:GDF", "1000:CLP"], help="particles:bc")
    p.add_argument(
        "--runs",
        type=_run_spec,
        nargs="+",
        default=[(1, 1), (2, 1), (1, 2), (4, 1)],
        help="ranks x numba threads per rank, e.g. 1x1 2x1 1x2 4x1 (the default)",
    )
    p.add_argument("--repeat", type=int, default=1, help="rounds of --runs, interleaved (>= 1)")
    p.add_argument("--steps", type=int, default=10)
    p.add_argument("--warmup", type=int, default=20)
    p.add_argument("--results", type=Path, default=HERE / "measured" / "scale_out.jsonl")
    args = p.parse_args(argv)
    if args.repeat < 1:
        p.error(f"--repeat = {args.repeat} must be >= 1")
    args.results.parent.mkdir(parents=True, exist_ok=True)
    done = set()
    if args.results.exists():
        done = {json.loads(line)["key"] for line in args.results.read_text().splitlines() if line}
    mpirun = Path(sys.executable).parent / "mpirun"
    for case in args.cases:
        particles, bc = case.split(":")
        for repeat in range(args.repeat):
            for ranks, threads in args.runs:
                key = _key(case, ranks, threads, repeat)
                if key in done:
                    print(f"{key}: already measured", flush=True)
                    continue
                cmd = [str(mpirun), "-n", str(ranks), sys.executable, str(HERE / "compaction.py")]
                cmd += ["--particles", particles, "--bc", bc, "--increments", "40"]
                cmd += ["--warmup", str(args.warmup), "--steps", str(args.steps)]
                env = {**os.environ, "NUMBA_NUM_THREADS": str(threads)}
                print(f"{key}: {' '.join(cmd)}", flush=True)
                run = subprocess.run(cmd, capture_output=True, text=True, env=env)
                if run.returncode != 0:
                    sys.exit(f"{key} failed:\n{run.stdout[-2000:]}\n{run.stderr[-3000:]}")
                result = json.loads(run.stdout.strip().splitlines()[-1])
                result.update(key=key, numba_threads=threads, repeat=repeat)
                with open(args.results, "a") as fh:
                    fh.write(json.dumps(result) + "\n")
                contact = result["contact"]
                print(
                    f"{key}: {result['s_per_step']:.3f} s/step, peak "
                    f"{result['peak_rss_mb_per_rank']} MB, held {contact['held_surface_share']} "
                    f"(nodes {contact['held_node_share']}), pairs {contact['pairs_share']}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
