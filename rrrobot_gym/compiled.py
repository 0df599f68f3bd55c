"""The compiled backend: RK4 with the leg servo, JIT-compiled by numba (an optional extra).

No second implementation of the physics: this module compiles :data:`rrrobot_gym.dynamics.KERNELS`
and :data:`rrrobot_gym.control.KERNELS` themselves (copies of the function objects whose globals
point at the compiled helpers).

RK4 is written here for lanes (:func:`_lanes`): a block of LANES robots laid out one row per
quantity, each derivative evaluation a loop over the block that the compiler turns into SIMD
instructions. The arithmetic is :func:`rrrobot_gym.integrators.rk4.step`'s, operation for
operation, so every robot's result is the numpy backend's one-robot result to the bit. A batch's
remainder takes a padded block (at least PADDED_MIN robots) or :func:`_one_robot`, RK4 for one
robot's (13,) row, kept for the single env's speed (docs/notes/layout.md). Robots are independent,
so a batch may be split across threads (``workers``) without changing a bit.

Used by :func:`rrrobot_gym.simulation.advance` for the scenes of :func:`supports` and targets with
a ``compiled_targets()`` method (:mod:`rrrobot_gym.control`'s, ``gait_search.SinusoidGait``).
The compiled code is cached on disk in a directory named by the content of the compiled sources
(:func:`cache_dir`), so an edit to the equations never meets a stale build.
"""

from __future__ import annotations

import functools
import glob
import os
import sys
import types
from collections import namedtuple

import numpy as np

from . import control, dynamics, numerics

RECORD_ROWS = 11  # rows of a step record, both backends: torque (2), force (3), normal, tangential, clearance (2), leg rates (2)
SUMMARY_ROWS = 6  # rows of a record's summary (rrrobot_gym.simulation.SUMMARY_KEYS), made by this stepper

_Gains = namedtuple("_Gains", "kp kd")  # what pd_torque reads of a PDGains, in a form numba takes


@functools.lru_cache(maxsize=1)
def available() -> bool:
    """True if numba can be imported (``pip install "rrrobot_gym[fast]"``)."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


INTEGRATORS = ("rk4",)
"""The integrators compiled (in lanes of robots, SIMD)."""


def supports(config) -> bool:
    """True if the compiled stepper covers this :class:`~rrrobot_gym.simulation.SimConfig`'s scene
    (the targets are checked by :func:`target_arrays`)."""
    return config.integrator in INTEGRATORS and config.legs == "servo"


def target_arrays(targets):
    """(kind, per-robot parameters (M, P), shared parameters) of a leg-target source, M = 1 when
    every robot has the same targets; None for a source the compiled stepper does not know."""
    describe = getattr(targets, "compiled_targets", None)
    described = None if describe is None else describe()
    if described is None:
        return None
    kind, per_robot, shared = described
    if isinstance(per_robot, np.ndarray):  # (N, P) already
        return kind, per_robot, np.asarray(shared, dtype=float)
    if all(type(v) is float for v in per_robot):  # one set of targets (a gait, one robot's ramp)
        return kind, np.array([per_robot]), np.array(shared, dtype=float)
    columns = [np.asarray(v, dtype=float) for v in per_robot]
    rows = max((c.size for c in columns if c.ndim), default=1)
    params = np.empty((rows, len(columns)))
    for j, c in enumerate(columns):
        params[:, j] = c
    return kind, params, np.asarray(shared, dtype=float)


def _copies(functions, wrap, namespace, suffix=""):
    """Copies of ``functions`` (sharing their code) in ``namespace``, each wrapped by ``wrap`` (numba's
    njit, or nothing) under its own name, so that each refers to the others' copies (numba resolves
    a function's globals when it compiles it). ``suffix`` is added to their qualified names, which
    numba's disk cache keys them by: copies compiled with other globals need names of their own."""
    for fn in functions:
        copy = types.FunctionType(fn.__code__, namespace, fn.__name__, fn.__defaults__, fn.__closure__)
        copy.__qualname__ = fn.__qualname__ + suffix
        namespace[fn.__name__] = wrap(copy)
    return namespace


# The stepper. Plain Python here (it runs uncompiled too, slowly: ``prange`` is ``range``);
# :func:`_stepper` compiles copies whose globals are the compiled kernels, servo and targets.
prange = range
derivative_kernel, contact_kernel = dynamics.derivative_kernel, dynamics.contact_kernel
robot_derivative_kernel = dynamics.derivative_kernel  # (compiled called, not inlined: the one-robot stepper's)
pd_torque, motor_torque = control.pd_torque, control.motor_torque
ramp_targets, sinusoid_targets = control.ramp_targets, control.sinusoid_targets
_HELD, _RAMP = control.TARGETS_HELD, control.TARGETS_RAMP
Constants, ContactConstants = dynamics.Constants, dynamics.ContactConstants


