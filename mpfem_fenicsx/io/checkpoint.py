"""Checkpoints: the complete state of a run, one ``.npz`` per rank plus a ``meta.json``.

A run writes its checkpoints under ``<out>/checkpoints/step<NNNNNNN>/``, keeping the newest few;
a checkpoint is a directory::

    step0000400/
        meta.json          what was run (case, step, time, number of ranks, format version)
        rank0.npz ...      each rank's arrays: solver state, material and contact histories,
                           owned dof coordinates (to refuse another partition); rank 0 also the
                           history rows so far

It is written into ``<dir>.tmp`` and renamed over the previous one only when complete, so a run
killed while writing still has its last good checkpoint. A checkpoint is read back by the same
model on the same number of ranks (the mesh partition must be the same).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
from mpi4py import MPI

FORMAT = 2


class CheckpointError(ValueError):
    """A checkpoint that cannot be used for this run (missing, other model or partition)."""


def save_checkpoint(
    directory: str | Path, comm: MPI.Comm, arrays: dict[str, np.ndarray], meta: dict
) -> Path:
    """Write this rank's ``arrays`` and rank 0's ``meta`` (JSON-serializable) atomically."""
    directory = Path(directory)
    tmp = directory.with_name(directory.name + ".tmp")
    if comm.rank == 0:
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir(parents=True)
    comm.barrier()
    np.savez(tmp / f"rank{comm.rank}.npz", **arrays)
    comm.barrier()
    if comm.rank == 0:
        (tmp / "meta.json").write_text(
            json.dumps({**meta, "format": FORMAT, "num_ranks": comm.size}, indent=1)
        )
        old = directory.with_name(directory.name + ".old")
        shutil.rmtree(old, ignore_errors=True)
        if directory.exists():
            directory.rename(old)
        tmp.rename(directory)
        shutil.rmtree(old, ignore_errors=True)
    comm.barrier()
    return directory


def checkpoint_path(root: str | Path, step: int) -> Path:
    """``root/step<NNNNNNN>``: where the checkpoint of ``step`` goes."""
    return Path(root) / f"step{step:07d}"


def prune_checkpoints(root: str | Path, keep: int) -> None:
    """Remove all but the ``keep`` newest checkpoints under ``root`` (keep = 0: keep all)."""
    if keep > 0:
        for old in sorted(Path(root).glob("step*[0-9]"))[:-keep]:
            shutil.rmtree(old, ignore_errors=True)


def resolve_checkpoint(path: str | Path) -> Path:
    """A checkpoint directory, or the newest complete one under a ``checkpoints/`` folder (or
    under a results folder holding ``checkpoints/``)."""
    path = Path(path)
    if (path / "meta.json").is_file():
        return path
    for root in (path, path / "checkpoints"):
        found = sorted(d for d in root.glob("step*[0-9]") if (d / "meta.json").is_file())
        if found:
            return found[-1]
    raise CheckpointError(
        f"restart: no checkpoint in {path} (a checkpoint directory holds meta.json; a run "
        "writes them under <out>/checkpoints/)"
    )


def read_meta(directory: str | Path) -> dict:
    """``meta.json`` of a checkpoint (any rank)."""
    path = Path(directory) / "meta.json"
    if not path.is_file():
        raise CheckpointError(f"restart: {directory} is not a checkpoint directory (no meta.json)")
    return json.loads(path.read_text())


def load_checkpoint(directory: str | Path, comm: MPI.Comm) -> tuple[dict[str, np.ndarray], dict]:
    """This rank's arrays and the metadata of a checkpoint written with ``comm.size`` ranks."""
    meta = read_meta(directory)
    if meta.get("format") != FORMAT:
        raise CheckpointError(f"restart: checkpoint format {meta.get('format')} is not {FORMAT}")
    if meta["num_ranks"] != comm.size:
        raise CheckpointError(
            f"restart: the checkpoint was written by {meta['num_ranks']} MPI ranks; "
            f"restart it with mpirun -n {meta['num_ranks']} (this run has {comm.size})"
        )
    with np.load(Path(directory) / f"rank{comm.rank}.npz") as data:
        arrays = {k: data[k] for k in data.files}
    return arrays, meta
