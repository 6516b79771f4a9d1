"""The chapter-4 fan with reloads by Newton against the explicit fans, yield point by yield point.

    python bench/implicit_fan.py                                  # the table of the kept fans
    python bench/implicit_fan.py --run implicit                   # (re)run or resume one fan
    python bench/implicit_fan.py --run explicit --reload-increments 3000

Three realizations of `demos/yield_surface.py`'s default fan (24 lead particles, gamma 1e-2
mJ/mm^2, isotropic loading to rho 0.80 at 4000 increments, the isotropic unload, 16 reloads; the
loading and the unload are explicit in all three): the reloads by Newton (40 load steps each), and
by central differences at the default reload rate and at slower ones (``--reload-increments``).
The fans are kept in bench/measured/implicit_fan/<implicit | explicit | explicit_n<N>>/; a run
resumes a killed fan (finished reloads are kept), and the other fans start from the default
explicit fan's load and unload when that one has them (Newton's reloads from their static
equilibrium, the implicit settle). The table gives each direction's
yield point (E_d = E_0 (1 + 0.3 %)) of every fan and its distance to the reference fan's point
(the slowest explicit one), relative to that point's distance from the origin of the Rendulic
plane (sigma_m, sigma~_d); the largest over the directions is the fan's figure. A second table
gives Newton's work per reload (steps, iterations, cut-backs, wall time, contacts at the end) and
how far its last row lies from the slowest explicit reload at equal strain.
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
KEPT = ROOT / "measured" / "implicit_fan"
DEMO = ROOT.parent / "demos" / "yield_surface.py"


def folder(solver: str, reload_increments: int) -> Path:
    """A kept fan: the implicit one, the explicit one at the default reload rate, or an explicit
    one at ``reload_increments`` per reload."""
    if solver == "explicit" and reload_increments:
        return KEPT / f"explicit_n{reload_increments}"
    return KEPT / solver


def run(solver: str, reload_increments: int) -> None:
    """Run (or resume) one fan through the demo at its defaults."""
    out = folder(solver, reload_increments)
    if out != folder("explicit", 0):
        sys.path.insert(0, str(ROOT.parent))  # the repository: the validation package
        from validation.run import share_loading

        share_loading(folder("explicit", 0), out, print)
    cmd = [sys.executable, str(DEMO), "--solver", solver, "--out", str(out)]
    if reload_increments:
        cmd += ["--reload-increments", str(reload_increments)]
    if (out / "load").exists():
        cmd.append("--resume")
    subprocess.run(cmd, check=True)


def yield_points(out: Path) -> dict[float, np.ndarray]:
    """phi (rad) -> the yield point (sigma_m, sigma~_d) (MPa) of a fan: from its surfaces.csv
    when it is finished, else from its finished reloads (a ``done`` marker) as the demo's
    surfaces stage reads them (16 directions, the demo's yield threshold; NaN: a finished
    reload without a yield point)."""
    if (out / "surfaces.csv").exists():
        with open(out / "surfaces.csv") as f:
            rows = [r for r in csv.DictReader(f) if r["kind"] == "yield"]
        return {
            round(float(r["phi"]), 9): np.array([float(r["sigma_m"]), float(r["sigma_tilde_d"])])
            for r in rows
        }
    from mpfem_fenicsx.homogenization.surfaces import surface_points
    from mpfem_fenicsx.workflows.yield_surface import YieldSurfaceCase, fan_rows, read_unloaded

    case = YieldSurfaceCase()
    unloaded = read_unloaded(out)
    points = {}
    for k, phi in enumerate(case.phis):
        history = out / f"reload_{k:03d}" / "history.csv"
        if not (history.parent / "done").exists():
            continue
        fan = fan_rows(history, float(phi), unloaded.t_unloaded, 0)
        found = surface_points(fan, unloaded.E_0, case.dissipation_threshold, ())
        points[round(float(phi), 9)] = np.array(found.get("yield", (np.nan, np.nan)))
    return points


def table() -> None:
    """Every finished fan's yield points against the slowest explicit fan's."""
    fans = {
        p.name: p
        for p in sorted(KEPT.iterdir())
        if (p / "surfaces.csv").exists() or (p / "unloaded.json").exists()
    }
    explicit = [n for n in fans if n.startswith("explicit")]
    if not explicit:
        print("no finished explicit fan in", KEPT)
        return

    def increments(name: str) -> int:  # a fan's reload increments (the default's: 0)
        return int(name.removeprefix("explicit_n")) if "_n" in name else 0

    reference = max(explicit, key=increments)
    points = {n: yield_points(p) for n, p in fans.items()}
    ref = points[reference]
    others = [n for n in fans if n != reference]
    print(f"reference: {reference}")
    print("| phi (deg) | " + " | ".join(f"{n} (sigma_m, sigma~_d) / off" for n in fans) + " |")
    print("|---|" + "---|" * len(fans))
    worst = dict.fromkeys(others, 0.0)
    for phi in sorted(ref):
        cells = []
        for n in fans:
            p = points[n].get(phi)
            if p is None or not np.all(np.isfinite(p)):
                cells.append("not run" if p is None else "no yield")
                continue
            cell = f"({p[0]:.3f}, {p[1]:.3f})"
            if n != reference:
                off = np.linalg.norm(p - ref[phi]) / np.linalg.norm(ref[phi])
                worst[n] = max(worst[n], off)
                cell += f" / {off:.1%}"
            cells.append(cell)
        print(f"| {np.degrees(phi):.1f} | " + " | ".join(cells) + " |")
    for n in others:
        found = {k for k, p in points[n].items() if np.all(np.isfinite(p))}
        missing = sorted(set(ref) - found)
        print(
            f"{n}: {len(found)} yield points, largest distance to {reference}'s "
            f"{worst[n]:.1%}" + (f", {len(missing)} directions without yield" if missing else "")
        )


def reload_rows(history: Path, t_unloaded: float) -> dict[str, np.ndarray]:
    """The reload rows (from the end of the unload on) of a reload's history.csv, by column."""
    with open(history) as f:
        rows = [r for r in csv.DictReader(f) if float(r["time"]) > t_unloaded * (1 + 1e-9)]
    return {k: np.array([float(r[k] or "nan") for r in rows]) for k in (rows[0] if rows else {})}


