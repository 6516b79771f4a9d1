"""Stress-controlled probes from one consolidated state (issue 24): the common first stage of the
deviatoric-plane fan (workflows.deviatoric_surface) and of force-controlled rupture
(workflows.force_rupture).

Stage (data flow: volume -> stress-controlled consolidation and unload -> checkpoint -> probes):
the three normal stresses servo-controlled (loading.mixed.StressControl) up to the pressure
``p_load`` (ramp, hold), then down to the probes' mean stress ``p_probe`` < ``p_load`` (ramp,
hold), ending with a checkpoint in ``out_dir/consolidate``. Every probe restarts from that
checkpoint with the servo's state and the contact history carried over (``run_probe``). E_0 = E_d
at the end of the consolidation: the reference of the iso-dissipation yield (thesis §4.2.2) and
of the kinetic / dissipated energy ratio (eq. 4.14).

Times in units of ``base.duration``; the servo's ``rate`` in strain per duration. MPa,
compression > 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from mpi4py import MPI

from ..boundary import boundary_kind
from ..loading.mixed import StressControl, pressure_control
from ..solvers import solver_kind
from .compaction import CompactionCase, CompactionModel, run_compaction

_FINAL_ONLY = 10 ** 9  # checkpoint_every that writes the final checkpoint only


@dataclass
class StressProbeCase:
    """A consolidated state and the servo settings of the probes run from it. ``base``: the volume
    (packing, mesh, material, gamma, CLP / CLPS, explicit; its ``duration`` and ``increments`` set
    the time unit and the increment); its path is replaced."""

    base: CompactionCase = field(default_factory=CompactionCase)
    p_load: float = 2.0  # MPa, consolidation pressure
    p_probe: float = 1.0  # MPa, mean stress of the unloaded state where the probes start
    ramp: float = 1.0
    hold: float = 0.3
    unload: float = 0.3
    probe: float = 1.0  # duration of a probe
    rate: float = 0.1
    band: float | None = None  # MPa (None: p_load / 4)
    integral_time: float | None = 0.1
    filter_time: float = 0.01
    rows_per_probe: int = 20
    out_dir: str = "results/stress_probes"

    def __post_init__(self):
        if not boundary_kind(self.base.bc).periodic or not solver_kind(self.base.solver).stress_control:
            raise ValueError(f"base: a stress-controlled probe needs bc CLP or CLPS and the explicit solver, got "
                             f"{self.base.bc!r} / {self.base.solver!r}")
        if not 0 < self.p_probe < self.p_load:
            raise ValueError(f"p_probe must be in (0, p_load = {self.p_load}) MPa, got {self.p_probe}")
        for name in ("ramp", "unload", "probe", "rate"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0 (x duration), got {getattr(self, name)}")
        if not self.hold >= 0:
            raise ValueError(f"hold must be >= 0 (x duration), got {self.hold}")
        if not 2 <= self.rows_per_probe <= 10000:
            raise ValueError(f"rows_per_probe must be in [2, 10000], got {self.rows_per_probe}")

    def servo(self) -> dict:
        """The servo's keyword arguments in seconds (loading.mixed.StressControl)."""
        T = self.base.duration
        return dict(rate=self.rate / T, band=self.band if self.band is not None else self.p_load / 4,
                    integral_time=None if self.integral_time is None else self.integral_time * T,
                    filter_time=self.filter_time * T)

    def consolidation(self) -> StressControl:
        """Pressure up to p_load (ramp), held, down to p_probe (unload), held."""
        T = self.base.duration
        return pressure_control(self.p_load, self.ramp * T, self.hold * T, unload_to=self.p_probe,
                                unload=self.unload * T, **self.servo())


@dataclass
class ConsolidatedState:
    """The end of the consolidation: its time (s), E_d (mJ), checkpoint and built model."""

    time: float
    E_0: float
    checkpoint: Path
    model: CompactionModel


def consolidate(case: StressProbeCase, comm: MPI.Comm = MPI.COMM_WORLD, log=print) -> ConsolidatedState:
    """Run the consolidation and unload into ``out_dir/consolidate`` (module docstring)."""
    out = Path(case.out_dir) / "consolidate"
    log(f"consolidation to {case.p_load} MPa, unload to {case.p_probe} MPa -> {out}")
    run = run_compaction(replace(case.base, control=case.consolidation(), out_dir=str(out),
                                 checkpoint_every=_FINAL_ONLY, outputs=max(8, case.rows_per_probe)), comm, log=log)
    return ConsolidatedState(time=float(run.history.column("time")[-1]), E_0=float(run.history.column("E_d")[-1]),
                             checkpoint=sorted((out / "checkpoints").glob("step*"))[-1], model=run.model)


def run_probe(case: StressProbeCase, state: ConsolidatedState, control: StressControl, name: str,
              comm: MPI.Comm = MPI.COMM_WORLD, log=print):
    """One probe (``control`` starting at ``state.time``) restarted from the consolidated state
    into ``out_dir/<name>``, ``rows_per_probe`` history rows over the probe; returns its history
    (the consolidation's rows included)."""
    T = case.base.duration
    probe = replace(case.base, control=control, out_dir=str(Path(case.out_dir) / name), checkpoint_every=0,
                    outputs=max(4, round(case.rows_per_probe * (state.time + case.probe * T) / (case.probe * T))))
    log(f"probe {name} -> {probe.out_dir}")
    return run_compaction(probe, comm, log=log, restart=state.checkpoint, model=state.model).history
