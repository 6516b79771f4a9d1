"""Shared timing helper of the benchmarks."""

import time

import numpy as np


def median_time(fn, repeat: int, comm) -> float:
    """Median wall time (s) of ``fn()`` over ``repeat`` runs, ranks synchronized around each."""
    times = []
    for _ in range(repeat):
        comm.Barrier()
        t0 = time.perf_counter()
        fn()
        comm.Barrier()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))
