"""Shared fixtures. Tests run in-process (serial); MPI cases spawn ``mpirun -n 2``."""

import sys
from pathlib import Path

import pytest

import mpfem_fenicsx  # noqa: F401  (imports dolfinx_solver first)

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def python() -> str:
    return sys.executable
