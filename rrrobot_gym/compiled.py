"""The compiled backend: RK4 with the leg servo, JIT-compiled by numba (an optional extra).

No second implementation of the physics: this module compiles :data:`rrrobot_gym.dynamics.KERNELS`
and :data:`rrrobot_gym.control.KERNELS` themselves (copies of the function objects whose globals
point at the compiled helpers).

RK4 is written here for a block of robots laid out one row per quantity (:func:`_block`), each
derivative evaluation a loop over the block that the compiler turns into SIMD instructions. It is
compiled for blocks of LANES robots (the lanes) and of one (a single env's). The arithmetic is
:func:`rrrobot_gym.integrators.rk4.step`'s, operation for operation, so every robot's result is the
numpy backend's one-robot result to the bit. A batch's remainder takes a padded block (at least
PADDED_MIN robots) or the one-robot block (docs/notes/layout.md). Robots are independent, so a
batch may be split across threads (``workers``) without changing a bit. The legs' layout is a
tuple whose length numba knows, so each leg count compiles a stepper of its own.

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

from . import control, dynamics, numerics, specialise

SUMMARY_ROWS = 6  # rows of a record's summary (rrrobot_gym.simulation.SUMMARY_KEYS), made by this stepper


def record_rows(num_legs: int) -> int:
    """Rows of a step record of a robot of ``num_legs`` legs, both backends: the torques (L), the
    ground's force (3), its normal and tangential parts, the tips' clearance (L), the leg rates (L)."""
    return 3 * num_legs + 5


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


def _copies(functions, wrap, namespace, suffix="", legs=None):
    """Copies of ``functions`` (sharing their code) in ``namespace``, each wrapped by ``wrap`` (numba's
    njit, or nothing) under its own name, so that each refers to the others' copies (numba resolves
    a function's globals when it compiles it). ``suffix`` is added to their qualified names, which
    numba's disk cache keys them by: copies compiled with other globals need names of their own.
    With ``legs``, their loops over the legs are unrolled (:func:`_unrolled`)."""
    for fn in functions:
        if legs is None:
            copy = types.FunctionType(fn.__code__, namespace, fn.__name__, fn.__defaults__, fn.__closure__)
        else:
            copy = _unrolled(fn, legs, namespace)
        copy.__qualname__ = fn.__qualname__ + suffix
        namespace[fn.__name__] = wrap(copy)
    return namespace


LEG_LOOP_BOUNDS = ("num_legs", "legs")
"""A loop ``for m in range(num_legs)`` (or ``legs``) runs over a robot's legs: :func:`_unrolled` unrolls it."""


def _unrolled(fn, legs: int, namespace):
    """A copy of ``fn`` (globals ``namespace``) with each loop over the legs (``for m in
    range(num_legs)``, :data:`LEG_LOOP_BOUNDS`) written out ``legs`` times, ``m`` a constant in each:
    the same operations in the same order. The compiler then sees each leg's rows of a work array
    as constant offsets, and keeps a block's robots in SIMD lanes: it does not unroll loops this
    long itself, and a loop inside the loop over a block's robots keeps that one scalar."""
    import ast
    import copy
    import inspect
    import textwrap

    class Unroll(ast.NodeTransformer):
        def visit_For(self, node):
            self.generic_visit(node)
            bound = node.iter
            if not (isinstance(bound, ast.Call) and isinstance(bound.func, ast.Name) and bound.func.id == "range"
                    and len(bound.args) == 1 and isinstance(bound.args[0], ast.Name)
                    and bound.args[0].id in LEG_LOOP_BOUNDS):  # fmt: skip
                return node
            if node.orelse or any(isinstance(n, (ast.Break, ast.Continue)) for n in ast.walk(node)):
                raise ValueError(f"{fn.__qualname__}: a loop over the legs with break, continue or else cannot be unrolled")
            body = []
            for m in range(legs):
                body.append(ast.Assign([ast.Name(node.target.id, ast.Store())], ast.Constant(m)))
                body.extend(copy.deepcopy(node.body))
            return body

    tree = ast.parse(textwrap.dedent(inspect.getsource(fn)))
    tree = ast.fix_missing_locations(Unroll().visit(tree))
    scope = {}
    exec(compile(tree, fn.__code__.co_filename, "exec"), namespace, scope)
    out = scope[fn.__name__]
    out.__defaults__ = fn.__defaults__
    return out


# The stepper. Plain Python here (it runs uncompiled too, slowly); :func:`_stepper` compiles copies
# whose globals are the compiled kernels, servo and targets.
derivative_kernel, to_momentum, from_momentum = dynamics.derivative_kernel, dynamics.to_momentum, dynamics.from_momentum
motor_torque, ramp_target, sinusoid_target = control.motor_torque, control.ramp_target, control.sinusoid_target
_HELD, _RAMP = control.TARGETS_HELD, control.TARGETS_RAMP
Constants = dynamics.Constants