def _leg_targets(kind, p, shared, t):
    if kind == _HELD:
        return (p[0], p[1]), (0.0, 0.0), (0.0, 0.0)
    if kind == _RAMP:
        return ramp_targets(t, shared[0], shared[1], (p[0], p[1]), (p[2], p[3]), (p[4], p[5]), (p[6], p[7]), (0.0, 0.0))
    return sinusoid_targets(t, (p[0], p[1]), p[2], (p[3], p[4]), (p[5], p[6]))


def _torque(c, t, gains, torque_limit, rate_limit, kind, p, shared):
    """The servo of simulation._stage_fns: the PD law on the targets at t, then the motor limit if any."""
    return _servo(c, _leg_targets(kind, p, shared, t), gains, torque_limit, rate_limit)


def _servo(c, targets, gains, torque_limit, rate_limit):
    tau = pd_torque(gains, (c[6], c[7]), (c[11], c[12]), targets)
    if torque_limit is None:
        return tau
    return motor_torque(tau[0], c[11], torque_limit, rate_limit), motor_torque(tau[1], c[12], torque_limit, rate_limit)


def _one_robot(y, t, h, n_steps, k, gains, torque_limit, rate_limit, kind, p, shared, rows, summary, i):
    """RK4 on robot i's state y (13,), in place, with its record into rows[:, :, i] and its summary
    into summary[:, i] (when rows has any): the lanes' arithmetic for one robot, kept for speed."""
    half, sixth = 0.5 * h, h / 6.0
    stage = np.empty(13)
    contact = np.empty(7)
    for step in range(n_steps):
        tau = _torque(y, t, gains, torque_limit, rate_limit, kind, p, shared)
        if rows.shape[0]:
            k1 = robot_derivative_kernel(y, tau, k, None, None, contact)
            rows[step, 0, i], rows[step, 1, i] = tau[0], tau[1]
            for j in range(7):
                rows[step, 2 + j, i] = contact[j]
            rows[step, 9, i], rows[step, 10, i] = y[11], y[12]
        else:
            k1 = robot_derivative_kernel(y, tau, k)
        for j in range(13):
            stage[j] = y[j] + half * k1[j]
        k2 = robot_derivative_kernel(stage, _torque(stage, t + half, gains, torque_limit, rate_limit, kind, p, shared), k)
        for j in range(13):
            stage[j] = y[j] + half * k2[j]
        k3 = robot_derivative_kernel(stage, _torque(stage, t + half, gains, torque_limit, rate_limit, kind, p, shared), k)
        for j in range(13):
            stage[j] = y[j] + h * k3[j]
        k4 = robot_derivative_kernel(stage, _torque(stage, t + h, gains, torque_limit, rate_limit, kind, p, shared), k)
        for j in range(13):
            y[j] = y[j] + sixth * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j])
        inv = 1.0 / np.sqrt(y[2] * y[2] + y[3] * y[3] + y[4] * y[4] + y[5] * y[5])
        y[2] *= inv
        y[3] *= inv
        y[4] *= inv
        y[5] *= inv
        t += h
    if rows.shape[0]:
        _summarise(rows, summary, i, 1)


def _lesser(a, b):
    """min(a, b), a NaN winning (as in numpy's min of an array)."""
    return b if b < a or b != b else a


def _greater(a, b):
    """max(a, b), a NaN winning (as in numpy's max of an array)."""
    return b if b > a or b != b else a


def _summarise(rows, summary, first, count):
    """The summary of robots first .. first + count - 1 of the record ``rows`` (S, 11, N) into
    ``summary`` (6, N), made here while the block's record is still in cache: what
    StepRecord.summary computes from a record's arrays, the same numbers, sample by sample in
    the same order (simulation.SUMMARY_KEYS)."""
    for i in range(first, first + count):
        # (each starts at its operation's identity, which the first sample replaces exactly, NaN and inf too)
        least_normal = least_clearance = np.inf
        most_ratio = peak_torque = peak_rate = -np.inf
        squares = 0.0
        for s in range(rows.shape[0]):
            least_normal = _lesser(least_normal, rows[s, 5, i])
            most_ratio = _greater(most_ratio, rows[s, 6, i] / rows[s, 5, i])
            least_clearance = _lesser(least_clearance, _lesser(rows[s, 7, i], rows[s, 8, i]))
            squares = squares + (rows[s, 0, i] * rows[s, 0, i] + rows[s, 1, i] * rows[s, 1, i])
            peak_torque = _greater(peak_torque, _greater(abs(rows[s, 0, i]), abs(rows[s, 1, i])))
            peak_rate = _greater(peak_rate, _greater(abs(rows[s, 9, i]), abs(rows[s, 10, i])))
        summary[0, i], summary[1, i], summary[2, i] = least_normal, most_ratio, least_clearance
        summary[3, i], summary[4, i], summary[5, i] = squares, peak_torque, peak_rate