def along_explicit(rows: dict[str, np.ndarray], ref: dict[str, np.ndarray]) -> float:
    """How far a Newton reload's last row (sigma_m, sigma~_d) within the explicit reload's
    strains lies from the explicit reload at equal strain, relative to the explicit point's
    distance from the origin of the Rendulic plane. Strain: the distance travelled from the
    explicit reload's first row in the plane (h_v, h~_d) (the reloads are straight there; the
    mixed control makes time no common axis), the explicit curve interpolated at it. NaN
    without a common strain."""

    def travelled(r: dict[str, np.ndarray]) -> np.ndarray:
        return np.hypot(r["h_v"] - ref["h_v"][0], r["h_tilde_d"] - ref["h_tilde_d"][0])

    x, along = travelled(ref), travelled(rows)
    inside = np.flatnonzero(along <= x.max())
    if not inside.size:
        return float("nan")
    last, at = inside[-1], along[inside[-1]]
    order = np.argsort(x)
    explicit = np.array(
        [np.interp(at, x[order], ref[c][order]) for c in ("sigma_m", "sigma_tilde_d")]
    )
    newton = np.array([rows[c][last] for c in ("sigma_m", "sigma_tilde_d")])
    return float(np.linalg.norm(newton - explicit) / np.linalg.norm(explicit))


def newton_effort() -> None:
    """Newton's work per reload of the implicit fan: converged steps, iterations per step,
    cut-backs, wall time (s, the histories' clock: pauses included), the contacts at the
    reload's end against the slowest explicit fan's, and the distance of its last row (within
    the explicit strains) from that fan's reload at equal strain (:func:`along_explicit`: a
    reload under way is checked before its yield point)."""
    from mpfem_fenicsx.workflows.yield_surface import YieldSurfaceCase, read_unloaded

    out = folder("implicit", 0)
    if not (out / "unloaded.json").exists():
        return
    explicit = sorted(
        KEPT.glob("explicit_n*"), key=lambda p: int(p.name.removeprefix("explicit_n"))
    )
    t_unloaded = read_unloaded(out).t_unloaded
    print(
        "\n| phi (deg) | state | steps | iterations per step (median / max) | cut-backs "
        "| wall (s) | contacts at the end (explicit) | last row off explicit at equal strain |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for k, phi in enumerate(YieldSurfaceCase().phis):
        history = out / f"reload_{k:03d}" / "history.csv"
        if not history.exists():
            continue
        rows = reload_rows(history, t_unloaded)
        if "newton_iterations" not in rows:
            continue
        its = rows["newton_iterations"]
        state = "done" if (history.parent / "done").exists() else "under way"
        contacts, off = f"{rows['n_contacts'][-1]:.0f}", "-"
        if explicit and (explicit[-1] / history.relative_to(out)).exists():
            ref = reload_rows(explicit[-1] / history.relative_to(out), t_unloaded)
            contacts += f" ({ref['n_contacts'][-1]:.0f})"
            off = f"{along_explicit(rows, ref):.1%}".replace("nan%", "-")
        print(
            f"| {np.degrees(phi):.1f} | {state} | {its.size} | {np.median(its):.0f} / "
            f"{its.max():.0f} | {rows['cutbacks'][-1]:.0f} | "
            f"{rows['wall_time'][-1] - rows['wall_time'][0]:.0f} | {contacts} | {off} |"
        )


def main(argv=None) -> None:
    """Run what ``--run`` asks, then print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", choices=("explicit", "implicit"), default=None)
    parser.add_argument(
        "--reload-increments",
        type=int,
        default=0,
        help="explicit: increments of a reload (0: the demo's default rate)",
    )
    args = parser.parse_args(argv)
    if args.run:
        run(args.run, args.reload_increments if args.run == "explicit" else 0)
    table()
    newton_effort()


if __name__ == "__main__":
    main()