# A block of BLOCK robots is stepped together in a work array w that holds one row of BLOCK values per
# quantity at fixed offsets (:func:`_rows`), so the compiler can see that the rows it writes never
# overlap those it reads, and takes the robots in SIMD lanes. Bit-identity with the numpy stepper
# needs the same order of operations: no fast-math, no fused multiply-adds, no libm trig. Two copies
# are compiled: BLOCK = LANES (the lanes) and BLOCK = 1 (one robot, the single env's).
LANES = 32
BLOCK = LANES  # (each compiled copy's own)
MOMENTUM = False  # (each compiled stepper's own: True on the pivot, dynamics.integrates_momentum)


def _rows(legs):
    """Offsets (in rows) of a block's work array for robots of ``legs`` legs: (state, stage state,
    k1, k2, k3, the last derivative, the legs' torques, the kernel's scratch, the record (its
    values, then the leg rates), the per-robot target parameters, each robot's own values, the
    rows in all). Constants where ``legs`` is (a tuple's length, to the compiler)."""
    n = 9 + 2 * legs
    drive = 6 * n
    scratch = drive + legs
    record = scratch + 4 * legs
    params = record + 3 * legs + 5
    robot = params + 4 * legs
    return 0, n, 2 * n, 3 * n, 4 * n, 5 * n, drive, scratch, record, params, robot, robot + ROBOT_ROWS


ROBOT_ROWS = len(Constants._fields) + 4
"""A robot's own values, in :func:`_robot`'s order: its Constants, kp, kd, torque limit, rate limit."""


def _leg_target(kind, p, at, step, shared, t, m, legs):
    """(angle, rate) of leg m's target at t, from the parameters p[at + j * step] of a target of
    ``kind`` (control.py's compiled_targets: held angles; a ramp's starts, ends, changes, slopes;
    a sinusoid's amplitudes, frequency, phases, offsets)."""
    if kind == _HELD:
        return p[at + m * step], 0.0
    if kind == _RAMP:
        return ramp_target(t, shared[0], shared[1], p[at + m * step], p[at + (legs + m) * step],
                           p[at + (2 * legs + m) * step], p[at + (3 * legs + m) * step])  # fmt: skip
    angle, rate, _ = sinusoid_target(t, p[at + m * step], p[at + legs * step], p[at + (legs + 1 + m) * step],
                                     p[at + (2 * legs + 1 + m) * step])  # fmt: skip
    return angle, rate


def _servo(angle, rate, phi, phidot, gains, torque_limit, rate_limit):
    """One leg's servo torque (simulation._stage_fns): the PD law, then the motor's limit if any."""
    tau = gains.kp * (angle - phi) + gains.kd * (rate - phidot)
    if torque_limit is None:
        return tau
    return motor_torque(tau, phidot, torque_limit, rate_limit)


def _lesser(a, b):
    """min(a, b), a NaN winning (as in numpy's min of an array)."""
    return b if b < a or b != b else a


def _greater(a, b):
    """max(a, b), a NaN winning (as in numpy's max of an array)."""
    return b if b > a or b != b else a


def _summarise(rows, summary, first, count, legs):
    """The summary of robots first .. first + count - 1 of the record ``rows`` (S, record_rows, N)
    into ``summary`` (6, N), made here while the block's record is still in cache: what
    StepRecord.summary computes from a record's arrays, the same numbers, sample by sample and leg
    by leg in the same order (simulation.SUMMARY_KEYS)."""
    for i in range(first, first + count):
        # (each starts at its operation's identity, which the first sample replaces exactly, NaN and inf too)
        least_normal = least_clearance = np.inf
        most_ratio = peak_torque = peak_rate = -np.inf
        squares = 0.0
        for s in range(rows.shape[0]):
            normal = rows[s, legs + 3, i]
            least_normal = _lesser(least_normal, normal)
            most_ratio = _greater(most_ratio, rows[s, legs + 4, i] / normal)
            torque = rows[s, 0, i]
            lowest, sample_squares, largest = rows[s, legs + 5, i], torque * torque, abs(torque)
            fastest = abs(rows[s, 2 * legs + 5, i])
            for m in range(1, legs):
                torque = rows[s, m, i]
                lowest = _lesser(lowest, rows[s, legs + 5 + m, i])
                sample_squares = sample_squares + torque * torque
                largest = _greater(largest, abs(torque))
                fastest = _greater(fastest, abs(rows[s, 2 * legs + 5 + m, i]))
            least_clearance = _lesser(least_clearance, lowest)
            squares = squares + sample_squares
            peak_torque = _greater(peak_torque, largest)
            peak_rate = _greater(peak_rate, fastest)
        summary[0, i], summary[1, i], summary[2, i] = least_normal, most_ratio, least_clearance
        summary[3, i], summary[4, i], summary[5, i] = squares, peak_torque, peak_rate


