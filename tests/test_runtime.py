"""The package import has no side effect; the thread rules are applied by configure_runtime.

Each case runs in a fresh interpreter (``python -c``): this one has imported the library and
built solvers already."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest


def _clean_env() -> dict:
    """os.environ without the thread counts that configure_runtime leaves alone when exported."""
    exported = ("OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")
    return {k: v for k, v in os.environ.items() if k not in exported}


def _run(code: str, env: dict | None = None) -> dict:
    """Run ``code`` in a fresh interpreter (no OPENBLAS_NUM_THREADS / NUMBA_NUM_THREADS unless
    ``env`` sets them); its last output line, JSON, decoded."""
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        env={**_clean_env(), **(env or {})},
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_homogenization_imports_and_works_without_mpi_and_the_fe_stack():
    """The homogenization is pure numpy: importable where MPI, the FE stack and numba are not."""
    out = _run("""
        import json, sys
        import numpy as np
        blocked = ("mpi4py", "mpi4py.MPI", "dolfinx", "dolfinx_solver", "petsc4py", "ufl", "basix",
                   "numba", "gmsh")
        for name in blocked:
            sys.modules[name] = None  # an import of any of them raises ImportError
        import mpfem_fenicsx.homogenization as hom
        sigma = np.diag([-3.0, -3.0, -6.0])  # compression, mechanics sign
        print(json.dumps({"sigma_m": float(np.trace(hom.reported_stress(sigma))) / 3.0,
                          "deviator_trace": float(np.trace(hom.deviator(sigma)))}))
    """)
    assert out == {"sigma_m": 4.0, "deviator_trace": 0.0}


def test_importing_the_library_changes_no_environment_variable_nor_numba_threads():
    """The whole library imported (solvers, workflows, command line): os.environ and numba's
    thread count as they were (numba set to 1 thread first: the rule would raise it)."""
    out = _run("""
        import json, os
        import numba
        numba.set_num_threads(1)
        before = dict(os.environ)
        import mpfem_fenicsx, mpfem_fenicsx.solvers, mpfem_fenicsx.workflows.compaction
        import mpfem_fenicsx.cli.main
        keys = set(before) | set(os.environ)
        changed = sorted(k for k in keys if before.get(k) != os.environ.get(k))
        print(json.dumps({"changed": changed, "numba": numba.get_num_threads()}))
    """)
    assert out == {"changed": [], "numba": 1}


_CONFIGURE = """
    import ctypes, json, os
    import numpy as np  # its OpenBLAS is loaded (and has read the environment) before the call
    from mpfem_fenicsx.runtime import configure_runtime

    applied = configure_runtime()
    again = configure_runtime()
    import numba

    def threads(path):
        lib = ctypes.CDLL(path)
        names = [n for n in ("openblas_get_num_threads", "scipy_openblas_get_num_threads64_",
                             "scipy_openblas_get_num_threads") if hasattr(lib, n)]
        return getattr(lib, names[0])() if names else None

    print(json.dumps({"blas": applied.blas, "numba": applied.numba, "same": again is applied,
                      "libraries": {p: threads(p) for p in applied.blas_libraries},
                      "env": os.environ.get("OPENBLAS_NUM_THREADS"),
                      "cores": len(os.sched_getaffinity(0)), "numba_now": numba.get_num_threads(),
                      "numba_max": numba.config.NUMBA_NUM_THREADS}))
"""


def test_configure_runtime_sets_one_blas_thread_even_after_numpy_and_shares_the_cores():
    """One process: OpenBLAS told to use 1 thread although numpy loaded it first (numpy's
    library among those told), the variable set for later ones, numba on min(max, cores) threads
    (one rank on the node); a second call changes nothing and returns the first result."""
    out = _run(_CONFIGURE)
    assert out["blas"] == 1 and out["env"] == "1" and out["same"]
    assert any("numpy" in path for path in out["libraries"]), out["libraries"]
    assert set(out["libraries"].values()) == {1}, out["libraries"]
    assert out["numba"] == out["numba_now"] == max(1, min(out["numba_max"], out["cores"]))


def test_configure_runtime_leaves_exported_thread_counts_alone():
    out = _run(_CONFIGURE, env={"OPENBLAS_NUM_THREADS": "2", "NUMBA_NUM_THREADS": "1"})
    assert out["blas"] is None and out["numba"] is None and out["libraries"] == {}
    assert out["env"] == "2" and out["numba_now"] == 1


@pytest.mark.mpi
def test_two_ranks_on_a_node_share_its_cores_for_numba():
    """mpirun -n 2: each rank gets max(1, min(NUMBA_NUM_THREADS, cores // 2)) numba threads."""
    code = textwrap.dedent("""
        import json, os
        import numba
        from mpi4py import MPI
        from mpfem_fenicsx.runtime import configure_runtime
        share = max(1, min(numba.config.NUMBA_NUM_THREADS, len(os.sched_getaffinity(0)) // 2))
        applied = configure_runtime(MPI.COMM_WORLD)
        rows = MPI.COMM_WORLD.gather([applied.numba, numba.get_num_threads(), share])
        if MPI.COMM_WORLD.rank == 0:
            print(json.dumps(rows))
    """)
    mpirun = str(Path(sys.executable).parent / "mpirun")
    done = subprocess.run(
        [mpirun, "-n", "2", sys.executable, "-c", code],
        env=_clean_env(),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    rows = json.loads(done.stdout.strip().splitlines()[-1])
    assert len(rows) == 2 and all(a == b == share for a, b, share in rows), rows
