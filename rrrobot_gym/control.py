"""Leg control: the paper's PD servo and the sinusoidal gaits of Table II.

A *leg-target source* is any object with a method ``leg_targets(t)`` that returns
three pairs ``(angles, rates, accels)``: the target angle (rad), rate (rad/s) and
acceleration (rad/s^2) of leg 1 and leg 2 at time t (s). Each item is a float (the
same for every robot) or an array of shape (N,) (one value a robot). The servo
uses angles and rates; the kinematic-legs mode uses all three.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .params import _require_finite


TARGETS_HELD, TARGETS_RAMP, TARGETS_SINUSOID = 0, 1, 2
"""The kinds of leg-target source the compiled stepper knows (``compiled_targets()``, see
:func:`rrrobot_gym.compiled.target_arrays`): held angles, a ramp, a sinusoid."""


@dataclass(frozen=True)
class Gait:
    """phi_k(t) = amplitude sin(frequency t + phase_k) + offset_k (paper Section III)."""

    amplitude: float = 0.3  # rad
    frequency: float = 8.0  # rad/s
    phase: tuple = (0.0, 0.5 * math.pi)  # rad, (leg 1, leg 2)
    offset: tuple = (0.5 * math.pi, 0.5 * math.pi)  # rad, (leg 1, leg 2)
    name: str = "gait"

    def __post_init__(self):
        _require_finite(self, ("amplitude", "frequency"))
        for field in ("phase", "offset"):
            value = tuple(float(v) for v in np.asarray(getattr(self, field), dtype=float).ravel())
            if len(value) != 2:
                raise ValueError(f"Gait.{field} must have 2 entries (leg 1, leg 2), got {len(value)}")
            if not all(math.isfinite(v) for v in value):
                raise ValueError(f"Gait.{field} must be finite, got {value}")
            object.__setattr__(self, field, value)

    @property
    def period(self) -> float:
        """s, one cycle of the legs; inf for a gait that does not oscillate."""
        return 2.0 * math.pi / abs(self.frequency) if self.frequency else math.inf

    def swapped(self) -> "Gait":
        """The same gait with the legs' phases exchanged: the paper's reversed motion."""
        name = self.name[: -len("-swapped")] if self.name.endswith("-swapped") else self.name + "-swapped"
        return Gait(self.amplitude, self.frequency, self.phase[::-1], self.offset, name)

    def leg_targets(self, t):
        a = self.amplitude
        return sinusoid_targets(t, (a, a), self.frequency, self.phase, self.offset)

    def compiled_targets(self):
        """(kind, per-robot parameters, shared parameters) for :mod:`rrrobot_gym.compiled`."""
        a = self.amplitude
        return TARGETS_SINUSOID, (a, a, self.frequency, *self.phase, *self.offset), ()

    def robot(self, i: int) -> "Gait":
        """The targets of robot ``i`` of a batch: the same gait (see :meth:`RampTargets.robot`)."""
        return self

    def angles(self, times):
        """Target leg angles at an array of times, shape (T, 2), rad."""
        times = np.asarray(times, dtype=float)[..., None]
        return self.amplitude * np.sin(self.frequency * times + np.asarray(self.phase)) + np.asarray(self.offset)


def sinusoid_targets(t, amplitude, frequency, phase, offset):
    """Targets of phi_k(t) = a_k sin(w t + beta_k) + o_k at time t (a float): ``amplitude``,
    ``phase`` and ``offset`` are (leg 1, leg 2) pairs, ``frequency`` w in rad/s. The one
    sinusoid of the gaits (:class:`Gait`, ``gait_search.SinusoidGait``) and of the compiled
    stepper (:mod:`rrrobot_gym.compiled`)."""
    (a1, a2), (b1, b2), (o1, o2), w = amplitude, phase, offset, frequency
    s1, c1 = math.sin(w * t + b1), math.cos(w * t + b1)
    s2, c2 = math.sin(w * t + b2), math.cos(w * t + b2)
    return (
        (a1 * s1 + o1, a2 * s2 + o2),
        (a1 * w * c1, a2 * w * c2),
        (-a1 * w * w * s1, -a2 * w * w * s2),
    )


GAIT_OFFSETS = {1: 0.5 * math.pi, 2: 0.0, 3: 0.25 * math.pi}
"""rad, the offset gamma of each Table II gait (legs about vertical, horizontal, pi/4)."""


def table2_gait(number: int, swapped: bool = False) -> Gait:
    """Gait 1, 2 or 3 of the paper's Table II, optionally with the legs' phases swapped."""
    if isinstance(number, bool) or not isinstance(number, (int, np.integer)) or number not in GAIT_OFFSETS:
        raise ValueError(f"unknown gait {number!r}: Table II has gaits 1, 2 and 3")
    gamma = GAIT_OFFSETS[number]
    gait = Gait(offset=(gamma, gamma), name=f"gait{number}")
    return gait.swapped() if swapped else gait


class HeldTargets:
    """Leg targets held constant (an RL action over a control step): target rate 0."""

    def __init__(self, angles):
        angles = np.asarray(angles, dtype=float)
        if angles.shape[-1:] != (2,) or angles.ndim > 2:
            raise ValueError(f"leg target angles must have shape (2,) or (N, 2), got {angles.shape}")
        if not np.all(np.isfinite(angles)):
            raise ValueError("leg target angles contain NaN or inf")
        # (1, 2): one robot's targets, kept as numbers like (2,): every robot of a batch takes them
        one = angles.ndim == 1 or angles.shape[0] == 1
        self._angles = tuple(angles.reshape(2).tolist()) if one else (angles[:, 0].copy(), angles[:, 1].copy())

    def leg_targets(self, t):
        return self._angles, (0.0, 0.0), (0.0, 0.0)

    def compiled_targets(self):
        """(kind, per-robot parameters, shared parameters) for :mod:`rrrobot_gym.compiled`."""
        return TARGETS_HELD, self._angles, ()

    def robot(self, i: int) -> "HeldTargets":
        """The targets of robot ``i`` of a batch, on Python floats (see :meth:`RampTargets.robot`)."""
        if isinstance(self._angles[0], float):
            return self
        return HeldTargets([self._angles[0][i], self._angles[1][i]])


def pd_torque(gains, leg_angles, leg_rates, targets):
    """The paper's PD servo, tau_k = kp (phi_d - phi) + kd (phid_d - phid), per leg (N m)."""
    (a1, a2), (r1, r2), _ = targets
    return (
        gains.kp * (a1 - leg_angles[0]) + gains.kd * (r1 - leg_rates[0]),
        gains.kp * (a2 - leg_angles[1]) + gains.kd * (r2 - leg_rates[1]),
    )


