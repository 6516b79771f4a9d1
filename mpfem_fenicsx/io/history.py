"""Row-wise history written as CSV by rank 0 (one row per output step, named columns)."""

from __future__ import annotations

import csv
import os
from pathlib import Path

import numpy as np
from mpi4py import MPI

#: the components of a 3 x 3 tensor in history columns, row by row: "11", "12", ..., "33"
TENSOR_COMPONENTS = tuple(f"{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3))


def tensor_columns(prefix: str) -> list[str]:
    """The nine column names of the tensor ``prefix`` (e.g. "F" -> F11, F12, ..., F33)."""
    return [prefix + c for c in TENSOR_COMPONENTS]


def tensor_values(prefix: str, tensor) -> dict[str, float]:
    """A (3, 3) tensor as the history values of its columns ``prefix`` + 11 ... 33."""
    return dict(zip(tensor_columns(prefix), np.asarray(tensor, dtype=float).ravel(), strict=True))


def tensor_from_columns(columns, prefix: str) -> np.ndarray:
    """(n, 3, 3) tensors from the columns ``prefix`` + 11 ... 33 of a mapping of column arrays
    (``read_csv``) or of anything with a ``column(name)`` method (a :class:`History`)."""
    get = columns.column if hasattr(columns, "column") else columns.__getitem__
    return np.stack(
        [np.asarray(get(c), dtype=float) for c in tensor_columns(prefix)], axis=-1
    ).reshape(-1, 3, 3)


class History:
    """Collects rows of named values; :meth:`write` saves ``path`` (rank 0 only).

    The file is rewritten after every row when ``flush_every_row`` is set, so a run that stops
    early still leaves its history on disk.
    """

    def __init__(
        self,
        path: str | Path,
        columns: list[str],
        comm: MPI.Comm = MPI.COMM_WORLD,
        flush_every_row: bool = False,
    ):
        self.path = Path(path)
        self.columns = list(columns)
        self.comm = comm
        self.rows: list[list[float]] = []
        self.flush_every_row = flush_every_row

    def append(self, **values) -> None:
        """Add a row: one value per column, by name (ValueError naming the missing or unknown)."""
        missing = set(self.columns) - set(values)
        unknown = set(values) - set(self.columns)
        if missing or unknown:
            raise KeyError(f"history row: missing {sorted(missing)}, unknown {sorted(unknown)}")
        self.rows.append([float(values[c]) for c in self.columns])
        if self.flush_every_row:
            self.write()

    def array(self) -> np.ndarray:
        """The rows as an (n, columns) array."""
        return np.array(self.rows, dtype=float).reshape(-1, len(self.columns))

    def column(self, name: str) -> np.ndarray:
        """The values (n,) of the column ``name``."""
        return self.array()[:, self.columns.index(name)]

    def tensor(self, prefix: str) -> np.ndarray:
        """(rows, 3, 3) tensors of the columns ``prefix`` + 11 ... 33 (e.g. "F", "sigma_vol_")."""
        return tensor_from_columns(self, prefix)

    def write(self) -> Path:
        """Write the CSV (rank 0; NaN as an empty field) and return its path. The rows go to a
        temporary file that then replaces the CSV: a run killed while writing leaves the last
        complete file, not a truncated one."""
        if self.comm.rank == 0:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            partial = self.path.with_name(self.path.name + ".partial")
            with open(partial, "w", newline="") as fh:
                writer = csv.writer(fh)
                writer.writerow(self.columns)
                for row in self.rows:
                    # NaN: not defined
                    writer.writerow(["" if np.isnan(v) else repr(v) for v in row])
            os.replace(partial, self.path)
        return self.path


def read_csv(path: str | Path) -> dict[str, np.ndarray]:
    """Columns of a history CSV as float arrays (empty cells, values not defined, read as NaN)."""
    with open(path) as fh:
        reader = csv.reader(fh)
        header = next(reader)
        data = np.array(
            [[float(v) if v else np.nan for v in row] for row in reader], dtype=float
        ).reshape(-1, len(header))
    return {name: data[:, i] for i, name in enumerate(header)}
