"""The directional-locomotion task: everything the single env and the vector env share.

One implementation of the task, over batches: every function here takes arrays with a
leading batch axis of N robots, and the single env calls them with N = 1. The physics
itself is not here: both envs integrate through :func:`rrrobot_gym.simulation.advance`.

Glossary
--------
state               (N, 13) float64, the simulator's state (:data:`rrrobot_gym.dynamics.STATE_FIELDS`)
action              (N, 2) in [-1, 1], one number a leg; mapped affinely to a target angle
leg target          rad, the angle the leg servo holds over one control step (target rate 0)
target direction    rad, the commanded heading of travel in the world XY plane, from +X
                    towards +Y; the unit vector d = (cos, sin, 0)
up vector           world +Z seen from the body, n = R^T z (the third row of R)
heading in body     d seen from the body, R^T d; when upright it is
                    (cos(target - yaw), sin(target - yaw), 0) with yaw the body's heading
contact point       p, m, the shell's point on the ground (state entries 0:2)
upright contact     q, m, where p would be if the shell rolled back upright without slip
point               (:func:`upright_contact_points`); the forward reward is q's velocity
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
from gymnasium import spaces

from .. import dynamics, validity
from ..params import PDGains, RobotParams, real_number
from ..control import HeldTargets, RampTargets
from ..simulation import DEFAULT_TIMESTEP, NumericalFailure, SimConfig, advance, check_state

LEG_TARGET_MIN = -0.25 * math.pi
"""rad, leg target of action -1: 45 degrees below horizontal, pointing back (-X) and down."""
LEG_TARGET_MAX = 1.25 * math.pi
"""rad, leg target of action +1: 45 degrees below horizontal, pointing back (mirror of -1).
Action 0 is the rest pose, legs vertical. The Table II gaits span
-0.3 .. 1.87 rad, inside [LEG_TARGET_MIN, LEG_TARGET_MAX]."""
_LEG_TARGET_MID = 0.5 * (LEG_TARGET_MIN + LEG_TARGET_MAX)
_LEG_TARGET_HALF_RANGE = 0.5 * (LEG_TARGET_MAX - LEG_TARGET_MIN)

FORWARD_VELOCITY_UNIT = 100.0
"""cm per m: the forward reward counts centimetres per second. The robot moves at about
1 cm/s, so a good step earns about 1 (and a 1000-step episode about 1000), a scale that
suits PPO's default hyperparameters better than the raw 0.01 m/s."""

OBSERVATION_FIELDS = (
    ("up_in_body", 0, 3),
    ("heading_in_body", 3, 6),
    ("body_rate", 6, 9),
    ("leg_angles", 9, 11),
    ("leg_rates", 11, 13),
    ("target_direction_world", 13, 15),
    ("contact_xy", 15, 17),
)
"""(name, start, stop) of each observation entry; ``contact_xy`` only when positions are included."""

RESET_INFO_KEYS = ("x_position", "y_position", "x_upright", "y_upright", "tilt", "target_direction")
"""Keys of the info ``reset()`` returns (and a vector env's top-level info for a sub-env it reset)."""
STEP_INFO_KEYS = RESET_INFO_KEYS + (
    "x_velocity",
    "y_velocity",
    "forward_velocity",
    "reward_forward",
    "reward_ctrl",
    "reward_survive",
    "numerical_failure",
    "normal_force",
    "friction_ratio",
    "liftoff_fraction",
    "liftoff_time",
    "slip_velocity",
    "leg_clearance",
    "torque_rms",
    "torque_peak",
    "leg_rate_peak",
    "outside_model",
)
"""Keys of the info ``step()`` returns."""
RESET_OPTIONS = ("state", "target_direction")
"""Keys ``reset(options=...)`` accepts: an exact start state (no noise is added) and the
commanded heading for that episode (overrides the ``target_direction`` keyword)."""


NUMERICAL_FAILURES = (NumericalFailure, ArithmeticError, ValueError)
"""What ``advance`` raises when the integration blows up: NumericalFailure for a non-finite
result, and on the one-robot Python-float path also ZeroDivisionError, OverflowError or
ValueError ("math domain error" from math.sin(inf)). The envs validate every input before
calling ``advance``, so an error of these types from inside it is a blow-up, not a bad argument."""


