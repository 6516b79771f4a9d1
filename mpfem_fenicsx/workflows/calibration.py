"""From particles to a continuum model: calibrate two density-dependent continuum models, the
Drucker-Prager Cap and the critical-state (Cam-clay) ellipse, on computed fans and compaction
curves, export them for Abaqus, and replay the particle model's paths with them.

Stages (data flow: fans + compaction curves -> fit -> models -> fragments -> round trip):

1. **fit**: at each fan's relative density, each model's surface through its yield points
   (``surfaces.csv``, kind ``yield``; :func:`~mpfem_fenicsx.calibration.fit_cap`,
   :func:`~mpfem_fenicsx.calibration.fit_clay`) and the elastic moduli from its reloads' first
   rows (``fan.csv``; :func:`~mpfem_fenicsx.calibration.reload_moduli`);
2. **hardening**: the hydrostatic yield stress against the plastic volumetric strain from the
   isotropic compaction curve (``history.csv``: rho, sigma_m), its elastic part removed with
   the fans' bulk moduli;
3. **die-calibrated cap** (when a die history is given): the cap model ``cap_die`` whose cap
   and hardening follow the die path (:func:`die_calibrated_cap`), the way die tests calibrate
   powders' caps; its surfaces' misfit to the fans is reported;
4. **export**, per model (``cap``, ``clay``, ``cap_die``): ``<model>_model.json`` and
   ``<model>_model.csv`` (the parameters by density with each fit's misfit),
   ``<model>_model.inp`` (the Abaqus fragment, field variable 1 = relative density);
5. **round trip**: the material-point driver runs each model along the isotropic path (and the
   die path when a die history is given) to the particle runs' end density, and along the
   triaxial test when its history is given (consolidated to its confining pressure, then
   compressed axially with the lateral stresses held); ``round_trip.csv`` lists, at each
   reported density, sigma_m of the model and of the particles (and the die's radial / axial
   stress ratio), at each reported axial strain the triaxial test's axial stress;
   ``summary.csv`` gives each model's largest misfits (to the fans and along each path), and
   ``calibration.png`` shows the points with the fits.

Units mm, N, MPa; stresses compression > 0.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..calibration import (
    CalibratedDensity,
    ContinuumModel,
    cap_fragment,
    clay_fragment,
    deviatoric_misfit,
    die_cap,
    drive,
    elastic_constants,
    fit_cap,
    fit_clay,
    hardening_table,
    isotropic_hardening,
    paths_cap,
    reload_moduli,
)
from ..io.history import read_csv

#: the relative densities at which the round trip compares the models with the particles
REPORT_DENSITIES = (0.7, 0.75, 0.8, 0.85, 0.9, 0.95)
#: the models calibrated, by name
MODELS = ("cap", "clay")


@dataclass(frozen=True)
class Calibration:
    """What :func:`calibrate` found, by model name: the model, each density's fit figures and
    the round trip's rows."""

    models: dict[str, ContinuumModel]
    fits: dict[str, dict[float, dict[str, float]]]  # model -> density -> figures
    round_trip: list[dict]