# The lane stepper's work array w holds one row of LANES values per quantity at fixed offsets, so the
# compiler can see that the rows it writes never overlap those it reads. Bit-identity with the float
# stepper needs the same order of operations: no fast-math, no fused multiply-adds, no libm trig.
LANES = 32
_Y, _S, _K1, _K2, _K3, _D = 0, 13, 26, 39, 52, 65  # state, stage state, k1..k3, the last derivative
_P = 78  # per-robot target parameters (8)
_TAU, _C, _RATES = 86, 88, 95  # the record's rows: torques, contact values (7), leg rates
_ROWS = 97
_R = _ROWS  # with each robot's own values (k None): ROBOT_ROWS rows more, _robot's
ROBOT_ROWS = len(Constants._fields) + 5
"""A robot's own values, in :func:`_robot`'s order: its Constants, total mass, kp, kd, torque limit, rate limit."""


def _robot(a, at, stride, torque_limit, rate_limit):
    """(constants, contact constants, gains, torque limit, rate limit) of the robot whose ROBOT_ROWS
    values are a[at], a[at + stride], ...; a limit None where ``torque_limit`` (``rate_limit``) is
    None, for every robot. The contact constants shared with Constants are its values, the same
    numbers (dynamics.constants and contact_constants take them from the same RobotParams fields)."""
    s = stride
    k = Constants(a[at], a[at + s], a[at + 2 * s], a[at + 3 * s], a[at + 4 * s], a[at + 5 * s], a[at + 6 * s],
                  a[at + 7 * s], a[at + 8 * s], a[at + 9 * s], a[at + 10 * s], a[at + 11 * s], a[at + 12 * s],
                  a[at + 13 * s], a[at + 14 * s], a[at + 15 * s], a[at + 16 * s], a[at + 17 * s], a[at + 18 * s],
                  a[at + 19 * s])  # fmt: skip
    kc = ContactConstants(k.radius, k.leg_length, k.mass_tip, k.depth, k.gravity, a[at + 20 * s], k.mb_r)
    gains = _Gains(a[at + 21 * s], a[at + 22 * s])
    return k, kc, gains, _limit(torque_limit, a[at + 23 * s]), _limit(rate_limit, a[at + 24 * s])


def _limit(given, own):
    """None where ``given`` is None, else ``own`` (numba types a dead branch unless its condition is
    on a None: returning ``given`` keeps both branches a float where ``given`` is one)."""
    if given is None:
        return given
    return own


def _own(a, at, stride, k, kc, gains, torque_limit, rate_limit):
    """(constants, contact constants, gains, torque limit, rate limit): those given, or where k is
    None (a per-robot run) a robot's own, :func:`_robot`'s of a[at], a[at + stride], ...; the
    limits then None (none) or any float (each robot's own)."""
    if k is None:
        return _robot(a, at, stride, torque_limit, rate_limit)
    return k, kc, gains, torque_limit, rate_limit


def _given(a, at, stride, k, kc, gains, torque_limit, rate_limit):
    """:func:`_own` of the shared stepper (k never None): the values given. numba prunes ``k is None``
    only where k is None, so with :func:`_own` the shared stepper would compile the per-robot
    branch too, dead; with this (:func:`_stepper`) its code is the lanes' without per-robot values."""
    return k, kc, gains, torque_limit, rate_limit


def _lane_state(w, row, i):
    """Lane i's 13 state components, from rows row .. row + 12."""
    L = LANES
    return (
        w[row * L + i], w[(row + 1) * L + i], w[(row + 2) * L + i], w[(row + 3) * L + i], w[(row + 4) * L + i],
        w[(row + 5) * L + i], w[(row + 6) * L + i], w[(row + 7) * L + i], w[(row + 8) * L + i],
        w[(row + 9) * L + i], w[(row + 10) * L + i], w[(row + 11) * L + i], w[(row + 12) * L + i],
    )  # fmt: skip


def _lane_torques(w, t, k, kc, gains, torque_limit, rate_limit, kind, params, shared):
    """The servo's torques on the stage state, every lane, into _TAU (inlined where ``kind`` is a
    constant, so each kind of target has a loop of its own); k None: each lane's own gains and limits."""
    L = LANES
    if params.shape[0] == 1:  # the same targets for every robot: once a stage
        targets = _leg_targets(kind, params[0], shared, t)
        for i in range(L):
            _, _, g, tl, rl = _own(w, _R * L + i, L, k, kc, gains, torque_limit, rate_limit)
            tau = _servo(_lane_state(w, _S, i), targets, g, tl, rl)
            w[_TAU * L + i], w[(_TAU + 1) * L + i] = tau[0], tau[1]
    else:
        for i in range(L):
            p = (w[_P * L + i], w[(_P + 1) * L + i], w[(_P + 2) * L + i], w[(_P + 3) * L + i],
                 w[(_P + 4) * L + i], w[(_P + 5) * L + i], w[(_P + 6) * L + i], w[(_P + 7) * L + i])  # fmt: skip
            _, _, g, tl, rl = _own(w, _R * L + i, L, k, kc, gains, torque_limit, rate_limit)
            tau = _torque(_lane_state(w, _S, i), t, g, tl, rl, kind, p, shared)
            w[_TAU * L + i], w[(_TAU + 1) * L + i] = tau[0], tau[1]


