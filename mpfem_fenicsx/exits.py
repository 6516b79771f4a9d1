"""Exit codes shared by ``mpfem`` and the demos: one code for bad input, one for a failed run.

0  done
2  bad input: a case, an option or a file refused before any computation (one line naming
   the field and the allowed range)
3  the run diverged or did not converge (history so far and the last good checkpoint kept)
"""

from __future__ import annotations

import sys
from contextlib import contextmanager
from typing import NoReturn

from mpi4py import MPI

BAD_INPUT = 2
RUN_FAILED = 3


def fail(code: int, message: str, prog: str | None = None) -> NoReturn:
    """Print ``prog: error: message`` (rank 0, one line) and exit with ``code``."""
    if MPI.COMM_WORLD.rank == 0:
        first = str(message).strip().splitlines()[0] if str(message).strip() else "error"
        print(f"{prog or _prog()}: error: {first}", file=sys.stderr)
    raise SystemExit(code)


@contextmanager
def bad_input_exits(prog: str | None = None):
    """Inside the block a ValueError (a refused value) or an OSError (a missing or unreadable
    file) exits with :data:`BAD_INPUT` and one line, like ``mpfem`` and argparse do. Wrap the
    construction and validation of a demo's inputs, not its computation."""
    try:
        yield
    except (ValueError, OSError) as err:
        fail(BAD_INPUT, str(err), prog)


def _prog() -> str:
    from pathlib import Path

    return Path(sys.argv[0]).name if sys.argv and sys.argv[0] else "mpfem"
