"""Where the model stops describing a real robot: contact force and leg clearance.

The model's shell rolls without slip and never leaves the ground, and its legs never touch it,
by construction; so a motion can need an impossible force: a pull from the ground (a hop), more
grip than a floor gives, or a leg through the floor. These functions measure that.

The force is Newton's for the whole robot with the integrated accelerations
(:func:`rrrobot_gym.dynamics.derivative_kernel`), recorded by the integrator at every substep
(:class:`rrrobot_gym.simulation.StepRecord`); :func:`step_measures` turns a record into the
measures an environment checks.
"""

from __future__ import annotations

import numpy as np

from . import dynamics, simulation
from .numerics import anywhere, select
from .params import RobotParams


def _record(states, derivatives, params: RobotParams, model: str):
    """The step record's values (:func:`rrrobot_gym.dynamics.derivative_kernel`) of states (N, 9 + 2L)
    moving with ``derivatives``' leg accelerations (the body's follow from them): torques (L), force
    (3), normal, tangential, clearances (L), each an (N,) array."""
    states = np.atleast_2d(np.asarray(states, dtype=float))
    derivatives = np.broadcast_to(np.asarray(derivatives, dtype=float), states.shape)
    legs = dynamics.state_fields(params.num_legs)
    _, record = dynamics.state_derivative(list(states.T), list(derivatives[:, legs.leg_rates].T), params, model,
                                          kinematic=True, record=True)  # fmt: skip
    return record


def leg_clearance(states, params: RobotParams):
    """Height of each leg tip above the ground (m), shape (N, L)."""
    record = _record(states, 0.0, params, "plane")
    return np.stack(np.broadcast_arrays(*record[params.num_legs + 5 :]), axis=-1)


def ground_force(states, derivatives, params: RobotParams, model: str):
    """The ground's force on the shell (N), body coordinates, shape (N, 3), and its normal part (N,).

    ``derivatives`` are the state derivatives (N, 9 + 2L) at ``states`` (from
    :func:`rrrobot_gym.dynamics.state_derivative` with the torques that acted). For the
    pivot model this is the force of the spherical joint instead.
    """
    legs = params.num_legs
    fx, fy, fz, normal = _record(states, derivatives, params, model)[legs : legs + 4]
    return np.stack([fx, fy, fz], axis=-1), normal


def friction_ratio(force, normal, tangential=None):
    """|tangential| / normal force: the friction coefficient the no-slip contact needs (inf if N <= 0).

    ``tangential`` (the force's part along the ground), if given, is used instead of ``force``.
    """
    if tangential is None:
        force = np.asarray(force, dtype=float)
        tangential = dynamics.tangential_force(force[..., 0], force[..., 1], force[..., 2], normal)
    # inf where the floor would have to pull; a NaN force is not "pulled", so its ratio stays NaN
    pulled = np.asarray(normal, dtype=float) <= 0.0
    return np.where(pulled, np.inf, tangential / np.where(pulled, 1.0, normal))


QUADRATURES = ("rectangle", "trapezoid")
"""How :func:`step_measures` turns the record's samples into the plane's lift-off and slip
measures. ``"rectangle"``: each sample stands for its whole substep. ``"trapezoid"``: the
normal force and the grip and pull the floor would have to give vary linearly between
samples, so a sample's excess counts only until the line through the next one crosses
zero (the last substep, whose end the record does not sample, holds its start). The
second converges with the step, the first does not where the force spikes for less than a
step: at a new ramp's kick, or a gait's brief peaks of grip (README, "Episode end")."""


