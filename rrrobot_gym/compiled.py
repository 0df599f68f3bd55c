"""The compiled stepper: RK4 (and the exponential ETDRK4-B) with the leg servo, JIT-compiled by numba (an optional extra).

Nothing here is a second implementation. The equations of motion are
:func:`rrrobot_gym.dynamics.derivative_kernel` and its helpers, and the servo, the motor
limit and the leg targets are the functions of :mod:`rrrobot_gym.control`: this module
compiles those very functions (copies of the function objects, sharing their code, whose
globals point at the compiled helpers instead of the Python ones). The stepper around them
does what :func:`rrrobot_gym.simulation.advance` does for one robot on Python floats, in the
same order of operations, so its results are those of the float stepper to the last bit
(``tests/test_compiled.py``), for every batch size; robots are independent, so a batch may be
split across threads (``workers``) without changing a bit either.

Batches are integrated LANES robots at a time (:func:`_lanes`): the state of a block is laid out
one row per quantity, and each derivative evaluation is a loop over the block's robots into which
the compiler inlines ``derivative_kernel`` and turns it into SIMD instructions (several robots per
instruction). The robots left over (fewer than LANES) take a block of their own padded with
copies of the last of them if they are at least PADDED_MIN, else the one-robot stepper
(:func:`_one_robot`). All give the float stepper's numbers to the bit.

Used by :func:`rrrobot_gym.simulation.advance` when ``SimConfig.backend`` allows it and the
scene is one it covers: servo legs, ``integrator="rk4"``, ``"rk4_locked"`` (RK4's stepper compiled
again with _LOCKED_RATE true: the locked rate in rows 8-10 while it steps) or ``"etdrk4b"`` (the exponential step,
compiling simulation's own servo algebra; lanes too, :func:`_etd_lanes`), and targets from
:class:`rrrobot_gym.control.RampTargets`, :class:`~rrrobot_gym.control.HeldTargets`,
:class:`~rrrobot_gym.control.Gait` or ``gait_search.SinusoidGait`` (any source with a
``compiled_targets()`` method). Everything else takes the numpy path.

Compiling takes several seconds the first time; the result is cached on disk in a directory
named by the content of the compiled sources (:func:`cache_dir`), so later processes load it
and an edit to the equations can never meet a stale build.
"""

from __future__ import annotations

import functools
import sys
import types
from collections import namedtuple

import numpy as np

from . import control, dynamics

_DYNAMICS = ("_sincos", "_leg_trig", "_rotation_products", "_configuration", "_configuration_rate", "_legs_share",
             "locked_share", "_sym_cofactors", "_sym_inverse", "_sym_apply", "_sym_solve", "tangential_force",
             "_contact_force", "derivative_and_mobility", "derivative_kernel")  # fmt: skip
_CONTROL = ("pd_torque", "motor_torque", "ramp_targets", "sinusoid_targets")
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


INTEGRATORS = ("rk4", "etdrk4b", "rk4_locked")
"""The integrators compiled: RK4, the exponential ETDRK4-B and RK4 in the body's locked rate, all
in lanes of robots (SIMD)."""


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


def _compiled_copies(module, names, njit, namespace=None, suffix=""):
    """The functions ``names`` of ``module`` compiled, in a copy of its namespace (or in ``namespace``)
    in which each refers to the compiled others (numba resolves a function's globals when it compiles it).
    ``suffix`` is added to their qualified names, which numba's disk cache keys them by: copies
    compiled with other globals need names of their own, else one is loaded for the other."""
    namespace = dict(vars(module)) if namespace is None else namespace
    for name in names:
        fn = getattr(module, name)
        copy = types.FunctionType(fn.__code__, namespace, name, fn.__defaults__, fn.__closure__)
        copy.__qualname__ = fn.__qualname__ + suffix
        namespace[name] = njit(copy)
    return namespace


# The stepper. Plain Python here (it runs uncompiled too, slowly: ``prange`` is ``range``);
# :func:`_stepper` compiles copies whose globals are the compiled kernel, servo and targets.
prange = range
_LOCKED_RATE = False
"""True in the copy of the RK4 stepper compiled for ``integrator="rk4_locked"``: rows 8-10 hold the
body's locked rate while it steps (converted at the ends of a call, as simulation's stepper
does). A global, so each copy is compiled with the branches it takes and no other."""
derivative_kernel, locked_share = dynamics.derivative_kernel, dynamics.locked_share
pd_torque, motor_torque = control.pd_torque, control.motor_torque
ramp_targets, sinusoid_targets = control.ramp_targets, control.sinusoid_targets
_HELD, _RAMP = control.TARGETS_HELD, control.TARGETS_RAMP


def _leg_targets(kind, p, shared, t):
    if kind == _HELD:
        return (p[0], p[1]), (0.0, 0.0), (0.0, 0.0)
    if kind == _RAMP:
        return ramp_targets(t, shared[0], shared[1], (p[0], p[1]), (p[2], p[3]), (p[4], p[5]), (p[6], p[7]), (0.0, 0.0))
    return sinusoid_targets(t, (p[0], p[1]), p[2], (p[3], p[4]), (p[5], p[6]))


def _torque(c, t, gains, torque_limit, rate_limit, kind, p, shared):
    """simulation._stage_fns' servo: the PD law on the targets at t, then the motor limit if any."""
    return _servo(c, _leg_targets(kind, p, shared, t), gains, torque_limit, rate_limit)


def _servo(c, targets, gains, torque_limit, rate_limit):
    tau = pd_torque(gains, (c[6], c[7]), (c[11], c[12]), targets)
    if torque_limit is None:
        return tau
    return motor_torque(tau[0], c[11], torque_limit, rate_limit), motor_torque(tau[1], c[12], torque_limit, rate_limit)


