"""What a rank holds, receives and costs at 1, 2 and 4 ranks: the measurements of the scaling model.

    python bench/scale_out.py                          # 350 GDF and 1000 CLP at P = 1, 2, 4
    python bench/scale_out.py --cases 50:CLP --ranks 1 2
    python bench/scale_out.py --threads 2 --ranks 1    # the single process with 2 numba threads

Runs ``bench/compaction.py`` (short mode: a few increments from the packing, already in contact)
under ``mpirun -n P`` for every case and P, one run at a time, and appends each run's JSON (with
the case, P and the numba threads) to ``--results`` (default ``bench/measured/scale_out.jsonl``,
kept in the repository): time by phase, peak memory per rank, and per rank the contact surface
held, the candidate pairs of the broad phase and the bytes received per step. Runs already in the
file are skipped, so an interrupted series resumes where it stopped. On a 2-core machine 4 ranks
are oversubscribed: their bytes and memory are valid, their times are not.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def _key(case: str, ranks: int, threads: int) -> str:
    return f"{case}/P{ranks}/T{threads}"


def main(argv=None) -> None:
    """Run the missing (case, P) pairs and append their results."""
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--cases", nargs="+", default=["350:GDF", "1000:CLP"], help="particles:bc")
    p.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 4])
    p.add_argument("--threads", type=int, default=1, help="numba threads per rank")
    p.add_argument("--steps", type=int, default=10)
    p.add_argument("--warmup", type=int, default=20)
    p.add_argument("--results", type=Path, default=HERE / "measured" / "scale_out.jsonl")
    args = p.parse_args(argv)
    args.results.parent.mkdir(parents=True, exist_ok=True)
    done = set()
    if args.results.exists():
        done = {json.loads(line)["key"] for line in args.results.read_text().splitlines() if line}
    mpirun = Path(sys.executable).parent / "mpirun"
    for case in args.cases:
        particles, bc = case.split(":")
        for ranks in args.ranks:
            key = _key(case, ranks, args.threads)
            if key in done:
                print(f"{key}: already measured", flush=True)
                continue
            cmd = [str(mpirun), "-n", str(ranks), sys.executable, str(HERE / "compaction.py")]
            cmd += ["--particles", particles, "--bc", bc, "--increments", "40"]
            cmd += ["--warmup", str(args.warmup), "--steps", str(args.steps)]
            env = {**os.environ, "NUMBA_NUM_THREADS": str(args.threads)}
            print(f"{key}: {' '.join(cmd)}", flush=True)
            run = subprocess.run(cmd, capture_output=True, text=True, env=env)
            if run.returncode != 0:
                sys.exit(f"{key} failed:\n{run.stdout[-2000:]}\n{run.stderr[-3000:]}")
            result = json.loads(run.stdout.strip().splitlines()[-1])
            result.update(key=key, numba_threads=args.threads)
            with open(args.results, "a") as fh:
                fh.write(json.dumps(result) + "\n")
            contact = result["contact"]
            print(
                f"{key}: {result['s_per_step']:.3f} s/step, peak {result['peak_rss_mb_per_rank']} "
                f"MB, held {contact['held_surface_share']} (nodes {contact['held_node_share']}), "
                f"pairs {contact['pairs_share']}",
                flush=True,
            )


if __name__ == "__main__":
    main()