def _robot(a, at, stride, torque_limit, rate_limit):
    """(constants, gains, torque limit, rate limit) of the robot whose ROBOT_ROWS values are a[at],
    a[at + stride], ...; a limit None where ``torque_limit`` (``rate_limit``) is None, for every robot."""
    s = stride
    k = Constants(a[at], a[at + s], a[at + 2 * s], a[at + 3 * s], a[at + 4 * s], a[at + 5 * s], a[at + 6 * s],
                  a[at + 7 * s], a[at + 8 * s], a[at + 9 * s], a[at + 10 * s], a[at + 11 * s], a[at + 12 * s],
                  a[at + 13 * s], a[at + 14 * s], a[at + 15 * s], a[at + 16 * s], a[at + 17 * s], a[at + 18 * s],
                  a[at + 19 * s])  # fmt: skip
    gains = _Gains(a[at + 20 * s], a[at + 21 * s])
    return k, gains, _limit(torque_limit, a[at + 22 * s]), _limit(rate_limit, a[at + 23 * s])


def _limit(given, own):
    """None where ``given`` is None, else ``own`` (numba types a dead branch unless its condition is
    on a None: returning ``given`` keeps both branches a float where ``given`` is one)."""
    if given is None:
        return given
    return own


def _own(a, at, stride, k, gains, torque_limit, rate_limit):
    """(constants, gains, torque limit, rate limit): those given, or where k is None (a per-robot
    run) a robot's own, :func:`_robot`'s of a[at], a[at + stride], ...; the limits then None
    (none) or any float (each robot's own)."""
    if k is None:
        return _robot(a, at, stride, torque_limit, rate_limit)
    return k, gains, torque_limit, rate_limit


def _given(a, at, stride, k, gains, torque_limit, rate_limit):
    """:func:`_own` of the shared stepper (k never None): the values given. numba prunes ``k is None``
    only where k is None, so with :func:`_own` the shared stepper would compile the per-robot
    branch too, dead; with this (:func:`_stepper`) its code is the lanes' without per-robot values."""
    return k, gains, torque_limit, rate_limit


def _block_torques(w, t, k, gains, torque_limit, rate_limit, kind, params, shared, layout):
    """The servo's torques on the stage state, every robot of the block, into the torque rows
    (inlined where ``kind`` is a constant, so each kind of target has a loop of its own); k None:
    each robot's own gains and limits."""
    B, legs = BLOCK, len(layout)
    _, S, _, _, _, _, DRIVE, _, _, P, R, _ = _rows(legs)
    if params.shape[0] == 1:  # the same targets for every robot: once a stage
        for m in range(legs):
            angle, rate = _leg_target(kind, params[0], 0, 1, shared, t, m, legs)
            for i in range(B):
                _, g, tl, rl = _own(w, R * B + i, B, k, gains, torque_limit, rate_limit)
                w[(DRIVE + m) * B + i] = _servo(angle, rate, w[(S + 6 + m) * B + i], w[(S + 9 + legs + m) * B + i], g, tl, rl)
    else:
        for i in range(B):
            _, g, tl, rl = _own(w, R * B + i, B, k, gains, torque_limit, rate_limit)
            for m in range(legs):
                angle, rate = _leg_target(kind, w, P * B + i, B, shared, t, m, legs)
                w[(DRIVE + m) * B + i] = _servo(angle, rate, w[(S + 6 + m) * B + i], w[(S + 9 + legs + m) * B + i], g, tl, rl)


def _block_derivatives(w, k, gains, layout, record):
    """The stage state's derivative into the derivative rows, every robot of the block, and with
    ``record`` the record's values into its rows: one loop, so the compiler takes the robots in
    lanes (inlined where ``record`` is a constant: a flag read inside the loop would keep it
    scalar); k None: each robot's own constants."""
    B, legs = BLOCK, len(layout)
    _, S, _, _, _, D, DRIVE, X, REC, _, R, _ = _rows(legs)
    for i in range(B):
        lk, _, _, _ = _own(w, R * B + i, B, k, gains, None, None)
        derivative_kernel(w, S * B + i, D * B + i, B, lk, layout, DRIVE * B + i, X * B + i, False,
                          REC * B + i if record else -1, MOMENTUM)  # fmt: skip