def yield_points(fan_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    """(sigma_m, sigma~_d) of a fan's yield points (MPa)."""
    with open(fan_dir / "surfaces.csv") as f:
        rows = [r for r in csv.DictReader(f) if r["kind"] == "yield"]
    return (
        np.array([float(r["sigma_m"]) for r in rows]),
        np.array([float(r["sigma_tilde_d"]) for r in rows]),
    )


def fit_density(density: float, fan_dir: Path, alpha: float = 0.01):
    """{model: (calibrated density, fit figures)} of one fan."""
    points = yield_points(fan_dir)
    bulk, shear = reload_moduli(read_csv(fan_dir / "fan.csv"))
    young, poisson = elastic_constants(bulk, shear)
    out = {}
    for name, fit in (("cap", fit_cap(*points, alpha=alpha)), ("clay", fit_clay(*points))):
        figures = {
            "radial_rms": fit.radial_rms,
            "deviatoric_rms": fit.deviatoric_rms,
            "points": len(fit.radial_residuals),
            "bulk_MPa": bulk,
            "shear_MPa": shear,
        }
        out[name] = (CalibratedDensity(density, fit.surface, young, poisson), figures)
    return out


def build_model(rows: list[CalibratedDensity], isotropic: dict[str, np.ndarray]):
    """The model of the calibrated ``rows`` with the hardening of the isotropic curve
    ``isotropic`` (history columns rho, sigma_m); rho_0 is the curve's first density."""
    rho, p = isotropic["rho"], isotropic["sigma_m"]
    bulk = np.interp(
        rho,
        [r.density for r in rows],
        [r.young / (3.0 * (1.0 - 2.0 * r.poisson)) for r in rows],
    )
    hardening = hardening_table(*isotropic_hardening(rho[1:], p[1:], float(rho[0]), bulk[1:]))
    return ContinuumModel(tuple(rows), hardening, float(rho[0]))


def replay(model: ContinuumModel, history: dict[str, np.ndarray], path: str, increments=400):
    """The model along the particle run's ``path`` (isotropic or die along axis 3) to its end
    density; rows at :data:`REPORT_DENSITIES` inside the run's range."""
    strain_v = math.log(history["rho"][-1] / model.density_0)  # compaction > 0
    end = -strain_v * (np.full(3, 1.0 / 3.0) if path == "isotropic" else np.array([0, 0, 1.0]))
    rows, _ = drive(model, end, increments=increments)
    out = []
    for rho in REPORT_DENSITIES:
        if not history["rho"][0] < rho <= history["rho"][-1]:
            continue
        row = {"path": path, "density": rho}
        row["sigma_m_model"] = float(np.interp(rho, rows["density"], rows["sigma_m"]))
        row["sigma_m_particles"] = float(np.interp(rho, history["rho"], history["sigma_m"]))
        eps_v_pl = float(np.interp(rho, rows["density"], rows["eps_v_pl"]))
        row["beyond_hardening"] = bool(eps_v_pl > model.hardening[1][-1])
        if path == "die":
            ratio = rows["sigma_1"] / rows["sigma_3"]
            row["ratio_model"] = float(np.interp(rho, rows["density"], ratio))
            lateral = 0.5 * (history["sigma11"] + history["sigma22"])
            with np.errstate(invalid="ignore", divide="ignore"):
                ratio_p = lateral / history["sigma33"]
            row["ratio_particles"] = float(np.interp(rho, history["rho"], ratio_p))
        out.append(row)
    return out


#: the axial strains (compression > 0) at which the triaxial round trip compares the stresses
#: (and the run's last)
TRIAXIAL_STRAINS = (0.01, 0.02, 0.04, 0.06, 0.08, 0.10)


def axial_phase(history: dict[str, np.ndarray], axial_start: float) -> tuple[int, float]:
    """The row from which a triaxial run's axial compression is measured (its last row at
    time <= ``axial_start``, s: the end of the consolidation) and the confining pressure: the
    lateral stresses' median over the axial phase (MPa, compression > 0)."""
    rows = np.flatnonzero(history["time"] > axial_start * (1.0 + 1e-9))
    if len(rows) < 3 or rows[0] == 0:
        raise ValueError(
            f"triaxial: {len(rows)} rows after the axial start {axial_start:g} s of "
            f"{len(history['time'])}: need >= 3 and a consolidation before (not a triaxial "
            "run, or its axial phase unfinished)"
        )
    lateral = 0.5 * (history["sigma11"][rows] + history["sigma22"][rows])
    return int(rows[0] - 1), float(np.median(lateral))


def replay_triaxial(model, history: dict[str, np.ndarray], axial_start: float, increments=400):
    """The model along a triaxial test: consolidated isotropically to the particle run's
    confining pressure, then compressed axially to the run's end axial strain -ln(F33 /
    F33_start) with the lateral stresses held at that pressure. Rows at
    :data:`TRIAXIAL_STRAINS` within the run and at its end: the axial stress sigma_33 of the
    model and of the particles (MPa, compression > 0) and the densities."""
    start, confining = axial_phase(history, axial_start)
    axial = -np.log(history["F33"][start:] / history["F33"][start])  # compression > 0
    # consolidation: the isotropic strain at which the model's sigma_m reaches the pressure
    reach = math.log(max(history["rho"][-1], history["rho"][start]) / model.density_0) + 0.1
    probe, _ = drive(model, -reach * np.full(3, 1.0 / 3.0), increments=increments)
    if probe["sigma_m"][-1] < confining:
        raise ValueError(f"triaxial: the model does not reach the confining {confining:g} MPa")
    density = float(np.interp(confining, probe["sigma_m"], probe["density"]))
    strain_v = math.log(density / model.density_0)
    _, state = drive(model, -strain_v * np.full(3, 1.0 / 3.0), increments=increments)
    end = state.strain + np.array([0.0, 0.0, -float(axial[-1])])
    rows, _ = drive(model, end, (confining, confining, None), increments, state)
    model_axial = float(axial[-1]) * np.arange(1, increments + 1) / increments
    out = []
    for e in [e for e in TRIAXIAL_STRAINS if e < axial[-1] * (1.0 - 1e-6)] + [float(axial[-1])]:
        out.append(
            {
                "path": "triaxial",
                "density": float(np.interp(e, axial, history["rho"][start:])),
                "axial_strain": e,
                "confining": confining,
                "sigma_axial_model": float(np.interp(e, model_axial, rows["sigma_3"])),
                "sigma_axial_particles": float(np.interp(e, axial, history["sigma33"][start:])),
                "density_model": float(np.interp(e, model_axial, rows["density"])),
                "beyond_hardening": bool(
                    np.interp(e, model_axial, rows["eps_v_pl"]) > model.hardening[1][-1]
                ),
            }
        )
    return out


def die_calibrated_cap(fitted: ContinuumModel, die: dict[str, np.ndarray], fans: dict[float, Path]):
    """The cap model whose cap follows the die path (:func:`~mpfem_fenicsx.calibration.die_cap`
    at every 0.01 of relative density where the die's sigma_m exceeds 5 % of its end value):
    the shear line, K and the moduli of the cap model ``fitted`` to the fans (interpolated in
    the density, held beyond them), R and p_b from the die's stress, the hardening p_b against
    the die's plastic volumetric strain ln(rho / rho_0) - sigma_m / bulk. Returns the model
    and, by density, the die stress and, at the fans' densities, the surface's misfit to the
    fan."""

    def cap_at(rho, shear, sigma_m, s_d):
        return die_cap(shear, sigma_m, s_d), {}, sigma_m

    return _cap_along_die(fitted, die, fans, cap_at)


def paths_calibrated_cap(
    fitted: ContinuumModel,
    die: dict[str, np.ndarray],
    fans: dict[float, Path],
    isotropic: dict[str, np.ndarray],
):
    """The cap model calibrated on both compaction curves
    (:func:`~mpfem_fenicsx.calibration.paths_cap` at the densities of
    :func:`die_calibrated_cap` inside the isotropic curve's range): the shear line, K and the
    moduli of ``fitted``; R and p_b sharing the misfit equally among the isotropic curve's
    sigma_m and the die's sigma_m and radial / axial ratio; the hardening p_b against the
    plastic volumetric strain ln(rho / rho_0) - p_b / bulk of the isotropic path. Returns the
    model and, by density, the die stress, the three errors and, at the fans' densities, the
    surface's misfit to the fan."""
    inside = die["rho"] <= isotropic["rho"][-1]
    die = {k: v[inside] for k, v in die.items()}

    def cap_at(rho, shear, sigma_m, s_d):
        p_iso = float(np.interp(rho, isotropic["rho"], isotropic["sigma_m"]))
        surface, errors = paths_cap(shear, p_iso, sigma_m, s_d)
        return surface, {f"error_{k}": v for k, v in errors.items()}, surface.p_b

    model, figures = _cap_along_die(fitted, die, fans, cap_at)
    # beyond the die curve's end, the hardening follows the isotropic curve at the last
    # density's ratio p_b / sigma_m (its shape held)
    last = model.rows[-1]
    scale = 1.0 + figures[last.density]["error_isotropic"]
    beyond = np.arange(last.density + 0.01, isotropic["rho"][-1] + 1e-9, 0.01)
    p_b = scale * np.interp(beyond, isotropic["rho"], isotropic["sigma_m"])
    bulk = np.array([fitted.elastic(float(rho))[0] for rho in beyond])
    eps = np.log(beyond / model.density_0) - p_b / bulk
    extended = zip(model.hardening, (p_b, eps), strict=True)
    hardening = tuple(np.concatenate([h, x]) for h, x in extended)
    return ContinuumModel(model.rows, hardening, model.density_0), figures


def _cap_along_die(fitted, die, fans, cap_at):
    """The cap model of ``cap_at(rho, shear, die sigma_m, die sigma~_d)`` -> (surface, figures,
    the mean stress whose elastic part leaves the plastic volumetric strain) at every 0.01 of
    the die's density where its sigma_m exceeds 5 % of its end value, and at the fans'."""
    rho0 = float(die["rho"][0])
    start = die["rho"][np.argmax(die["sigma_m"] > 0.05 * die["sigma_m"][-1])]
    # a 0.01 grid rounded to its decimals, so that a fan's density is not repeated beside it
    densities = np.round(np.arange(math.ceil(start * 100) / 100, die["rho"][-1], 0.01), 6)
    densities = np.union1d(densities, [r.density for r in fitted.rows])
    densities = densities[(densities >= start) & (densities <= die["rho"][-1])]
    rows, figures, p_b, eps = [], {}, [], []
    for rho in densities:
        sigma_m = float(np.interp(rho, die["rho"], die["sigma_m"]))
        s_d = float(np.interp(rho, die["rho"], die["sigma_tilde_d"]))
        # the fitted shear line at this density (its cap is replaced)
        surface, more, p_elastic = cap_at(float(rho), fitted.surface(float(rho), 0.0), sigma_m, s_d)
        bulk, shear = fitted.elastic(float(rho))
        rows.append(CalibratedDensity(float(rho), surface, *elastic_constants(bulk, shear)))
        p_b.append(surface.p_b)
        eps.append(math.log(rho / rho0) - p_elastic / bulk)
        figures[float(rho)] = {"die_sigma_m": sigma_m, "die_sigma_tilde_d": s_d, **more}
        if float(rho) in fans:
            figures[float(rho)]["fan_deviatoric_rms"] = deviatoric_misfit(
                surface, *yield_points(Path(fans[float(rho)]))
            )
    model = ContinuumModel(tuple(rows), hardening_table(np.array(p_b), np.array(eps)), rho0)
    return model, figures


def calibrate(
    fans: dict[float, Path],
    isotropic: Path,
    out: Path,
    die: Path | None = None,
    alpha: float = 0.01,
    log=print,
    triaxial: Path | None = None,
    axial_start: float | None = None,
) -> Calibration:
    """Fit, export and replay both models (see the module). ``fans``: relative density -> fan
    directory (``surfaces.csv``, ``fan.csv``); ``isotropic`` / ``die`` / ``triaxial``: the
    particle runs' history.csv; ``axial_start``: the time (s) at which the triaxial run's axial
    compression starts (default: after the ramp and hold of ``StressPath``'s defaults)."""
    if triaxial is not None and axial_start is None:
        axial_start = default_axial_start()
    if len(fans) < 1:
        raise ValueError("fans: need >= 1 fan (density -> directory)")
    out.mkdir(parents=True, exist_ok=True)
    rows = {name: [] for name in MODELS}
    fits = {name: {} for name in MODELS}
    for density, fan_dir in sorted(fans.items()):
        for name, (row, figures) in fit_density(density, Path(fan_dir), alpha).items():
            rows[name].append(row)
            fits[name][density] = figures
            log(f"[fit] {name} rho {density:.3f}: {_describe(row, figures)}")
    curves = {"isotropic": read_csv(isotropic)}
    if die is not None:
        curves["die"] = read_csv(die)
    models = {name: build_model(rows[name], curves["isotropic"]) for name in MODELS}
    if die is not None:
        models["cap_die"], fits["cap_die"] = die_calibrated_cap(models["cap"], curves["die"], fans)
        models["cap_paths"], fits["cap_paths"] = paths_calibrated_cap(
            models["cap"], curves["die"], fans, curves["isotropic"]
        )
        for name, what in (("cap_die", "through the die path"), ("cap_paths", "of both paths")):
            for density, figures in sorted(fits[name].items()):
                if "fan_deviatoric_rms" in figures:
                    log(
                        f"[fit] {name} rho {density:.3f}: the cap {what} misses the fan by "
                        f"{100 * figures['fan_deviatoric_rms']:.1f} % (deviatoric)"
                    )
    trip = []
    for name, model in models.items():
        write_model(name, model, fits[name], out)
        for path, history in curves.items():
            trip += [{"model": name, **r} for r in replay(model, history, path)]
        if triaxial is not None:
            rows = replay_triaxial(model, read_csv(triaxial), axial_start)
            trip += [{"model": name, **r} for r in rows]
    write_round_trip(trip, out / "round_trip.csv", log)
    write_summary(fits, trip, out / "summary.csv", log)
    plot_fits(models, fans, out / "calibration.png")
    return Calibration(models, fits, trip)


def model_summary(fits: dict, trip: list[dict]) -> list[dict]:
    """Per model, the figures a user chooses by: the largest deviatoric misfit to the fans,
    and the largest round-trip error (model / particles - 1, signed) of each compared quantity
    within the calibrated hardening, with the density or axial strain where it occurs."""
    quantities = {
        "isotropic_sigma_m": ("isotropic", "sigma_m_model", "sigma_m_particles", "density"),
        "die_sigma_m": ("die", "sigma_m_model", "sigma_m_particles", "density"),
        "die_ratio": ("die", "ratio_model", "ratio_particles", "density"),
        "triaxial_sigma_33": (
            "triaxial",
            "sigma_axial_model",
            "sigma_axial_particles",
            "axial_strain",
        ),
    }
    out = []
    for name, by_density in fits.items():
        misfits = [
            f.get("fan_deviatoric_rms", f.get("deviatoric_rms")) for f in by_density.values()
        ]
        row = {
            "model": name,
            "fan_misfit": max((m for m in misfits if m is not None), default=None),
        }
        for key, (path, model, particles, where) in quantities.items():
            rows = [
                r
                for r in trip
                if r["model"] == name and r["path"] == path and not r["beyond_hardening"]
            ]
            if rows:
                worst = max(rows, key=lambda r: abs(r[model] / r[particles] - 1.0))
                row[key] = worst[model] / worst[particles] - 1.0
                row[f"{key}_at"] = worst[where]
        out.append(row)
    return out


def write_summary(fits: dict, trip: list[dict], path: Path, log=print) -> None:
    """summary.csv (:func:`model_summary`) and one log line per model."""
    rows = model_summary(fits, trip)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)
    for r in rows:
        parts = [] if r["fan_misfit"] is None else [f"fans {100 * r['fan_misfit']:.1f} %"]
        for key in ("isotropic_sigma_m", "die_sigma_m", "die_ratio", "triaxial_sigma_33"):
            if key in r:
                at = "strain" if key.startswith("triaxial") else "rho"
                parts.append(f"{key} {100 * r[key]:+.1f} % ({at} {r[key + '_at']:.2f})")
        log(f"[summary] {r['model']}, the largest misfits: " + "; ".join(parts))


