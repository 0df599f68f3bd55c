"""Leg control: the paper's PD servo and the sinusoidal gaits of Table II.

A *leg-target source* is any object with a method ``leg_targets(t)`` that returns three
tuples ``(angles, rates, accels)``, one item a leg: the target angle (rad), rate (rad/s) and
acceleration (rad/s^2) of each leg at time t (s). Each item is a float (the same for every
robot) or an array of shape (N,) (one value a robot). The servo uses angles and rates; the
kinematic-legs mode uses all three.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .params import MAX_LEGS, _require_finite


TARGETS_HELD, TARGETS_RAMP, TARGETS_SINUSOID = 0, 1, 2
"""The kinds of leg-target source the compiled stepper knows (``compiled_targets()``, see
:func:`rrrobot_gym.compiled.target_arrays`): held angles, a ramp, a sinusoid."""


@dataclass(frozen=True)
class Gait:
    """phi_k(t) = amplitude sin(frequency t + phase_k) + offset_k (paper Section III), one phase
    and offset a leg (two for the paper's robot)."""

    amplitude: float = 0.3  # rad
    frequency: float = 8.0  # rad/s
    phase: tuple = (0.0, 0.5 * math.pi)  # rad, one a leg
    offset: tuple = (0.5 * math.pi, 0.5 * math.pi)  # rad, one a leg
    name: str = "gait"

    def __post_init__(self):
        _require_finite(self, ("amplitude", "frequency"))
        for field in ("phase", "offset"):
            value = tuple(float(v) for v in np.asarray(getattr(self, field), dtype=float).ravel())
            if not 1 <= len(value) <= MAX_LEGS:
                raise ValueError(f"Gait.{field} must have one entry a leg (1 to {MAX_LEGS}), got {len(value)}")
            if not all(math.isfinite(v) for v in value):
                raise ValueError(f"Gait.{field} must be finite, got {value}")
            object.__setattr__(self, field, value)
        if len(self.phase) != len(self.offset):
            raise ValueError(f"Gait.phase and Gait.offset must have one entry a leg each, got {len(self.phase)} and "
                             f"{len(self.offset)}")  # fmt: skip

    @property
    def num_legs(self) -> int:
        return len(self.phase)

    @property
    def period(self) -> float:
        """s, one cycle of the legs; inf for a gait that does not oscillate."""
        return 2.0 * math.pi / abs(self.frequency) if self.frequency else math.inf

    def swapped(self) -> "Gait":
        """The same gait with the legs' phases in reverse order: for two legs the paper's reversed motion."""
        name = self.name[: -len("-swapped")] if self.name.endswith("-swapped") else self.name + "-swapped"
        return Gait(self.amplitude, self.frequency, self.phase[::-1], self.offset, name)

    def leg_targets(self, t):
        return sinusoid_targets(t, (self.amplitude,) * self.num_legs, self.frequency, self.phase, self.offset)

    def compiled_targets(self):
        """(kind, per-robot parameters, shared parameters) for :mod:`rrrobot_gym.compiled`."""
        return TARGETS_SINUSOID, ((self.amplitude,) * self.num_legs + (self.frequency,) + self.phase + self.offset), ()

    def robot(self, i: int) -> "Gait":
        """The targets of robot ``i`` of a batch: the same gait (see :meth:`RampTargets.robot`)."""
        return self

    def angles(self, times):
        """Target leg angles at an array of times, shape (T, legs), rad."""
        times = np.asarray(times, dtype=float)[..., None]
        return self.amplitude * np.sin(self.frequency * times + np.asarray(self.phase)) + np.asarray(self.offset)


def sinusoid_target(t, amplitude, frequency, phase, offset):
    """(angle, rate, acceleration) at time t (a float) of one leg's phi(t) = a sin(w t + beta) + o:
    the one sinusoid of the gaits (:class:`Gait`, ``gait_search.SinusoidGait``) and of the compiled
    stepper (:mod:`rrrobot_gym.compiled`)."""
    s, c = math.sin(frequency * t + phase), math.cos(frequency * t + phase)
    return amplitude * s + offset, amplitude * frequency * c, -amplitude * frequency * frequency * s


def sinusoid_targets(t, amplitude, frequency, phase, offset):
    """:func:`sinusoid_target` of every leg: ``amplitude``, ``phase`` and ``offset`` one a leg;
    (angles, rates, accelerations), each a tuple."""
    legs = [sinusoid_target(t, a, frequency, b, o) for a, b, o in zip(amplitude, phase, offset)]
    return tuple(v[0] for v in legs), tuple(v[1] for v in legs), tuple(v[2] for v in legs)


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
        if angles.ndim not in (1, 2) or not 1 <= angles.shape[-1] <= MAX_LEGS:
            raise ValueError(f"leg target angles must have shape (legs,) or (N, legs), got {angles.shape}")
        if not np.all(np.isfinite(angles)):
            raise ValueError("leg target angles contain NaN or inf")
        legs = angles.shape[-1]
        # (1, legs): one robot's targets, kept as numbers like (legs,): every robot of a batch takes them
        one = angles.ndim == 1 or angles.shape[0] == 1
        self._angles = tuple(angles.reshape(legs).tolist()) if one else tuple(angles[:, m].copy() for m in range(legs))
        self._still = (0.0,) * legs

    def leg_targets(self, t):
        return self._angles, self._still, self._still

    def compiled_targets(self):
        """(kind, per-robot parameters, shared parameters) for :mod:`rrrobot_gym.compiled`."""
        return TARGETS_HELD, self._angles, ()

    def robot(self, i: int) -> "HeldTargets":
        """The targets of robot ``i`` of a batch, on Python floats (see :meth:`RampTargets.robot`)."""
        if isinstance(self._angles[0], float):
            return self
        return HeldTargets([a[i] for a in self._angles])


def pd_torque(gains, leg_angles, leg_rates, targets):
    """The paper's PD servo, tau_k = kp (phi_d - phi) + kd (phid_d - phid), per leg (N m), a tuple."""
    angles, rates, _ = targets
    return tuple(gains.kp * (a - phi) + gains.kd * (r - rate) for a, r, phi, rate in zip(angles, rates, leg_angles, leg_rates))


def limit_torque(torque, leg_rates, torque_limit, rate_limit=None):
    """The torques a leg motor can give, per leg: at most ``torque_limit`` (N m) either way,
    and, with a no-load speed ``rate_limit`` (rad/s), no more than the torque-speed line of
    a DC motor at full voltage allows: tau in [-T (1 + w / W), T (1 - w / W)], w the leg's
    rate. So the motor pushes ever less as the leg speeds up and cannot drive it past W;
    it can always brake with up to T. The law's corners are rounded inside that envelope
    (:data:`CORNER_WIDTH`). With ``torque_limit`` None, ``torque`` unchanged (the paper's ideal servo).
    """
    if torque_limit is None:
        return torque
    return tuple(motor_torque(tau, rate, torque_limit, rate_limit) for tau, rate in zip(torque, leg_rates))


CORNER_WIDTH = 0.1
"""The corners where the servo's torque meets the motor's bounds are rounded over this fraction of
the stall torque T: the clip's min and max are :func:`_rounded_min`, inside the motor's envelope,
at most T / 60 from the clip (at a corner) and equal to it once T / 10 away. A real motor's torque
does not turn a sharp corner either (its current takes time to follow the driver), and a law with
corners puts kinks in the right-hand side, where RK4 loses its order: on the pivot the shipped
policy's 5 s windows erred 9 mm at the default step with them, 0.6 mm without. (The bounds' own
corner at zero speed, where the torque-speed line meets the stall torque, stays: rounding it too
bought nothing, docs/notes/servo_accuracy.md.)"""


def _rounded_min(a, b, width, inverse):
    """min(a, b) with its corner rounded: less by (width / 6) (1 - |a - b| / width)^3 where
    |a - b| < width (width / 6 at a = b), equal elsewhere; twice continuously differentiable.
    ``inverse`` is 1 / width (a product is cheaper than a quotient). Floats or arrays; the same
    operations on both, so the same bits."""
    near = 1.0 - abs(a - b) * inverse
    if isinstance(near, float):
        near = max(near, 0.0)
        return min(a, b) - (width / 6.0) * (near * near * near)
    near = np.maximum(near, 0.0)
    return np.minimum(a, b) - (width / 6.0) * (near * near * near)


def motor_torque(tau, rate, torque_limit, rate_limit=None):
    """One leg's part of :func:`limit_torque`: the servo's ``tau`` as the motor can give it at
    leg rate ``rate`` (floats, or arrays of a batch). Also compiled by :mod:`rrrobot_gym.compiled`."""
    high = low = torque_limit
    if rate_limit is not None:
        drop = rate * (torque_limit / rate_limit)  # (the quotient is the same for every evaluation)
        if isinstance(rate, float):
            high, low = min(high, torque_limit - drop), min(low, torque_limit + drop)
        else:
            high, low = np.minimum(high, torque_limit - drop), np.minimum(low, torque_limit + drop)
    width = CORNER_WIDTH * torque_limit
    inverse = 1.0 / width
    return _rounded_min(-_rounded_min(-tau, low, width, inverse), high, width, inverse)


class RampTargets:
    """Leg targets ramped linearly from ``start`` to ``end`` over [t0, t0 + duration], then held.

    A first-order hold of step-wise targets (an RL action per control step): the target angle is
    continuous, so a new action steps only the servo's rate term (by kd times the change of slope).
    ``start``/``end`` have shape (legs,) or (N, legs), rad.
    """

    def __init__(self, start, end, t0: float, duration: float):
        start = np.asarray(start, dtype=float)
        end = np.asarray(end, dtype=float)
        if start.shape != end.shape or start.ndim not in (1, 2) or not 1 <= start.shape[-1] <= MAX_LEGS:
            raise ValueError(f"ramp ends must both have shape (legs,) or (N, legs), got {start.shape} and {end.shape}")
        if not (math.isfinite(duration) and duration > 0.0):
            raise ValueError(f"ramp duration must be a positive number of seconds, got {duration}")
        self.t0, self.duration = float(t0), float(duration)
        legs = start.shape[-1]
        if start.ndim == 2 and start.shape[0] == 1:  # one robot's ramp: as (legs,), every robot of a batch takes it
            start, end = start[0], end[0]
        if start.ndim == 1:
            # One robot: Python floats throughout (the single env's every step; same arithmetic).
            a, b = start.tolist(), end.tolist()
            if not all(math.isfinite(v) for v in a + b):
                raise ValueError("ramp ends contain NaN or inf")
            change = [y - x for x, y in zip(a, b)]
            self._start, self._end, self._change = tuple(a), tuple(b), tuple(change)
            self._slope = tuple(v / duration for v in change)
            self._still = (0.0,) * legs
            return
        if not (np.all(np.isfinite(start)) and np.all(np.isfinite(end))):
            raise ValueError("ramp ends contain NaN or inf")
        change = end - start
        # The compiled stepper's (N, 4 legs) parameters in one piece, the numpy steppers' views of its columns.
        self._params = np.empty((len(start), 4 * legs))
        for j, part in enumerate((start, end, change, change / duration)):
            self._params[:, j * legs : (j + 1) * legs] = part
        columns = tuple(self._params.T)
        self._start, self._end = columns[0:legs], columns[legs:2 * legs]
        self._change, self._slope = columns[2 * legs:3 * legs], columns[3 * legs:4 * legs]
        self._still = (np.zeros(len(start)),) * legs

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
        return RampTargets([a[i] for a in self._start], [b[i] for b in self._end], self.t0, self.duration)

    def leg_targets(self, t):
        legs = [ramp_target(t, self.t0, self.duration, a, b, c, d)
                for a, b, c, d in zip(self._start, self._end, self._change, self._slope)]  # fmt: skip
        return tuple(v[0] for v in legs), tuple(v[1] for v in legs), self._still


def ramp_target(t, t0, duration, start, end, change, slope):
    """(angle, rate) at time t (a float) of one leg's :class:`RampTargets`: ``start``, ``end``,
    ``change`` (end - start) and ``slope`` (change / duration), floats or (N,) arrays. Also
    compiled by :mod:`rrrobot_gym.compiled`."""
    s = (t - t0) / duration
    # Closed at the end: RK4's last stage falls on t0 + duration up to rounding, and the
    # rate must not depend on which side of it rounding lands.
    if s > 1.0 + 1e-9:
        return end, 0.0 * slope
    if s < 0.0:
        s = 0.0
    return start + change * s, slope


KERNELS = (_rounded_min, motor_torque, ramp_target, sinusoid_target)
"""The functions :mod:`rrrobot_gym.compiled` compiles for the servo and the leg targets."""