def _block_stage(w, t, k, gains, torque_limit, rate_limit, kind, params, shared, layout, record):
    """The stage state's servo torques and derivative, every robot of the block; with ``record``,
    the record's values too."""
    if kind == _HELD:
        _block_torques(w, t, k, gains, torque_limit, rate_limit, _HELD, params, shared, layout)
    elif kind == _RAMP:
        _block_torques(w, t, k, gains, torque_limit, rate_limit, _RAMP, params, shared, layout)
    else:
        _block_torques(w, t, k, gains, torque_limit, rate_limit, kind, params, shared, layout)
    if record:
        _block_derivatives(w, k, gains, layout, True)
    else:
        _block_derivatives(w, k, gains, layout, False)


def _block_combine(w, legs, keep, scale):
    """Copy the last derivative to rows ``keep`` and set the stage state to y + scale * it."""
    B = BLOCK
    Y, S, _, _, _, D, _, _, _, _, _, _ = _rows(legs)
    for m in range((9 + 2 * legs) * B):  # one loop over every row's lanes: long enough to be vectorised, not unrolled
        d = w[D * B + m]
        w[keep * B + m] = d
        w[S * B + m] = w[Y * B + m] + scale * d


def _block_update(w, legs, sixth):
    """RK4's step from the four stages, then the quaternion back to unit length."""
    B = BLOCK
    Y, S, K1, K2, K3, D, _, _, _, _, _, _ = _rows(legs)
    for m in range((9 + 2 * legs) * B):
        w[Y * B + m] = w[Y * B + m] + sixth * (w[K1 * B + m] + 2.0 * (w[K2 * B + m] + w[K3 * B + m]) + w[D * B + m])
    for i in range(B):
        qw, qx, qy, qz = w[2 * B + i], w[3 * B + i], w[4 * B + i], w[5 * B + i]
        inv = 1.0 / np.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        w[2 * B + i], w[3 * B + i], w[4 * B + i], w[5 * B + i] = qw * inv, qx * inv, qy * inv, qz * inv
    for m in range((9 + 2 * legs) * B):
        w[S * B + m] = w[Y * B + m]


def _block_substep(w, first, t, h, k, gains, torque_limit, rate_limit, kind, params, shared, layout, rows, row):
    """One RK4 substep of the block in w, recorded into rows[row] (unless rows is empty)."""
    B, legs = BLOCK, len(layout)
    _, _, K1, K2, K3, _, _, _, REC, _, _, _ = _rows(legs)
    half, sixth = 0.5 * h, h / 6.0
    record = rows.shape[0] > 0
    _block_stage(w, t, k, gains, torque_limit, rate_limit, kind, params, shared, layout, record)
    if record:
        size = rows.shape[1]
        for m in range(legs):  # the leg rates, after the kernel's values, complete the record's rows
            for i in range(B):
                w[(REC + 2 * legs + 5 + m) * B + i] = w[(9 + legs + m) * B + i]
        flat = rows.reshape(-1)
        n = rows.shape[2]
        for j in range(size):  # rows REC .. REC + size - 1 are the record's, in its order
            for i in range(B):
                flat[(row * size + j) * n + first + i] = w[(REC + j) * B + i]
    _block_combine(w, legs, K1, half)
    _block_stage(w, t + half, k, gains, torque_limit, rate_limit, kind, params, shared, layout, False)
    _block_combine(w, legs, K2, half)
    _block_stage(w, t + half, k, gains, torque_limit, rate_limit, kind, params, shared, layout, False)
    _block_combine(w, legs, K3, h)
    _block_stage(w, t + h, k, gains, torque_limit, rate_limit, kind, params, shared, layout, False)
    _block_update(w, legs, sixth)


def _block(y, first, t, h, n_steps, k, gains, torque_limit, rate_limit, kind, params, shared, layout, rows, summary,
           robot):
    """Robots first .. first + BLOCK - 1 of y (N, 9 + 2L) together, in place, with the record and its
    summary; k None: each with its own values from ``robot`` (_batch's) into the block's rows."""
    B, legs = BLOCK, len(layout)
    n = 9 + 2 * legs
    Y, S, _, _, _, _, _, _, _, P, R, TOTAL = _rows(legs)
    w = np.zeros(TOTAL * B)
    for i in range(B):
        for j in range(n):
            w[(Y + j) * B + i] = y[first + i, j]
        if params.shape[0] > 1:
            for j in range(params.shape[1]):
                w[(P + j) * B + i] = params[first + i, j]
        if k is None:  # (robot is empty otherwise)
            for j in range(ROBOT_ROWS):
                w[(R + j) * B + i] = robot[(first + i) * ROBOT_ROWS + j]
    if MOMENTUM:  # (the pivot's: the body rows integrate the angular momentum, dynamics.integrates_momentum)
        for i in range(B):
            to_momentum(w, Y * B + i, B, _own(w, R * B + i, B, k, gains, None, None)[0], layout)
    w[S * B : (S + n) * B] = w[Y * B : (Y + n) * B]
    for step in range(n_steps):
        _block_substep(w, first, t, h, k, gains, torque_limit, rate_limit, kind, params, shared, layout, rows, step)
        t += h
    if MOMENTUM:
        for i in range(B):
            from_momentum(w, Y * B + i, B, _own(w, R * B + i, B, k, gains, None, None)[0], layout)
    for i in range(B):
        for j in range(n):
            y[first + i, j] = w[(Y + j) * B + i]
    if rows.shape[0]:
        _summarise(rows, summary, first, B, legs)