def _one_robot(y, t0, h0, n0, t, h, n_steps, k, gains, torque_limit, rate_limit, kind, p, shared, rows, summary, i):
    """simulation._rk4_floats on robot i's state y (13,), in place, with the record of simulation._Recorder
    into rows[:, :, i] and its summary into summary[:, i] (when rows has any): first n0 substeps of
    h0 from t0, recorded every other one (a graded start's halves), then n_steps of h from t."""
    stage = np.empty(13)
    contact = np.empty(7)
    if _LOCKED_RATE:
        _to_locked(y, k, 1.0)
    for step in range(n0):
        _robot_substep(y, t0, h0, k, gains, torque_limit, rate_limit, kind, p, shared, rows, i, step // 2 if step % 2 == 0 else -1, stage, contact)
        t0 += h0
    if _LOCKED_RATE and n0 and n_steps:  # back to Omega and again, as simulation's graded advance between its two parts
        _to_locked(y, k, -1.0)
        _to_locked(y, k, 1.0)
    for step in range(n_steps):
        _robot_substep(y, t, h, k, gains, torque_limit, rate_limit, kind, p, shared, rows, i, n0 // 2 + step, stage, contact)
        t += h
    if _LOCKED_RATE:
        _to_locked(y, k, -1.0)
    if rows.shape[0]:
        _summarise(rows, summary, i, 1)


def _first_derivative(y, tau, k, mobility, contact, rows, i, row, locked=False):
    """A step's first derivative under the torques tau (with ``mobility``, the legs' columns of
    M^-1 into it), and unless row < 0 (or rows is empty) the record of simulation._Recorder into
    rows[row, :, i]: the torques, the contact values and the leg rates. ``locked``: y's rows 8-10
    are the locked rate (derivative_kernel's ``locked``)."""
    if rows.shape[0] and row >= 0:
        d = derivative_kernel(y, tau, k, None, None, mobility, contact, locked)
        rows[row, 0, i], rows[row, 1, i] = tau[0], tau[1]
        for j in range(7):
            rows[row, 2 + j, i] = contact[j]
        rows[row, 9, i], rows[row, 10, i] = y[11], y[12]
        return d
    return derivative_kernel(y, tau, k, None, None, mobility, None, locked)


def _stage_derivative(c, tau, k):
    """derivative_kernel at a later RK4 stage, in the locked rate in the "rk4_locked" copy."""
    if _LOCKED_RATE:
        return derivative_kernel(c, tau, k, None, None, None, None, True)
    return derivative_kernel(c, tau, k)


def _robot_substep(y, t, h, k, gains, torque_limit, rate_limit, kind, p, shared, rows, i, row, stage, contact):
    """One RK4 substep of _one_robot, in place; recorded into rows[row, :, i] unless row < 0."""
    half, sixth = 0.5 * h, h / 6.0
    tau = _torque(y, t, gains, torque_limit, rate_limit, kind, p, shared)
    k1 = _first_derivative(y, tau, k, None, contact, rows, i, row, _LOCKED_RATE)
    for j in range(13):
        stage[j] = y[j] + half * k1[j]
    k2 = _stage_derivative(stage, _torque(stage, t + half, gains, torque_limit, rate_limit, kind, p, shared), k)
    for j in range(13):
        stage[j] = y[j] + half * k2[j]
    k3 = _stage_derivative(stage, _torque(stage, t + half, gains, torque_limit, rate_limit, kind, p, shared), k)
    for j in range(13):
        stage[j] = y[j] + h * k3[j]
    k4 = _stage_derivative(stage, _torque(stage, t + h, gains, torque_limit, rate_limit, kind, p, shared), k)
    for j in range(13):
        y[j] = y[j] + sixth * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j])
    inv = 1.0 / np.sqrt(y[2] * y[2] + y[3] * y[3] + y[4] * y[4] + y[5] * y[5])
    y[2] *= inv
    y[3] *= inv
    y[4] *= inv
    y[5] *= inv


# The exponential step (SimConfig(integrator="etdrk4b")): simulation._etdrk4b_rows on one robot,
# operation for operation, with the servo algebra compiled from simulation's own functions
# (_etd_setup, _etd_correction, _servo_rows: plain arithmetic on tuples). Whole blocks of robots
# take its lanes (_etd_lanes, below the RK4 lanes).


def _simulation_function(name):
    """simulation's function ``name``, looked up when called (simulation imports this module); the
    compiled stepper's namespace binds its compiled copy instead."""

    def call(*args):
        from . import simulation

        return getattr(simulation, name)(*args)

    call.__name__ = call.__qualname__ = name
    return call


_ETD_CALLED = ("_etd_setup", "_etd_correction", "_servo_rows", "_phi_scale", "_phi_taylor", "_phi_stiff", "_phi_doubling",
               "_per_leg_block", "_etd_finish")  # fmt: skip
"""simulation's servo algebra that the stepper below calls."""
for _name in _ETD_CALLED:
    globals()[_name] = _simulation_function(_name)
del _name
TAYLOR_TERMS = 13
"""Terms of Taylor's series of phi_4 (simulation._ServoExponential.TERMS), a constant so that the
lane stepper's loop over them unrolls: at ||X|| <= 1/2 the remainder is below 1e-15."""