def _lane_derivatives(w, k, kc, gains, record):
    """The stage state's derivative into _D, every lane, and with ``record`` its contact values
    (contact_kernel of the state and that derivative) into _C: one loop, so the compiler shares
    their common terms (inlined where ``record`` is a constant: a flag read inside the loop would
    keep it scalar); k None: each lane's own constants."""
    L = LANES
    for i in range(L):
        c = _lane_state(w, _S, i)
        lk, lkc, _, _, _ = _own(w, _R * L + i, L, k, kc, gains, None, None)
        d = derivative_kernel(c, (w[_TAU * L + i], w[(_TAU + 1) * L + i]), lk)
        for j in range(13):
            w[(_D + j) * L + i] = d[j]
        if record:
            f = contact_kernel(c, d, lkc)
            for j in range(7):
                w[(_C + j) * L + i] = f[j]


def _lane_stage(w, t, k, kc, gains, torque_limit, rate_limit, kind, params, shared, record):
    """The stage state's servo torques and derivative (into _D), every lane; with ``record``,
    the contact values too (into _C)."""
    if kind == _HELD:
        _lane_torques(w, t, k, kc, gains, torque_limit, rate_limit, _HELD, params, shared)
    elif kind == _RAMP:
        _lane_torques(w, t, k, kc, gains, torque_limit, rate_limit, _RAMP, params, shared)
    else:
        _lane_torques(w, t, k, kc, gains, torque_limit, rate_limit, kind, params, shared)
    if record:
        _lane_derivatives(w, k, kc, gains, True)
    else:
        _lane_derivatives(w, k, kc, gains, False)


def _lane_combine(w, keep, scale):
    """Copy the last derivative to rows ``keep`` and set the stage state to y + scale * it."""
    L = LANES
    for m in range(13 * L):  # one loop over every row's lanes: long enough to be vectorised, not unrolled
        d = w[_D * L + m]
        w[keep * L + m] = d
        w[_S * L + m] = w[_Y * L + m] + scale * d


def _lane_update(w, sixth):
    """RK4's step from the four stages, then the quaternion back to unit length."""
    L = LANES
    for m in range(13 * L):
        w[_Y * L + m] = w[_Y * L + m] + sixth * (w[_K1 * L + m] + 2.0 * (w[_K2 * L + m] + w[_K3 * L + m]) + w[_D * L + m])
    for i in range(L):
        qw, qx, qy, qz = w[2 * L + i], w[3 * L + i], w[4 * L + i], w[5 * L + i]
        inv = 1.0 / np.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        w[2 * L + i], w[3 * L + i], w[4 * L + i], w[5 * L + i] = qw * inv, qx * inv, qy * inv, qz * inv
    for m in range(13 * L):
        w[_S * L + m] = w[_Y * L + m]


def _lane_substep(w, first, t, h, k, kc, gains, torque_limit, rate_limit, kind, params, shared, rows, row):
    """One RK4 substep of the lanes in w, recorded into rows[row] (unless rows is empty)."""
    L = LANES
    half, sixth = 0.5 * h, h / 6.0
    record = rows.shape[0] > 0
    _lane_stage(w, t, k, kc, gains, torque_limit, rate_limit, kind, params, shared, record)
    if record:
        flat = rows.reshape(-1)
        for i in range(L):
            w[_RATES * L + i], w[(_RATES + 1) * L + i] = w[(_Y + 11) * L + i], w[(_Y + 12) * L + i]
        n = rows.shape[2]
        for m in range(RECORD_ROWS * L):  # rows _TAU .. _RATES + 1 are the record's, in its order
            j = m // L
            flat[(row * RECORD_ROWS + j) * n + first + m - j * L] = w[_TAU * L + m]
    _lane_combine(w, _K1, half)
    _lane_stage(w, t + half, k, kc, gains, torque_limit, rate_limit, kind, params, shared, False)
    _lane_combine(w, _K2, half)
    _lane_stage(w, t + half, k, kc, gains, torque_limit, rate_limit, kind, params, shared, False)
    _lane_combine(w, _K3, h)
    _lane_stage(w, t + h, k, kc, gains, torque_limit, rate_limit, kind, params, shared, False)
    _lane_update(w, sixth)


