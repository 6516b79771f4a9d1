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
        raise ValueError(
            f"{history_csv}: not a compaction history (missing columns {', '.join(missing)})"
        )
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
    return _save(fig, png, title)


def rendulic_frame(ax, reach: float) -> None:
    """The Rendulic plane's frame on ``ax``: axes through 0, the uniaxial path sigma~_d = 3 sigma_m
    up to |sigma_m| = ``reach`` / 3 (MPa), labels (compression > 0, axis I = z)."""
    s = np.linspace(-reach / 3, reach / 3, 2)
    ax.plot(s, 3 * s, ":", color="0.4", lw=1, label="uniaxial sigma~_d = 3 sigma_m")
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.axvline(0.0, color="0.6", lw=0.8)
    ax.set_xlabel("sigma_m (MPa, compression > 0)")
    ax.set_ylabel("sigma~_d = sigma_I - (sigma_II + sigma_III)/2 (MPa)")


def plot_yield_surface(
    unload_history_csv: str | Path,
    fan_csv: str | Path,
    surfaces_csv: str | Path,
    png: str | Path,
    title: str = "",
    gamma_limit: float = float("nan"),
) -> Path:
    """Draw a chapter-4 fan in the style of thesis fig. 4.5 / 4.7 / 4.18: (a) strain paths
    (h_v, h~_d) of the loading, the unload and the reloads; (b) stress paths (sigma_m, sigma~_d)
    with the yield surface (iso-dissipation), the iso-Gamma curves, Hill's W2 <= 0 points and the
    uniaxial line sigma~_d = 3 sigma_m; the iso-Gamma curve at ``gamma_limit`` (Gamma_l, 1/mm) is
    marked as the limit one. Stresses compression > 0, strains natural sign."""
    import csv

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = read_csv(unload_history_csv)
    fan = read_csv(fan_csv)
    surfaces: dict[str, list[tuple[float, float, float]]] = {}
    with open(surfaces_csv) as fh:
        for row in csv.DictReader(fh):
            surfaces.setdefault(row["kind"], []).append(
                (float(row["phi"]), float(row["sigma_m"]), float(row["sigma_tilde_d"]))
            )
    fig, axes = plt.subplots(1, 2, figsize=(15, 5.6), constrained_layout=True)
    for ax, (x, y) in zip(axes, (("h_v", "h_tilde_d"), ("sigma_m", "sigma_tilde_d")), strict=True):
        ax.plot(path[x], path[y], "k.-", ms=3, lw=1.2, label="loading + isotropic unload")
        for phi in np.unique(fan["phi"]):
            rows = fan["phi"] == phi
            ax.plot(fan[x][rows], fan[y][rows], "-", lw=0.8, color=plt.cm.hsv(phi / (2 * np.pi)))
        ax.grid(alpha=0.3)
    # zoom on the unload and the reloads (the loading path runs far off to the left)
    near = np.r_[fan["h_v"], path["h_v"][-1:]], np.r_[fan["h_tilde_d"], path["h_tilde_d"][-1:]]
    for lim, values in zip((axes[0].set_xlim, axes[0].set_ylim), near, strict=True):
        lo, hi = np.nanmin(values), np.nanmax(values)
        pad = 0.15 * max(hi - lo, 1e-6)
        lim(lo - pad, hi + pad)
    axes[0].set_xlabel("h_v (-)")
    axes[0].set_ylabel("h~_d (-)")
    axes[0].set_title("(a) strain paths near the unloaded state (reload colour = phi)")
    ax = axes[1]
    styles = {
        "yield": ("o-", "tab:red", "yield (iso-dissipation)"),
        "w2": ("x", "tab:purple", "Hill W2 <= 0"),
    }
    greys = iter(plt.cm.Blues(np.linspace(0.45, 0.95, max(1, len(surfaces)))))
    for kind, pts in surfaces.items():
        p = np.array(sorted(pts))
        if np.isfinite(gamma_limit) and kind == f"gamma_{gamma_limit:.6g}":
            marker, colour, label = "D-", "tab:green", f"limit Gamma_l = {kind[6:]} 1/mm"
        elif kind.startswith("gamma_"):
            marker, colour, label = "s--", next(greys), f"Gamma = {kind[6:]} 1/mm"
        else:
            marker, colour, label = styles[kind]
        complete = len(p) == np.unique(fan["phi"]).size  # a closed curve: every reload crossed
        # points only: joining a partial set would draw false chords
        if kind == "w2" or not complete:
            ax.plot(
                p[:, 1], p[:, 2], marker[0], color=colour, ms=5, label=f"{label} ({len(p)} reloads)"
            )
        else:
            closed = np.vstack([p, p[:1]])
            ax.plot(closed[:, 1], closed[:, 2], marker, color=colour, ms=4, lw=1.4, label=label)
    rendulic_frame(ax, np.nanmax(np.abs(np.r_[fan["sigma_m"], path["sigma_m"]])))
    ax.set_title("(b) Rendulic plane (axis I = z)")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    return _save(fig, png, title)


def _save(fig, png: str | Path, title: str = "") -> Path:
    """Title, write (creating the folder) and close a figure."""
    import matplotlib.pyplot as plt

    if title:
        fig.suptitle(title)
    png = Path(png)
    png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return png