def step_measures(record, config, friction_coefficient, contact_lost=None, quadrature="rectangle", robots=None):
    """Per robot, what a :class:`rrrobot_gym.simulation.StepRecord` says about the model's validity.

    ``config`` is the :class:`rrrobot_gym.simulation.SimConfig` the record was made with, and
    ``robots`` the per-robot parameters it was made with (``simulation.advance``'s: each robot's
    slip takes its own total mass); ``friction_coefficient`` the floor's grip, one for every
    robot or an (N,) array (each robot's floor), None: unlimited; ``contact_lost`` (N,) s, how
    long the contact had been lost (normal force <= 0) at the record's start (0 if None);
    ``quadrature`` one of :data:`QUADRATURES`, how the lift-off and slip measures integrate
    the samples over time.

    Returns ``(measures, contact_lost_after)``: measures is a dict of (N,) arrays,
    ``normal_force`` (N, the least), ``friction_ratio`` (the largest grip the no-slip contact
    needs, inf where the floor would have to pull), ``liftoff_fraction`` (the share of the
    record's time without contact), ``liftoff_time`` (s, the longest spell without contact,
    counting one carried in), ``slip_velocity`` (m/s, the impulse the floor could not give,
    a pull or grip beyond friction, per unit mass: the velocity the shell would slip or hop
    with), ``leg_clearance`` (m, the lower leg tip's least height), ``torque_rms`` and
    ``torque_peak`` (N m, over both legs), ``leg_rate_peak`` (rad/s). The pivot model's joint
    holds any force: its lift-off and slip measures are 0 (its force is still reported).
    ``contact_lost_after`` (N,) s is the spell without contact still going at the end.
    """
    if quadrature not in QUADRATURES:
        raise ValueError(f"unknown quadrature {quadrature!r}: expected one of {', '.join(QUADRATURES)}")
    samples = record.normal.shape[0]
    normal = record.normal.reshape(samples, -1)
    num_robots = normal.shape[1]
    friction_coefficient = _friction(friction_coefficient, num_robots)
    mass = config.robot.total_mass if robots is None else simulation.total_mass(
        config, simulation.robot_values(config, robots, num_robots if record.normal.ndim > 1 else None))
    tangential = record.tangential.reshape(samples, num_robots)
    lost = np.zeros(num_robots) if contact_lost is None else np.array(contact_lost, dtype=float).reshape(num_robots)
    if not (lost >= 0.0).all():  # (NaN too)
        raise ValueError(f"contact_lost must be spells of seconds >= 0, got {contact_lost!r}")
    summary = {key: np.reshape(value, num_robots) for key, value in record.summary().items()}
    if quadrature == "rectangle":
        values = record_measures(normal, tangential, *(summary[key] for key in SUMMARY_KEYS), lost, friction_coefficient,
                                 mass, record.step, config.model == "plane", config.robot.num_legs)  # fmt: skip
        measures = {key: np.array(np.broadcast_to(value, (num_robots,)), dtype=float) for key, value in zip(MEASURE_KEYS, values)}
        return measures, measures.pop("contact_lost")
    # The trapezoid quadrature (numpy only): the usual case, every sample pushing, skips the sums.
    in_contact = not (summary["least_normal"] <= 0.0).any()
    measures = {
        "normal_force": summary["least_normal"],
        "friction_ratio": summary["most_ratio"] if in_contact else friction_ratio(None, normal, tangential).max(axis=0),
        "leg_clearance": summary["least_clearance"],
        "torque_rms": np.sqrt(summary["torque_squares"] / (config.robot.num_legs * samples)),
        "torque_peak": summary["peak_torque"],
        "leg_rate_peak": summary["peak_leg_rate"],
    }
    if config.model != "plane":
        zero = np.zeros(num_robots)
        measures.update(liftoff_fraction=zero, liftoff_time=zero.copy(), slip_velocity=zero.copy())
        return measures, zero.copy()
    lifted = ~(summary["least_normal"] > 0.0)  # the robots that lost contact
    if in_contact:  # any spell carried in ended at the first sample
        longest, lost, fraction = lost, np.zeros(num_robots), np.zeros(num_robots)
    else:  # on the robots that lost contact (the rest as in the branch above)
        longest, after, fraction = lost.copy(), np.zeros(num_robots), np.zeros(num_robots)
        spells = _interpolated_spells(normal[:, lifted], lost[lifted], record.step)
        longest[lifted], after[lifted], fraction[lifted] = spells
        lost = after
    # With every sample pushing and the grip needed below the floor's by more than rounding, the
    # floor gives all of the force: unprovided_force is exactly 0 there (and so is every line
    # between two samples, each below 0).
    beyond = np.zeros(num_robots, dtype=bool) if friction_coefficient is None else ~(
        measures["friction_ratio"] <= friction_coefficient * (1 - FRICTION_ROUNDING)
    )  # the robots that needed more grip than that
    slip = np.zeros(num_robots)
    short = lifted | beyond  # the robots that lost contact or needed more grip (the rest: 0, as above)
    if short.any():
        grip = friction_coefficient if np.ndim(friction_coefficient) == 0 else friction_coefficient[short]
        slip[short] = _unprovided_impulse(normal[:, short], tangential[:, short], grip, record.step)
        slip /= mass
    measures.update(liftoff_fraction=fraction, liftoff_time=longest, slip_velocity=slip)
    return measures, lost