def _lanes(y, first, t, h, n_steps, k, kc, gains, torque_limit, rate_limit, kind, params, shared, rows, summary, robot):
    """Robots first .. first + LANES - 1 of y (N, 13) together, in place, with the record and its
    summary; k None: each with its own values from ``robot`` (_batch's) into rows _R .. of the lanes."""
    L = LANES
    w = np.zeros((_ROWS if k is not None else _R + ROBOT_ROWS) * L)
    for i in range(L):
        for j in range(13):
            w[(_Y + j) * L + i] = y[first + i, j]
        if params.shape[0] > 1:
            for j in range(params.shape[1]):
                w[(_P + j) * L + i] = params[first + i, j]
        if k is None:  # (robot is empty otherwise)
            for j in range(ROBOT_ROWS):
                w[(_R + j) * L + i] = robot[(first + i) * ROBOT_ROWS + j]
    w[_S * L : (_S + 13) * L] = w[_Y * L : (_Y + 13) * L]
    for step in range(n_steps):
        _lane_substep(w, first, t, h, k, kc, gains, torque_limit, rate_limit, kind, params, shared, rows, step)
        t += h
    for i in range(L):
        for j in range(13):
            y[first + i, j] = w[(_Y + j) * L + i]
    if rows.shape[0]:
        _summarise(rows, summary, first, L)


def _batch(y, t, h, n_steps, k, kc, gains, torque_limit, rate_limit, kind, params, shared, rows, summary, robot):
    """Every robot of y (N, 13) in place; params (1 or N, P): the targets' parameters, shared or per robot.
    Every robot takes the constants k, kc, gains and the limits given (None: no limit; ``robot``
    empty), or with k, kc and gains None its own: ``robot`` (N * ROBOT_ROWS,) holds each robot's
    ROBOT_ROWS values (:func:`_robot`) in turn, and a limit is None (none) or any float (each robot's own).
    Whole blocks of LANES robots take the lane stepper; the rest (fewer than LANES), if at least
    PADDED_MIN, a block of their own padded with copies of the last (_padded), else one by one."""
    shared_targets = params.shape[0] == 1
    blocks, rest, padded, tasks = _partition(y.shape[0])
    for b in prange(tasks):
        if b < blocks:
            _lanes(y, b * LANES, t, h, n_steps, k, kc, gains, torque_limit, rate_limit, kind, params, shared, rows, summary,
                   robot)
        elif padded:
            yp, pp, rp, sp, ap = _padded(y, blocks * LANES, rest, params, rows, summary, robot)
            _lanes(yp, 0, t, h, n_steps, k, kc, gains, torque_limit, rate_limit, kind, pp, shared, rp, sp, ap)
            _unpadded(y, rows, summary, blocks * LANES, rest, yp, rp, sp)
        else:
            i = blocks * LANES + (b - blocks)
            p = params[0] if shared_targets else params[i]
            ik, _, ig, itl, irl = _own(robot, i * ROBOT_ROWS, 1, k, kc, gains, torque_limit, rate_limit)
            _one_robot(y[i], t, h, n_steps, ik, ig, itl, irl, kind, p, shared, rows, summary, i)


def _partition(n):
    """How _batch shares n robots among tasks: (whole blocks of LANES, robots left over, whether
    those take a padded block, the number of tasks: the blocks, then the padded block or each
    robot left over). The task count is a plain value, computed before the loop: numba does not
    parallelise a prange whose bound is a conditional expression."""
    blocks, rest = n // LANES, n % LANES
    padded = rest >= PADDED_MIN
    return blocks, rest, padded, blocks + 1 if padded else blocks + rest


PADDED_MIN = 8
"""Fewer robots than a block, but at least this many, take a lane block padded with copies of the
last of them (whose results are dropped): no slower than the one-robot stepper from 8 on (physics
alone: equal at 8, 1.3x faster at 12, 1.7x at 16)."""


def _padded(y, first, count, params, rows, summary, robot):
    """(state, target parameters, record, summary, robots' own values) of one lane block
    holding robots first .. first + count - 1 of y, the rest of its LANES lanes copies of the last of them."""
    L = LANES
    yp = np.empty((L, 13))
    pp = np.empty((L if params.shape[0] > 1 else 1, params.shape[1]))
    for i in range(L):
        source = first + min(i, count - 1)
        for j in range(13):
            yp[i, j] = y[source, j]
        if params.shape[0] > 1:
            for j in range(params.shape[1]):
                pp[i, j] = params[source, j]
    if params.shape[0] == 1:
        for j in range(params.shape[1]):
            pp[0, j] = params[0, j]
    rp, sp = np.empty((rows.shape[0], rows.shape[1], L)), np.empty((summary.shape[0], L))
    return yp, pp, rp, sp, _padded_robot(robot, first, count)


def _padded_robot(robot, first, count):
    """_padded's copy of ``robot`` (_batch's), empty where it is."""
    out = np.empty(LANES * ROBOT_ROWS if robot.size else 0)
    for i in range(LANES if robot.size else 0):
        source = first + min(i, count - 1)
        for j in range(ROBOT_ROWS):
            out[i * ROBOT_ROWS + j] = robot[source * ROBOT_ROWS + j]
    return out