def default_axial_start() -> float:
    """The time (s) at which a triaxial ``StressPath`` with its default ramp and hold starts its
    axial compression, for the default loading duration."""
    from ..case import LoadingSection
    from ..loading.stress_paths import StressPath
    from ..parameters import parameter_default

    duration = parameter_default(LoadingSection, "duration")
    ramp, hold = (parameter_default(StressPath, name) for name in ("ramp", "hold"))
    return (ramp + hold) * duration


def _describe(row: CalibratedDensity, figures: dict) -> str:
    shape = ", ".join(f"{k} {v:.4g}" for k, v in asdict(row.surface).items())
    return (
        f"{shape}; E {row.young:.0f} MPa, nu {row.poisson:.3f}; misfit radial "
        f"{100 * figures['radial_rms']:.1f} %, deviatoric {100 * figures['deviatoric_rms']:.1f} %"
        f" ({figures['points']} points)"
    )


def write_model(name: str, model: ContinuumModel, fits: dict, out: Path) -> None:
    """<name>_model.json, <name>_model.csv and the Abaqus fragment <name>_model.inp."""
    records = [
        {
            "density": row.density,
            **asdict(row.surface),
            "young_MPa": row.young,
            "poisson": row.poisson,
            **{f"fit_{k}": v for k, v in fits[row.density].items()},
        }
        for row in model.rows
    ]
    p_b, eps = model.hardening
    hardening = {"p_high_MPa": p_b.tolist(), "eps_v_pl": eps.tolist()}
    (out / f"{name}_model.json").write_text(
        json.dumps(
            {"model": name, "density_0": model.density_0, "densities": records, **hardening},
            indent=1,
        )
    )
    with open(out / f"{name}_model.csv", "w", newline="") as f:
        keys = list(dict.fromkeys(k for r in records for k in r))
        writer = csv.DictWriter(f, fieldnames=keys)
        writer.writeheader()
        writer.writerows(records)
    rows = list(model.rows)
    fragment = (
        clay_fragment(rows, model.hardening, model.density_0)
        if name == "clay"
        else cap_fragment(rows, model.hardening)
    )
    (out / f"{name}_model.inp").write_text(fragment)