def _batch(y, t, h, n_steps, k, gains, torque_limit, rate_limit, kind, params, shared, layout, rows, summary, robot):
    """Every robot of y (N, 9 + 2L) in place; params (1 or N, P): the targets' parameters, shared or per
    robot. Every robot takes the constants k, gains and the limits given (None: no limit; ``robot``
    empty), or with k and gains None its own: ``robot`` (N * ROBOT_ROWS,) holds each robot's
    ROBOT_ROWS values (:func:`_robot`) in turn, and a limit is None (none) or any float (each robot's own).
    Whole blocks of LANES robots take the lanes; the rest (fewer than LANES), if at least
    PADDED_MIN, a block of their own padded with copies of the last (_padded), else one by one."""
    blocks, rest, padded, tasks = _partition(y.shape[0])
    for b in range(tasks):
        if b < blocks:
            _lanes(y, b * LANES, t, h, n_steps, k, gains, torque_limit, rate_limit, kind, params, shared, layout, rows,
                   summary, robot)  # fmt: skip
        elif padded:
            yp, pp, rp, sp, ap = _padded(y, blocks * LANES, rest, params, rows, summary, robot)
            _lanes(yp, 0, t, h, n_steps, k, gains, torque_limit, rate_limit, kind, pp, shared, layout, rp, sp, ap)
            _unpadded(y, rows, summary, blocks * LANES, rest, yp, rp, sp)
        else:
            i = blocks * LANES + (b - blocks)
            _single(y, i, t, h, n_steps, k, gains, torque_limit, rate_limit, kind, _robot_params(params, i), shared,
                    layout, rows, summary, robot)  # fmt: skip


def _robot_params(params, i):
    """Robot i's target parameters as a (1, P) block (every robot's, where they are shared)."""
    if params.shape[0] == 1:
        return params
    return params[i : i + 1]


def _partition(n):
    """How _batch shares n robots among tasks: (whole blocks of LANES, robots left over, whether
    those take a padded block, the number of tasks: the blocks, then the padded block or each
    robot left over)."""
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
    yp = np.empty((L, y.shape[1]))
    pp = np.empty((L if params.shape[0] > 1 else 1, params.shape[1]))
    for i in range(L):
        source = first + min(i, count - 1)
        for j in range(y.shape[1]):
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
        for j in range(y.shape[1]):
            y[first + i, j] = yp[i, j]
        for s in range(rp.shape[0]):
            for j in range(rp.shape[1]):
                rows[s, j, first + i] = rp[s, j, i]
        for j in range(sp.shape[0]):
            summary[j, first + i] = sp[j, i]


def _physics_shared(y, h, n_steps, scene, torque_limit, rate_limit, linear, params, dt, layout, rows, summary, robot):
    """The env step's physics (rrrobot_gym.envs.task.fused_step) for robots that share the config:
    from t = 0, the targets a ramp over ``dt`` (``linear``) or held, per robot ``params``; its
    constants and gains from ``scene`` (one array: cheaper to pass than tuples)."""
    k = Constants(scene[0], scene[1], scene[2], scene[3], scene[4], scene[5], scene[6], scene[7], scene[8], scene[9],
                  scene[10], scene[11], scene[12], scene[13], scene[14], scene[15], scene[16], scene[17], scene[18],
                  scene[19])  # fmt: skip
    _batch(y, 0.0, h, n_steps, k, _Gains(scene[20], scene[21]), torque_limit, rate_limit, _RAMP if linear else _HELD,
           params, np.array([0.0, dt]), layout, rows, summary, robot)  # fmt: skip


def _physics_own(y, h, n_steps, scene, torque_limit, rate_limit, linear, params, dt, layout, rows, summary, robot):
    """:func:`_physics_shared` for robots of their own values (``robot``, :func:`robot_rows`)."""
    _batch(y, 0.0, h, n_steps, None, None, torque_limit, rate_limit, _RAMP if linear else _HELD, params,
           np.array([0.0, dt]), layout, rows, summary, robot)  # fmt: skip


