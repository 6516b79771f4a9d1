"""Mixed strain / stress control of a periodic volume through its auxiliary nodes (beyond the
thesis: its perspectives 4-5).

Each component of the macroscopic state is either strain-driven (a prescribed velocity gradient
L_ij, 1/s) or stress-driven (a prescribed Cauchy stress sigma_ij(t), MPa, compression > 0 as in
the histories). The stress-driven components of L are set by a servo on the measured stress (the
auxiliary nodes' reactions, Schmidt's eq. 2.19, or the volume average of the particles' stress,
eq. C.7, over the VEP's volume V0 det F, F the centroids' least-squares gradient: ``measure``; the
history's ``sigma_schmidt_*`` and ``sigma_vol_*`` columns report the same two measures), like the
periodic-cell controllers of DEM codes:

    e_ij = target_ij - sigma_ij                                            (compression > 0)
    L_ij = -rate * clip((e_ij + (1 / integral_time) int e_ij dt) / band, -1, 1)

i.e. the cell is compressed along ij at up to ``rate`` while the compression there is below its
target, at a rate proportional to the error within ``band``. The medium's stress responds to the
cell's strain (an integrating plant), so at a constant target the error decays to zero with the
time constant band / (K rate), K the tangent modulus. With the proportional term alone, a stress
drifting at D MPa/s (a ramped target, or the lateral stress of a triaxial test pushed up by the
axial compression) is followed with a lag error of D band / (K rate); the integral term
(``integral_time``, a PI servo) takes that drift up and brings the error back to zero. The
integral stops growing while the rate is saturated (anti-windup). Following a ramped target,
the integral holds the strain rate the ramp needs; where the target's rate drops (a ramp's end,
a waypoint) the integral is scaled down with it (never up): unwinding it would otherwise drive
the stress past the target (3 % on an elastoplastic model medium). ``filter_time`` low-passes the
measured stress first (exponential moving average): the explicit pseudo-dynamics make it ring
about the quasi-static value. An average lags a stress ramped at R MPa/s by R filter_time, so a
servo holding the average on a ramped target would hold the stress that far ahead of it; the
filter also tracks the average's own rate, low-passed over the same time, and the servo reads
average + filter_time x rate: no lag on a ramp. The gradient is integrated from the servo's velocity
gradient, F0(t + dt) = exp(L dt) F0(t); off-diagonal stress-driven components use the symmetric part
(no spin).

The control is a gradient path t -> F0(t) (``GranularBoundaryConditions.gradient``); the
workflow calls :meth:`StressControl.update` with the measured stress every ``every`` explicit
increments. Its time must only advance.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm


@dataclass
class StressControl:
    """Mixed control of F0 over ``duration`` (s).

    Args:
        duration: length of the path (s).
        stress_driven: (3, 3) bool, symmetric: True where the Cauchy stress is prescribed; or
            t -> such a mask (e.g. isotropic consolidation, then axial strain at constant
            lateral stress).
        target: t -> (3, 3) prescribed Cauchy stress (MPa, compression > 0); read on the
            stress-driven components only.
        velocity_gradient: t -> (3, 3) velocity gradient (1/s) of the strain-driven components
            (natural sign: negative compresses); None: zero (held).
        rate: the servo's largest strain rate (1/s, > 0).
        band: stress error (MPa, > 0) at which the servo reaches ``rate``.
        start: F0 at t = 0 (e.g. the end of a strain-driven compaction).
        every: explicit increments between two servo updates (the servo's time constant must
            span many more: sampling the volume average every 10 increments with a time constant
            of ~20 made the simple cubic cell overshoot by 50 %).
        measure: "schmidt" (default; smooth on the elastic simple cubic cell, but on a plastic
            granular volume loaded fast it follows every contact impact across the faces) or
            "volume" (rings with the particles' elastic waves on the simple cubic cell).
        integral_time: the PI servo's integral time (s, > 0); None: proportional only. For a
            well-damped loop take it >= 2 band / (K rate), K the medium's tangent modulus.
        filter_time: time constant (s, >= 0) of the low-pass filter on the measured stress
            (0: none). Keep it well below the servo's time constant band / (K rate).
    """

    duration: float
    stress_driven: np.ndarray | Callable[[float], np.ndarray]
    target: Callable[[float], np.ndarray]
    rate: float
    band: float
    velocity_gradient: Callable[[float], np.ndarray] | None = None
    start: np.ndarray = field(default_factory=lambda: np.eye(3))
    every: int = 1
    measure: str = "schmidt"
    integral_time: float | None = None
    filter_time: float = 0.0

    def __post_init__(self):
        if not callable(self.stress_driven):
            mask = np.asarray(self.stress_driven, dtype=bool)
            self.stress_driven = lambda t, mask=mask: mask
        self._check_mask(self.stress_driven(0.0))
        if not self.duration > 0:
            raise ValueError(f"duration must be > 0 s, got {self.duration}")
        if not self.rate > 0:
            raise ValueError(f"rate must be > 0 (1/s), got {self.rate}")
        if not self.band > 0:
            raise ValueError(f"band must be > 0 MPa, got {self.band}")
        if self.measure not in ("schmidt", "volume"):
            raise ValueError(f"measure must be schmidt or volume, got {self.measure!r}")
        if not (isinstance(self.every, int) and self.every >= 1):
            raise ValueError(f"every must be an integer >= 1 (increments), got {self.every}")
        if self.integral_time is not None and not self.integral_time > 0:
            raise ValueError(
                f"integral_time must be > 0 s (or None: no integral term), got {self.integral_time}"
            )
        if not self.filter_time >= 0:
            raise ValueError(f"filter_time must be >= 0 s, got {self.filter_time}")
        self._t = 0.0
        self._F = np.asarray(self.start, dtype=float).copy()
        self._L_servo = np.zeros((3, 3))
        self._filtered = None  # low-passed measured stress (MPa)
        self._trend = np.zeros((3, 3))  # low-passed rate of the filtered stress (MPa/s)
        self._target_before = np.zeros((3, 3))  # the target at the last update (MPa)
        self._target_rate = np.zeros((3, 3))  # its rate over the last update interval (MPa/s)
        self._integral = np.zeros((3, 3))  # int e dt (MPa s)
        self._t_update = None  # time of the last update
        self._previous = (0.0, self._F.copy())  # the step before: the solver asks for F0(t_n) again

    @staticmethod
    def _check_mask(mask) -> np.ndarray:
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != (3, 3) or not np.array_equal(mask, mask.T):
            raise ValueError("stress_driven must be a symmetric 3x3 boolean mask")
        return mask

    @property
    def knots(self) -> list[float]:
        """The path's start and end times (s)."""
        return [0.0, self.duration]

    def _velocity_gradient(self, t: float) -> np.ndarray:
        L = (
            np.zeros((3, 3))
            if self.velocity_gradient is None
            else np.asarray(self.velocity_gradient(t), float)
        )
        return np.where(self._check_mask(self.stress_driven(t)), self._L_servo, L)

    def __call__(self, t: float) -> np.ndarray:
        """F0(t) (3, 3): integrated forward from the last time asked (midpoint rule in L); the
        time before it is remembered too."""
        if t == self._previous[0] and t < self._t:
            return self._previous[1].copy()
        if t < self._t:
            raise ValueError(
                f"StressControl: time must advance (asked t = {t:.6g} s after {self._t:.6g} s)"
            )
        if t > self._t:
            dt = t - self._t
            self._previous = (self._t, self._F.copy())
            self._F = expm(self._velocity_gradient(self._t + 0.5 * dt) * dt) @ self._F
            self._t = t
        return self._F.copy()

    def begin(self, t: float, F: np.ndarray) -> None:
        """Start the path at time ``t`` from the gradient ``F`` (3, 3), servo at rest: a stress
        path continuing a strain-driven run from its checkpoint."""
        self._t, self._F = float(t), np.asarray(F, dtype=float).copy()
        self._previous = (self._t, self._F.copy())
        self._L_servo = np.zeros((3, 3))
        self._filtered, self._integral, self._t_update = None, np.zeros((3, 3)), None
        self._trend = np.zeros((3, 3))
        self._target_before, self._target_rate = np.zeros((3, 3)), np.zeros((3, 3))

    def state_dict(self) -> dict:
        """The servo's state (plain lists and floats, for a checkpoint's metadata): restoring it
        with :meth:`load_state` into the same control continues the path bit for bit."""
        return {
            "t": self._t,
            "F": self._F.tolist(),
            "previous_t": self._previous[0],
            "previous_F": self._previous[1].tolist(),
            "L_servo": self._L_servo.tolist(),
            "filtered": None if self._filtered is None else self._filtered.tolist(),
            "integral": self._integral.tolist(),
            "t_update": self._t_update,
            "trend": self._trend.tolist(),
            "target_before": self._target_before.tolist(),
            "target_rate": self._target_rate.tolist(),
        }

    def load_state(self, state: dict) -> None:
        """Restore :meth:`state_dict`."""
        self._t, self._F = float(state["t"]), np.array(state["F"], dtype=float)
        self._previous = (float(state["previous_t"]), np.array(state["previous_F"], dtype=float))
        self._L_servo = np.array(state["L_servo"], dtype=float)
        self._filtered = (
            None if state["filtered"] is None else np.array(state["filtered"], dtype=float)
        )
        self._integral = np.array(state["integral"], dtype=float)
        self._t_update = state["t_update"]
        # older checkpoints: none
        self._trend = np.array(state.get("trend", np.zeros((3, 3))), dtype=float)
        self._target_before = np.array(state.get("target_before", np.zeros((3, 3))), dtype=float)
        self._target_rate = np.array(state.get("target_rate", np.zeros((3, 3))), dtype=float)

    def update(self, t: float, sigma: np.ndarray) -> None:
        """Servo: set the stress-driven velocity gradient from the measured Cauchy stress
        ``sigma`` (3, 3) (MPa, compression > 0) at time t."""
        sigma = np.asarray(sigma, dtype=float)
        dt = 0.0 if self._t_update is None else t - self._t_update
        self._t_update = t
        if self._filtered is None or self.filter_time == 0.0:
            self._filtered = sigma.copy()
            measured = self._filtered
        else:
            weight = -np.expm1(-dt / self.filter_time)
            before = self._filtered.copy()
            self._filtered += weight * (sigma - self._filtered)
            if dt > 0:
                self._trend += weight * ((self._filtered - before) / dt - self._trend)
            measured = self._filtered + self.filter_time * self._trend  # the average's lag made up
        mask = self._check_mask(self.stress_driven(t))
        target = np.asarray(self.target(t), dtype=float)
        error = np.where(mask, target - measured, 0.0)
        command = error
        if self.integral_time is not None and dt > 0:
            # the integral holds the strain rate that followed the target's rate: where the target
            # slows down (the end of a ramp, a waypoint) it is scaled down with it, so it does not
            # drive the stress past the target while it unwinds (never scaled up)
            target_rate = (target - self._target_before) / dt
            previous = self._target_rate
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(
                    np.abs(previous) > 0, np.clip(target_rate / previous, -1.0, 1.0), 1.0
                )
            self._integral = self._integral * ratio
            self._target_rate = target_rate
        self._target_before = target
        if self.integral_time is not None:
            # anti-windup: the integral grows only where the rate is not saturated
            free = np.abs(error + self._integral / self.integral_time) < self.band
            self._integral = np.where(
                mask & free, self._integral + error * dt, np.where(mask, self._integral, 0.0)
            )
            command = error + self._integral / self.integral_time
        L = -self.rate * np.clip(command / self.band, -1.0, 1.0)
        self._L_servo = np.where(mask, 0.5 * (L + L.T), 0.0)


def rounded_waypoints(times, values, corner: float = 0.1) -> Callable[[float], np.ndarray]:
    """t -> values (k,) through the waypoints (``times`` (n,), ``values`` (n, k)), linear in
    between and held after the last, with each interior corner rounded: over ``corner`` times
    the shorter adjacent segment, centred on the waypoint, the rate changes linearly from one
    segment's to the next (C1; the path is off the corner by at most |rate change| x width / 8).

    A stress target whose rate stops at once (the end of a ramp) makes the servo stop the cell at
    once, and the stress the pseudo-dynamics carried while it moved is lost in a dip (-7 % on the
    flagship after its consolidation ramp); the PI integral, scaled with the target's rate, then
    eases off over the rounded corner instead."""
    times = np.asarray(times, dtype=float)
    values = np.asarray(values, dtype=float).reshape(times.size, -1)
    if not 0 <= corner <= 1:
        raise ValueError(
            f"corner must be in [0, 1] (fraction of the shorter adjacent segment), got {corner}"
        )
    rates = np.diff(values, axis=0) / np.diff(times)[:, None]
    corners = []  # (start a, half width h, value at a, rate before, rate change)
    for k in range(1, times.size - 1):
        h = 0.5 * corner * min(times[k] - times[k - 1], times[k + 1] - times[k])
        if h > 0:
            a = times[k] - h
            at_a = values[k - 1] + rates[k - 1] * (a - times[k - 1])
            corners.append((a, h, at_a, rates[k - 1], rates[k] - rates[k - 1]))

    def path(t: float) -> np.ndarray:
        for a, h, at_a, before, change in corners:
            if a < t < a + 2 * h:
                u = t - a
                return at_a + before * u + change * u * u / (4 * h)
        return np.array([np.interp(t, times, values[:, i]) for i in range(values.shape[1])])

    return path


def normal_stress_path(
    times,
    stresses,
    rate: float,
    band: float,
    start: np.ndarray | None = None,
    measure: str = "schmidt",
    integral_time: float | None = None,
    filter_time: float = 0.0,
    corner: float = 0.1,
) -> StressControl:
    """The three normal stresses driven through the waypoints (``times`` (n,) s, increasing;
    ``stresses`` (n, 3) MPa, compression > 0, or (n,) for an isotropic pressure), linearly in
    between and held after the last: load / unload / reload paths, a tensile probe to rupture.
    Interior waypoints are rounded over ``corner`` of the shorter adjacent segment
    (:func:`rounded_waypoints`). The path starts at ``times[0]`` from the gradient ``start``
    (default I); shear strains stay zero. ``rate`` (1/s), ``band`` (MPa), ``measure``,
    ``integral_time`` and ``filter_time`` (s): the servo's (see :class:`StressControl`)."""
    times = np.asarray(times, dtype=float)
    stresses = np.asarray(stresses, dtype=float)
    if stresses.ndim == 1:
        stresses = np.repeat(stresses[:, None], 3, axis=1)
    if times.ndim != 1 or times.size < 2 or stresses.shape != (times.size, 3):
        raise ValueError(
            f"stresses must hold one (3,) or scalar stress per time (>= 2 waypoints), got times "
            f"{times.shape} and stresses {stresses.shape}"
        )
    if not (np.all(np.isfinite(times)) and np.all(np.isfinite(stresses))):
        raise ValueError("times and stresses must be finite")
    if times[0] < 0 or np.any(np.diff(times) <= 0):
        raise ValueError(f"times must start >= 0 s and increase strictly, got {times.tolist()}")

    rounded = rounded_waypoints(times, stresses, corner)

    def target(t):
        return np.diag(rounded(t))

    return StressControl(
        duration=float(times[-1]),
        stress_driven=np.eye(3, dtype=bool),
        target=target,
        rate=rate,
        band=band,
        start=np.eye(3) if start is None else start,
        measure=measure,
        integral_time=integral_time,
        filter_time=filter_time,
    )


def pressure_control(
    pressure: float,
    ramp: float,
    hold: float,
    rate: float,
    band: float,
    measure: str = "schmidt",
    integral_time: float | None = None,
    filter_time: float = 0.0,
    unload_to: float | None = None,
    unload: float = 0.0,
) -> StressControl:
    """Isotropic pressure path: the three normal stresses ramped to ``pressure`` MPa (compression
    > 0) over ``ramp`` s, then held ``hold`` s; with ``unload_to``, then ramped down to it over
    ``unload`` s and held ``hold`` s again (a :func:`normal_stress_path`). ``rate`` (1/s),
    ``band`` (MPa), ``measure``, ``integral_time`` and ``filter_time`` (s): the servo's (see
    :class:`StressControl`)."""
    for name, value in (("pressure", pressure), ("ramp", ramp)):
        if not value > 0:
            raise ValueError(f"{name} must be > 0, got {value}")
    if hold < 0:
        raise ValueError(f"hold must be >= 0 s, got {hold}")
    if unload_to is not None and not (0 < unload_to < pressure and unload > 0):
        raise ValueError(
            f"unload_to must be in (0, pressure = {pressure}) MPa and unload > 0 s, got "
            f"{unload_to} / {unload}"
        )
    times, levels = [0.0, ramp], [0.0, pressure]
    if unload_to is not None:
        times += [ramp + hold, ramp + hold + unload]
        levels += [pressure, unload_to]
    times.append(times[-1] + hold)
    levels.append(levels[-1])
    if hold == 0:  # no repeated waypoint
        times, levels = times[:-1], levels[:-1]
        if unload_to is not None:
            times, levels = times[:2] + times[3:], levels[:2] + levels[3:]
    return normal_stress_path(
        times,
        levels,
        rate=rate,
        band=band,
        measure=measure,
        integral_time=integral_time,
        filter_time=filter_time,
    )


def triaxial_control(
    confining: float,
    consolidation: float,
    hold: float,
    axial_strain: float,
    axial_time: float,
    rate: float,
    band: float,
    axis: int = 2,
    measure: str = "schmidt",
    integral_time: float | None = None,
    filter_time: float = 0.0,
    axial_ramp: float = 0.3,
) -> StressControl:
    """Triaxial compression: isotropic consolidation (the three normal stresses ramped to
    ``confining`` MPa over ``consolidation`` s, then held ``hold`` s), then axial compression
    along ``axis`` to the Hencky strain ``axial_strain`` (> 0: shortening) over ``axial_time`` s,
    the lateral normal stresses held at ``confining``. The axial strain rate rises linearly over
    the first ``axial_ramp`` fraction of ``axial_time``, then stays constant: a sudden start
    jolts the lateral stresses before the servo reacts, a short ramp-in still leaves a transient
    in its first rows (the flagship's ramp-in study: README.md, ``demos/triaxial.py``). Shear
    strains stay zero.
    ``rate`` (1/s), ``band`` (MPa), ``measure``, ``integral_time`` and ``filter_time`` (s): the
    servo's (see :class:`StressControl`)."""
    for name, value in (
        ("confining", confining),
        ("consolidation", consolidation),
        ("axial_strain", axial_strain),
        ("axial_time", axial_time),
    ):
        if not value > 0:
            raise ValueError(f"{name} must be > 0, got {value}")
    if hold < 0:
        raise ValueError(f"hold must be >= 0 s, got {hold}")
    if axis not in (0, 1, 2):
        raise ValueError(f"axis must be 0, 1 or 2, got {axis}")
    if not 0 <= axial_ramp < 1:
        raise ValueError(f"axial_ramp must be in [0, 1) (fraction of axial_time), got {axial_ramp}")
    start_axial = consolidation + hold
    lateral = np.eye(3, dtype=bool)
    lateral[axis, axis] = False
    shortening = np.zeros((3, 3))
    ramp_in = axial_ramp * axial_time
    # the ramp-in loses half its length
    shortening[axis, axis] = -axial_strain / (axial_time - 0.5 * ramp_in)

    # the consolidation ramp's end rounded (rounded_waypoints) like the axial rate's start
    consolidated = rounded_waypoints(
        [0.0, consolidation, start_axial + axial_time],
        [0.0, confining, confining],
        corner=axial_ramp,
    )

    def axial(t):
        if t < start_axial:
            return np.zeros((3, 3))
        return shortening * (min((t - start_axial) / ramp_in, 1.0) if ramp_in > 0 else 1.0)

    return StressControl(
        duration=start_axial + axial_time,
        stress_driven=lambda t: np.eye(3, dtype=bool) if t < start_axial else lateral,
        target=lambda t: float(consolidated(t)[0]) * np.eye(3),
        velocity_gradient=axial,
        rate=rate,
        band=band,
        measure=measure,
        integral_time=integral_time,
        filter_time=filter_time,
    )


def lode_direction(theta: float) -> np.ndarray:
    """Unit deviatoric direction (3,) of principal stresses at Lode angle ``theta`` (rad):
    sqrt(2/3) (cos theta, cos(theta - 2 pi/3), cos(theta + 2 pi/3)). Compression > 0: theta = 0 is
    triaxial compression along x (sigma_1 > sigma_2 = sigma_3), theta = pi/3 triaxial extension
    along z (sigma_1 = sigma_2 > sigma_3)."""
    return np.sqrt(2.0 / 3.0) * np.cos(theta - np.array([0.0, 2.0, -2.0]) * np.pi / 3.0)


def lode_shear_control(
    mean: float,
    q_max: float,
    theta: float,
    duration: float,
    rate: float,
    band: float,
    start: np.ndarray | None = None,
    t0: float = 0.0,
    measure: str = "schmidt",
    integral_time: float | None = None,
    filter_time: float = 0.0,
) -> StressControl:
    """Shear at constant mean stress: the three normal stresses driven to
    sigma = mean I + sqrt(2/3) q(t) diag(lode_direction(theta)), q (the von Mises equivalent
    stress, MPa) ramped from 0 at t0 to ``q_max`` at t0 + duration; shear strains stay zero.
    ``start``: F0 at t0 (a fan of probes from one consolidated state). MPa, compression > 0."""
    if not duration > 0:
        raise ValueError(f"duration must be > 0 s, got {duration}")
    if not q_max > 0:
        raise ValueError(f"q_max must be > 0 MPa, got {q_max}")
    direction = np.diag(lode_direction(theta))

    def target(t):
        q = q_max * min(max((t - t0) / duration, 0.0), 1.0)
        return mean * np.eye(3) + np.sqrt(2.0 / 3.0) * q * direction

    return StressControl(
        duration=t0 + duration,
        stress_driven=np.eye(3, dtype=bool),
        target=target,
        rate=rate,
        band=band,
        start=np.eye(3) if start is None else start,
        measure=measure,
        integral_time=integral_time,
        filter_time=filter_time,
    )