def write_round_trip(trip: list[dict], path: Path, log=print) -> None:
    """round_trip.csv and one log line per row."""
    keys = ["model", "path", "density", "sigma_m_model", "sigma_m_particles"]
    keys += ["ratio_model", "ratio_particles", "axial_strain", "confining"]
    keys += ["sigma_axial_model", "sigma_axial_particles", "density_model", "beyond_hardening"]
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=keys)
        writer.writeheader()
        writer.writerows(trip)
    for r in trip:
        if r["path"] == "triaxial":
            log(
                f"[round trip] {r['model']} triaxial ({r['confining']:.2f} MPa) axial strain "
                f"{r['axial_strain']:.2f}: sigma_33 model {r['sigma_axial_model']:.3f} / "
                f"particles {r['sigma_axial_particles']:.3f} MPa "
                f"({100 * (r['sigma_axial_model'] / r['sigma_axial_particles'] - 1):+.1f} %)"
                + (" (beyond the calibrated hardening: p_b held)" if r["beyond_hardening"] else "")
            )
            continue
        line = (
            f"[round trip] {r['model']} {r['path']} rho {r['density']:.2f}: sigma_m model "
            f"{r['sigma_m_model']:.3f} / particles {r['sigma_m_particles']:.3f} MPa "
            f"({100 * (r['sigma_m_model'] / r['sigma_m_particles'] - 1):+.1f} %)"
        )
        if "ratio_model" in r:
            line += (
                f"; radial / axial {r['ratio_model']:.3f} / {r['ratio_particles']:.3f} "
                f"({100 * (r['ratio_model'] / r['ratio_particles'] - 1):+.1f} %)"
            )
        if r["beyond_hardening"]:
            line += " (beyond the calibrated hardening: p_b held)"
        log(line)


def plot_fits(models: dict[str, ContinuumModel], fans: dict[float, Path], path: Path) -> None:
    """The fans' yield points and the fitted surfaces in the Rendulic plane (cap: solid,
    ellipse: dashed, the cap of both compaction curves when calibrated: dotted)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 5))
    densities = sorted(fans)
    colors = dict(zip(densities, plt.cm.viridis(np.linspace(0, 0.85, len(densities))), strict=True))
    for density in densities:
        m, s = yield_points(Path(fans[density]))
        ax.plot(m, s, "o", color=colors[density], label=f"particles, rho {density:.2f}")
    for name, style in (("cap", "-"), ("clay", "--"), ("cap_paths", ":")):
        rows = models[name].rows if name in models else ()
        for row in (r for r in rows if r.density in colors):
            bm, bs = row.surface.boundary()
            label = f"{name}, rho {row.density:.2f}"
            ax.plot(bm, bs, style, color=colors[row.density], lw=1, label=label)
    ax.axhline(0, color="0.7", lw=0.5)
    ax.set_xlabel("sigma_m (MPa)")
    ax.set_ylabel("sigma~_d (MPa)")
    ax.set_aspect("equal")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