_BLOCK_FUNCTIONS = (_block_stage, _block)
"""The functions compiled twice, for BLOCK = LANES (:func:`_lanes`) and BLOCK = 1 (:func:`_single`).
The stage stays a call: inlined four times a substep, it made the first compile a quarter longer
for no speed."""
_BLOCK_INLINED = (_rows, _limit, _robot, _own, _block_torques, _block_derivatives, _block_substep)
"""Inlined into their callers (by LLVM), so that each loop has a constant kind and flag and a straight-line body."""
_BLOCK_LOOPS = (_block_combine, _block_update)
"""Inlined into :func:`_block_substep` by numba itself, before LLVM sees them, so that their rows are
constants where LLVM first meets their loops. Compiled on their own and inlined by LLVM, their loops
had been optimised with the rows unknown, which left them scalar (unrolled, not vectorised): 0.35 us
of a robot's 0.05 s at N = 4096, a sixth of the physics (docs/notes/family_throughput.md, "The
session after")."""
_STEPPER = (_leg_target, _servo, _lesser, _greater, _summarise, _partition, _padded_robot, _padded, _unpadded,
            _robot_params)  # fmt: skip
"""This module's other functions the compiled :func:`_batch` calls."""


def _plain_block(block: int):
    """:func:`_block` for blocks of ``block`` robots, uncompiled (what :func:`_stepper` compiles)."""
    namespace = dict(globals(), BLOCK=block)
    _copies(_BLOCK_INLINED + _BLOCK_LOOPS + _BLOCK_FUNCTIONS, lambda fn: fn, namespace)
    return namespace["_block"]


_lanes, _single = _plain_block(LANES), _plain_block(1)  # (plain Python; compiled: :func:`_stepper`'s copies)


SOURCES = (__file__, dynamics.__file__, control.__file__, numerics.__file__)
"""The files whose functions every stepper compiles (the env's step also its task's modules')."""


def cache_dir(sources=None, generated: str = ""):
    """Where compiled code is cached: one directory per content of the compiled sources (:data:`SOURCES`
    unless given, and the ``generated`` source), numba and Python (numba itself re-checks only a
    function's own file).
    ``$XDG_CACHE_HOME``/rrrobot_gym, else ~/.cache/rrrobot_gym."""
    import hashlib
    import platform

    import numba

    digest = hashlib.sha256(f"{numba.__version__} {sys.version} {platform.machine()}".encode())
    for path in sources or SOURCES:
        with open(path, "rb") as f:
            digest.update(f.read())
    digest.update(generated.encode())
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
def _stepper(per_robot: bool = False, task: tuple | None = None, legs: int = 2, kernel: str | None = None,
             momentum: bool = False):
    """The compiled :func:`_batch` for robots of ``legs`` legs (``per_robot``: a copy for robots of
    their own values, cached under a name of its own), releasing the GIL (:func:`integrate` shares a
    batch among threads); with
    ``task`` = (entry, kernels), the compiled ``entry`` instead (:func:`task_stepper`): loaded from
    the disk cache (:func:`cache_dir`) or compiled, with a line on stderr, once a process.
    ``kernel``: the source of one robot's specialised derivative kernel (:func:`specialised`) to
    run instead of the general one. ``momentum``: a stepper for the pivot, whose states' body rows
    it integrates as the angular momentum (:func:`rrrobot_gym.dynamics.integrates_momentum`)."""
    import numba

    entry, task_kernels = task if task is not None else (_batch, ())
    # (the task step also compiles the task's modules: its cache is named by their sources too)
    sources = None if task is None else (*SOURCES, *sorted({fn.__code__.co_filename for fn in (entry, *task_kernels)}))
    directory = cache_dir(sources, kernel or "")
    try:
        os.makedirs(directory, exist_ok=True)
        cache = os.access(directory, os.W_OK)
    except OSError:
        cache = False
    if cache:
        _prune_stale_caches(directory)
        _content_keyed_locator()
    # numba's cache files are named by the function's qualified name and keyed by its signature,
    name = entry.__name__ + ("_per_robot" if per_robot else "") + f"_{legs}_legs" + ("_momentum" if momentum else "")
    if not (cache and glob.glob(os.path.join(glob.escape(directory), "**", f"*.{name}-*.nbi"), recursive=True)):
        print(f"rrrobot_gym: compiling the numba stepper ({legs} legs){' (per-robot)' if per_robot else ''}{' (env step)' if task else ''}: up to about {COMPILE_SECONDS} s "
              f"on first use, cached after{'' if cache else ' (not here: ' + directory + ' is not writable)'}",
              file=sys.stderr, flush=True)  # fmt: skip
    previous = numba.config.CACHE_DIR
    numba.config.CACHE_DIR = directory  # read when a dispatcher is made, not later
    try:
        # numpy's error model: a blow-up gives inf/NaN (reported by advance by name), not an exception.
        njit = functools.partial(numba.njit, error_model="numpy", cache=cache)
        inline = functools.partial(njit, forceinline=True)  # inlined into the lanes' loops, which lets them vectorise
        namespace = dict(globals(), MOMENTUM=momentum)
        # numerics' functions on floats (its select and anywhere in their scalar forms), inlined
        scalar = {name: inline(fn) for name, fn in numerics.SCALAR.items()}
        scalar.update(_copies(numerics.KERNELS, inline, {**vars(numerics), **scalar}))
        kernels = _copies(dynamics.KERNELS, inline, {**vars(dynamics), **scalar}, f"_{legs}", legs)
        if kernel is not None:
            _compile_specialised(kernel, kernels, directory if cache else None, inline)
        namespace.update((name, kernels[name]) for name in ("derivative_kernel", "to_momentum", "from_momentum"))
        servo = _copies(control.KERNELS, njit, dict(vars(control)))
        namespace.update((fn.__name__, servo[fn.__name__]) for fn in control.KERNELS)
        # (copies with other globals, or unrolled for another leg count: names of their own in the cache)
        suffix = ("_per_robot" if per_robot else "") + f"_{legs}" + ("_momentum" if momentum else "")
        _copies(_STEPPER, njit, namespace, suffix)
        for block, entry_name in ((LANES, "_lanes"), (1, "_single")):  # the block stepper, for each BLOCK
            copy = dict(namespace, BLOCK=block)
            _copies(_BLOCK_INLINED, inline, copy, f"{suffix}_{block}", legs)
            _copies(_BLOCK_LOOPS, functools.partial(njit, inline="always"), copy, f"{suffix}_{block}", legs)
            if not per_robot:
                copy["_own"] = _copies((_given,), inline, copy, f"_{block}")["_given"]
            _copies(_BLOCK_FUNCTIONS, njit, copy, f"{suffix}_{block}", legs)
            namespace[entry_name] = copy["_block"]
        if task is None:
            return njit(_named_copy(_batch, namespace, name), nogil=True)
        # The task's own functions, each module's with its own globals, on floats: numerics' select
        # and anywhere in their scalar forms, and the functions compiled before them.
        compiled = dict(scalar)
        compiled["_quaternion_rows"] = _copies((dynamics.rotation_rows,), njit, dict(vars(dynamics)))["rotation_rows"]
        for module in dict.fromkeys(fn.__module__ for fn in task_kernels):
            functions = [fn for fn in task_kernels if fn.__module__ == module]
            compiled.update(_copies(functions, njit, {**functions[0].__globals__, **compiled}, f"_{legs}", legs))
        physics = _physics_own if per_robot else _physics_shared
        compiled["_physics"] = _copies((_batch, physics), njit, namespace, suffix)[physics.__name__]
        return njit(_named_copy(entry, {**entry.__globals__, **compiled}, name))
    finally:
        numba.config.CACHE_DIR = previous


