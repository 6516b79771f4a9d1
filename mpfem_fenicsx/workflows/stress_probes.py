"""Stress-controlled probes from one consolidated state: the common first stage of the
deviatoric-plane fan (workflows.deviatoric_surface) and of force-controlled rupture
(workflows.force_rupture).

Stage (data flow: volume -> stress-controlled consolidation and unload -> checkpoint -> probes):
the three normal stresses servo-controlled (loading.mixed.StressControl) up to the pressure
``p_load`` (ramp, hold), then down to the probes' mean stress ``p_probe`` < ``p_load`` (ramp,
hold), ending with a checkpoint in ``out_dir/consolidate``. Every probe restarts from that
checkpoint with the servo's state and the contact history carried over (``run_probe``). E_0 = E_d
at the end of the consolidation: the reference of the iso-dissipation yield (thesis §4.2.2) and
of the kinetic / dissipated energy ratio (eq. 4.14).

Times in units of ``base.loading.duration``; the servo's ``rate`` in strain per duration. MPa,
compression > 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from mpi4py import MPI

from ..boundary import boundary_kind
from ..loading.mixed import StressControl, pressure_control
from ..loading.stress_paths import ServoSettings, StressPath
from ..parameters import parameter, parameter_of
from ..solvers import solver_kind
from .compaction import CompactionCase, CompactionModel, run_compaction

_FINAL_ONLY = 10**9  # checkpoint_every that writes the final checkpoint only


@dataclass
class StressProbeCase(ServoSettings):
    """A consolidated state and the servo settings of the probes run from it (the servo's fields:
    :class:`~mpfem_fenicsx.loading.stress_paths.ServoSettings`). ``base``: the volume (packing,
    mesh, material, gamma, CLP / CLPS, explicit; its ``duration`` and ``increments`` set the time
    unit and the increment); its path is replaced."""

    base: CompactionCase = field(default_factory=CompactionCase)
    p_load: float = parameter(
        2.0, "consolidation pressure (MPa, compression > 0)", low=0, high=1000, open_low=True
    )
    p_probe: float = parameter(
        1.0,
        "mean stress of the unloaded state where the probes start (MPa, below p_load)",
        low=0,
        high=1000,
        open_low=True,
    )
    ramp: float = parameter_of(StressPath, "ramp")
    hold: float = parameter_of(StressPath, "hold")
    unload: float = parameter(
        0.3,
        "time of the unload from p_load to p_probe (x duration)",
        low=0,
        high=100,
        open_low=True,
    )
    probe: float = parameter(1.0, "time of a probe (x duration)", low=0, high=100, open_low=True)
    rows_per_probe: int = parameter(20, "history rows over a probe", low=2, high=10000)
    out_dir: str = "results/stress_probes"

    def __post_init__(self):
        super().__post_init__()  # every declared range
        if (
            not boundary_kind(self.base.boundary.condition).periodic
            or not solver_kind(self.base.solver.kind).stress_control
        ):
            raise ValueError(
                "base: a stress-controlled probe needs bc CLP or CLPS and the explicit solver, got "
                f"{self.base.boundary.condition!r} / {self.base.solver.kind!r}"
            )
        if not self.p_probe < self.p_load:
            raise ValueError(
                f"p_probe must be in (0, p_load = {self.p_load}) MPa, got {self.p_probe}"
            )

    def servo(self) -> dict:
        """The servo's keyword arguments in seconds (loading.mixed.StressControl)."""
        return self.in_seconds(self.base.loading.duration, self.p_load)

    def consolidation(self) -> StressControl:
        """Pressure up to p_load (ramp), held, down to p_probe (unload), held."""
        T = self.base.loading.duration
        return pressure_control(
            self.p_load,
            self.ramp * T,
            self.hold * T,
            unload_to=self.p_probe,
            unload=self.unload * T,
            **self.servo(),
        )


@dataclass
class ConsolidatedState:
    """The end of the consolidation: its time (s), E_d (mJ), checkpoint and built model."""

    time: float
    E_0: float
    checkpoint: Path
    model: CompactionModel


def consolidate(
    case: StressProbeCase, comm: MPI.Comm = MPI.COMM_WORLD, log=print
) -> ConsolidatedState:
    """Run the consolidation and unload into ``out_dir/consolidate`` (module docstring)."""
    out = Path(case.out_dir) / "consolidate"
    log(f"consolidation to {case.p_load} MPa, unload to {case.p_probe} MPa -> {out}")
    run = run_compaction(
        case.base.updated(
            control=case.consolidation(),
            directory=str(out),
            checkpoint_every=_FINAL_ONLY,
            outputs=max(8, case.rows_per_probe),
        ),
        comm,
        log=log,
    )
    return ConsolidatedState(
        time=float(run.history.column("time")[-1]),
        E_0=float(run.history.column("E_d")[-1]),
        checkpoint=sorted((out / "checkpoints").glob("step*"))[-1],
        model=run.model,
    )


def run_probe(
    case: StressProbeCase,
    state: ConsolidatedState,
    control: StressControl,
    name: str,
    comm: MPI.Comm = MPI.COMM_WORLD,
    log=print,
):
    """One probe (``control`` starting at ``state.time``) restarted from the consolidated state
    into ``out_dir/<name>``, ``rows_per_probe`` history rows over the probe; returns its history
    (the consolidation's rows included)."""
    T = case.base.loading.duration
    probe = case.base.updated(
        control=control,
        directory=str(Path(case.out_dir) / name),
        checkpoint_every=0,
        outputs=max(
            4, round(case.rows_per_probe * (state.time + case.probe * T) / (case.probe * T))
        ),
    )
    log(f"probe {name} -> {probe.output.directory}")
    return run_compaction(probe, comm, log=log, restart=state.checkpoint, model=state.model).history