def _unpadded(y, rows, summary, first, count, yp, rp, sp):
    """A padded block's first ``count`` robots (state, record, summary) back into robots first .. of the batch."""
    for i in range(count):
        for j in range(13):
            y[first + i, j] = yp[i, j]
        for s in range(rp.shape[0]):
            for j in range(rp.shape[1]):
                rows[s, j, first + i] = rp[s, j, i]
        for j in range(sp.shape[0]):
            summary[j, first + i] = sp[j, i]


def _physics_shared(y, h, n_steps, scene, torque_limit, rate_limit, linear, params, dt, rows, summary, robot):
    """The env step's physics (rrrobot_gym.envs.task.fused_step) for robots that share the config:
    from t = 0, the targets a ramp over ``dt`` (``linear``) or held, per robot ``params``; its
    constants, contact constants and gains from ``scene`` (one array: cheaper to pass than tuples)."""
    k = Constants(scene[0], scene[1], scene[2], scene[3], scene[4], scene[5], scene[6], scene[7], scene[8], scene[9],
                  scene[10], scene[11], scene[12], scene[13], scene[14], scene[15], scene[16], scene[17], scene[18],
                  scene[19])  # fmt: skip
    kc = ContactConstants(scene[20], scene[21], scene[22], scene[23], scene[24], scene[25], scene[26])
    _batch(y, 0.0, h, n_steps, k, kc, _Gains(scene[27], scene[28]), torque_limit, rate_limit, _RAMP if linear else _HELD,
           params, np.array([0.0, dt]), rows, summary, robot)  # fmt: skip


def _physics_own(y, h, n_steps, scene, torque_limit, rate_limit, linear, params, dt, rows, summary, robot):
    """:func:`_physics_shared` for robots of their own values (``robot``, :func:`robot_rows`)."""
    _batch(y, 0.0, h, n_steps, None, None, None, torque_limit, rate_limit, _RAMP if linear else _HELD, params,
           np.array([0.0, dt]), rows, summary, robot)  # fmt: skip


_STEPPER = (_leg_targets, _servo, _torque, _lesser, _greater, _summarise, _one_robot, _partition, _padded_robot, _padded,
            _unpadded, _lane_stage, _lane_update, _lane_substep, _lanes)  # fmt: skip
"""This module's functions the compiled :func:`_batch` calls."""
_LANE_INLINED = (_limit, _robot, _own, _lane_state, _lane_torques, _lane_derivatives, _lane_combine)
"""Inlined into their callers' loops, so that each loop has a constant kind and flag and a straight-line body."""


SOURCES = (__file__, dynamics.__file__, control.__file__, numerics.__file__)
"""The files whose functions every stepper compiles (the env's step also its task's modules')."""


def cache_dir(sources=None):
    """Where compiled code is cached: one directory per content of the compiled sources (:data:`SOURCES`
    unless given), numba and Python (numba itself re-checks only a function's own file).
    ``$XDG_CACHE_HOME``/rrrobot_gym, else ~/.cache/rrrobot_gym."""
    import hashlib
    import platform

    import numba

    digest = hashlib.sha256(f"{numba.__version__} {sys.version} {platform.machine()}".encode())
    for path in sources or SOURCES:
        with open(path, "rb") as f:
            digest.update(f.read())
    root = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(root, "rrrobot_gym", "numba-" + digest.hexdigest()[:16])


@functools.lru_cache(maxsize=1)
def _content_keyed_locator():
    """Register (once) a numba cache locator for the code :func:`_stepper` compiles: its files go
    straight into the :func:`cache_dir` being compiled into, stamped with that directory's content
    digest. numba's own locator files them under a folder named by the source's path and stamps them
    with its modification time, so a copy of the package at another path (a Ray worker's unpacked
    working directory, a new virtual environment) would compile everything again."""
    from numba.core import caching
    from numba.core import config as numba_config

    class ContentKeyedLocator(caching.UserProvidedCacheLocator):
        def __init__(self, py_func, py_file):
            super().__init__(py_func, py_file)
            self._cache_path = self._directory = numba_config.CACHE_DIR

        def get_source_stamp(self):
            return os.path.basename(self._directory)  # numba-<digest of every compiled source>

        @classmethod
        def from_function(cls, py_func, py_file):
            directory = numba_config.CACHE_DIR
            # only while _stepper compiles into one of our cache directories
            if not (directory and os.path.basename(directory).startswith("numba-")
                    and os.path.basename(os.path.dirname(directory)) == "rrrobot_gym"):
                return None
            return super().from_function(py_func, py_file)

    caching.CacheImpl._locator_classes.insert(0, ContentKeyedLocator)


CACHE_UNUSED_DAYS = 30
"""A cache directory of other sources (an older install, an edited checkout) that no process has
used for this many days is removed when a stepper is made."""