def specialised(robot, model: str, momentum: bool | None = None) -> str | None:
    """The source of ``robot``'s specialised derivative kernel on ``model`` (``momentum``: whether the
    body rows hold the angular momentum; by default the steppers' choice, on the pivot) if it is one
    of :data:`rrrobot_gym.specialise.SPECIALISED`, else None (the general kernel)."""
    return specialise.kernel_source(robot, model, momentum) if robot in specialise.SPECIALISED else None


def _compile_specialised(source: str, kernels: dict, directory, wrap):
    """Put the compiled specialised kernel of ``source`` into ``kernels`` (the compiled kernels'
    namespace, whose ``sincos`` and ``_sqrt`` it calls) as ``derivative_kernel``. Its source goes to
    a file in the cache ``directory`` (None: not cached), which numba's cache needs to exist."""
    path = "<rrrobot_gym.specialise>"
    if directory is not None:
        path = os.path.join(directory, "specialised_kernel.py")
        if not os.path.exists(path):
            with open(path, "w") as f:
                f.write(source)
    exec(compile(source, path, "exec"), kernels)
    kernels["derivative_kernel"].__qualname__ = "derivative_kernel_specialised"
    kernels["derivative_kernel"] = wrap(kernels["derivative_kernel"])


def _named_copy(fn, namespace, name):
    """A copy of ``fn`` with the globals ``namespace``, under the qualified name ``name`` (its cache's)."""
    copy = types.FunctionType(fn.__code__, namespace, fn.__name__)
    copy.__qualname__ = name
    return copy


def task_stepper(per_robot: bool, entry, kernels: tuple, legs: int = 2, kernel: str | None = None, momentum: bool = False):
    """The compiled ``entry`` (``rrrobot_gym.envs.task.fused_step``: the env's whole step), which
    calls the physics (:func:`_physics_shared`, or :func:`_physics_own` where ``per_robot``) as
    ``_physics`` and the task's ``kernels`` (functions of the modules above this one, compiled from
    their own source, :data:`rrrobot_gym.numerics.SCALAR`'s forms on floats), one thread;
    ``kernel``, ``momentum``: :func:`_stepper`'s."""
    return _stepper(per_robot, (entry, tuple(kernels)), legs, kernel, momentum)