def limit_torque(torque, leg_rates, torque_limit, rate_limit=None):
    """The torques a leg motor can give, per leg: at most ``torque_limit`` (N m) either way,
    and, with a no-load speed ``rate_limit`` (rad/s), no more than the torque-speed line of
    a DC motor at full voltage allows: tau in [-T (1 + w / W), T (1 - w / W)], w the leg's
    rate. So the motor pushes ever less as the leg speeds up and cannot drive it past W;
    it can always brake with up to T. With ``torque_limit`` None, ``torque`` unchanged
    (the paper's ideal servo).
    """
    if torque_limit is None:
        return torque
    return (
        motor_torque(torque[0], leg_rates[0], torque_limit, rate_limit),
        motor_torque(torque[1], leg_rates[1], torque_limit, rate_limit),
    )


def motor_torque(tau, rate, torque_limit, rate_limit=None):
    """One leg's part of :func:`limit_torque`: the servo's ``tau`` as the motor can give it at
    leg rate ``rate`` (floats, or arrays of a batch). Also compiled by :mod:`rrrobot_gym.compiled`."""
    high = low = torque_limit
    if rate_limit is not None:
        drop = torque_limit * rate / rate_limit
        if isinstance(rate, float):
            high, low = min(high, torque_limit - drop), min(low, torque_limit + drop)
        else:
            high, low = np.minimum(high, torque_limit - drop), np.minimum(low, torque_limit + drop)
    # (the bounds are floats when the rate is, or when there is no rate limit)
    if isinstance(tau, float) and (rate_limit is None or isinstance(rate, float)):
        return min(max(tau, -low), high)
    return np.minimum(np.maximum(tau, -low), high)