def plot_deviatoric_surface(points, png: str | Path, mean: float, title: str = "") -> Path:
    """Yield points of a Lode-angle fan [(theta_deg, sigma_m, q, lode_deg), ...] (MPa, compression
    > 0) in the deviatoric plane (radius q, angle the measured Lode angle; the points mirrored by
    the symmetry of an isotropic state, theta -> -theta and + 120 deg, drawn hollow) and in
    principal-stress space (the hydrostatic axis, the surface's section at sigma_m = ``mean``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..loading.mixed import lode_direction

    pts = np.array([(p[2], np.radians(p[3])) for p in points]).reshape(-1, 2)
    images = [(s, t) for s in (1, -1) for t in (0, 1, 2)]  # theta -> +-theta + 120 deg k
    fig = plt.figure(figsize=(10, 4.6))
    ax = fig.add_subplot(1, 2, 1)
    for k, (sign, turn) in enumerate(images):
        angle = sign * pts[:, 1] + turn * 2 * np.pi / 3
        ax.plot(
            pts[:, 0] * np.cos(angle),
            pts[:, 0] * np.sin(angle),
            "o",
            mfc="tab:red" if k == 0 else "none",
            mec="tab:red",
            ms=6 if k == 0 else 4,
            label="yield (measured)" if k == 0 else ("mirrored by symmetry" if k == 1 else None),
        )
    r = 1.15 * (pts[:, 0].max() if pts.size else 1.0)
    for i, name in enumerate(("sigma_1 (x)", "sigma_2 (y)", "sigma_3 (z)")):
        a = 2 * np.pi / 3 * i  # the direction of a stress along axis i (lode_angle)
        ax.plot([0, r * np.cos(a)], [0, r * np.sin(a)], color="0.6", lw=0.8)
        ax.annotate(name, (r * np.cos(a), r * np.sin(a)), fontsize=8, color="0.4")
    ax.set_aspect("equal")
    ax.set_xlabel("q cos(theta) (MPa)")
    ax.set_ylabel("q sin(theta) (MPa)")
    ax.legend(fontsize=8, loc="best")
    ax.grid(alpha=0.3)
    ax3 = fig.add_subplot(1, 2, 2, projection="3d")
    ring = sorted(
        (float((sign * theta + turn * 2 * np.pi / 3) % (2 * np.pi)), q)
        for q, theta in pts
        for sign, turn in images
    )  # the whole section at sigma_m = mean, closed
    if ring:
        section = np.array(
            [mean + np.sqrt(2.0 / 3.0) * q * lode_direction(a) for a, q in ring + ring[:1]]
        )
        ax3.plot(*section.T, color="tab:red", lw=0.8, label=f"section at sigma_m = {mean:g} MPa")
    measured = np.array(
        [mean + np.sqrt(2.0 / 3.0) * q * lode_direction(theta) for q, theta in pts]
    ).reshape(-1, 3)
    ax3.scatter(*measured.T, color="tab:red", s=14)
    top = mean + (pts[:, 0].max() if pts.size else 1.0)
    ax3.plot([0, top], [0, top], [0, top], color="0.5", lw=0.8, label="hydrostatic axis")
    ax3.set_xlabel("sigma_1 (MPa)")
    ax3.set_ylabel("sigma_2 (MPa)")
    ax3.set_zlabel("sigma_3 (MPa)")
    ax3.legend(fontsize=8)
    return _save(fig, png, title)


def plot_force_rupture(
    rows: dict, points: dict, phi_c: float, png: str | Path, title: str = ""
) -> Path:
    """A force-controlled rupture probe (workflows.force_rupture): left, the stress along the
    path against the strain along it (MPa, mm/mm); right, E_c / E_d (log) and W2 against time,
    with the threshold phi_c and each criterion's rupture point marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = rows["time"]
    strain = np.column_stack([rows[f"h_{i}{i}"] for i in (1, 2, 3)])
    strain_along = np.linalg.norm(strain - strain[0], axis=1)
    marks = {
        "phi": ("tab:red", "E_c / E_d = phi_c"),
        "w2": ("tab:blue", "W2 <= 0"),
        "peak": ("k", "peak stress"),
    }
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(10, 4.2))
    ax.plot(strain_along, rows["path_stress"], ".-", color="0.3")
    for key, (color, label) in marks.items():
        if key in points:
            ax.plot(
                np.interp(points[key]["time"], t, strain_along),
                points[key]["path_stress"],
                "o",
                mfc="none",
                mec=color,
                ms=9,
                label=label,
            )
    ax.set_xlabel("strain along the path |h - h_start|")
    ax.set_ylabel("stress along the path (MPa, from the start)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax2.semilogy(t * 1e3, rows["phi"], ".-", color="tab:red", label="E_c / E_d")
    ax2.axhline(phi_c, color="tab:red", ls=":", lw=0.8)
    ax2.set_xlabel("time (ms)")
    ax2.set_ylabel("E_c / E_d", color="tab:red")
    ax3 = ax2.twinx()
    ax3.plot(t * 1e3, rows["W2"], ".-", color="tab:blue", label="W2")
    ax3.axhline(0.0, color="tab:blue", ls=":", lw=0.8)
    ax3.set_ylabel("W2 = dsigma : dh (MPa)", color="tab:blue")
    for key, (color, _) in marks.items():
        if key in points:
            ax2.axvline(points[key]["time"] * 1e3, color=color, lw=0.8, ls="--")
    return _save(fig, png, title)
