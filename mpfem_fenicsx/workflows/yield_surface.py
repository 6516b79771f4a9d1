"""Yield, damage and rupture surfaces of a compacted granular volume (thesis chapter 4).

Stages (data flow: compaction -> unload -> checkpoint -> fan of reloads -> surfaces):
1. **load**: the compaction of ``base`` (isotropic or die) to its target density, ending with
   a checkpoint (``out/load``);
2. **unload**: isotropic expansion F^d = exp(h_v^d / 3) I (eq. 4.7) from that checkpoint. The
   thesis found the amplitude by trial (zeta = 0.01); here a probe unload (``out/unload_probe``)
   records sigma_m against the imposed volumetric strain and h_v^d is interpolated where the
   mean stress has dropped to ``unload_stress_ratio`` of its loaded value; the real unload
   (``out/unload``) applies that h_v^d and ends at rest, with a checkpoint. Decelerating to rest,
   it keeps more stress than the probe read at the same strain (validation fans: 5.5-10.8 % of
   the loaded sigma_m for a 5 % target). E_0 = E_d at its end;
3. **reloads**: ``nphi`` directions phi_k = 2 pi k / nphi, F^r = diag(exp h^r) with
   h_v = A cos phi, h~_d = A sin phi (compression > 0), A = ``amplitude_factor`` h_v^d
   (eq. 4.8-4.9), each restarted from the unload checkpoint **with the contact history kept**
   (alpha, sigma_max, stick anchors, W_f: unlike Abaqus in the thesis, no spurious dissipation
   at the restart), each following ``reload_profile`` in time (the thesis' smooth step, or a
   constant strain rate between smooth ramps). Reloads are independent: under ``mpirun -n P``
   each rank takes the next unclaimed direction whenever it is free (:func:`claimed_reloads`) and
   runs it on its own communicator (the load and unload run on rank 0 alone, since a checkpoint
   restarts on the number of ranks that wrote it);
4. **surfaces** (rank 0): yield where E_d first reaches E_0 (1 + ``dissipation_threshold``)
   (iso-dissipation, §4.2.2); iso-Gamma points where the specific contact surface crosses each
   threshold for the last time (§4.3, "le seuil le plus tardif"); Hill's rupture where the
   second-order work W2 = dsigma : dh first becomes <= 0 (eq. 4.15); all interpolated linearly
   in (sigma_m, sigma~_d) between history rows. Uniaxial compressive yield / tensile rupture
   stresses are the intersections with sigma~_d = 3 sigma_m. The limit specific contact surface
   Gamma_l (table 4.2) is the level below which the iso-Gamma curves superpose.

Reload solver (``solver``): explicit (cheap; W2 from Savitzky-Golay derivatives, as the thesis
filtered its explicit W2), or implicit: the explicit unload state is continued with Newton at a
fixed gradient (stage "settle": the dynamic relaxation's residual removed, E_0 read there) and
every reload is a sequence of ``reload_steps`` static equilibria, whose raw W2 needs no filter.

Outputs in ``out_dir``: ``fan.csv`` (one row per reload output: phi, sigma_m, sigma_tilde_d,
h_v, h_tilde_d, E_d, Gamma, W2), ``surfaces.csv`` (kind, phi, sigma_m, sigma_tilde_d; kind in
yield | gamma_<value> | w2; the limit iso-Gamma curve Gamma_l among the gamma kinds),
``uniaxial.csv`` (kind, compressive_MPa, tensile_MPa), ``summary.json`` (E_0, Gamma_l, points
per surface, raw W2 sign changes per reload, the reloads' discretization), ``yield_surface.png`` and
the stage directories with their histories and checkpoints. Units mm, N, MPa, mJ; reported stresses
compression > 0, strains natural sign (h_v < 0 in compaction).
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numba
import numpy as np
from mpi4py import MPI

from ..boundary import boundary_kind
from ..homogenization import (
    first_crossing,
    hencky_strain,
    row_increments,
    second_order_work,
    uniaxial_strengths,
)
from ..homogenization.surfaces import (
    MIN_GAMMA_COLLAPSE,
    default_gamma_levels,
    iso_gamma_point,
    limit_specific_surface,
    surface_points,
    w2_sign_changes,
)
from ..io.checkpoint import CheckpointError, resolve_checkpoint
from ..io.history import read_csv, tensor_from_columns
from ..io.plots import plot_yield_surface
from ..loading import PROFILES, reload_gradient, unload_gradient
from ..meshes.packing import Packing, read_packing
from ..parameters import check_parameters, parameter
from ..runtime import configure_runtime
from ..solvers import SOLVERS, solver_kind
from .compaction import CompactionCase, CompactionModel, build_compaction, run_compaction

#: fan.csv columns (one row per reload output)
FAN_COLUMNS = ("phi", "sigma_m", "sigma_tilde_d", "h_v", "h_tilde_d", "E_d", "Gamma", "W2")

_FINAL_ONLY = 10**9  # checkpoint_every that writes the final checkpoint only


@dataclass
class YieldSurfaceCase:
    """A chapter-4 fan. ``base``: the loading stage (loading path, target density rho_f, gamma,
    packing, increments, ...); its ``out_dir`` is ignored (stages go under ``out_dir``)."""

    base: CompactionCase = field(default_factory=CompactionCase)
    nphi: int = parameter(16, "reload directions in [0, 2 pi)", low=3, high=720)
    unload_stress_ratio: float = parameter(
        0.05,
        "the unload's expansion is read on a probe where sigma_m is this "
        "fraction of its value at the end of the loading (-)",
        low=0,
        high=1,
        open_high=True,
    )
    amplitude_factor: float = parameter(
        1.5,
        "reload amplitude A / |h_v^d| of the unload (thesis: 1.5) (-)",
        low=0,
        high=20,
        open_low=True,
    )
    dissipation_threshold: float = parameter(
        3e-3,
        "yield: E_d >= E_0 (1 + this) (thesis §4.2.2: 0.3 %) (-)",
        low=0,
        high=1,
        open_low=True,
        open_high=True,
    )
    #: iso-Gamma levels (1/mm); empty: 0.25, 0.5, 0.75 and 1.0 x Gamma at the end of the unload
    gamma_thresholds: tuple = ()
    #: an elastic unload / reload is quasi-static only if it lasts many elastic wave transits of
    #: the cell: ~10-20 increments per particle diameter
    reload_increments: int = parameter(
        0,
        "explicit increments of a reload (0: the compaction's strain rate slowed "
        "by `slowdown`, at least `min_increments`)",
        low=0,
    )
    slowdown: float = parameter(
        4.0,
        "reloads slower than the compaction by this factor (-)",
        low=0,
        high=1000,
        open_low=True,
    )
    min_increments: int = parameter(400, "fewest explicit increments of a reload", low=10)
    #: the thesis' reloads follow Abaqus' smooth step (rate 1.875 x the mean at mid-path, zero at
    #: the end: points read late in a reload are read while it decelerates); "smooth-ramps" holds a
    #: constant rate (1.25 x the mean) from 10 % to 70 % of the reload's time
    reload_profile: str = parameter(
        "smooth-step",
        "amplitude of every reload in time (loading.amplitude.PROFILES)",
        choices=tuple(PROFILES),
    )
    rows_per_reload: int = parameter(40, "history rows over a reload", low=4, high=10000)
    #: implicit reloads always use raw differences (no dynamic oscillation to filter)
    w2_window: int = parameter(
        7,
        "explicit reloads: rows of the Savitzky-Golay derivatives of W2 (0: raw differences)",
        low=0,
        high=1001,
    )
    #: The loading and the unload always run explicit; an implicit fan first relaxes the unloaded
    #: state to static equilibrium (stage "settle", out/settle) and restarts from it
    solver: str = parameter(
        "explicit",
        "solver of the reloads: explicit, or implicit (Newton, quasi-static: W2 needs no filter)",
        choices=SOLVERS,
    )
    reload_steps: int = parameter(
        40, "implicit: load steps of a reload (each one a history row)", low=4, high=10000
    )
    #: a Newton reload is rate-free: going on along its direction is the same path as a larger
    #: amplitude, so a direction whose yield lies just beyond the fan's amplitude still closes
    #: the surface (the explicit reloads' amplitude is part of their loading rate: not extended)
    reload_extension: float = parameter(
        0.25,
        "implicit: a reload that ends below the yield threshold goes on along its direction by "
        "up to this fraction of its amplitude, once, until it yields (0: never) (-)",
        low=0,
        high=4,
    )
    out_dir: str = "results/yield_surface"

    def __post_init__(self):
        check_parameters(self)
        if solver_kind(self.base.solver.kind).static:
            raise ValueError(
                f"base.solver: the loading and unload of a fan run with the explicit solver "
                f"(implicit granular compaction is experimental), got {self.base.solver.kind!r}; "
                f"choose the reloads' solver with YieldSurfaceCase.solver"
            )
        if not boundary_kind(self.base.boundary.condition).periodic:
            raise ValueError(
                f"bc must be CLP or CLPS for a yield surface (periodic volume whose macroscopic "
                f"gradient is imposed), got {self.base.boundary.condition!r}"
            )
        if any(not g > 0 for g in self.gamma_thresholds):
            raise ValueError(f"gamma_thresholds must be > 0 (1/mm), got {self.gamma_thresholds}")

    @property
    def phis(self) -> np.ndarray:
        """The reload directions phi_k = 2 pi k / nphi (rad)."""
        return 2.0 * np.pi * np.arange(self.nphi) / self.nphi


@dataclass
class Unloaded:
    """State after stages 1-2 (what every reload needs)."""

    checkpoint: str  # checkpoint the reloads restart from (end of the unload, or of the settle)
    # ((duration s, increment gradient), ...) after the loading: the unload [, hold]
    segments: tuple
    h_v_unload: float  # imposed volumetric strain of the unload (> 0: expansion)
    E_0: float  # dissipated energy at the end of the unload (mJ)
    sigma_m_loaded: float  # MPa
    sigma_m_unloaded: float  # MPa
    Gamma_unloaded: float  # 1/mm
    t_unloaded: float  # s
    increments: int  # explicit increments of the unload
    increments_per_strain: float  # the compaction's increments per unit |h_v|, x slowdown
    dt: float  # the compaction's increment (s)
    packing: Packing  # the loaded volume's packing (every reload rebuilds the same model)
    # the checkpoint is the implicit settle's static equilibrium (implicit fans)
    settled: bool = False


def _newest_checkpoint(directory: Path) -> str | None:
    """The newest complete checkpoint of a stage directory, or None."""
    try:
        return str(resolve_checkpoint(directory))
    except CheckpointError:
        return None


def _imposed_expansion(h: dict, rho_imposed_ref: float) -> np.ndarray:
    """Imposed volumetric strain since the reference row, > 0 in expansion: ln(rho_ref / rho)."""
    return np.log(rho_imposed_ref / h["rho_imposed"])


def read_unloaded(out_dir: str | Path, with_packing: bool = False) -> Unloaded:
    """The unloaded state a finished stage 2 left in ``out_dir/unloaded.json`` (``with_packing``:
    and the loaded volume's packing, ``load/packing.txt``, which the reloads rebuild). A fan
    moved to another folder or machine finds its checkpoint in ``out_dir`` again
    (``<stage>/checkpoints/<step>``)."""
    out = Path(out_dir)
    state = json.loads((out / "unloaded.json").read_text())
    checkpoint = Path(state["checkpoint"])
    if not checkpoint.exists() and out.joinpath(*checkpoint.parts[-3:]).exists():
        state["checkpoint"] = str(out.joinpath(*checkpoint.parts[-3:]))
    packing = read_packing(out / "load" / "packing.txt", validate=False) if with_packing else None
    return Unloaded(
        **{
            **state,
            "segments": tuple((d, np.array(G)) for d, G in state["segments"]),
            "packing": packing,
        }
    )


def load_and_unload(
    case: YieldSurfaceCase, comm: MPI.Comm, log=print, resume: bool = False
) -> tuple[Unloaded, CompactionModel]:
    """Stages 1-2 on ``comm``; returns the unload checkpoint and E_0, and the model (reused by
    the probe, the unload and the reloads of this rank). ``resume``: the loading continues from
    its newest checkpoint in ``out/load`` if a killed run left one (it writes one every
    ``base.output.checkpoint_every`` outputs, keeping the newest)."""
    base, out = case.base, Path(case.out_dir)
    dt = base.loading.duration / base.solver.increments
    quiet = _quiet(log)
    restart = _newest_checkpoint(out / "load") if resume else None
    log(
        f"[load] {base.loading.path} compaction to rho = {base.loading.target_density} "
        f"({base.solver.increments} "
        "increments)" + (f", continued from {restart}" if restart else "")
    )
    loaded = run_compaction(
        base.updated(
            directory=str(out / "load"),
            checkpoint_every=base.output.checkpoint_every or _FINAL_ONLY,
            checkpoint_keep=1,
        ),
        comm,
        log,
        restart=restart,
    )
    h = loaded.history
    model = loaded.model
    base = base.updated(spheres=loaded.packing)
    sigma_m_c = float(h.column("sigma_m")[-1])
    rho_imp_c = float(h.column("rho_imposed")[-1])
    h_v_c = abs(float(h.column("h_v")[-1]))
    t_c = float(h.column("time")[-1])
    load_checkpoint_dir = str(resolve_checkpoint(out / "load"))
    log(
        f"[load] rho = {h.column('rho')[-1]:.4f}, sigma_m = {sigma_m_c:.4g} MPa, h_v = "
        f"{-h_v_c:.4g}; "
        f"{loaded.wall_time:.0f} s"
    )

    def increments_for(strain: float) -> int:  # the compaction's strain rate / slowdown
        return max(
            case.min_increments,
            int(math.ceil(case.slowdown * base.solver.increments * strain / h_v_c)),
        )

    # probe: how much expansion brings sigma_m to the target (linear elastic guess x 30: the
    # porous compact is much softer than its solid)
    K_solid = base.material.E / (3.0 * (1.0 - 2.0 * base.material.nu))
    target = case.unload_stress_ratio * sigma_m_c
    guess = 30.0 * max(sigma_m_c, 1e-3 * base.material.sigma_0) / K_solid
    h_d = np.nan
    for _ in range(3):
        n_p = increments_for(guess)
        probe = run_compaction(
            base.updated(
                directory=str(out / "unload_probe"),
                checkpoint_every=0,
                visual=False,
                segments_after=((n_p * dt, unload_gradient(guess)),),
                every=max(1, n_p // 50),
            ),
            comm,
            quiet,
            restart=load_checkpoint_dir,
            model=model,
        )
        hp = {c: probe.history.column(c) for c in ("time", "sigma_m", "rho_imposed")}
        after = hp["time"] >= t_c * (1 - 1e-12)
        h_d = first_crossing(
            hp["sigma_m"][after],
            target,
            _imposed_expansion({k: v[after] for k, v in hp.items()}, rho_imp_c),
            rising=False,
        )[1]
        log(
            f"[unload probe] expansion {guess:.3g}: sigma_m {hp['sigma_m'][after][0]:.4g} -> "
            f"{hp['sigma_m'][-1]:.4g} MPa ({n_p} increments)"
        )
        if np.isfinite(h_d):
            break
        # not far enough: extrapolate the probe's secant, with margin
        drop = max(float(hp["sigma_m"][after][0] - hp["sigma_m"][-1]), 1e-9 * abs(sigma_m_c))
        guess = float(
            np.clip(
                1.5 * guess * (hp["sigma_m"][after][0] - target) / drop, 2.0 * guess, 50.0 * guess
            )
        )
    if not np.isfinite(h_d):
        raise RuntimeError(
            f"unload: sigma_m did not drop to {target:.3g} MPa within an isotropic expansion of "
            f"{guess:.3g}; raise unload_stress_ratio or check the loading stage"
        )
    n_d = increments_for(float(h_d))
    segments = ((n_d * dt, unload_gradient(float(h_d))),)
    unload = run_compaction(
        base.updated(
            directory=str(out / "unload"),
            checkpoint_every=_FINAL_ONLY,
            checkpoint_keep=1,
            visual=False,
            segments_after=segments,
            every=max(1, n_d // 20),
        ),
        comm,
        quiet,
        restart=load_checkpoint_dir,
        model=model,
    )
    hu = unload.history
    E_0 = float(hu.column("E_d")[-1])
    log(
        f"[unload] isotropic expansion h_v^d = {h_d:.4g} ({n_d} increments): sigma_m = "
        f"{hu.column('sigma_m')[-1]:.4g} MPa (target {target:.3g}), E_0 = {E_0:.5g} mJ, "
        f"Gamma = {hu.column('Gamma')[-1]:.4g} 1/mm"
    )
    unloaded = Unloaded(
        checkpoint=str(resolve_checkpoint(out / "unload")),
        segments=segments,
        h_v_unload=float(h_d),
        E_0=E_0,
        sigma_m_loaded=sigma_m_c,
        sigma_m_unloaded=float(hu.column("sigma_m")[-1]),
        Gamma_unloaded=float(hu.column("Gamma")[-1]),
        t_unloaded=float(hu.column("time")[-1]),
        increments=n_d,
        increments_per_strain=case.slowdown * base.solver.increments / h_v_c,
        dt=dt,
        packing=loaded.packing,
    )
    if solver_kind(case.solver).static:  # reloads from a static equilibrium
        unloaded, model = settle(case, unloaded, comm, log)
    write_unloaded(out, unloaded)
    return unloaded, model


def write_unloaded(out_dir: str | Path, unloaded: Unloaded) -> None:
    """``out_dir/unloaded.json``, which ``read_unloaded`` reads back (the packing stays in
    load/)."""
    state = {k: v for k, v in vars(unloaded).items() if k not in ("packing", "segments")}
    state["segments"] = [[d, G.tolist()] for d, G in unloaded.segments]
    (Path(out_dir) / "unloaded.json").write_text(json.dumps(state, indent=1))


def _reload_amplitude(case: YieldSurfaceCase, unloaded: Unloaded) -> float:
    """Amplitude A of every reload (eq. 4.8: a multiple of the unload's |h_v^d|, -)."""
    return case.amplitude_factor * unloaded.h_v_unload


def _reload_duration(case: YieldSurfaceCase, unloaded: Unloaded) -> tuple[float, int]:
    """Duration (s) and explicit increments of every reload (the same for all directions)."""
    A = _reload_amplitude(case, unloaded)
    n_r = case.reload_increments or max(
        case.min_increments, int(math.ceil(unloaded.increments_per_strain * A))
    )
    return n_r * unloaded.dt, n_r


def reload_discretization(case: YieldSurfaceCase, unloaded: Unloaded) -> dict:
    """How every reload is discretized: amplitude A (the Hencky strain of eq. 4.8, -), duration
    (s), increments (explicit) or load steps (implicit), the mean strain rate A / duration (1/s)
    and the amplitude's profile in time."""
    duration, n_r = _reload_duration(case, unloaded)
    A = _reload_amplitude(case, unloaded)
    steps = case.reload_steps if solver_kind(case.solver).static else n_r
    return {
        "amplitude": A,
        "duration_s": duration,
        "steps": steps,
        "strain_rate_per_s": A / duration,
        "profile": case.reload_profile,
    }


def settle(
    case: YieldSurfaceCase, unloaded: Unloaded, comm: MPI.Comm, log=print
) -> tuple[Unloaded, CompactionModel]:
    """Implicit fans: continue the explicit unload checkpoint with the implicit solver at a fixed
    macroscopic gradient (a hold segment, two Newton steps) so that every reload starts from a
    static equilibrium; E_0, sigma_m and Gamma of the unloaded state are read at its end. Returns
    the updated state (checkpoint out/settle) and the implicit model the reloads reuse."""
    out = Path(case.out_dir)
    hold = (2.0 * _reload_duration(case, unloaded)[0] / case.reload_steps, np.eye(3))
    segments = (*unloaded.segments, hold)
    held = run_compaction(
        case.base.updated(
            kind=case.solver,
            spheres=unloaded.packing,
            directory=str(out / "settle"),
            checkpoint_every=_FINAL_ONLY,
            checkpoint_keep=1,
            visual=False,
            segments_after=segments,
            segment_steps=(1,) * len(unloaded.segments) + (2,),
        ),
        comm,
        _quiet(log),
        restart=unloaded.checkpoint,
    )
    hs = held.history
    E_0 = float(hs.column("E_d")[-1])
    log(
        "[settle] implicit equilibrium of the unloaded state: sigma_m "
        f"{unloaded.sigma_m_unloaded:.4g} -> "
        f"{hs.column('sigma_m')[-1]:.4g} MPa, E_d {unloaded.E_0:.5g} -> {E_0:.5g} mJ "
        f"({held.wall_time:.0f} s)"
    )
    return replace(
        unloaded,
        checkpoint=str(resolve_checkpoint(out / "settle")),
        segments=segments,
        E_0=E_0,
        sigma_m_unloaded=float(hs.column("sigma_m")[-1]),
        Gamma_unloaded=float(hs.column("Gamma")[-1]),
        t_unloaded=float(hs.column("time")[-1]),
        settled=True,
    ), held.model


#: a Newton reload checkpoints every so many of its steps (its history rows)
RELOAD_CHECKPOINT_EVERY = 5


def reload_case(
    case: YieldSurfaceCase, unloaded: Unloaded, k: int, extended: bool = False
) -> CompactionCase:
    """The compaction case of reload ``k`` (direction phi_k), to restart from the unload
    checkpoint; ``extended``: with its extension (a further segment along the same direction,
    ``reload_extension`` x the amplitude in as large a share of the reload's time and steps),
    to restart from the reload's last checkpoint."""
    duration, n_r = _reload_duration(case, unloaded)
    phi, A = float(case.phis[k]), _reload_amplitude(case, unloaded)
    segments = (*unloaded.segments, (duration, reload_gradient(phi, A)))
    steps = (case.reload_steps,)
    if extended:
        f = case.reload_extension
        segments += ((f * duration, reload_gradient(phi, f * A)),)
        steps += (max(4, math.ceil(f * case.reload_steps)),)
    static = solver_kind(case.solver).static
    reload = case.base.updated(
        spheres=unloaded.packing,
        directory=str(Path(case.out_dir) / f"reload_{k:03d}"),
        # a Newton reload (an hour on a granular volume) can be continued after a kill
        checkpoint_every=RELOAD_CHECKPOINT_EVERY if static else 0,
        visual=False,
        segments_after=segments,
        segment_profiles=(*("smooth-step" for _ in unloaded.segments), case.reload_profile)
        + ("smooth-step",) * extended,
        every=max(1, n_r // case.rows_per_reload),
    )
    if static:  # every step a history row
        reload = reload.updated(
            kind=case.solver, segment_steps=(1,) * len(unloaded.segments) + steps
        )
    return reload


def yielded(history_csv: str | Path, E_0: float, threshold: float) -> bool:
    """Whether a reload's dissipated energy E_d has reached the yield threshold
    E_0 (1 + ``threshold``) (thesis §4.2.2)."""
    return bool(np.nanmax(read_csv(history_csv)["E_d"]) >= E_0 * (1.0 + threshold))


def fan_rows(
    history_csv: str | Path, phi: float, t_unloaded: float, w2_window: int = 7
) -> dict[str, np.ndarray]:
    """The reload part of a history (rows from the end of the unload on) as fan.csv columns, with
    Hill's W2 = dsigma : dh per output increment (MPa; tension-positive Cauchy stress, natural
    Hencky strain, eq. 4.15). The increments are Savitzky-Golay derivatives (quadratic fits over
    ``w2_window`` rows) rather than raw row differences: an explicit reload carries small elastic
    oscillations that flip the sign of raw increments (the thesis low-pass filtered W2 for the
    same reason, §4.5); 0 or a too short reload: raw differences (first row NaN)."""
    h = read_csv(history_csv)
    rows = h["time"] >= t_unloaded * (1 - 1e-12)
    m = int(rows.sum())
    sigma = -tensor_from_columns(h, "sigma")[rows]  # tension > 0
    F = tensor_from_columns(h, "F")[rows]
    hencky = hencky_strain(F)
    dsigma, dh = row_increments(sigma, w2_window), row_increments(hencky, w2_window)
    raw = second_order_work(np.diff(sigma, axis=0), np.diff(hencky, axis=0))
    fan = {
        "phi": np.full(m, phi),
        "W2": second_order_work(dsigma, dh),
        "_W2_raw": np.concatenate([[np.nan], raw]),
    }
    for c in FAN_COLUMNS:
        if c not in fan:
            fan[c] = h[c][rows]
    fan["_dh"] = np.linalg.norm(dh, axis=(1, 2))
    return fan


def run_yield_surface(
    case: YieldSurfaceCase, comm: MPI.Comm = MPI.COMM_WORLD, log=print, resume: bool = False
) -> dict:
    """Stages 1-4; returns (on every rank) {"unloaded", "points", "uniaxial", "wall_time",
    "reload_wall"}. ``resume``: continue a killed fan in ``case.out_dir`` (same case): stages 1-2
    are skipped if they finished (``unloaded.json``), else the loading continues from its newest
    checkpoint; finished reloads (a ``done`` file in ``reload_<k>/``) are not repeated. The wall
    times then count this run only."""
    start = time.perf_counter()
    out = Path(case.out_dir)
    configure_runtime(comm)  # the thread share of the whole run, before any solver on `alone`
    alone = comm.Split(color=comm.rank, key=0)  # each rank on its own communicator
    unloaded, model = None, None
    if comm.rank == 0:  # the other ranks sleep meanwhile: rank 0 may use every core of the node
        for stale in out.glob("claims.*"):  # a killed fan's claims
            shutil.rmtree(stale, ignore_errors=True)
        threads = numba.get_num_threads()
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        try:
            if resume and (out / "unloaded.json").exists():
                unloaded = read_unloaded(out, with_packing=True)
                log(f"[resume] load and unload finished: reloads from {unloaded.checkpoint}")
                # an explicit fan's unload
                if solver_kind(case.solver).static and not unloaded.settled:
                    unloaded, model = settle(case, unloaded, alone, log)
                    write_unloaded(out, unloaded)
            else:
                unloaded, model = load_and_unload(case, alone, log, resume=resume)
        finally:
            numba.set_num_threads(threads)
    _sleeping_barrier(comm)
    unloaded = comm.bcast(unloaded, root=0)
    t_fan = time.perf_counter()
    quiet = _quiet(log)
    claims = out / f"claims.{comm.bcast(time.time_ns() if comm.rank == 0 else None, root=0)}"
    for k in claimed_reloads(claims, case.nphi, first=comm.rank):
        t0 = time.perf_counter()
        reload = reload_case(case, unloaded, k)
        finished = Path(reload.output.directory) / "done"
        if resume and finished.exists():
            log(
                f"[reload {k + 1}/{case.nphi}] phi = {np.degrees(case.phis[k]):.1f} deg: done "
                "before"
            )
        else:
            restart = unloaded.checkpoint
            if resume and (Path(reload.output.directory) / "checkpoints").is_dir():
                try:  # a reload killed on its way continues from its newest checkpoint
                    restart = str(resolve_checkpoint(Path(reload.output.directory)))
                    log(f"[reload {k + 1}/{case.nphi}] continues from {restart}")
                except CheckpointError:
                    pass
            if model is None:  # one model per rank, reused by all its reloads
                model = build_compaction(reload, alone, quiet)
            (Path(reload.output.directory) / "extended").unlink(missing_ok=True)
            run_compaction(reload, alone, quiet, restart=restart, model=model)
            finished.write_text(f"{time.perf_counter() - t0:.0f}\n")
            log(
                f"[reload {k + 1}/{case.nphi}] phi = {np.degrees(case.phis[k]):.1f} deg on rank "
                f"{comm.rank}: "
                f"{time.perf_counter() - t0:.0f} s"
            )
        model = _extend(case, unloaded, k, alone, model, log, quiet)
    _sleeping_barrier(comm)
    reload_wall = time.perf_counter() - t_fan
    result = None
    if comm.rank == 0:
        shutil.rmtree(claims, ignore_errors=True)
        result = surfaces(case, unloaded, log)
        result.update(
            unloaded=unloaded, reload_wall=reload_wall, wall_time=time.perf_counter() - start
        )
        log(
            f"[fan] {case.nphi} reloads on {comm.size} rank(s) in {reload_wall:.0f} s; total "
            f"{result['wall_time']:.0f} s; outputs in {out}"
        )
    alone.Free()
    return comm.bcast(result, root=0)


def claimed_reloads(claims: Path, count: int, first: int = 0):
    """The reload indices in [0, ``count``) this process claims, one at a time as it asks for
    the next: each index goes to exactly one of the processes sharing the folder ``claims`` (a
    file created exclusively per index), so a rank whose reloads are short takes more of them
    than a rank whose reloads are long. The scan starts at ``first`` (the rank: the first claims
    go round the ranks) and wraps round."""
    claims.mkdir(parents=True, exist_ok=True)
    for i in range(count):
        k = (first + i) % count
        try:
            fd = os.open(claims / f"{k:03d}", os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            continue  # another process has it
        os.close(fd)
        yield k


def _extend(case, unloaded, k, comm, model, log, quiet):
    """Reload ``k``'s extension (Newton reloads with ``reload_extension``): run once, from the
    reload's last checkpoint, if the reload ended below the yield threshold, and stopped at the
    first row past it; returns the model (built if None)."""
    if not (solver_kind(case.solver).static and case.reload_extension > 0):
        return model
    folder = Path(case.out_dir) / f"reload_{k:03d}"
    marker = folder / "extended"
    threshold = case.dissipation_threshold
    if marker.exists() or yielded(folder / "history.csv", unloaded.E_0, threshold):
        return model
    t0 = time.perf_counter()
    reload = reload_case(case, unloaded, k, extended=True)
    if model is None:
        model = build_compaction(reload, comm, quiet)
    log(
        f"[reload {k + 1}/{case.nphi}] phi = {np.degrees(case.phis[k]):.1f} deg ended below "
        f"the yield threshold: extended by {case.reload_extension:g} x its amplitude"
    )
    limit = unloaded.E_0 * (1.0 + threshold)
    run_compaction(
        reload,
        comm,
        quiet,
        restart=resolve_checkpoint(folder),
        model=model,
        until=lambda row: row["E_d"] >= limit,  # the yield point is reached: enough
    )
    marker.write_text(f"{time.perf_counter() - t0:.0f}\n")
    return model


def surfaces(case: YieldSurfaceCase, unloaded: Unloaded | None = None, log=print) -> dict:
    """Stage 4 alone, from the files of a finished fan in ``case.out_dir`` (rank 0): fan.csv,
    surfaces.csv, uniaxial.csv and the PNG again, e.g. with other thresholds (thesis §4.2.2
    discusses the yield threshold's influence). ``unloaded``: None reads ``unloaded.json``."""
    out = Path(case.out_dir)
    if unloaded is None:
        unloaded = read_unloaded(out)
    window = 0 if solver_kind(case.solver).static else case.w2_window
    fans = [
        fan_rows(out / f"reload_{k:03d}" / "history.csv", float(phi), unloaded.t_unloaded, window)
        for k, phi in enumerate(case.phis)
    ]
    gammas = tuple(case.gamma_thresholds) or default_gamma_levels(
        unloaded.Gamma_unloaded, np.concatenate([f["Gamma"] for f in fans])
    )
    points = {}
    for fan in fans:
        for kind, p in surface_points(
            fan, unloaded.E_0, case.dissipation_threshold, gammas
        ).items():
            points.setdefault(kind, []).append((float(fan["phi"][0]), *p))
    scale = max(
        (math.hypot(m, d) for _, m, d in points.get("yield", [])),
        default=abs(unloaded.sigma_m_loaded),
    )
    gamma_limit = limit_specific_surface(fans, unloaded.Gamma_unloaded, scale)
    if np.isfinite(gamma_limit):  # the limit iso-Gamma curve (the thesis' rupture surface)
        for fan in fans:
            p = iso_gamma_point(fan, gamma_limit)
            if p is not None:
                points.setdefault(f"gamma_{gamma_limit:.6g}", []).append((float(fan["phi"][0]), *p))
    sign_changes = [w2_sign_changes(f) for f in fans]
    with open(out / "fan.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(FAN_COLUMNS)
        for fan in fans:
            for i in range(fan["phi"].size):
                w.writerow(
                    [
                        "" if not np.isfinite(fan[c][i]) else repr(float(fan[c][i]))
                        for c in FAN_COLUMNS
                    ]
                )
    with open(out / "surfaces.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(("kind", "phi", "sigma_m", "sigma_tilde_d"))
        for kind, pts in points.items():
            for p in pts:
                w.writerow((kind, *map(repr, p)))
    uniaxial = {}
    for kind, pts in points.items():
        if len(pts) == case.nphi:  # a closed surface: every direction crossed
            pts_arr = np.array(pts)
            uniaxial[kind] = uniaxial_strengths(pts_arr[:, 1], pts_arr[:, 2])
    with open(out / "uniaxial.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(("kind", "compressive_MPa", "tensile_MPa"))
        for kind, (c, t) in uniaxial.items():
            w.writerow(
                (kind, "" if not np.isfinite(c) else repr(c), "" if not np.isfinite(t) else repr(t))
            )
    summary = {
        "solver": case.solver,
        "E_0_mJ": unloaded.E_0,
        "sigma_m_unloaded_MPa": unloaded.sigma_m_unloaded,
        "Gamma_unloaded_per_mm": unloaded.Gamma_unloaded,
        "gamma_thresholds_per_mm": list(gammas),
        "Gamma_limit_per_mm": gamma_limit,
        "points": {k: len(v) for k, v in points.items()},
        "w2_raw_sign_changes": sign_changes,
        "reload": reload_discretization(case, unloaded),
        "uniaxial_MPa": {k: {"compressive": c, "tensile": t} for k, (c, t) in uniaxial.items()},
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=1, default=float))
    n_yield = len(points.get("yield", []))
    log(
        f"[surfaces] yield points {n_yield}/{case.nphi}"
        + ("" if n_yield == case.nphi else " (the surface is not closed: raise amplitude_factor)")
        + "".join(f"; {kind}: {len(p)}" for kind, p in points.items() if kind != "yield")
    )
    for kind, (c, t) in uniaxial.items():
        log(f"[surfaces] {kind}: uniaxial compressive {c:.4g} MPa, tensile {t:.4g} MPa")
    log(
        f"[surfaces] limit specific contact surface Gamma_l = {gamma_limit:.5g} 1/mm"
        + (
            ""
            if np.isfinite(gamma_limit)
            else " (no collapse of the contacts within these reloads: Gamma falls by "
            f"less than {100 * MIN_GAMMA_COLLAPSE:g} %, or the iso-Gamma curves do not "
            "superpose)"
        )
    )
    log(
        f"[surfaces] raw W2 sign changes per reload ({case.solver}): median "
        f"{np.median(sign_changes):.0f}, "
        f"max {max(sign_changes)}"
    )
    plot_yield_surface(
        out / "unload" / "history.csv",
        out / "fan.csv",
        out / "surfaces.csv",
        out / "yield_surface.png",
        title=f"{case.base.loading.path} compaction to rho = {case.base.loading.target_density}, "
        f"gamma = {case.base.contact.gamma:g} mJ/mm^2, {case.nphi} {case.solver} reloads",
        gamma_limit=gamma_limit,
    )
    return {
        "points": points,
        "uniaxial": uniaxial,
        "gamma_thresholds": gammas,
        "gamma_limit": gamma_limit,
        "w2_raw_sign_changes": sign_changes,
    }


def _sleeping_barrier(comm: MPI.Comm, poll: float = 0.05) -> None:
    """Barrier whose waiting ranks sleep instead of spinning (MPICH polls): an idle rank then
    leaves its core to the working ones."""
    request = comm.Ibarrier()
    while not request.Test():
        time.sleep(poll)


def _quiet(log):
    """Keep warnings and errors of a stage's log, drop its progress lines."""

    def quiet(message: str) -> None:
        if "WARNING" in message or "rror" in message:
            log(message)

    return quiet
