"""Matplotlib figures of a run's history (rank 0, no display needed).

``loading_path.png``: the three views of thesis chapters 2 and 4 --
(a) mean stress vs relative density (compaction curve; Love-Weber, and Schmidt when defined),
(b) deviatoric vs volumetric Hencky strain (h_d vs h_v; h_v < 0 in compaction),
(c) Rendulic plane sigma~_d vs sigma_m (compression > 0).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .history import read_csv


def plot_loading_path(history_csv: str | Path, png: str | Path, title: str = "") -> Path:
    """Draw ``loading_path.png`` from a ``history.csv`` (columns of workflows.compaction)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h = read_csv(history_csv)
    missing = [c for c in ("rho", "sigma_m", "h_v", "h_d", "sigma_tilde_d") if c not in h]
    if missing:
        raise ValueError(f"{history_csv}: not a compaction history (missing columns {', '.join(missing)})")
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6), constrained_layout=True)
    ax = axes[0]
    ax.plot(h["rho"], h["sigma_m"], "o-", ms=3, label="Love-Weber")
    if "sigma_schmidt_11" in h and np.isfinite(h["sigma_schmidt_11"]).any():
        schmidt_m = (h["sigma_schmidt_11"] + h["sigma_schmidt_22"] + h["sigma_schmidt_33"]) / 3.0
        ax.plot(h["rho"], schmidt_m, "s--", ms=3, label="Schmidt (auxiliary nodes)")
    ax.set_xlabel("relative density rho (-)")
    ax.set_ylabel("mean stress sigma_m (MPa, compression > 0)")
    ax.set_title("(a) compaction curve")
    ax.legend()
    ax = axes[1]
    ax.plot(h["h_v"], h["h_d"], "o-", ms=3)
    ax.set_xlabel("volumetric Hencky strain h_v (-)")
    ax.set_ylabel("deviatoric Hencky strain h_d (-)")
    ax.set_title("(b) strain path")
    ax = axes[2]
    ax.plot(h["sigma_m"], h["sigma_tilde_d"], "o-", ms=3)
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.set_xlabel("sigma_m (MPa)")
    ax.set_ylabel("sigma~_d = sigma_I - (sigma_II + sigma_III)/2 (MPa)")
    ax.set_title("(c) Rendulic plane (axis I = z)")
    for ax in axes:
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    png = Path(png)
    png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return png
