"""Stress-controlled paths and their servo, declared once (the paths and their parameters).

:class:`ServoSettings` (the PI servo of :class:`~.mixed.StressControl`) and :class:`StressPath`
(a named path: pressure, triaxial, cycle, lode) declare every field with
:func:`~mpfem_fenicsx.parameters.parameter`: the case file's ``[control]`` keys, the options of
``demos/triaxial.py`` and the stress-probe cases (``workflows.stress_probes``) read their
defaults, units and ranges from here. Times are in units of the loading duration (the
``CompactionCase.duration`` of mass-scaled time), the servo's rate in strain per duration;
:meth:`ServoSettings.in_seconds` and :meth:`StressPath.control` convert. MPa, compression > 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..parameters import check_parameters, parameter
from .mixed import (
    StressControl,
    lode_direction,
    normal_stress_path,
    pressure_control,
    triaxial_control,
)

#: the paths of :class:`StressPath` ("none": no stress control, the strain-driven compaction)
PATHS = ("none", "pressure", "triaxial", "cycle", "lode")
#: the fields that belong to one path only
PATH_FIELDS = {
    "triaxial": ("axial_strain", "axial_time", "axial_ramp"),
    "cycle": ("unload_to", "reload_to"),
    "lode": ("q_max", "lode_angle", "shear_time"),
}


@dataclass
class ServoSettings:
    """The PI servo of a stress-controlled path (:class:`~.mixed.StressControl`), times in units
    of the loading duration."""

    rate: float = parameter(
        0.1, "the servo's largest strain rate (strain per duration)", low=0, high=10, open_low=True
    )
    band: float | None = parameter(
        None,
        "stress error at which the servo reaches its rate (MPa; default: "
        "band_fraction x the pressure)",
        kind=float,
        low=0,
        open_low=True,
    )
    band_fraction: float = parameter(
        0.25,
        "the servo's band as a fraction of the pressure where `band` is not given (-)",
        low=0,
        high=1,
        open_low=True,
    )
    integral_time: float = parameter(
        0.1,
        "integral time of the PI servo (x duration; 0: proportional only, which "
        "lags behind a drifting stress)",
        low=0,
        high=100,
    )
    filter_time: float = parameter(
        0.01, "low-pass filter of the measured stress (x duration)", low=0, high=1
    )
    measure: str = parameter(
        "schmidt",
        "the servo's stress: schmidt (auxiliary nodes' reactions, eq. 2.19) or "
        "volume (the particles' volume average, eq. C.7)",
        choices=("schmidt", "volume"),
    )

    def __post_init__(self):
        check_parameters(self)

    def in_seconds(self, duration: float, pressure: float) -> dict:
        """The servo's keyword arguments of :class:`~.mixed.StressControl` (rate 1/s, times s) for
        a loading ``duration`` (s); ``band`` defaults to ``band_fraction`` x ``pressure`` (MPa)."""
        band = self.band if self.band is not None else self.band_fraction * pressure
        return dict(
            rate=self.rate / duration,
            band=band,
            measure=self.measure,
            filter_time=self.filter_time * duration,
            integral_time=self.integral_time * duration if self.integral_time > 0 else None,
        )


@dataclass
class StressPath(ServoSettings):
    """A named stress-controlled path (beyond the thesis), every one starting with an
    isotropic consolidation to ``pressure`` over ``ramp``, held ``hold``:

    - pressure: nothing more;
    - triaxial: axial compression along z to ``axial_strain`` over ``axial_time``, the lateral
      stresses held at ``pressure`` (the axial rate ramped in over ``axial_ramp`` of it);
    - cycle: unload to ``unload_to``, hold, reload to ``reload_to`` (default ``pressure``), hold;
    - lode: the von Mises stress ramped to ``q_max`` along ``lode_angle`` at constant mean stress
      over ``shear_time``.
    """

    path: str = parameter(
        "none",
        "stress-controlled path replacing the compaction (CLP or CLPS, explicit): "
        "pressure = isotropic pressure ramp to `pressure`, then held; triaxial = the same "
        "consolidation, then axial compression along z at constant lateral stress; cycle = the "
        "same "
        "consolidation, unload to `unload_to`, reload to `reload_to` (each ramp `ramp`, each hold "
        "`hold`); lode = the same consolidation, then the von Mises stress ramped to `q_max` along "
        "`lode_angle` at constant mean stress over `shear_time`",
        choices=PATHS,
    )
    pressure: float | None = parameter(
        None,
        "target (pressure) or confining (triaxial) pressure (MPa, compression "
        "> 0); required with a path",
        kind=float,
        low=0,
        high=1000,
        open_low=True,
    )
    ramp: float = parameter(
        1.0, "time of the pressure ramp (x duration)", low=0, high=100, open_low=True
    )
    hold: float = parameter(
        0.3, "hold at the pressure after the ramp (x duration)", low=0, high=100
    )
    axial_strain: float = parameter(
        0.1, "triaxial: axial Hencky shortening (-)", low=0, high=0.5, open_low=True
    )
    axial_time: float = parameter(
        1.0, "triaxial: time of the axial compression (x duration)", low=0, high=100, open_low=True
    )
    axial_ramp: float = parameter(
        0.3,
        "triaxial: fraction of the axial phase over which the axial strain rate "
        "rises from zero (a sudden start jolts the lateral stresses) (-)",
        low=0,
        high=1,
        open_high=True,
    )
    unload_to: float | None = parameter(
        None,
        "cycle: pressure of the unload (MPa; required, below `pressure`)",
        kind=float,
        low=0,
        high=1000,
    )
    reload_to: float | None = parameter(
        None,
        "cycle: pressure of the reload (MPa; default `pressure`; above `unload_to`)",
        kind=float,
        low=0,
        high=1000,
        open_low=True,
    )
    q_max: float | None = parameter(
        None,
        "lode: von Mises stress at the end of the shear (MPa; required)",
        kind=float,
        low=0,
        high=1000,
        open_low=True,
    )
    lode_angle: float = parameter(
        0.0,
        "lode: Lode angle of the shear (degrees; 0 = triaxial compression along x, "
        "60 = triaxial extension along z)",
        low=-360,
        high=360,
    )
    shear_time: float = parameter(
        1.0, "lode: time of the shear ramp (x duration)", low=0, high=100, open_low=True
    )

    def __post_init__(self):
        super().__post_init__()
        if self.path == "none":
            return
        if self.pressure is None:
            raise ValueError(f"pressure is required with path = {self.path!r} (MPa, > 0)")
        required = {"cycle": "unload_to", "lode": "q_max"}.get(self.path)
        if required and getattr(self, required) is None:
            raise ValueError(f"{required} is required with path = {self.path!r}")
        if self.path == "cycle":
            reload_to = self.pressure if self.reload_to is None else self.reload_to
            if not self.unload_to < self.pressure or not reload_to > self.unload_to:
                raise ValueError(
                    f"unload_to must be below pressure = {self.pressure} MPa and reload_to above "
                    "it, "
                    f"got unload_to = {self.unload_to}, reload_to = {reload_to}"
                )

    def control(self, duration: float) -> StressControl:
        """The :class:`~.mixed.StressControl` of the path for a loading ``duration`` (s)."""
        if self.path == "none":
            raise ValueError("path = 'none' is no stress-controlled path")
        servo = self.in_seconds(duration, self.pressure)
        ramp, hold = self.ramp * duration, self.hold * duration
        if self.path == "pressure":
            return pressure_control(self.pressure, ramp, hold, **servo)
        if self.path == "triaxial":
            return triaxial_control(
                self.pressure,
                consolidation=ramp,
                hold=hold,
                axial_strain=self.axial_strain,
                axial_time=self.axial_time * duration,
                axial_ramp=self.axial_ramp,
                **servo,
            )
        p = np.full(3, self.pressure)
        if self.path == "cycle":  # load, hold, unload, hold, reload, hold
            low = np.full(3, self.unload_to)
            high = np.full(3, self.pressure if self.reload_to is None else self.reload_to)
            stages = [(ramp, p), (hold, p), (ramp, low), (hold, low), (ramp, high), (hold, high)]
        else:  # load, hold, then q ramped at constant mean stress along the Lode angle
            sheared = p + np.sqrt(2.0 / 3.0) * self.q_max * lode_direction(
                np.radians(self.lode_angle)
            )
            stages = [(ramp, p), (hold, p), (self.shear_time * duration, sheared)]
        times, stresses = [0.0], [np.zeros(3)]
        for length, stress in stages:
            if length > 0:
                times.append(times[-1] + length)
                stresses.append(stress)
        return normal_stress_path(times, stresses, **servo)
