"""Shared fixtures and the suite's scheduling. Tests run in-process (in `make test`: one
pytest-xdist worker per core); MPI cases spawn ``mpirun -n 2``."""

import os
import sys
from pathlib import Path

import pytest

# `make test` runs the serial tests on one pytest-xdist worker per core: give each worker its
# share of the cores for the numba kernels before mpfem_fenicsx imports numba (2 workers x 2
# threads on 2 cores oversubscribe). Subprocesses the tests spawn inherit it.
_workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
if _workers > 1 and "NUMBA_NUM_THREADS" not in os.environ:
    os.environ["NUMBA_NUM_THREADS"] = str(max(1, len(os.sched_getaffinity(0)) // _workers))


ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def python() -> str:
    return sys.executable


# `make test` hands whole files to its workers (their module fixtures are built once), in
# collection order: a heavy file handed out last leaves the other core idle for minutes. Hand out
# the heaviest first (longest-processing-time order; measured runs: bench/README.md, CI table).
HEAVIEST_FILES_FIRST = (
    "test_demos",
    "test_two_spheres",
    "test_yield_surface",
    "test_simple_cubic",
    "test_quasi_static",
    "test_mixed_control",
    "test_granular",
    "test_validation",
    "test_sphere_squeeze",
    "test_hertz",
    "test_cli",
)


# The 900 s timeout (pyproject.toml) guards the CI suite; a heavy case runs by hand, often on
# one thread beside other work, and gets an hour unless it sets its own.
HEAVY_TIMEOUT_S = 3600


def pytest_collection_modifyitems(items):
    rank = {name: i for i, name in enumerate(HEAVIEST_FILES_FIRST)}
    # stable: a file's own order kept
    items.sort(key=lambda item: rank.get(item.path.stem, len(rank)))
    for item in items:
        if item.get_closest_marker("heavy") and not item.get_closest_marker("timeout"):
            item.add_marker(pytest.mark.timeout(HEAVY_TIMEOUT_S))