class RampTargets:
    """Leg targets ramped linearly from ``start`` to ``end`` over [t0, t0 + duration], then held.

    A first-order hold of step-wise targets (an RL action per control step): the target angle is
    continuous, so a new action steps only the servo's rate term (by kd times the change of slope).
    ``start``/``end`` have shape (2,) or (N, 2), rad.
    """

    def __init__(self, start, end, t0: float, duration: float):
        start = np.asarray(start, dtype=float)
        end = np.asarray(end, dtype=float)
        if start.shape != end.shape or start.shape[-1:] != (2,) or start.ndim > 2:
            raise ValueError(f"ramp ends must both have shape (2,) or (N, 2), got {start.shape} and {end.shape}")
        if not (math.isfinite(duration) and duration > 0.0):
            raise ValueError(f"ramp duration must be a positive number of seconds, got {duration}")
        self.t0, self.duration = float(t0), float(duration)
        if start.ndim == 2 and start.shape[0] == 1:  # one robot's ramp: as (2,), every robot of a batch takes it
            start, end = start[0], end[0]
        if start.ndim == 1:
            # One robot: Python floats throughout (the single env's every step; same arithmetic).
            (a1, a2), (b1, b2) = start.tolist(), end.tolist()
            if not all(math.isfinite(v) for v in (a1, a2, b1, b2)):
                raise ValueError("ramp ends contain NaN or inf")
            self._start, self._end, self._change = (a1, a2), (b1, b2), (b1 - a1, b2 - a2)
            self._slope = ((b1 - a1) / duration, (b2 - a2) / duration)
            self._still = (0.0, 0.0)
            return
        if not (np.all(np.isfinite(start)) and np.all(np.isfinite(end))):
            raise ValueError("ramp ends contain NaN or inf")
        change = end - start
        # The compiled stepper's (N, 8) parameters in one piece, the numpy steppers' pairs views of its
        # columns. Each (N, 2) part goes in as (N, 1) complex numbers: numpy copies 2-wide rows ~2x slower.
        parts = [np.ascontiguousarray(part).view(np.complex128) for part in (start, end, change, change / duration)]
        self._params = np.concatenate(parts, axis=1).view(np.float64)
        columns = tuple(self._params.T)
        self._start, self._end, self._change, self._slope = columns[0:2], columns[2:4], columns[4:6], columns[6:8]
        self._still = (np.zeros(len(start)), np.zeros(len(start)))

    def compiled_targets(self):
        """(kind, per-robot parameters, shared parameters) for :mod:`rrrobot_gym.compiled`."""
        if isinstance(self._start[0], float):
            return TARGETS_RAMP, (*self._start, *self._end, *self._change, *self._slope), (self.t0, self.duration)
        return TARGETS_RAMP, self._params, (self.t0, self.duration)

    def robot(self, i: int) -> "RampTargets":
        """The ramp of robot ``i`` of a batch, on Python floats (same arithmetic, same results): how
        the simulator integrates a small batch robot by robot without indexing arrays at every stage."""
        if isinstance(self._start[0], float):
            return self
        (a1, a2), (b1, b2) = self._start, self._end
        return RampTargets([a1[i], a2[i]], [b1[i], b2[i]], self.t0, self.duration)

    def leg_targets(self, t):
        return ramp_targets(t, self.t0, self.duration, self._start, self._end, self._change, self._slope, self._still)


def ramp_targets(t, t0, duration, start, end, change, slope, still):
    """The targets of :class:`RampTargets` at time t (a float); ``start``, ``end``, ``change``
    (end - start), ``slope`` (change / duration) and ``still`` (zeros) are (leg 1, leg 2) pairs
    of floats or (N,) arrays. Also compiled by :mod:`rrrobot_gym.compiled`."""
    s = (t - t0) / duration
    # Closed at the end: RK4's last stage falls on t0 + duration up to rounding, and the
    # rate must not depend on which side of it rounding lands.
    if s > 1.0 + 1e-9:
        return end, still, still
    if s < 0.0:
        s = 0.0
    (a1, a2), (d1, d2) = start, change
    return (a1 + d1 * s, a2 + d2 * s), slope, still


KERNELS = (pd_torque, motor_torque, ramp_targets, sinusoid_targets)
"""The functions :mod:`rrrobot_gym.compiled` compiles for the servo and the leg targets."""