@functools.lru_cache(maxsize=32)
def _scene(robot, model, gains):
    """The constants of the equations of motion, the servo gains and the legs' layout, as the stepper takes them."""
    # (floats: the stepper's per-robot branch, typed though dead here, makes them of floats)
    k = dynamics.constants(robot, model)
    return Constants(*map(float, k)), _Gains(float(gains.kp), float(gains.kd)), dynamics.leg_layout(robot)


def robot_rows(scene, n: int):
    """(robot, limits): the per-robot stepper's values of ``n`` robots from a per-robot ``scene``
    (constants, gains, torque limit, rate limit; fields (N,) arrays or floats), ROBOT_ROWS a robot
    in :func:`_robot`'s order, and the limits it is given: None (none for any robot) or NaN (each
    robot's own)."""
    k, gains, torque_limits, rate_limits = scene
    robot = np.zeros((n, ROBOT_ROWS))  # (a limit of None stays 0, unread)
    for j, value in enumerate((*k, gains.kp, gains.kd, torque_limits, rate_limits)):
        if value is not None:
            robot[:, j] = value
    return robot.reshape(-1), tuple(None if limit is None else np.nan for limit in (torque_limits, rate_limits))


def integrate(config, targets, state, t0: float, h: float, n_steps: int, record: bool, workers: int = 1, scene=None):
    """:func:`rrrobot_gym.simulation.advance`'s integration on the compiled stepper: ``state``
    (9 + 2L,) or (N, 9 + 2L) after ``n_steps`` RK4 steps of ``h`` from ``t0``, the record's rows
    ((S, record_rows) for one robot, (S, record_rows, N) for a batch) or None, and the record's
    summary ((6,) or (6, N): :data:`rrrobot_gym.simulation.SUMMARY_KEYS`) or None. ``targets`` is
    what :func:`target_arrays` made of the leg-target source. With ``workers`` > 1 the robots are
    shared among that many threads. ``scene`` (constants, gains, torque limit, rate limit), fields
    (N,) arrays or floats, a limit None for none, gives each robot its own (``simulation.advance``'s
    ``robots``).
    """
    kind, params, shared = targets
    k, gains, layout = _scene(config.robot, config.model, config.gains)
    legs = len(layout)
    y = np.array(state, dtype=float, order="C").reshape(-1, 9 + 2 * legs)
    if params.shape[0] not in (1, y.shape[0]):
        raise ValueError(f"the leg targets are for {params.shape[0]} robots, the state has {y.shape[0]}")
    rows = np.empty((n_steps if record else 0, record_rows(legs), y.shape[0]))
    summary = np.empty((SUMMARY_ROWS if record else 0, y.shape[0]))
    momentum = dynamics.integrates_momentum(config.model)
    kernel = None if scene is not None else specialised(config.robot, config.model, momentum)
    step = _stepper(scene is not None, None, legs, kernel, momentum)
    robot, limits = (np.empty(0), (config.torque_limit, config.leg_rate_limit)) if scene is None else robot_rows(scene, len(y))

    def run(first, stop):  # robots first .. stop - 1, into their own arrays (one thread each)
        part = slice(first, stop)
        own = (None, None) if scene is not None else (k, gains)
        chunk = (y[part], float(t0), float(h), int(n_steps), *own, *limits, kind,
                 params if params.shape[0] == 1 else params[part], shared, layout, np.empty((rows.shape[0], rows.shape[1], stop - first)),
                 np.empty((summary.shape[0], stop - first)), robot[first * ROBOT_ROWS : stop * ROBOT_ROWS])  # fmt: skip
        step(*chunk)
        y[part], rows[:, :, part], summary[:, part] = chunk[0], chunk[-3], chunk[-2]

    # Threads take whole blocks of LANES robots (the last the rest), so each robot steps as it would
    # in one call: the same bits whatever the number of workers. (The stepper releases the GIL.)
    blocks = -(-len(y) // LANES)
    bounds = [min(len(y), LANES * (blocks * w // workers)) for w in range(workers + 1)]
    chunks = [(a, b) for a, b in zip(bounds, bounds[1:]) if b > a]
    if len(chunks) > 1:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(len(chunks)) as pool:
            for done in [pool.submit(run, a, b) for a, b in chunks]:
                done.result()
    else:
        run(0, len(y))
    out = y.reshape(np.shape(state))
    if not record:
        return out, None, None
    if np.ndim(state) == 1:
        return out, rows[:, :, 0], summary[:, 0]
    return out, rows, summary