def _prune_stale_caches(directory, unused_days: float = CACHE_UNUSED_DAYS, now: float | None = None) -> list:
    """Mark ``directory`` (a :func:`cache_dir`) used now (its modification time is its last use), and
    remove its sibling ``numba-*`` directories, left by other sources, not used for ``unused_days``.
    Best effort: what cannot be touched or removed is left. Returns the paths removed."""
    import shutil
    import time

    now = time.time() if now is None else now
    try:
        os.utime(directory, (now, now))
        parent = os.path.dirname(directory)
        siblings = [os.path.join(parent, name) for name in os.listdir(parent) if name.startswith("numba-")]
    except OSError:
        return []
    removed = []
    for path in siblings:
        try:
            stale = path != directory and os.path.isdir(path) and os.stat(path).st_mtime < now - unused_days * 86400.0
        except OSError:
            continue
        if stale:
            shutil.rmtree(path, ignore_errors=True)
            removed.append(path)
    return removed


COMPILE_SECONDS = 60
"""s, about the most compiling the stepper takes on first use, printed in the notice (docs/notes/layout.md)."""


@functools.lru_cache(maxsize=None)
def _stepper(parallel: bool, per_robot: bool = False, task: tuple | None = None):
    """The compiled :func:`_batch` (``per_robot``: a copy for robots of their own values, cached
    under a name of its own), threaded over robots if ``parallel``; with ``task`` = (entry, kernels),
    the compiled ``entry`` instead (:func:`task_stepper`): loaded from the disk cache (:func:`cache_dir`)
    or compiled, with a line on stderr, once a process."""
    import numba

    entry, task_kernels = task if task is not None else (_batch, ())
    # (the task step also compiles the task's modules: its cache is named by their sources too)
    sources = None if task is None else (*SOURCES, *sorted({fn.__code__.co_filename for fn in (entry, *task_kernels)}))
    directory = cache_dir(sources)
    try:
        os.makedirs(directory, exist_ok=True)
        cache = os.access(directory, os.W_OK)
    except OSError:
        cache = False
    if cache:
        _prune_stale_caches(directory)
        _content_keyed_locator()
    # numba's cache files are named by the function's qualified name and keyed by its signature,
    # not by parallel=: the threaded copy needs a name of its own, else one is loaded for the other
    name = entry.__name__ + ("_per_robot" if per_robot else "") + ("_threaded" if parallel else "")
    if not (cache and glob.glob(os.path.join(glob.escape(directory), "**", f"*.{name}-*.nbi"), recursive=True)):
        print(f"rrrobot_gym: compiling the numba stepper{' (per-robot)' if per_robot else ''}{' (env step)' if task else ''}{' (threaded)' if parallel else ''}: up to about {COMPILE_SECONDS} s "
              f"on first use, cached after{'' if cache else ' (not here: ' + directory + ' is not writable)'}",
              file=sys.stderr, flush=True)  # fmt: skip
    previous = numba.config.CACHE_DIR
    numba.config.CACHE_DIR = directory  # read when a dispatcher is made, not later
    try:
        # numpy's error model: a blow-up gives inf/NaN (reported by advance by name), not an exception.
        njit = functools.partial(numba.njit, error_model="numpy", cache=cache)
        inline = functools.partial(njit, forceinline=True)  # inlined into the lanes' loops, which lets them vectorise
        namespace = dict(globals(), prange=numba.prange)
        # numerics' functions on floats (its select and anywhere in their scalar forms), inlined
        scalar = {name: inline(fn) for name, fn in numerics.SCALAR.items()}
        scalar.update(_copies(numerics.KERNELS, inline, {**vars(numerics), **scalar}))
        kernels = _copies(dynamics.KERNELS, inline, {**vars(dynamics), **scalar})
        namespace.update(derivative_kernel=kernels["derivative_kernel"], contact_kernel=kernels["contact_kernel"])
        robot_kernels = _copies(dynamics.KERNELS, njit, {**vars(dynamics), **scalar})
        namespace["robot_derivative_kernel"] = robot_kernels["derivative_kernel"]
        servo = _copies(control.KERNELS, njit, dict(vars(control)))
        namespace.update((fn.__name__, servo[fn.__name__]) for fn in control.KERNELS)
        suffix = "_per_robot" if per_robot else ""  # (copies with other globals: names of their own in the cache)
        _copies(_LANE_INLINED, inline, namespace, suffix)
        if not per_robot:
            namespace["_own"] = _copies((_given,), inline, namespace)["_given"]
        _copies(_STEPPER, njit, namespace, suffix)
        if task is None:
            return njit(_named_copy(_batch, namespace, name), parallel=parallel)
        # The task's own functions, each module's with its own globals, on floats: numerics' select
        # and anywhere in their scalar forms, and the functions compiled before them.
        compiled = dict(scalar)
        compiled["_quaternion_rows"] = _copies((dynamics.rotation_rows,), njit, dict(vars(dynamics)))["rotation_rows"]
        for module in dict.fromkeys(fn.__module__ for fn in task_kernels):
            functions = [fn for fn in task_kernels if fn.__module__ == module]
            compiled.update(_copies(functions, njit, {**functions[0].__globals__, **compiled}))
        physics = _physics_own if per_robot else _physics_shared
        compiled["_physics"] = _copies((_batch, physics), njit, namespace, suffix)[physics.__name__]
        return njit(_named_copy(entry, {**entry.__globals__, **compiled}, name), parallel=parallel)
    finally:
        numba.config.CACHE_DIR = previous