def _real(name, value, *, minimum=None, positive=False):
    if isinstance(value, bool):
        raise TypeError(f"{name} must be a real number, got {value!r}")
    number = real_number(name, value)
    if positive and number <= 0.0:
        raise ValueError(f"{name} must be positive, got {value!r}")
    if minimum is not None and number < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value!r}")
    return number


ACTION_HOLDS = ("linear", "zero_order")
"""How an action's leg targets act over its control step (``action_hold``)."""


def _choice(name, value, options):
    if value not in options:
        raise ValueError(f"unknown {name} {value!r}: expected one of {', '.join(options)}")
    return value


def _flag(name, value):
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be a bool, got {value!r}")
    return bool(value)


@dataclass(frozen=True)
class TaskConfig:
    """Everything that fixes one RRRobot-v0 scene and task, validated at construction.

    Both envs build it from their keyword arguments with :func:`make_task_config`.
    """

    sim: SimConfig = field(default_factory=SimConfig)
    frame_skip: int = 15  # integrator steps per control step
    forward_reward_weight: float = 1.0  # reward per cm/s along the commanded heading
    ctrl_cost_weight: float = 0.01  # cost per unit |action|^2
    reset_noise_scale: float = 0.01  # half-width of the uniform start noise (rad, rad/s)
    exclude_current_positions_from_observation: bool = True
    target_direction: float | None = None  # rad; None draws one per episode
    friction_coefficient: float | None = 1.0  # grip of the floor; None: unlimited (the paper's no-slip)
    max_slip_velocity: float = 0.02  # m/s, estimated slip or hop in one step that ends the episode
    max_liftoff_time: float = 0.005  # s, a spell without ground contact longer than this ends the episode
    healthy_reward: float = 0.0  # reward per step that does not end the episode
    clock_frequency: float | None = None  # rad/s: observe (sin, cos)(clock_frequency t); None: no clock
    terminate_outside_model: bool = True  # end the episode where the model stops holding
    action_hold: str = "linear"  # "linear": targets ramp over a step; "zero_order": jump and hold

    @property
    def dt(self) -> float:
        """s, one control step: frame_skip integrator steps of sim.timestep."""
        return self.frame_skip * self.sim.step

    @property
    def observation_size(self) -> int:
        size = 15 if self.exclude_current_positions_from_observation else 17
        return size + (2 if self.clock_frequency is not None else 0)


def make_task_config(
    *,
    frame_skip=15,
    timestep=DEFAULT_TIMESTEP,
    integrator="rk4",
    model="plane",
    robot=None,
    kp=PDGains.kp,
    kd=PDGains.kd,
    damping=None,
    forward_reward_weight=1.0,
    ctrl_cost_weight=0.01,
    reset_noise_scale=0.01,
    exclude_current_positions_from_observation=True,
    target_direction=None,
    friction_coefficient=1.0,
    max_slip_velocity=0.02,
    max_liftoff_time=0.005,
    healthy_reward=0.0,
    clock_frequency=None,
    terminate_outside_model=True,
    action_hold="linear",
) -> TaskConfig:
    """Validate the env keywords and collect them in a :class:`TaskConfig`.

    Raises TypeError for a wrong type and ValueError for a bad value, naming the keyword.
    """
    if isinstance(frame_skip, bool) or not isinstance(frame_skip, (int, np.integer)):
        raise TypeError(f"frame_skip must be an integer, got {frame_skip!r}")
    if frame_skip < 1:
        raise ValueError(f"frame_skip must be a positive integer, got {frame_skip}")
    if robot is None:
        robot = RobotParams()
    elif not isinstance(robot, RobotParams):
        raise TypeError(f"robot must be a rrrobot_gym.params.RobotParams, got {type(robot).__name__}")
    if damping is not None:
        robot = dataclasses.replace(robot, damping=_real("damping", damping))
    sim = SimConfig(
        model=model,
        robot=robot,
        gains=PDGains(kp=_real("kp", kp), kd=_real("kd", kd)),
        integrator=integrator,
        timestep=_real("timestep", timestep, positive=True),
    )
    _flag("exclude_current_positions_from_observation", exclude_current_positions_from_observation)
    return TaskConfig(
        sim=sim,
        frame_skip=int(frame_skip),
        forward_reward_weight=_real("forward_reward_weight", forward_reward_weight),
        ctrl_cost_weight=_real("ctrl_cost_weight", ctrl_cost_weight, minimum=0.0),
        reset_noise_scale=_real("reset_noise_scale", reset_noise_scale, minimum=0.0),
        exclude_current_positions_from_observation=bool(exclude_current_positions_from_observation),
        target_direction=None if target_direction is None else _real("target_direction", target_direction),
        friction_coefficient=None
        if friction_coefficient is None
        else _real("friction_coefficient", friction_coefficient, positive=True),
        max_slip_velocity=_real("max_slip_velocity", max_slip_velocity, positive=True),
        max_liftoff_time=_real("max_liftoff_time", max_liftoff_time, minimum=0.0),
        healthy_reward=_real("healthy_reward", healthy_reward, minimum=0.0),
        clock_frequency=None if clock_frequency is None else _real("clock_frequency", clock_frequency, positive=True),
        terminate_outside_model=_flag("terminate_outside_model", terminate_outside_model),
        action_hold=_choice("action_hold", action_hold, ACTION_HOLDS),
    )