def _one_robot_etd(y, t0, h0, n0, lead_doublings, t, h, n_steps, doublings, k, gains, torque_limit, rate_limit, kind, p,
                   shared, rows, summary, i):  # fmt: skip
    """_one_robot with ETDRK4-B: ``doublings`` (and ``lead_doublings`` for the lead's h0) = (terms,
    radius, levels) of simulation._ServoExponential at that step."""
    work = np.empty((6, 13))
    mobility = np.empty(9)
    contact = np.empty(7)
    _to_locked(y, k, 1.0)
    for step in range(n0):
        _etd_substep(y, t0, h0, lead_doublings, k, gains, torque_limit, rate_limit, kind, p, shared, rows, i,
                     step // 2 if step % 2 == 0 else -1, work, mobility, contact)  # fmt: skip
        t0 += h0
    if n0 and n_steps:  # back to Omega and again, as simulation's graded advance between its two parts
        _to_locked(y, k, -1.0)
        _to_locked(y, k, 1.0)
    for step in range(n_steps):
        _etd_substep(y, t, h, doublings, k, gains, torque_limit, rate_limit, kind, p, shared, rows, i, n0 // 2 + step,
                     work, mobility, contact)  # fmt: skip
        t += h
    _to_locked(y, k, -1.0)
    if rows.shape[0]:
        _summarise(rows, summary, i, 1)


def _etd_change(point, time, y, t, fu, g, pp, kp, kd, column, k, gains, torque_limit, rate_limit, kind, p, shared, out):
    """D = f(U) - f(u) - A (U - u) into ``out`` (simulation._etdrk4b_rows' change)."""
    linear = _servo_rows(g, pp, kp, kd, point[6] - y[6], point[7] - y[7], point[11] - y[11], point[12] - y[12], 1.0)
    dt = time - t
    d = derivative_kernel(point, _torque(point, time, gains, torque_limit, rate_limit, kind, p, shared), k, None, None, None,
                          None, True)  # fmt: skip
    for j in range(13):
        out[j] = d[j] - (linear[j] + dt * column[j]) - fu[j]


def _etd_substep(y, t, h, doublings, k, gains, torque_limit, rate_limit, kind, p, shared, rows, i, row, work, mobility, contact):
    """One ETDRK4-B step of _one_robot_etd, in place; recorded into rows[row, :, i] unless row < 0."""
    half_h, third, sixth = 0.5 * h, 1.0 / 3.0, 1.0 / 6.0
    kp, kd = gains.kp, gains.kd
    terms, radius, levels = doublings
    tau = _torque(y, t, gains, torque_limit, rate_limit, kind, p, shared)
    fu = _first_derivative(y, tau, k, mobility, contact, rows, i, row, True)
    _, rates, accels = _leg_targets(kind, p, shared, t)
    g, pp, elements, column, forcing_half, forcing = _etd_setup(mobility, kp, kd, h, levels, terms, radius, rates, accels)
    p2h, p3h, p2, p3, b23, b4 = elements
    u, base, d2, d3, d4, s = work[0], work[1], work[2], work[3], work[4], work[5]
    c = _etd_correction(g, pp, kp, kd, half_h, p2h, fu[6], fu[7], fu[11], fu[12])
    for j in range(13):
        u[j] = y[j] + half_h * (fu[j] + c[j] + forcing_half[j])
    _etd_change(u, t + half_h, y, t, fu, g, pp, kp, kd, column, k, gains, torque_limit, rate_limit, kind, p, shared, d2)
    c = _etd_correction(g, pp, kp, kd, half_h, p3h, d2[6], d2[7], d2[11], d2[12])
    for j in range(13):
        s[j] = u[j] + h * (0.5 * d2[j] + c[j])
    _etd_change(s, t + half_h, y, t, fu, g, pp, kp, kd, column, k, gains, torque_limit, rate_limit, kind, p, shared, d3)
    c = _etd_correction(g, pp, kp, kd, h, p2, fu[6], fu[7], fu[11], fu[12])
    for j in range(13):
        base[j] = y[j] + h * (fu[j] + c[j] + forcing[j])
    c = _etd_correction(g, pp, kp, kd, h, p3, d3[6], d3[7], d3[11], d3[12])
    for j in range(13):
        u[j] = base[j] + 2.0 * h * (0.5 * d3[j] + c[j])
    _etd_change(u, t + h, y, t, fu, g, pp, kp, kd, column, k, gains, torque_limit, rate_limit, kind, p, shared, d4)
    c23 = _etd_correction(g, pp, kp, kd, h, b23, d2[6] + d3[6], d2[7] + d3[7], d2[11] + d3[11], d2[12] + d3[12])
    c4 = _etd_correction(g, pp, kp, kd, h, b4, d4[6], d4[7], d4[11], d4[12])
    for j in range(13):
        y[j] = base[j] + h * (third * (d2[j] + d3[j]) + sixth * d4[j] + c23[j] + c4[j])
    inv = 1.0 / np.sqrt(y[2] * y[2] + y[3] * y[3] + y[4] * y[4] + y[5] * y[5])
    y[2] = y[2] * inv
    y[3] = y[3] * inv
    y[4] = y[4] * inv
    y[5] = y[5] * inv


def _batch_etd(y, t0, h0, n0, lead_doublings, t, h, n_steps, doublings, k, kc, gains, torque_limit, rate_limit, kind,
               params, shared, rows, summary):  # fmt: skip
    """_batch with ETDRK4-B: whole blocks of LANES robots by _etd_lanes, the rest in a padded block
    or by _one_robot_etd as _batch does (threaded over blocks and robots when compiled parallel)."""
    shared_targets = params.shape[0] == 1
    blocks, rest, padded, tasks = _partition(y.shape[0])
    for b in prange(tasks):
        if b < blocks:
            _etd_lanes(y, b * LANES, t0, h0, n0, lead_doublings, t, h, n_steps, doublings, k, kc, gains, torque_limit,
                       rate_limit, kind, params, shared, rows, summary)  # fmt: skip
        elif padded:
            yp, pp, rp, sp = _padded(y, blocks * LANES, rest, params, rows, summary)
            _etd_lanes(yp, 0, t0, h0, n0, lead_doublings, t, h, n_steps, doublings, k, kc, gains, torque_limit, rate_limit,
                       kind, pp, shared, rp, sp)  # fmt: skip
            _unpadded(y, rows, summary, blocks * LANES, rest, yp, rp, sp)
        else:
            i = blocks * LANES + (b - blocks)
            p = params[0] if shared_targets else params[i]
            _one_robot_etd(y[i], t0, h0, n0, lead_doublings, t, h, n_steps, doublings, k, gains, torque_limit, rate_limit,
                           kind, p, shared, rows, summary, i)  # fmt: skip


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


# The lane stepper: LANES robots at once, each derivative evaluation a loop over the robots whose
# body the compiler turns into SIMD instructions. Its work array w holds one row of LANES values
# per quantity (structure of arrays), at fixed offsets, so the compiler can see that the rows it
# writes never overlap the rows it reads. Everything is the float stepper's arithmetic, lane by
# lane, in the same order (no fast-math, no fused multiply-adds; the leg angles' cos and sin are
# dynamics._sincos, arithmetic, not libm), so each robot's result is the float stepper's to the bit.
LANES = 32
_Y, _S, _K1, _K2, _K3, _D = 0, 13, 26, 39, 52, 65  # state, stage state, k1..k3, the last derivative
_P = 78  # per-robot target parameters (8)
_TAU, _C, _RATES = 86, 88, 95  # the record's rows: torques, contact values (7), leg rates
_ROWS = 97


def _lane_state(w, row, i):
    """Lane i's 13 state components, from rows row .. row + 12."""
    L = LANES
    return (
        w[row * L + i], w[(row + 1) * L + i], w[(row + 2) * L + i], w[(row + 3) * L + i], w[(row + 4) * L + i],
        w[(row + 5) * L + i], w[(row + 6) * L + i], w[(row + 7) * L + i], w[(row + 8) * L + i],
        w[(row + 9) * L + i], w[(row + 10) * L + i], w[(row + 11) * L + i], w[(row + 12) * L + i],
    )  # fmt: skip


def _lane_torques(w, t, gains, torque_limit, rate_limit, kind, params, shared):
    """The servo's torques on the stage state, every lane, into _TAU (inlined where ``kind`` is a
    constant, so each kind of target has a loop of its own)."""
    L = LANES
    if params.shape[0] == 1:  # the same targets for every robot: once a stage
        targets = _leg_targets(kind, params[0], shared, t)
        for i in range(L):
            tau = _servo(_lane_state(w, _S, i), targets, gains, torque_limit, rate_limit)
            w[_TAU * L + i], w[(_TAU + 1) * L + i] = tau[0], tau[1]
    else:
        for i in range(L):
            p = (w[_P * L + i], w[(_P + 1) * L + i], w[(_P + 2) * L + i], w[(_P + 3) * L + i],
                 w[(_P + 4) * L + i], w[(_P + 5) * L + i], w[(_P + 6) * L + i], w[(_P + 7) * L + i])  # fmt: skip
            tau = _torque(_lane_state(w, _S, i), t, gains, torque_limit, rate_limit, kind, p, shared)
            w[_TAU * L + i], w[(_TAU + 1) * L + i] = tau[0], tau[1]


def _lane_derivatives(w, k, kc, record, locked):
    """The stage state's derivative into _D, every lane, and with ``record`` its contact values
    (contact_kernel of the state and that derivative) into _C: one loop, so the compiler shares
    their common terms (inlined where ``record`` and ``locked`` are constants: a flag read inside
    the loop would keep it scalar). ``locked``: rows 8-10 are the locked rate."""
    L = LANES
    for i in range(L):
        c = _lane_state(w, _S, i)
        if locked:
            # (rows 8-10 the locked rate: the contact values need the body rate, as simulation's recorder reads it)
            d, _, body = lane_derivative_and_mobility(c, (w[_TAU * L + i], w[(_TAU + 1) * L + i]), k, False, None, None,
                                                      None, True)  # fmt: skip
        else:
            d = lane_derivative_kernel(c, (w[_TAU * L + i], w[(_TAU + 1) * L + i]), k)
        for j in range(13):
            w[(_D + j) * L + i] = d[j]
        if record:
            if locked:
                f = lane_contact_kernel(_with_body(c, body[0], body[1], body[2]), _with_body(d, body[3], body[4], body[5]), kc)
            else:
                f = lane_contact_kernel(c, d, kc)
            for j in range(7):
                w[(_C + j) * L + i] = f[j]


def _lane_stage(w, t, k, kc, gains, torque_limit, rate_limit, kind, params, shared, record):
    """The stage state's servo torques and derivative (into _D), every lane; with ``record``,
    the contact values too (into _C)."""
    if kind == _HELD:
        _lane_torques(w, t, gains, torque_limit, rate_limit, _HELD, params, shared)
    elif kind == _RAMP:
        _lane_torques(w, t, gains, torque_limit, rate_limit, _RAMP, params, shared)
    else:
        _lane_torques(w, t, gains, torque_limit, rate_limit, kind, params, shared)
    if _LOCKED_RATE:
        if record:
            _lane_derivatives(w, k, kc, True, True)
        else:
            _lane_derivatives(w, k, kc, False, True)
    elif record:
        _lane_derivatives(w, k, kc, True, False)
    else:
        _lane_derivatives(w, k, kc, False, False)


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


def _lanes(y, first, t0, h0, n0, t, h, n_steps, k, kc, gains, torque_limit, rate_limit, kind, params, shared, rows, summary):
    """_one_robot for robots first .. first + LANES - 1 of y together (in place), with the record and its summary."""
    L = LANES
    w = np.zeros(_ROWS * L)
    _load_lanes(w, y, first, _Y, params, _P)
    if _LOCKED_RATE:
        _lanes_locked(w, _Y, k, 1.0)
    w[_S * L : (_S + 13) * L] = w[_Y * L : (_Y + 13) * L]
    for step in range(n0):
        _lane_substep(w, first, t0, h0, k, kc, gains, torque_limit, rate_limit, kind, params, shared, rows, step // 2 if step % 2 == 0 else -1)
        t0 += h0
    if _LOCKED_RATE and n0 and n_steps:  # back to Omega and again, as simulation's graded advance between its two parts
        _lanes_locked(w, _Y, k, -1.0)
        _lanes_locked(w, _Y, k, 1.0)
        w[_S * L : (_S + 13) * L] = w[_Y * L : (_Y + 13) * L]
    for step in range(n_steps):
        _lane_substep(w, first, t, h, k, kc, gains, torque_limit, rate_limit, kind, params, shared, rows, n0 // 2 + step)
        t += h
    if _LOCKED_RATE:
        _lanes_locked(w, _Y, k, -1.0)
    _store_lanes(y, w, first, _Y)
    if rows.shape[0]:
        _summarise(rows, summary, first, L)


def _load_lanes(w, y, first, row, params, param_row):
    """Robots first .. first + LANES - 1 of y into rows row .. row + 12 of w, and their target
    parameters (when each has its own) into rows param_row .."""
    L = LANES
    for i in range(L):
        for j in range(13):
            w[(row + j) * L + i] = y[first + i, j]
        if params.shape[0] > 1:
            for j in range(params.shape[1]):
                w[(param_row + j) * L + i] = params[first + i, j]


def _store_lanes(y, w, first, row):
    """Rows row .. row + 12 of w back into robots first .. first + LANES - 1 of y."""
    L = LANES
    for i in range(L):
        for j in range(13):
            y[first + i, j] = w[(row + j) * L + i]


def _lane_substep(w, first, t, h, k, kc, gains, torque_limit, rate_limit, kind, params, shared, rows, row):
    """One RK4 substep of the lanes in w, recorded into rows[row] unless row < 0 (or rows is empty)."""
    L = LANES
    half, sixth = 0.5 * h, h / 6.0
    record = rows.shape[0] > 0 and row >= 0
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


def _batch(y, t0, h0, n0, t, h, n_steps, k, kc, gains, torque_limit, rate_limit, kind, params, shared, rows, summary):
    """Every robot of y (N, 13) in place; params (1 or N, P): the targets' parameters, shared or per robot.
    Whole blocks of LANES robots take the lane stepper; the rest (fewer than LANES), if at least
    PADDED_MIN, a block of their own padded with copies of the last (_padded), else one by one.
    The schedule (n0 substeps of h0 from t0, then n_steps of h from t) is _one_robot's."""
    shared_targets = params.shape[0] == 1
    blocks, rest, padded, tasks = _partition(y.shape[0])
    for b in prange(tasks):
        if b < blocks:
            _lanes(y, b * LANES, t0, h0, n0, t, h, n_steps, k, kc, gains, torque_limit, rate_limit, kind, params, shared, rows, summary)
        elif padded:
            yp, pp, rp, sp = _padded(y, blocks * LANES, rest, params, rows, summary)
            _lanes(yp, 0, t0, h0, n0, t, h, n_steps, k, kc, gains, torque_limit, rate_limit, kind, pp, shared, rp, sp)
            _unpadded(y, rows, summary, blocks * LANES, rest, yp, rp, sp)
        else:
            i = blocks * LANES + (b - blocks)
            p = params[0] if shared_targets else params[i]
            _one_robot(y[i], t0, h0, n0, t, h, n_steps, k, gains, torque_limit, rate_limit, kind, p, shared, rows, summary, i)


def _partition(n):
    """How _batch and _batch_etd share n robots among tasks: (whole blocks of LANES, robots left
    over, whether those take a padded block, the number of tasks: the blocks, then the padded
    block or each robot left over). The task count is a plain value, computed before the loop:
    numba does not parallelise a prange whose bound is a conditional expression."""
    blocks, rest = n // LANES, n % LANES
    padded = rest >= PADDED_MIN
    return blocks, rest, padded, blocks + 1 if padded else blocks + rest


PADDED_MIN = 8
"""Fewer robots than a block, but at least this many, take a lane block padded with copies of the
last of them (whose results are dropped) instead of the one-robot stepper: from 8 on the padded
block was no slower in a scratch run (physics alone, side by side with the one-robot stepper: RK4
equal at 8, 1.3x at 12, 1.7x at 16; ETDRK4-B 1.2x at 8, 1.8x at 16; one at a time faster below;
`benchmarks.versus 00368c0` gives the env's side)."""


def _padded(y, first, count, params, rows, summary):
    """(state, target parameters, record, summary) of one lane block holding robots first ..
    first + count - 1 of y, the rest of its LANES lanes copies of the last of them."""
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
    return yp, pp, np.empty((rows.shape[0], rows.shape[1], L)), np.empty((summary.shape[0], L))


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


# The exponential step's lanes: ETDRK4-B (_etd_substep) on LANES robots at once, laid out as the
# lane stepper's (one row of LANES values per quantity). A step is a few loops over the robots, each
# with a straight-line body the compiler can vectorise: the servo torques (one loop per kind of
# target), the first evaluation with the legs' mobility, Taylor's series of phi_4, one loop per
# doubling (the levels, and which of them are stiff, are the scene's, the same for every robot),
# the step's setup, and the three later stages. Every number is the one _etd_substep computes, by
# the same functions of simulation's servo algebra in the same order, so each robot's result is
# the float stepper's to the bit.
_EY, _EF, _EU, _ES, _EB, _ED2, _ED3 = 0, 13, 26, 39, 52, 65, 78  # state, f(u), stage points (2), base, D2, D3
_EM = 91  # the legs' mobility (G's three, P's six)
_EPHI, _EHALF = 100, 120  # phi_0 .. phi_4 (four numbers each) of the current doubling, and of h L / 2
_EEL = 140  # the elements phi_3(hL/2), phi_3(hL), 2 phi_3 - 4 phi_4, 4 phi_4 - phi_3 (four numbers each)
_ECOL = 156  # A's time column (13)
_EP = 169  # per-robot target parameters (8)
_ETGT = 177  # the targets' rates and accelerations at the step's start (4)
_ETAU, _EC, _ERATES = 181, 183, 190  # the record's rows, in its order: torques, contact values (7), leg rates
_EROWS = 192


def _lane_phis(w, row, i):
    """Lane i's five phi-elements ((a0, a1), (b0, b1)) from rows row .. row + 19."""
    L = LANES
    return (
        ((w[row * L + i], w[(row + 1) * L + i]), (w[(row + 2) * L + i], w[(row + 3) * L + i])),
        ((w[(row + 4) * L + i], w[(row + 5) * L + i]), (w[(row + 6) * L + i], w[(row + 7) * L + i])),
        ((w[(row + 8) * L + i], w[(row + 9) * L + i]), (w[(row + 10) * L + i], w[(row + 11) * L + i])),
        ((w[(row + 12) * L + i], w[(row + 13) * L + i]), (w[(row + 14) * L + i], w[(row + 15) * L + i])),
        ((w[(row + 16) * L + i], w[(row + 17) * L + i]), (w[(row + 18) * L + i], w[(row + 19) * L + i])),
    )  # fmt: skip


def _lane_element(w, row, i):
    """Lane i's phi-element ((a0, a1), (b0, b1)) from rows row .. row + 3."""
    L = LANES
    return (w[row * L + i], w[(row + 1) * L + i]), (w[(row + 2) * L + i], w[(row + 3) * L + i])


def _put_element(w, row, i, element):
    """Store a phi-element into rows row .. row + 3 of lane i."""
    L = LANES
    (a0, a1), (b0, b1) = element
    w[row * L + i], w[(row + 1) * L + i], w[(row + 2) * L + i], w[(row + 3) * L + i] = a0, a1, b0, b1


def _put_rows(w, row, i, v):
    """Store 13 values into rows row .. row + 12 of lane i (written out: a loop indexing a tuple
    would keep a switch in the lanes' loops and stop their vectorisation)."""
    L = LANES
    w[row * L + i], w[(row + 1) * L + i], w[(row + 2) * L + i], w[(row + 3) * L + i] = v[0], v[1], v[2], v[3]
    w[(row + 4) * L + i], w[(row + 5) * L + i], w[(row + 6) * L + i], w[(row + 7) * L + i] = v[4], v[5], v[6], v[7]
    w[(row + 8) * L + i], w[(row + 9) * L + i], w[(row + 10) * L + i], w[(row + 11) * L + i] = v[8], v[9], v[10], v[11]
    w[(row + 12) * L + i] = v[12]


def _sum(x, y):
    """x + y for 13 rows."""
    return (x[0] + y[0], x[1] + y[1], x[2] + y[2], x[3] + y[3], x[4] + y[4], x[5] + y[5], x[6] + y[6], x[7] + y[7],
            x[8] + y[8], x[9] + y[9], x[10] + y[10], x[11] + y[11], x[12] + y[12])  # fmt: skip


def _difference(x, y):
    """x - y for 13 rows."""
    return (x[0] - y[0], x[1] - y[1], x[2] - y[2], x[3] - y[3], x[4] - y[4], x[5] - y[5], x[6] - y[6], x[7] - y[7],
            x[8] - y[8], x[9] - y[9], x[10] - y[10], x[11] - y[11], x[12] - y[12])  # fmt: skip


def _scaled(a, x):
    """a x for 13 rows."""
    return (a * x[0], a * x[1], a * x[2], a * x[3], a * x[4], a * x[5], a * x[6], a * x[7], a * x[8], a * x[9], a * x[10],
            a * x[11], a * x[12])  # fmt: skip


def _lane_mobility(w, i):
    """Lane i's G (three) and P (six), and G's trace and determinant as _etd_setup forms them."""
    L = LANES
    g = (w[_EM * L + i], w[(_EM + 1) * L + i], w[(_EM + 2) * L + i])
    p = (w[(_EM + 3) * L + i], w[(_EM + 4) * L + i], w[(_EM + 5) * L + i], w[(_EM + 6) * L + i], w[(_EM + 7) * L + i],
         w[(_EM + 8) * L + i])  # fmt: skip
    g11, g12, g22 = g
    return g, p, g11 + g22, g11 * g22 - g12 * g12


def _etd_lane_torques(w, row, t, gains, torque_limit, rate_limit, kind, params, shared, start):
    """The servo's torques on the state in rows row .., every lane, into _ETAU; with ``start``,
    the targets' rates and accelerations into _ETGT (inlined where ``kind`` and ``start`` are constants)."""
    L = LANES
    targets = _leg_targets(kind, params[0], shared, t)
    each = params.shape[0] > 1
    for i in range(L):
        if each:
            p = (w[_EP * L + i], w[(_EP + 1) * L + i], w[(_EP + 2) * L + i], w[(_EP + 3) * L + i],
                 w[(_EP + 4) * L + i], w[(_EP + 5) * L + i], w[(_EP + 6) * L + i], w[(_EP + 7) * L + i])  # fmt: skip
            targets = _leg_targets(kind, p, shared, t)
        tau = _servo(_lane_state(w, row, i), targets, gains, torque_limit, rate_limit)
        w[_ETAU * L + i], w[(_ETAU + 1) * L + i] = tau[0], tau[1]
        if start:
            _, rates, accels = targets
            w[_ETGT * L + i], w[(_ETGT + 1) * L + i] = rates[0], rates[1]
            w[(_ETGT + 2) * L + i], w[(_ETGT + 3) * L + i] = accels[0], accels[1]


def _etd_lane_targets(w, row, t, gains, torque_limit, rate_limit, kind, params, shared, start):
    """_etd_lane_torques with ``start`` and ``kind`` made constants of their own loops."""
    if start:
        _etd_lane_kinds(w, row, t, gains, torque_limit, rate_limit, kind, params, shared, True)
    else:
        _etd_lane_kinds(w, row, t, gains, torque_limit, rate_limit, kind, params, shared, False)


def _etd_lane_kinds(w, row, t, gains, torque_limit, rate_limit, kind, params, shared, start):
    """_etd_lane_torques with ``kind`` a constant of its own loop (``start`` one already)."""
    if kind == _HELD:
        _etd_lane_torques(w, row, t, gains, torque_limit, rate_limit, _HELD, params, shared, start)
    elif kind == _RAMP:
        _etd_lane_torques(w, row, t, gains, torque_limit, rate_limit, _RAMP, params, shared, start)
    else:
        _etd_lane_torques(w, row, t, gains, torque_limit, rate_limit, kind, params, shared, start)


def _etd_lane_first(w, k, kc, xkp, xkd, record):
    """The step's first evaluation (with the legs' mobility into _EM, and with ``record`` the
    contact values), every lane, and phi_0 .. phi_4 of h L / 2^levels by Taylor's series into _EPHI."""
    L = LANES
    for i in range(L):
        c = _lane_state(w, _EY, i)
        d, mobility, body = lane_derivative_and_mobility(c, (w[_ETAU * L + i], w[(_ETAU + 1) * L + i]), k, True, None, None,
                                                         None, True)  # fmt: skip
        _put_rows(w, _EF, i, d)
        w[_EM * L + i], w[(_EM + 1) * L + i], w[(_EM + 2) * L + i] = mobility[0], mobility[1], mobility[2]
        w[(_EM + 3) * L + i], w[(_EM + 4) * L + i], w[(_EM + 5) * L + i] = mobility[3], mobility[4], mobility[5]
        w[(_EM + 6) * L + i], w[(_EM + 7) * L + i], w[(_EM + 8) * L + i] = mobility[6], mobility[7], mobility[8]
        if record:
            f = lane_contact_kernel(_with_body(c, body[0], body[1], body[2]), _with_body(d, body[3], body[4], body[5]), kc)
            w[_EC * L + i], w[(_EC + 1) * L + i], w[(_EC + 2) * L + i], w[(_EC + 3) * L + i] = f[0], f[1], f[2], f[3]
            w[(_EC + 4) * L + i], w[(_EC + 5) * L + i], w[(_EC + 6) * L + i] = f[4], f[5], f[6]
            w[_ERATES * L + i], w[(_ERATES + 1) * L + i] = c[11], c[12]
        _, _, tg, dg = _lane_mobility(w, i)
        phis = _phi_taylor(tg, dg, xkp, xkd, TAYLOR_TERMS)
        for m in range(5):
            _put_element(w, _EPHI + 4 * m, i, phis[m])


def _etd_lane_doubling(w, xkp, xkd, stiff, last):
    """One doubling of the phi-elements in _EPHI, every lane (the elements before the last one
    kept in _EHALF: those of h L / 2)."""
    L = LANES
    for i in range(L):
        _, _, tg, dg = _lane_mobility(w, i)
        phis = _lane_phis(w, _EPHI, i)
        if last:
            for m in range(5):
                _put_element(w, _EHALF + 4 * m, i, phis[m])
        phis = _phi_doubling(phis, tg, dg, xkp, xkd, stiff)
        for m in range(5):
            _put_element(w, _EPHI + 4 * m, i, phis[m])


def _etd_lane_setup(w, kp, kd, h):
    """_etd_setup's rest (_etd_finish), the second stage's point into _EU and the base into _EB, every lane."""
    L = LANES
    half_h = 0.5 * h
    for i in range(L):
        g, pp, _, _ = _lane_mobility(w, i)
        rates = (w[_ETGT * L + i], w[(_ETGT + 1) * L + i])
        accels = (w[(_ETGT + 2) * L + i], w[(_ETGT + 3) * L + i])
        half = _per_leg_block(_lane_phis(w, _EHALF, i), 0.5 * h)
        whole = _per_leg_block(_lane_phis(w, _EPHI, i), h)
        g, pp, elements, column, forcing_half, forcing = _etd_finish(g, pp, half, whole, kp, kd, h, rates, accels)
        p2h, p3h, p2, p3, b23, b4 = elements
        y = _lane_state(w, _EY, i)
        fu = _lane_state(w, _EF, i)
        # (each x + a (b + c + e) of _etd_substep, as x + (a ((b + c) + e)): the same roundings)
        c = _etd_correction(g, pp, kp, kd, half_h, p2h, fu[6], fu[7], fu[11], fu[12])
        _put_rows(w, _EU, i, _sum(y, _scaled(half_h, _sum(_sum(fu, c), forcing_half))))
        c = _etd_correction(g, pp, kp, kd, h, p2, fu[6], fu[7], fu[11], fu[12])
        _put_rows(w, _EB, i, _sum(y, _scaled(h, _sum(_sum(fu, c), forcing))))
        _put_element(w, _EEL, i, p3h)
        _put_element(w, _EEL + 4, i, p3)
        _put_element(w, _EEL + 8, i, b23)
        _put_element(w, _EEL + 12, i, b4)
        _put_rows(w, _ECOL, i, column)


def _etd_lane_change(w, row, out, i, dt, k, kp, kd):
    """D = f(U) - f(u) - A (U - u) for lane i's point U in rows row .. into rows out .. (_etd_change);
    returns the lane's G and P."""
    L = LANES
    point = _lane_state(w, row, i)
    y = _lane_state(w, _EY, i)
    g, pp, _, _ = _lane_mobility(w, i)
    linear = _servo_rows(g, pp, kp, kd, point[6] - y[6], point[7] - y[7], point[11] - y[11], point[12] - y[12], 1.0)
    d = lane_derivative_kernel(point, (w[_ETAU * L + i], w[(_ETAU + 1) * L + i]), k, None, None, None, None, True)
    _put_rows(w, out, i, _difference(_difference(d, _sum(linear, _scaled(dt, _lane_state(w, _ECOL, i)))), _lane_state(w, _EF, i)))
    return g, pp


def _etd_lane_stage(w, stage, t, h, k, kp, kd):
    """The later stages, every lane: D at the point of stage 2, 3 or 4 (its torques in _ETAU), and
    the next point, or (stage 4) the step's result into _EY, the quaternion back to unit length."""
    L = LANES
    half_h, third, sixth = 0.5 * h, 1.0 / 3.0, 1.0 / 6.0
    dt = (t + (h if stage == 4 else half_h)) - t  # the stage's time less the step's, as _etd_change forms it
    for i in range(L):
        if stage == 2:
            g, pp = _etd_lane_change(w, _EU, _ED2, i, dt, k, kp, kd)
            d2 = _lane_state(w, _ED2, i)
            c = _etd_correction(g, pp, kp, kd, half_h, _lane_element(w, _EEL, i), d2[6], d2[7], d2[11], d2[12])
            _put_rows(w, _ES, i, _sum(_lane_state(w, _EU, i), _scaled(h, _sum(_scaled(0.5, d2), c))))
        elif stage == 3:
            g, pp = _etd_lane_change(w, _ES, _ED3, i, dt, k, kp, kd)
            d3 = _lane_state(w, _ED3, i)
            c = _etd_correction(g, pp, kp, kd, h, _lane_element(w, _EEL + 4, i), d3[6], d3[7], d3[11], d3[12])
            _put_rows(w, _EU, i, _sum(_lane_state(w, _EB, i), _scaled(2.0 * h, _sum(_scaled(0.5, d3), c))))
        else:
            g, pp = _etd_lane_change(w, _EU, _ES, i, dt, k, kp, kd)  # D4 where the third stage's point was
            d2, d3, d4 = _lane_state(w, _ED2, i), _lane_state(w, _ED3, i), _lane_state(w, _ES, i)
            c23 = _etd_correction(g, pp, kp, kd, h, _lane_element(w, _EEL + 8, i), d2[6] + d3[6], d2[7] + d3[7],
                                  d2[11] + d3[11], d2[12] + d3[12])  # fmt: skip
            c4 = _etd_correction(g, pp, kp, kd, h, _lane_element(w, _EEL + 12, i), d4[6], d4[7], d4[11], d4[12])
            step = _sum(_sum(_sum(_scaled(third, _sum(d2, d3)), _scaled(sixth, d4)), c23), c4)
            _put_rows(w, _EY, i, _sum(_lane_state(w, _EB, i), _scaled(h, step)))
            qw, qx, qy, qz = w[(_EY + 2) * L + i], w[(_EY + 3) * L + i], w[(_EY + 4) * L + i], w[(_EY + 5) * L + i]
            inv = 1.0 / np.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
            w[(_EY + 2) * L + i], w[(_EY + 3) * L + i], w[(_EY + 4) * L + i], w[(_EY + 5) * L + i] = qw * inv, qx * inv, qy * inv, qz * inv


def _etd_lane_substep(w, first, t, h, doublings, k, kc, gains, torque_limit, rate_limit, kind, params, shared, rows, row):
    """One ETDRK4-B step of the lanes in w (_etd_substep on each), recorded into rows[row] unless row < 0."""
    L = LANES
    kp, kd = gains.kp, gains.kd
    _, radius, levels = doublings
    record = rows.shape[0] > 0 and row >= 0
    _etd_lane_targets(w, _EY, t, gains, torque_limit, rate_limit, kind, params, shared, True)
    xkp, xkd = _phi_scale(kp, kd, h, levels)
    if record:
        _etd_lane_first(w, k, kc, xkp, xkd, True)
        flat = rows.reshape(-1)
        n = rows.shape[2]
        for m in range(RECORD_ROWS * L):  # rows _ETAU .. _ERATES + 1 are the record's, in its order
            j = m // L
            flat[(row * RECORD_ROWS + j) * n + first + m - j * L] = w[_ETAU * L + m]
    else:
        _etd_lane_first(w, k, kc, xkp, xkd, False)
    for level in range(levels):
        if _phi_stiff(radius, levels, level):
            _etd_lane_doubling(w, xkp, xkd, True, level == levels - 1)
        else:
            _etd_lane_doubling(w, xkp, xkd, False, level == levels - 1)
        xkd, xkp = 2.0 * xkd, 4.0 * xkp
    _etd_lane_setup(w, kp, kd, h)
    half_h = 0.5 * h
    _etd_lane_targets(w, _EU, t + half_h, gains, torque_limit, rate_limit, kind, params, shared, False)
    _etd_lane_stage(w, 2, t, h, k, kp, kd)
    _etd_lane_targets(w, _ES, t + half_h, gains, torque_limit, rate_limit, kind, params, shared, False)
    _etd_lane_stage(w, 3, t, h, k, kp, kd)
    _etd_lane_targets(w, _EU, t + h, gains, torque_limit, rate_limit, kind, params, shared, False)
    _etd_lane_stage(w, 4, t, h, k, kp, kd)


def _to_locked(y, k, sign):
    """simulation._to_locked on one robot's row y, in place."""
    s = locked_share(y, k)
    y[8], y[9], y[10] = y[8] + sign * s[0], y[9] + sign * s[1], y[10] + sign * s[2]


def _lanes_locked(w, row, k, sign):
    """_to_locked for every lane of the state rows row .. row + 12."""
    L = LANES
    for i in range(L):
        s = locked_share(_lane_state(w, row, i), k)
        for j in range(3):
            w[(row + 8 + j) * L + i] += sign * s[j]


def _with_body(c, a, b, d):
    """13 rows c with rows 8-10 replaced by (a, b, d)."""
    return (c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], a, b, d, c[11], c[12])


def _etd_lanes(y, first, t0, h0, n0, lead_doublings, t, h, n_steps, doublings, k, kc, gains, torque_limit, rate_limit,
               kind, params, shared, rows, summary):  # fmt: skip
    """_one_robot_etd for robots first .. first + LANES - 1 of y together (in place), with the record and its summary."""
    L = LANES
    w = np.zeros(_EROWS * L)
    _load_lanes(w, y, first, _EY, params, _EP)
    _lanes_locked(w, _EY, k, 1.0)
    for step in range(n0):
        _etd_lane_substep(w, first, t0, h0, lead_doublings, k, kc, gains, torque_limit, rate_limit, kind, params, shared,
                          rows, step // 2 if step % 2 == 0 else -1)  # fmt: skip
        t0 += h0
    if n0 and n_steps:  # back to Omega and again, as simulation's graded advance between its two parts
        _lanes_locked(w, _EY, k, -1.0)
        _lanes_locked(w, _EY, k, 1.0)
    for step in range(n_steps):
        _etd_lane_substep(w, first, t, h, doublings, k, kc, gains, torque_limit, rate_limit, kind, params, shared, rows,
                          n0 // 2 + step)  # fmt: skip
        t += h
    _lanes_locked(w, _EY, k, -1.0)
    _store_lanes(y, w, first, _EY)
    if rows.shape[0]:
        _summarise(rows, summary, first, L)


_STEPPER = ("_leg_targets", "_servo", "_torque", "_lesser", "_greater", "_summarise", "_one_robot", "_lanes",
            "_load_lanes", "_store_lanes", "_partition", "_padded", "_unpadded", "_etd_change", "_etd_substep",
            "_one_robot_etd", "_etd_lane_substep", "_etd_lanes", "_to_locked", "_lanes_locked")  # fmt: skip
_ETD_ALGEBRA = ("_servo_response", "_g_product", "_l_product", "_x_times", "_phis_from_phi4", "_per_l", "_per_leg_block",
                "_doubled", "_servo_phi", "_phi_scale", "_phi_taylor", "_phi_stiff", "_phi_doubling", "_servo_rows", "_g_apply",
                "_leg_function", "_etd_correction", "_combine_rows", "_etd_finish", "_etd_setup")  # fmt: skip
"""simulation's functions of the exponential step that the compiled stepper compiles (copies sharing their code)."""
_STEPPER_INLINED = ("_first_derivative", "_stage_derivative", "_robot_substep")  # into _one_robot's loops, as the loop body it was
_LANE_INLINED = ("_lane_state", "_lane_torques", "_lane_derivatives", "_lane_combine")  # into their callers' loops
_LANE_CALLED = ("_lane_stage", "_lane_update", "_lane_substep")
_ETD_LANE_INLINED = ("_with_body", "_lane_phis", "_lane_element", "_put_element", "_put_rows", "_sum", "_difference", "_scaled",
                     "_lane_mobility", "_etd_lane_torques", "_etd_lane_targets", "_etd_lane_kinds", "_etd_lane_first",
                     "_etd_lane_doubling", "_etd_lane_setup", "_etd_lane_change", "_etd_lane_stage")  # fmt: skip
"""Inlined into the exponential step's lanes, so that each loop has a constant kind, stage or flag and a
straight-line body."""


def _lane_kernels(njit):
    """derivative_kernel, derivative_and_mobility and contact_kernel compiled by ``njit`` (copies sharing their code)."""
    namespace = _compiled_copies(dynamics, _DYNAMICS + ("contact_kernel",), njit)
    return namespace["derivative_kernel"], namespace["derivative_and_mobility"], namespace["contact_kernel"]


lane_derivative_kernel, lane_derivative_and_mobility = dynamics.derivative_kernel, dynamics.derivative_and_mobility
lane_contact_kernel = dynamics.contact_kernel


def cache_dir(sources=None):
    """Where compiled code is cached: one directory per content of the compiled sources (this
    module, dynamics, control, simulation), numba and Python. numba itself re-checks only a function's own
    file, so an edit to the equations would otherwise meet a stale stepper; here any edit, or a
    new numba, makes a new directory. ``$XDG_CACHE_HOME``/rrrobot_gym, else ~/.cache/rrrobot_gym."""
    import hashlib
    import os
    import platform

    import numba

    from . import simulation  # (imported here: simulation imports this module)

    digest = hashlib.sha256(f"{numba.__version__} {sys.version} {platform.machine()}".encode())
    for path in sources or (__file__, dynamics.__file__, control.__file__, simulation.__file__):
        with open(path, "rb") as f:
            digest.update(f.read())
    root = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(root, "rrrobot_gym", "numba-" + digest.hexdigest()[:16])


CACHE_UNUSED_DAYS = 30
"""A cache directory of other sources (an older install, an edited checkout) that no process has
used for this many days is removed when a stepper is made."""


def _prune_stale_caches(directory, unused_days: float = CACHE_UNUSED_DAYS, now: float | None = None) -> list:
    """Mark ``directory`` (a :func:`cache_dir`) used now, and remove its sibling ``numba-*``
    directories not used for ``unused_days`` (each process marks its own when it makes a
    stepper: a directory's modification time is its last use). Every source edit or upgrade
    makes a new directory of a few MB, which nothing else would ever remove. Best effort:
    a directory that cannot be touched or removed is left. Returns the paths removed."""
    import os
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


def _stepper(parallel: bool, integrator: str = "rk4"):
    """The compiled :func:`_batch` (RK4) or :func:`_batch_etd` (ETDRK4-B), threaded over robots if
    ``parallel``; cached on disk (:func:`cache_dir`) and in memory."""
    if integrator not in INTEGRATORS:
        raise ValueError(f"the compiled stepper integrates with {' or '.join(INTEGRATORS)}, not {integrator!r}")
    return _compiled_stepper(bool(parallel), integrator)


@functools.lru_cache(maxsize=None)
def _compiled_stepper(parallel: bool, integrator: str):
    """:func:`_stepper`'s work, once a process per (parallel, integrator)."""
    import os

    import numba

    from . import simulation

    directory = cache_dir()
    try:
        os.makedirs(directory, exist_ok=True)
        cache = os.access(directory, os.W_OK)
    except OSError:
        cache = False
    if cache:
        _prune_stale_caches(directory)
    previous = numba.config.CACHE_DIR
    numba.config.CACHE_DIR = directory  # read when a dispatcher is made, not later
    try:
        # numpy's error model: a blow-up gives inf/NaN (reported by advance by name), not an exception.
        njit = functools.partial(numba.njit, error_model="numpy", cache=cache)
        namespace = dict(globals())
        locked = integrator == "rk4_locked"
        namespace["_LOCKED_RATE"] = locked
        own = "_locked" if locked else ""  # this module's copies, compiled with _LOCKED_RATE true, are named apart
        compiled_dynamics = _compiled_copies(dynamics, _DYNAMICS, njit)
        namespace["derivative_kernel"] = compiled_dynamics["derivative_kernel"]
        namespace["locked_share"] = compiled_dynamics["locked_share"]
        # the lane stepper's kernels are inlined into its loops, which is what lets them vectorise
        inline = functools.partial(njit, forceinline=True)
        lane_kernels = _lane_kernels(inline)
        namespace["lane_derivative_kernel"], namespace["lane_derivative_and_mobility"], namespace["lane_contact_kernel"] = lane_kernels
        _compiled_copies(sys.modules[__name__], _LANE_INLINED, inline, namespace, own)
        _compiled_copies(sys.modules[__name__], _LANE_CALLED, njit, namespace, own)
        compiled_control = _compiled_copies(control, _CONTROL, njit)
        namespace.update((name, compiled_control[name]) for name in _CONTROL)
        namespace["prange"] = numba.prange
        etd = _compiled_copies(simulation, _ETD_ALGEBRA, inline)  # inlined, so the lanes' loops vectorise
        _compiled_copies(sys.modules[__name__], _ETD_LANE_INLINED, inline, namespace, own)
        namespace.update((name, etd[name]) for name in _ETD_CALLED)
        _compiled_copies(sys.modules[__name__], _STEPPER_INLINED, inline, namespace, own)
        _compiled_copies(sys.modules[__name__], _STEPPER, njit, namespace, own)
        source = _batch_etd if integrator == "etdrk4b" else _batch
        batch = types.FunctionType(source.__code__, namespace, source.__name__)
        # numba's cache files are named by the function's qualified name and keyed by its
        # signature, not by parallel= or globals: the threaded and the locked copies need names
        # of their own, else one version is loaded for another
        batch.__qualname__ = source.__name__ + own + ("_threaded" if parallel else "")
        return njit(batch, parallel=parallel)
    finally:
        numba.config.CACHE_DIR = previous


@functools.lru_cache(maxsize=32)
def _scene(robot, depth, gains):
    """The constants of the equations of motion and of the contact force, and the servo gains,
    as the stepper takes them."""
    return dynamics.constants(robot, depth), dynamics.contact_constants(robot, depth), _Gains(float(gains.kp), float(gains.kd))


def integrate(config, targets, state, t0: float, h: float, n_steps: int, record: bool, workers: int = 1, lead=None):
    """:func:`rrrobot_gym.simulation.advance`'s integration on the compiled stepper: ``state``
    (13,) or (N, 13) after ``n_steps`` RK4 steps of ``h`` from ``t0``, the record's rows
    ((S, 11) for one robot, (S, 11, N) for a batch) or None, and the record's summary ((6,) or
    (6, N): :data:`rrrobot_gym.simulation.SUMMARY_KEYS`) or None. ``targets`` is what
    :func:`target_arrays` made of the leg-target source. With ``workers`` > 1 the robots are
    shared among that many threads. ``lead`` = (t_lead, h_lead, n_lead), if given, is a start
    taken first: n_lead (even) substeps of h_lead from t_lead, every other one recorded (a
    graded start's halves, on the substep grid), before the ``n_steps`` of ``h`` from ``t0``.
    """
    kind, params, shared = targets
    y = np.array(state, dtype=float, order="C").reshape(-1, dynamics.STATE_SIZE)
    if params.shape[0] not in (1, y.shape[0]):
        raise ValueError(f"the leg targets are for {params.shape[0]} robots, the state has {y.shape[0]}")
    t_lead, h_lead, n_lead = (float(t0), 0.0, 0) if lead is None else (float(lead[0]), float(lead[1]), int(lead[2]))
    if n_lead % 2:
        raise ValueError(f"a lead of halves has an even number of substeps, got {n_lead}")
    rows = np.empty((n_lead // 2 + n_steps if record else 0, RECORD_ROWS, y.shape[0]))
    summary = np.empty((SUMMARY_ROWS if record else 0, y.shape[0]))
    parallel = workers > 1 and y.shape[0] > 1
    step = _stepper(parallel, config.integrator)
    k, kc, gains = _scene(config.robot, config.depth, config.gains)
    if config.integrator == "etdrk4b":
        from .simulation import _doublings, _ServoExponential

        def doublings(step_h):
            return (_ServoExponential.TERMS, *_doublings(config, step_h)) if step_h > 0.0 else (_ServoExponential.TERMS, 0.0, 1)

        args = (y, t_lead, h_lead, n_lead, doublings(h_lead), float(t0), float(h), int(n_steps), doublings(float(h)), k, kc, gains,
                config.torque_limit, config.leg_rate_limit, kind, params, shared, rows, summary)  # fmt: skip
    else:
        args = (y, t_lead, h_lead, n_lead, float(t0), float(h), int(n_steps), k, kc, gains, config.torque_limit,
                config.leg_rate_limit, kind, params, shared, rows, summary)  # fmt: skip
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