def _named_copy(fn, namespace, name):
    """A copy of ``fn`` with the globals ``namespace``, under the qualified name ``name`` (its cache's)."""
    copy = types.FunctionType(fn.__code__, namespace, fn.__name__)
    copy.__qualname__ = name
    return copy


def task_stepper(per_robot: bool, entry, kernels: tuple):
    """The compiled ``entry`` (``rrrobot_gym.envs.task.fused_step``: the env's whole step), which
    calls the physics (:func:`_physics_shared`, or :func:`_physics_own` where ``per_robot``) as
    ``_physics`` and the task's ``kernels`` (functions of the modules above this one, compiled from
    their own source, :data:`rrrobot_gym.numerics.SCALAR`'s forms on floats), one thread."""
    return _stepper(False, per_robot, (entry, tuple(kernels)))


@functools.lru_cache(maxsize=32)
def _scene(robot, depth, gains):
    """The constants of the equations of motion and of the contact force, and the servo gains,
    as the stepper takes them."""
    # (floats: the stepper's per-robot branch, typed though dead here, makes them of floats)
    k, kc = dynamics.constants(robot, depth), dynamics.contact_constants(robot, depth)
    return Constants(*map(float, k)), ContactConstants(*map(float, kc)), _Gains(float(gains.kp), float(gains.kd))


def robot_rows(scene, n: int):
    """(robot, limits): the per-robot stepper's values of ``n`` robots from a per-robot ``scene``
    (constants, contact constants, gains, torque limit, rate limit; fields (N,) arrays or floats),
    ROBOT_ROWS a robot in :func:`_robot`'s order, and the limits it is given: None (none for any
    robot) or NaN (each robot's own)."""
    k, kc, gains, torque_limits, rate_limits = scene
    robot = np.zeros((n, ROBOT_ROWS))  # (a limit of None stays 0, unread)
    for j, value in enumerate((*k, kc.total_mass, gains.kp, gains.kd, torque_limits, rate_limits)):
        if value is not None:
            robot[:, j] = value
    return robot.reshape(-1), tuple(None if limit is None else np.nan for limit in (torque_limits, rate_limits))


def integrate(config, targets, state, t0: float, h: float, n_steps: int, record: bool, workers: int = 1, scene=None):
    """:func:`rrrobot_gym.simulation.advance`'s integration on the compiled stepper: ``state``
    (13,) or (N, 13) after ``n_steps`` RK4 steps of ``h`` from ``t0``, the record's rows
    ((S, 11) for one robot, (S, 11, N) for a batch) or None, and the record's summary ((6,) or
    (6, N): :data:`rrrobot_gym.simulation.SUMMARY_KEYS`) or None. ``targets`` is what
    :func:`target_arrays` made of the leg-target source. With ``workers`` > 1 the robots are
    shared among that many threads. ``scene`` (constants, contact constants, gains, torque limit,
    rate limit), fields (N,) arrays or floats, a limit None for none, gives each robot its own
    (``simulation.advance``'s ``robots``).
    """
    kind, params, shared = targets
    y = np.array(state, dtype=float, order="C").reshape(-1, dynamics.STATE_SIZE)
    if params.shape[0] not in (1, y.shape[0]):
        raise ValueError(f"the leg targets are for {params.shape[0]} robots, the state has {y.shape[0]}")
    rows = np.empty((n_steps if record else 0, RECORD_ROWS, y.shape[0]))
    summary = np.empty((SUMMARY_ROWS if record else 0, y.shape[0]))
    parallel = workers > 1 and y.shape[0] > 1
    step = _stepper(parallel) if scene is None else _stepper(parallel, True)  # (one lru_cache key for each stepper)
    if scene is None:
        k, kc, gains = _scene(config.robot, config.depth, config.gains)
        args = (y, float(t0), float(h), int(n_steps), k, kc, gains, config.torque_limit, config.leg_rate_limit, kind,
                params, shared, rows, summary, np.empty(0))  # fmt: skip
    else:
        robot, limits = robot_rows(scene, y.shape[0])
        args = (y, float(t0), float(h), int(n_steps), None, None, None, *limits, kind, params, shared, rows, summary,
                robot)  # fmt: skip
    if parallel:
        import numba

        previous = numba.get_num_threads()
        numba.set_num_threads(min(workers, numba.config.NUMBA_NUM_THREADS))
        try:
            step(*args)
        finally:
            numba.set_num_threads(previous)
    else:
        step(*args)
    out = y.reshape(np.shape(state))
    if not record:
        return out, None, None
    if np.ndim(state) == 1:
        return out, rows[:, :, 0], summary[:, 0]
    return out, rows, summary
