"""Progress of a long run on rank 0: a bar with the step, rho, sigma_m and the ETA.

On a terminal the bar is redrawn in place; in a log file (not a terminal) every update is one
line, so a batch job's output still shows how the run went.
"""

from __future__ import annotations

import sys
import time

from mpi4py import MPI


def format_seconds(seconds: float) -> str:
    """'1h02m', '3m05s', '42s'."""
    s = int(round(max(seconds, 0.0)))
    if s >= 3600:
        return f"{s // 3600}h{(s % 3600) // 60:02d}m"
    if s >= 60:
        return f"{s // 60}m{s % 60:02d}s"
    return f"{s}s"


class Progress:
    """``update(fraction, step, total, **values)`` prints
    ``[#######.............]  35.0 %  step 1400/4000  rho 0.7312  sigma_m 2.114 MPa  ETA 4m10s``.

    The ETA extrapolates the wall time since the first update (restart: since the restart). A
    run past its nominal step count (an implicit run's cut-backs) shows
    ``step 260 (100 nominal)``; the percentage is the fraction of the path either way."""

    def __init__(
        self, comm: MPI.Comm = MPI.COMM_WORLD, stream=None, width: int = 24, enabled: bool = True
    ):
        self.enabled = enabled and comm.rank == 0
        self.stream = stream if stream is not None else sys.stdout
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.width = width
        self._start = None
        self._fraction0 = 0.0
        self._open_line = False

    def update(
        self, fraction: float, step: int, total: int, *, rho: float, sigma_m: float, extra: str = ""
    ) -> str:
        """Print the progress line (rank 0, when enabled) and return it."""
        fraction = min(max(fraction, 0.0), 1.0)
        now = time.perf_counter()
        if self._start is None:
            self._start, self._fraction0 = now, fraction
        done = fraction - self._fraction0
        eta = (now - self._start) / done * (1.0 - fraction) if done > 1e-12 else float("nan")
        filled = int(round(self.width * fraction))
        steps = f"{step}/{total}" if step <= total else f"{step} ({total} nominal)"
        line = (
            f"[{'#' * filled}{'.' * (self.width - filled)}] {100 * fraction:5.1f} %  step "
            f"{steps}  "
            f"rho {rho:.4f}  sigma_m {sigma_m:.3f} MPa  "
            f"ETA {format_seconds(eta) if eta == eta else '--'}" + (f"  {extra}" if extra else "")
        )
        if self.enabled:
            if self.tty:
                self.stream.write("\r\033[K" + line)
                self._open_line = True
            else:
                self.stream.write(line + "\n")
            self.stream.flush()
        return line

    def close(self) -> None:
        """End the in-place line (before any other output)."""
        if self.enabled and self._open_line:
            self.stream.write("\n")
            self.stream.flush()
            self._open_line = False
