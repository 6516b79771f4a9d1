"""Point-to-point exchanges between the ranks that need each other, never a gather of the model.

Two building blocks of the rank-local contact surface and constraints:

- :func:`sparse_exchange` sends a payload to each listed rank and receives what the others sent
  (only a flag per pair of ranks travels to all; payloads go point to point);
- :class:`KeyedRows` keeps rows of data grouped by an integer key (a body's facets, a particle's
  nodes) whole on a *home* rank, the rank that has most of them, and hands any rank the rows of
  the keys it asks for. With whole particles per rank (``meshes.partition``) the rows already sit
  at home and only the asked-for keys of other ranks travel.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

_TAG = 77


def sparse_exchange(comm: MPI.Comm, outgoing: dict[int, object]) -> dict[int, object]:
    """Send ``outgoing[rank]`` (picklable) to each listed rank other than this one; return what
    the other ranks sent to this one, by source rank. Collective."""
    flags = np.zeros(comm.size, dtype=np.int32)
    flags[[rank for rank in outgoing if rank != comm.rank]] = 1
    incoming = np.empty_like(flags)
    comm.Alltoall(flags, incoming)
    requests = [
        comm.isend(payload, dest=rank, tag=_TAG)
        for rank, payload in outgoing.items()
        if rank != comm.rank
    ]
    received = {int(r): comm.recv(source=int(r), tag=_TAG) for r in np.flatnonzero(incoming)}
    MPI.Request.Waitall(requests)
    return received


def _nbytes(columns) -> int:
    return int(sum(np.asarray(c).nbytes for c in columns))


class KeyedRows:
    """Rows (columns of equal length) grouped by ``keys`` in [0, num_keys), each key's rows kept
    whole by its home rank (most rows of that key; ties: the lowest rank). Collective.

    Attributes:
        home: (num_keys,) home rank of every key (-1: a key without rows).
        bytes_received: bytes of rows received by this rank (setup and :meth:`fetch`).
    """

    def __init__(self, comm: MPI.Comm, keys: np.ndarray, columns: tuple, num_keys: int):
        self.comm = comm
        keys = np.asarray(keys, dtype=np.int64)
        count = np.bincount(keys, minlength=num_keys).astype(np.int64)
        score = np.where(count > 0, count * comm.size + (comm.size - 1 - comm.rank), -1)
        best = np.empty_like(score)
        comm.Allreduce(score, best, op=MPI.MAX)
        self.home = np.where(best >= 0, comm.size - 1 - best % comm.size, -1).astype(np.int32)
        home = self.home[keys]
        outgoing = {
            int(rank): (keys[home == rank], *(np.asarray(c)[home == rank] for c in columns))
            for rank in np.unique(home)
        }
        mine = outgoing.pop(comm.rank, (keys[:0], *(np.asarray(c)[:0] for c in columns)))
        received = sparse_exchange(comm, outgoing)
        self.bytes_received = sum(_nbytes(r) for r in received.values())
        parts = [mine, *received.values()]
        k = np.concatenate([p[0] for p in parts])
        order = np.argsort(k, kind="stable")
        self._keys = k[order]
        self._columns = tuple(
            np.concatenate([p[i + 1] for p in parts])[order] for i in range(len(columns))
        )
        self._ptr = np.searchsorted(self._keys, np.arange(num_keys + 1))

    def _local(self, keys: np.ndarray) -> tuple:
        """(keys, *columns) of the rows this rank keeps for ``keys`` (as home)."""
        start = self._ptr[keys]
        count = self._ptr[keys + 1] - start
        # row indices start_k, start_k + 1, ... of every key, without a loop over the keys
        idx = np.arange(count.sum(), dtype=np.int64) + np.repeat(
            start - np.cumsum(count) + count, count
        )
        return (self._keys[idx], *(c[idx] for c in self._columns))

    def fetch(self, keys: np.ndarray) -> tuple:
        """(keys, *columns) of every row of the given keys (those without rows are skipped), from
        their homes; rows of one key in their home's order. Collective."""
        keys = np.unique(np.asarray(keys, dtype=np.int64))
        keys = keys[self.home[keys] >= 0]
        rank = self.comm.rank
        remote = keys[self.home[keys] != rank]
        asks = {int(h): remote[self.home[remote] == h] for h in np.unique(self.home[remote])}
        wanted = sparse_exchange(self.comm, asks)
        received = sparse_exchange(self.comm, {r: self._local(k) for r, k in wanted.items()})
        self.bytes_received += sum(_nbytes(r) for r in received.values())
        parts = [self._local(keys[self.home[keys] == rank]), *received.values()]
        return tuple(np.concatenate([p[i] for p in parts]) for i in range(len(parts[0])))