SUMMARY_KEYS = simulation.SUMMARY_KEYS
MEASURE_KEYS = ("normal_force", "friction_ratio", "liftoff_fraction", "liftoff_time", "slip_velocity", "leg_clearance",
                "torque_rms", "torque_peak", "leg_rate_peak", "contact_lost")  # fmt: skip
"""What :func:`record_measures` returns, in order: :func:`step_measures`' measures, then the spell
without contact going at the end."""
FRICTION_ROUNDING = 1e-12
"""A grip needed within this share of the floor's is taken as given (the floor gives all of the
force): so a contact that needs exactly the floor's friction does not slip by rounding."""


def record_measures(normal, tangential, least_normal, most_ratio, least_clearance, torque_squares, peak_torque,
                    peak_leg_rate, carried, friction, mass, step, plane, num_legs):
    """The measures of :func:`step_measures` (rectangle quadrature) and the spell without contact
    going at the end, in :data:`MEASURE_KEYS`' order: the one implementation, for numpy arrays
    (a batch) and compiled into the env's step (one robot at a time, floats).

    ``normal`` and ``tangential`` are the record's S samples, each a float (one robot) or an (N,)
    array; the next six arguments the record's summary (:data:`SUMMARY_KEYS`); ``carried`` the
    spell without contact going at the record's start (s); ``friction`` the floor's grip (None:
    unlimited); ``mass`` (kg) the robot's; ``step`` (s) the record's; ``plane`` False for the pivot
    model, whose joint holds any force; ``num_legs`` the robot's. Each sample stands for its whole substep.
    """
    samples = len(normal)
    pulled = least_normal <= 0.0
    ratio = most_ratio
    if anywhere(pulled):  # the grip needed is inf where the floor would have to pull
        worst = -np.inf
        for s in range(samples):
            off = normal[s] <= 0.0
            worst = np.maximum(worst, select(off, np.inf, tangential[s] / select(off, 1.0, normal[s])))
        ratio = select(pulled, worst, ratio)
    torque_rms = np.sqrt(torque_squares / (num_legs * samples))
    if not plane:
        return least_normal, ratio, 0.0, 0.0, 0.0, least_clearance, torque_rms, peak_torque, peak_leg_rate, 0.0
    fraction, longest, lost = 0.0, carried, 0.0  # in contact throughout: a spell carried in ended at once
    if anywhere(pulled):
        last_contact, worst, spell, off_count = 0.0, -np.inf, 0.0, 0.0
        for s in range(samples):
            count = s + 1.0
            off = normal[s] <= 0.0
            off_count = off_count + select(off, 1.0, 0.0)
            last_contact = select(off, last_contact, count)  # (0 while none yet)
            spell = (count - last_contact) * step + select(last_contact == 0.0, carried, 0.0)
            worst = np.maximum(worst, spell)
        fraction = select(pulled, off_count / samples, fraction)
        longest = select(pulled, np.maximum(carried, worst), longest)
        lost = select(pulled, spell, lost)
    short = pulled
    if friction is not None:
        short = pulled | ~(ratio <= friction * (1.0 - FRICTION_ROUNDING))  # more grip than the floor gives
    slip = 0.0
    if anywhere(short):  # the impulse the floor could not give, per unit mass
        total = 0.0
        for s in range(samples):
            missing = np.maximum(-normal[s], 0.0)
            if friction is not None:
                missing = missing + np.maximum(tangential[s] - friction * np.maximum(normal[s], 0.0), 0.0)
            total = missing if s == 0 else total + missing
        slip = select(short, total * step / mass, slip)
    return least_normal, ratio, fraction, longest, slip, least_clearance, torque_rms, peak_torque, peak_leg_rate, lost


KERNELS = (record_measures,)
"""This module's functions :mod:`rrrobot_gym.compiled` compiles into the env's step."""


def _friction(friction_coefficient, num_robots: int):
    """``step_measures``' friction coefficient checked: None, a number > 0 (every robot's floor) or
    an (N,) array of finite numbers > 0 (each robot's)."""
    if friction_coefficient is None or np.ndim(friction_coefficient) == 0:
        if friction_coefficient is not None and not friction_coefficient > 0.0:  # (NaN too)
            raise ValueError(f"friction_coefficient must be positive or None (unlimited), got {friction_coefficient!r}")
        return friction_coefficient
    mu = np.asarray(friction_coefficient, dtype=float)
    if mu.shape != (num_robots,):
        raise ValueError(f"friction_coefficient must be a number or one per robot, shape ({num_robots},), got shape {mu.shape}")
    bad = ~(np.isfinite(mu) & (mu > 0.0))
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"friction_coefficient must be finite and positive for every robot, got {float(mu[i])!r} for robot {i}")
    return mu