# ---------------------------------------------------------------------------
# Spaces


def single_action_space() -> spaces.Box:
    return spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)


def single_observation_space(config: TaskConfig) -> spaces.Box:
    """Unit vectors and the commanded direction are bounded by 1; rates, angles and positions are not."""
    low = np.full(config.observation_size, -np.inf, dtype=np.float32)
    high = np.full(config.observation_size, np.inf, dtype=np.float32)
    bounded = np.r_[0:6, 13:15]
    if config.clock_frequency is not None:
        bounded = np.r_[bounded, config.observation_size - 2 : config.observation_size]
    low[bounded], high[bounded] = -1.0, 1.0
    return spaces.Box(low, high, dtype=np.float32)


# ---------------------------------------------------------------------------
# Actions


def check_actions(action, shape) -> np.ndarray:
    """Return ``action`` as float64 of the given shape, clipped to [-1, 1].

    Raises ValueError naming the problem for a wrong shape or a NaN/inf entry: these are
    bugs in the caller, whereas an out-of-range value is an ordinary policy output.
    """
    try:
        arr = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"action must be an array of numbers of shape {shape}, got {action!r}") from None
    if arr.shape != tuple(shape):
        raise ValueError(f"action must have shape {tuple(shape)}, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"action contains NaN or inf: {arr.tolist()}")
    return np.clip(arr, -1.0, 1.0)


def action_to_leg_targets(action):
    """rad, the leg target angles of actions in [-1, 1] (affine: -1 -> -pi/4, +1 -> 3pi/4)."""
    return _LEG_TARGET_MID + _LEG_TARGET_HALF_RANGE * np.asarray(action, dtype=np.float64)


def leg_targets_to_action(leg_targets):
    """The inverse of :func:`action_to_leg_targets` (not clipped): script a gait through the env."""
    return (np.asarray(leg_targets, dtype=np.float64) - _LEG_TARGET_MID) / _LEG_TARGET_HALF_RANGE


# ---------------------------------------------------------------------------
# Start state


def draw_start(rng: np.random.Generator, config: TaskConfig):
    """Draw one robot's start noise and commanded heading from ``rng``: (noise (10,), target rad).

    One draw of 10 numbers U(-s, s), s = reset_noise_scale, then, if
    ``config.target_direction`` is None, the heading U(-pi, pi). The single env and each
    sub-env of the vector env call this with their own generator, so the two agree draw for
    draw. :func:`start_states` turns the noise into states.
    """
    s = config.reset_noise_scale
    noise = rng.uniform(-s, s, size=10)
    if config.target_direction is None:
        target = float(rng.uniform(-math.pi, math.pi))
    else:
        target = config.target_direction
    return noise, target


def start_states(noise):
    """States (N, 13) from start noise (N, 10): the paper's start, perturbed.

    The paper's start is at rest at the origin, upright, legs vertical. The noise adds to
    the paper's three attitude angles (rad, entries 0:3), the leg angles (rad, 3:5), the body
    angular velocity (rad/s, body frame, 5:8) and the leg rates (rad/s, 8:10).
    """
    noise = np.asarray(noise, dtype=np.float64)
    states = np.zeros((len(noise), dynamics.STATE_SIZE))
    states[:, dynamics.QUAT] = dynamics.quat_from_paper_angles(noise[:, 0:3])
    states[:, dynamics.LEG_ANGLES] = 0.5 * math.pi + noise[:, 3:5]
    states[:, dynamics.BODY_RATE] = noise[:, 5:8]
    states[:, dynamics.LEG_RATES] = noise[:, 8:10]
    return states


def parse_reset_options(options, num_envs: int | None):
    """Validate ``reset(options=...)``: returns (states or None, targets or None).

    ``num_envs`` None means a single env: "state" must be (13,) and "target_direction" a
    number. For a vector env a (13,) state or a scalar heading is used for every sub-env.
    Raises ValueError for an unknown key, a bad state, or a start at or past the tilt limit.
    """
    if options is None:
        return None, None
    if not isinstance(options, dict):
        raise TypeError(f"options must be a dict, got {type(options).__name__}")
    unknown = set(options) - set(RESET_OPTIONS)
    if unknown:
        raise ValueError(f"unknown reset option(s) {sorted(unknown)}: expected some of {list(RESET_OPTIONS)}")
    states = targets = None
    if options.get("state") is not None:
        states = check_state(options["state"])
        if num_envs is None:
            if states.ndim != 1:
                raise ValueError(f"options['state'] must have shape (13,), got {states.shape}")
        else:
            states = np.broadcast_to(states, (num_envs, dynamics.STATE_SIZE)).copy() if states.ndim == 1 else states
            if states.shape != (num_envs, dynamics.STATE_SIZE):
                raise ValueError(f"options['state'] must have shape (13,) or ({num_envs}, 13), got {states.shape}")
        start_tilt = np.max(dynamics.tilt(states))
        if start_tilt >= dynamics.TILT_LIMIT:
            raise ValueError(
                f"options['state'] starts at tilt {start_tilt:.4g} rad, at or past the rim limit "
                f"{dynamics.TILT_LIMIT:.4g} rad where the model ends"
            )
    if options.get("target_direction") is not None:
        value = options["target_direction"]
        if num_envs is None:
            targets = _real("options['target_direction']", value)
        else:
            targets = np.array(np.broadcast_to(np.asarray(value, dtype=np.float64), (num_envs,)))
            if not np.all(np.isfinite(targets)):
                raise ValueError(f"options['target_direction'] must be finite, got {value!r}")
    return states, targets


# ---------------------------------------------------------------------------
# Observation, reward, termination


def observe(states, targets, config: TaskConfig, times=None) -> np.ndarray:
    """Observations (N, config.observation_size) float32 of states (N, 13), targets (N,) rad
    and the time since each episode began, ``times`` (N,) s (used by the clock only).

    Layout in :data:`OBSERVATION_FIELDS`. The attitude enters as two unit vectors seen from
    the body, world up and the commanded heading: together they fix the body's attitude
    relative to the task with no singularity anywhere, and they are unchanged when the
    whole scene is turned about the vertical (the dynamics are invariant to world yaw).
    """
    qw, qx, qy, qz = states[:, 2], states[:, 3], states[:, 4], states[:, 5]
    rows = dynamics.rotation_rows(qw, qx, qy, qz)
    cos_t, sin_t = np.cos(targets), np.sin(targets)
    obs = np.empty((len(states), config.observation_size), dtype=np.float32)
    # A blown-up state may overflow float32; finite_rows() catches that, so no warning here.
    with np.errstate(over="ignore", invalid="ignore"):
        for i in range(3):
            obs[:, i] = rows[2][i]
            # (R^T d)_i = R_0i d_x + R_1i d_y, with d horizontal.
            obs[:, 3 + i] = rows[0][i] * cos_t + rows[1][i] * sin_t
        np.clip(obs[:, 0:6], -1.0, 1.0, out=obs[:, 0:6])
        obs[:, 6:9] = states[:, dynamics.BODY_RATE]
        obs[:, 9:11] = states[:, dynamics.LEG_ANGLES]
        obs[:, 11:13] = states[:, dynamics.LEG_RATES]
        obs[:, 13] = cos_t
        obs[:, 14] = sin_t
        end = 15
        if not config.exclude_current_positions_from_observation:
            obs[:, 15:17] = states[:, 0:2]
            end = 17
        if config.clock_frequency is not None:
            # A gait clock: with it a sinusoidal gait is a linear function of the observation.
            phase = config.clock_frequency * (np.zeros(len(states)) if times is None else np.asarray(times, dtype=float))
            obs[:, end] = np.sin(phase)
            obs[:, end + 1] = np.cos(phase)
    return obs


def upright_contact_points(states, radius):
    """(N, 2) m: where the contact point would be if the shell rolled back upright.

    Rolling without slip about the horizontal axis that tips the body's z axis back to
    vertical moves the contact by r * tilt against the body axis's horizontal lean
    b_h = (R[0, 2], R[1, 2]), |b_h| = sin(tilt). So the upright contact point is
    p - r (tilt / sin(tilt)) b_h: it equals the contact point whenever the shell is upright,
    stays put while the shell merely rocks or tips over about a fixed axis, and moves only
    with net travel (the holonomy of the rocking that makes the robot locomote).
    """
    qw, qx, qy, qz = states[:, 2], states[:, 3], states[:, 4], states[:, 5]
    rows = dynamics.rotation_rows(qw, qx, qy, qz)
    lean_x, lean_y, cos_tilt = rows[0][2], rows[1][2], rows[2][2]
    sin_tilt = np.hypot(lean_x, lean_y)
    tilt = np.arctan2(sin_tilt, cos_tilt)
    # tilt / sin(tilt) -> 1 as the shell comes upright, where the lean direction is undefined.
    ratio = np.divide(tilt, sin_tilt, out=np.ones_like(tilt), where=sin_tilt > 1e-9)
    return states[:, 0:2] - radius * ratio[:, None] * np.stack([lean_x, lean_y], axis=-1)


def reset_info(states, targets, config: TaskConfig):
    """The info of a start: (N,) arrays keyed as in :data:`RESET_INFO_KEYS`."""
    upright = upright_contact_points(states, config.sim.robot.radius)
    return {
        "x_position": states[:, 0].copy(),
        "y_position": states[:, 1].copy(),
        "x_upright": upright[:, 0],
        "y_upright": upright[:, 1],
        "tilt": dynamics.tilt(states),
        "target_direction": np.array(targets, dtype=np.float64),
    }


def step_outcome(states_before, states_after, targets, actions, failed, config: TaskConfig, measures, elapsed):
    """Reward (N,), terminated (N,) and info (dict of (N,) arrays) of one control step.

    reward_forward = forward_reward_weight * 100 * forward_velocity: cm/s of the upright
    contact point (:func:`upright_contact_points`) along the heading. Rewarding the raw
    contact point instead would pay ~0.19 m (r pi/2, ~380 reward) for simply tipping over
    towards the heading; the upright point also drops the contact's rocking (over 20 s of
    Gait 1 its path is as long as its net travel, the raw contact's is 15 times longer).
    reward_ctrl = -ctrl_cost_weight * |action|^2 of the clipped action. A ``failed`` robot
    (numerical blow-up; its states_after is its unchanged last finite state) gets reward 0
    and terminates; so does one whose tilt reached the rim limit.
    """
    dt = config.dt
    info = reset_info(states_after, targets, config)
    before = upright_contact_points(states_before, config.sim.robot.radius)
    forward_velocity = (
        (info["x_upright"] - before[:, 0]) * np.cos(targets) + (info["y_upright"] - before[:, 1]) * np.sin(targets)
    ) / dt
    info["x_velocity"] = (states_after[:, 0] - states_before[:, 0]) / dt
    info["y_velocity"] = (states_after[:, 1] - states_before[:, 1]) / dt
    info["forward_velocity"] = forward_velocity
    info["reward_forward"] = config.forward_reward_weight * FORWARD_VELOCITY_UNIT * forward_velocity
    info["reward_ctrl"] = -config.ctrl_cost_weight * np.sum(np.square(actions), axis=1)
    for key in ("x_velocity", "y_velocity", "forward_velocity", "reward_forward", "reward_ctrl"):
        info[key][failed] = 0.0
    info["numerical_failure"] = np.array(failed, dtype=bool)
    info.update({key: np.array(value, dtype=np.float64) for key, value in measures.items()})
    info["outside_model"] = outside_model(info, config, elapsed) & ~info["numerical_failure"]
    # Travel the floor could not have given earns nothing (else a policy learns to kick and fall).
    if config.sim.model == "plane":
        # Nor does travel in the start-up grace, where slip is forgiven (a kick off the start).
        unearned = left_the_floor(info, config) | (np.asarray(elapsed, dtype=float) < STARTUP_GRACE - 1e-9)
        info["reward_forward"] = np.where(unearned, 0.0, info["reward_forward"])
    terminated = info["numerical_failure"] | tilt_reached_limit(info["tilt"])
    if config.terminate_outside_model:
        terminated |= info["outside_model"]
    info["reward_survive"] = np.where(terminated, 0.0, config.healthy_reward)
    return info["reward_forward"] + info["reward_ctrl"] + info["reward_survive"], terminated, info


MEASURE_KEYS = (
    "normal_force", "friction_ratio", "liftoff_fraction", "liftoff_time", "slip_velocity",
    "leg_clearance", "torque_rms", "torque_peak", "leg_rate_peak",
)  # fmt: skip
"""The step-record summaries in a step's info (:func:`rrrobot_gym.validity.step_measures`)."""
FAILED_MEASURES = {key: np.nan for key in MEASURE_KEYS}
"""Measures reported for a robot whose step failed numerically (it terminates anyway)."""


def advance_and_check(states, actions, t: float, config: TaskConfig, previous_targets, contact_lost):
    """One control step of ``states`` ((13,) or (N, 13)) under ``actions``.

    With ``config.action_hold == "linear"`` the leg targets ramp from ``previous_targets``
    (rad, the last step's targets) to the action's over the step; with "zero_order" they
    jump to the action's and are held with target rate 0. ``contact_lost`` (N,) s is how
    long each robot's shell had been off the ground when the step began.

    One integration call, whose :class:`rrrobot_gym.simulation.StepRecord` (the torques
    applied and the ground force at every substep start) gives the step's measures.
    Returns (states after the step, measures: an (N,) dict keyed :data:`MEASURE_KEYS`,
    contact_lost after the step). Raises the simulator's numerical failures
    (:data:`NUMERICAL_FAILURES`).
    """
    leg_targets = action_to_leg_targets(actions)
    if config.action_hold == "linear":
        held = RampTargets(previous_targets, leg_targets, t, config.dt)
    else:
        held = HeldTargets(leg_targets)
    states, record = advance(config.sim, states, t, config.dt, held, check=False, record=True)
    with np.errstate(all="ignore"):
        measures, contact_lost = validity.step_measures(record, config.sim, config.friction_coefficient, contact_lost)
    return states, measures, contact_lost


STARTUP_GRACE = 0.1
"""s: slipping is allowed for this long into an episode. At the paper's start the legs leave
vertical abruptly, and even the Table II gaits would slip at up to 0.63 m/s for an instant
(and never again: 0 after it)."""


def outside_model(info, config: TaskConfig, elapsed):
    """True where a robot left the model's validity envelope (:mod:`rrrobot_gym.validity`).

    A leg tip at or below the ground (leg contact is not modelled), or, on a plane, a floor
    that could not give the force rolling needs: the normal force stayed <= 0 (the shell
    would lift off) for longer than ``max_liftoff_time``, or the impulse the floor could not
    give over the step (a pull, or grip beyond ``friction_coefficient``), per unit mass,
    exceeds ``max_slip_velocity`` (the shell would slip or hop that fast); from
    :data:`STARTUP_GRACE` into the episode, ``elapsed`` (N,) being the time in s at the
    start of the step. The pivot model has no ground contact: only its legs are checked.
    ``info`` holds the step's measures (:func:`advance_and_check`).
    """
    out = info["leg_clearance"] <= 0.0
    if config.sim.model == "plane":
        started = np.asarray(elapsed, dtype=float) >= STARTUP_GRACE - 1e-9
        out |= started & left_the_floor(info, config)
    return out


def left_the_floor(info, config: TaskConfig):
    """True where a step lifted off or slipped beyond the task's tolerances (plane model)."""
    return (info["slip_velocity"] > config.max_slip_velocity) | (info["liftoff_time"] > config.max_liftoff_time)


def tilt_reached_limit(tilts):
    """True where the rim touches the ground (MODEL.md: the rolling model ends there)."""
    return tilts >= dynamics.TILT_LIMIT


def finite_rows(states, observations):
    """True for robots whose state and float32 observation are both finite.

    The observation is checked too: a finite but huge float64 state overflows float32.
    """
    return np.all(np.isfinite(states), axis=1) & np.all(np.isfinite(observations), axis=1)