def _sample_sum(values):
    """The sum over samples of (S, N) values, sample by sample: the same numbers whatever N (numpy's
    sum pairs the samples of one robot's (S, 1), not those of a batch's (S, N))."""
    return np.add.accumulate(values, axis=0)[-1] if len(values) else np.zeros(values.shape[1:])


def _positive_part(a, b):
    """The mean over [0, 1] of max(a + (b - a) s, 0): the line from a to b, only where it is
    above 0, elementwise: (a+ + b+)^2 / (2 (|a| + |b|)), which is the trapezoid (a+ + b+) / 2
    where neither end is below 0, the triangle a+^2 / (2 |a - b|) where the line crosses 0 down
    (b+^2 / ... up), and 0 where both ends are <= 0 (a NaN stays NaN, an infinite excess infinite)."""
    above = np.maximum(a, 0.0) + np.maximum(b, 0.0)
    size = np.abs(a) + np.abs(b)
    # the share above 0, in [0, 1] (no overflow); 1 for an infinite excess, as the rectangle's
    share = np.divide(above, size, out=np.ones_like(size), where=~(size <= 0.0) & ~np.isinf(above))
    return 0.5 * above * np.where(size <= 0.0, 0.0, share)


def _unprovided_impulse(normal, tangential, friction_coefficient, step):
    """(N,) N s: :func:`unprovided_force` integrated over a record's S substeps of ``step``,
    ``normal`` and ``tangential`` (S, N), by the trapezoid rule on the pull (-normal) and the
    grip beyond the floor's (tangential - mu max(normal, 0)), each a line between samples whose
    part above 0 counts; the last substep holds its start's value."""
    pull = -normal
    inner = _positive_part(pull[:-1], pull[1:])
    if friction_coefficient is not None:
        beyond = tangential - friction_coefficient * np.maximum(normal, 0.0)
        inner = inner + _positive_part(beyond[:-1], beyond[1:])
    last = unprovided_force(normal[-1], tangential[-1], friction_coefficient)
    return (_sample_sum(inner) + last) * step


def _interpolated_spells(normal, carried, step):
    """(longest spell, spell going at the end, share of the record's time), each (N,), without
    contact, ``normal`` (S, N) being a line between samples (held over the last substep) and
    ``carried`` (N,) s the spell going at the first sample: as :func:`record_measures`' rectangle spells,
    with each spell starting and ending where the line crosses 0 instead of at samples."""
    samples = normal.shape[0]
    off = normal <= 0.0
    start, end = normal[:-1], normal[1:]
    with np.errstate(divide="ignore", invalid="ignore"):
        crossing = step * np.abs(np.minimum(start, end)) / np.abs(end - start)  # the part <= 0 of a mixed line
    crossing = np.where(np.isfinite(crossing), crossing, step)  # an infinite end: the line is off all the way
    # the time without contact within each substep, the last one held at its sample
    part = np.concatenate([np.where(off[:-1] & off[1:], step, np.where(off[:-1] != off[1:], crossing, 0.0)),
                           np.where(off[-1:], step, 0.0)])  # fmt: skip
    total = np.concatenate([np.zeros((1,) + part.shape[1:]), np.add.accumulate(part, axis=0)])
    # the spell through substep k began in the substep of the last sample in contact at or before
    # k (1-based below; 0: none, so it began before the record, with ``carried``)
    count = np.arange(1, samples + 1)[:, None]
    began = np.maximum.accumulate(np.where(off, 0, count), axis=0)
    before = np.take_along_axis(total, np.maximum(began - 1, 0), axis=0)
    spells = total[1:] - before + np.where(began == 0, carried, 0.0)
    return np.maximum(carried, spells.max(axis=0)), spells[-1].copy(), total[-1] / (samples * step)


def unprovided_force(normal, tangential, friction_coefficient):
    """N: the part of the needed ground force a floor cannot give (0 while the model holds).

    A pull (normal < 0: the shell would hop) and grip beyond ``friction_coefficient`` times
    the push (it would slip). None: unlimited grip (the paper's no-slip contact).
    """
    pull = np.maximum(-normal, 0.0)
    if friction_coefficient is None:
        return pull
    return pull + np.maximum(tangential - friction_coefficient * np.maximum(normal, 0.0), 0.0)
