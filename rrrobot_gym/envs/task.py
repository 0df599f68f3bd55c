"""The directional-locomotion task: everything the single env and the vector env share.

One implementation of the task, over batches: every function here takes arrays with a
leading batch axis of N robots, and the single env calls them with N = 1. The physics
itself is not here: both envs integrate through :func:`rrrobot_gym.simulation.advance`.

Glossary
--------
state               (N, 9 + 2L) float64, the simulator's state of robots of L legs
                    (:func:`rrrobot_gym.dynamics.state_fields`; 13 numbers for the paper's two)
action              (N, L) in [-1, 1], one number a leg; mapped affinely to a target angle
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
import difflib
import inspect
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from gymnasium import spaces

from .. import compiled, dynamics, simulation, validity
from ..numerics import anywhere, arctan2, select, sincos
from ..validity import record_measures
from ..params import PDGains, RobotParams, real_number
from ..control import HeldTargets, RampTargets
from ..simulation import DEFAULT_TIMESTEP, LEG_MODES, MAX_SAMPLES, NumericalFailure, SimConfig, advance, check_state

LEG_TARGET_MIN = -0.25 * math.pi
"""rad, leg target of action -1: 45 degrees below horizontal, forward (leg angle 0 is body +X, pi/2 up)."""
LEG_TARGET_MAX = 1.25 * math.pi
"""rad, leg target of action +1: 45 degrees below horizontal, back. Action 0 is the rest pose, legs
vertical; the Table II gaits span -0.3 .. 1.87 rad."""
_LEG_TARGET_MID = 0.5 * (LEG_TARGET_MIN + LEG_TARGET_MAX)
_LEG_TARGET_HALF_RANGE = 0.5 * (LEG_TARGET_MAX - LEG_TARGET_MIN)

FORWARD_VELOCITY_UNIT = 100.0
"""cm per m: the forward reward counts cm/s, so a good step (about 1 cm/s) earns about 1, a scale
that suits PPO's default hyperparameters better than the raw 0.01 m/s."""

def observation_fields(num_legs: int = 2) -> tuple:
    """(name, start, stop) of each observation entry of a robot of ``num_legs`` legs (11 + 2L
    entries, then ``contact_xy`` where positions are included and the clock's two where it runs)."""
    legs = int(num_legs)
    return (("up_in_body", 0, 3), ("heading_in_body", 3, 6), ("body_rate", 6, 9), ("leg_angles", 9, 9 + legs),
            ("leg_rates", 9 + legs, 9 + 2 * legs), ("target_direction_world", 9 + 2 * legs, 11 + 2 * legs),
            ("contact_xy", 11 + 2 * legs, 13 + 2 * legs))  # fmt: skip


OBSERVATION_FIELDS = observation_fields(2)
"""The default robot's :func:`observation_fields`."""

RESET_INFO_KEYS = ("x_position", "y_position", "x_upright", "y_upright", "tilt", "target_direction")
"""Keys of the info ``reset()`` returns (and a vector env's top-level info for a sub-env it reset)."""
MEASURE_KEYS = validity.MEASURE_KEYS[:-1]
"""The step-record summaries in a step's info (:func:`rrrobot_gym.validity.step_measures`)."""
TERMINATIONS = ("", "numerical_failure", "tilt", "leg_clearance", "liftoff_time", "slip_velocity")
"""What ``info["termination"]`` names: why a step ended its episode, "" where it did not (a truncation
included). Each names the info entry that crossed its limit (``numerical_failure``: the integration
blew up); where several did at once, the first of these."""
STEP_INFO_KEYS = RESET_INFO_KEYS + (
    "x_velocity", "y_velocity", "forward_velocity", "reward_forward", "reward_ctrl", "reward_survive",
) + MEASURE_KEYS + ("numerical_failure", "outside_model", "termination")  # fmt: skip
"""Keys of the info ``step()`` returns, in order."""
RESET_OPTIONS = ("state", "target_direction")
"""Keys ``reset(options=...)`` accepts: an exact start state (no noise) and the episode's heading."""


NUMERICAL_FAILURES = (NumericalFailure, ArithmeticError, ValueError)
"""What ``advance`` raises when the integration blows up (the one-robot float path also raises
ArithmeticError, or ValueError from math.sin(inf)). The envs validate every input first, so these
mean a blow-up, not a bad argument."""


REWARD_WEIGHT_LIMIT = 1e30
"""The largest reward weight (in size) the env takes: a larger one times a step's velocity or
effort could overflow the reward (float32 for SB3, 3.4e38 at most) to inf or NaN."""


def _real(name, value, *, minimum=None, positive=False, weight=False):
    number = real_number(name, value)
    if positive and number <= 0.0:
        raise ValueError(f"{name} must be positive, got {value!r}")
    if minimum is not None and number < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value!r}")
    if weight and abs(number) > REWARD_WEIGHT_LIMIT:
        raise ValueError(f"{name} must be at most {REWARD_WEIGHT_LIMIT:g} in size (a larger reward weight can "
                         f"overflow the reward, a float32 for SB3, to inf or NaN), got {value!r}")
    return number


def control_steps(label: str, duration: float, dt: float) -> int:
    """The whole number of control steps of ``dt`` s nearest to ``duration`` s, or a ValueError
    naming ``label`` if it is under half a step."""
    steps = int(round(duration / dt))
    if steps < 1:
        raise ValueError(f"{label} {duration!r} s is under half of the env's {dt!r} s control step")
    return steps


class Servo(NamedTuple):
    """The leg servo of RRRobot-v0's defaults: a motor a robot of this size could carry."""

    torque_limit: float | None
    """N m, stall torque."""
    leg_rate_limit: float | None
    """rad/s, no-load speed: the torque falls linearly to 0 there."""
    leg_accel_limit: float | None
    """rad/s^2, the motion profile's largest change of the reference's rate."""


SERVO = Servo(torque_limit=0.5, leg_rate_limit=10.0, leg_accel_limit=60.0)
"""The env's servo: 0.5 N m stall and 10 rad/s no-load, a hobby servo's class (a standard one
gives about 1 N m at 5-7 rad/s; each leg is a 57 g tip at 0.1 m), with a motion profile as smart
servos set one (a limit on the reference's acceleration): at 60 rad/s^2 a random policy's
episodes last about 2 s instead of 0.25 s, where the shell's reaction to full-torque swings
makes it hop or slip."""
IDEAL_SERVO = Servo(None, None, None)
"""The paper's servo: the PD law unlimited, the target reached at once (``rrrobot figures``, Tables I
and II)."""


class Range(NamedTuple):
    """Where a randomized quantity is drawn from, uniformly: [low, high] times the env's own value
    (``scale``) or [low, high] itself."""

    low: float
    high: float
    scale: bool


RANDOMIZATIONS = {
    "default": {
        "mass_bottom": Range(0.9, 1.1, True),
        "mass_pin": Range(0.9, 1.1, True),
        "mass_tip": Range(0.9, 1.1, True),
        "leg_length": Range(0.9, 1.1, True),
        "damping": Range(0.5, 1.5, True),
        "kp": Range(0.85, 1.15, True),
        "kd": Range(0.85, 1.15, True),
        "torque_limit": Range(0.8, 1.2, True),
        "leg_rate_limit": Range(0.8, 1.2, True),
        "friction_coefficient": Range(0.7, 1.0, False),
        "observation_noise": Range(0.0, 0.02, False),
        "action_delay": Range(0, 1, False),
    },
}
"""The named sets of ranges ``randomize`` takes (the env docstring's Domain Randomization table)."""
PHYSICAL = ("mass_bottom", "mass_pin", "mass_tip", "leg_length", "damping", "kp", "kd", "torque_limit", "leg_rate_limit")
"""The randomized quantities the integrator takes per robot (``advance(robots=...)``)."""
RANDOMIZED = PHYSICAL + ("friction_coefficient", "observation_noise", "action_delay")
def noisy_observations(num_legs: int) -> slice:
    """The observation entries ``observation_noise`` perturbs: attitude, rates and legs (not the
    commanded heading, which the task sets, nor positions or the clock); the unit vectors' stay
    within [-1, 1]."""
    return slice(0, 9 + 2 * num_legs)


def randomization_ranges(randomize, config) -> dict:
    """``randomize`` (None, a name of :data:`RANDOMIZATIONS` or {name: (low, high)}) as {name: Range},
    checked; the motor limits vary only where the env has them."""
    if randomize is None:
        return {}
    if isinstance(randomize, str):
        ranges = dict(RANDOMIZATIONS[_choice("randomize", randomize, tuple(RANDOMIZATIONS))])
    elif isinstance(randomize, dict):
        unknown = [name for name in randomize if name not in RANDOMIZED]
        if unknown:
            raise ValueError(f"randomize: unknown quantity {unknown[0]!r}: expected some of {', '.join(RANDOMIZED)}")
        default = RANDOMIZATIONS["default"]
        ranges = {}
        for name, bounds in randomize.items():
            if isinstance(bounds, Range):
                bounds = (bounds.low, bounds.high)
            try:
                low, high = (real_number(f"randomize[{name!r}]", b) for b in bounds)
            except (TypeError, ValueError):
                raise ValueError(f"randomize[{name!r}] must be a pair (low, high) of numbers, got {bounds!r}") from None
            if not 0.0 <= low <= high:
                raise ValueError(f"randomize[{name!r}] must have 0 <= low <= high, got ({low!r}, {high!r})")
            ranges[name] = Range(low, high, default[name].scale)
    else:
        raise TypeError(f"randomize must be None, a name ({', '.join(RANDOMIZATIONS)}) or a dict, got {randomize!r}")
    if config.torque_limit is None:
        ranges.pop("torque_limit", None)
    if config.leg_rate_limit is None:
        ranges.pop("leg_rate_limit", None)
    for name in ("torque_limit", "leg_rate_limit", "kp", "kd"):
        if name in ranges and config.legs == "kinematic":
            ranges.pop(name)
    for name in ("mass_bottom", "mass_pin", "mass_tip", "leg_length", "kp", "friction_coefficient"):
        if name in ranges and ranges[name].low <= 0.0:
            raise ValueError(f"randomize[{name!r}] must be above 0, got low {ranges[name].low!r}")
    return ranges


RANDOMIZATION_DOCS = {
    "mass_bottom": "kg, the shell's bottom mass", "mass_pin": "kg, each leg pin's mass",
    "mass_tip": "kg, each leg tip's mass", "leg_length": "m, both legs' length",
    "damping": "N m s/rad, the body damping", "kp": "N m/rad, the servo's stiffness",
    "kd": "N m s/rad, the servo's damping", "torque_limit": "N m, the motors' stall torque",
    "leg_rate_limit": "rad/s, the motors' no-load speed", "friction_coefficient": "the floor's grip",
    "observation_noise": "standard deviation of the observation noise",
    "action_delay": "control steps an action waits (0 or 1)",
}


def randomization_table(name: str = "default") -> str:
    """The Markdown table of a named set of :data:`RANDOMIZATIONS`."""
    lines = ["| Quantity | Drawn from | Unit, meaning |", "|---|---|---|"]
    for key, (low, high, scale) in RANDOMIZATIONS[name].items():
        drawn = f"{low:g}-{high:g} x the env's" if scale else f"{low:g}-{high:g}"
        lines.append(f"| `{key}` | {drawn} | {RANDOMIZATION_DOCS[key]} |")
    return "\n".join(lines)


def nominal(name: str, config) -> float:
    """The env's own value of a randomized quantity (0 for observation noise and action delay)."""
    if name in ("kp", "kd", "torque_limit", "leg_rate_limit", "friction_coefficient"):
        return getattr(config, name)
    if name in PHYSICAL:
        return getattr(config.sim.robot, name)
    return 0.0


def draw_robots(generators, config) -> dict:
    """One robot per generator (the sub-envs' own, in order): {name: (N,) array} of the quantities
    ``config.ranges`` varies, drawn in :data:`RANDOMIZED` order; action delays are whole steps."""
    draws = {name: np.empty(len(generators)) for name in config.ranges}
    for i, rng in enumerate(generators):
        for name, (low, high, scale) in config.ranges.items():
            if name == "action_delay":
                draws[name][i] = rng.integers(int(low), int(high) + 1)
            else:
                draws[name][i] = rng.uniform(low, high) * (nominal(name, config) if scale else 1.0)
    return draws


def delayed_actions(actions, previous, draws):
    """The actions that reach the servo: last step's where a robot's ``action_delay`` is 1."""
    delay = draws.get("action_delay")
    if delay is None:
        return actions
    return np.where(delay.reshape(np.shape(actions)[:-1] + (1,)) > 0, previous, actions)


def noisy(observations, draws, rng, num_legs: int = 2):
    """``observations`` (N, size) of robots of ``num_legs`` legs with Gaussian noise of each robot's
    ``observation_noise`` (standard deviation) on :func:`noisy_observations`, from ``rng``."""
    sigma = draws.get("observation_noise")
    if sigma is None:
        return observations
    out = observations.copy()
    part = out[:, noisy_observations(num_legs)]
    part += (sigma[:, None] * rng.standard_normal(part.shape)).astype(out.dtype)
    out[:, 0:6].clip(-1.0, 1.0, out=out[:, 0:6])  # (unit vectors' entries stay in the observation space)
    return out


def robot_physics(draws):
    """(the per-robot physics for ``advance(robots=...)`` or None, the floors' friction or None)."""
    physics = {name: draws[name] for name in PHYSICAL if name in draws}
    return physics or None, draws.get("friction_coefficient")


def with_servo(env_kwargs) -> dict:
    """``env_kwargs`` with every servo keyword (:class:`Servo`) an env built from them runs under,
    the defaults' where not given: what a searched file records, so that it names its servo
    whatever the defaults become."""
    return {**SERVO._asdict(), **env_kwargs}


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


def _keyword(default, doc, *, shown=None):
    """A TaskConfig field: an env keyword with its default and a one-line doc (units first)."""
    return field(default=default, metadata={"doc": doc, "shown": shown})


@dataclass(frozen=True)
class TaskConfig:
    """The env keywords of one RRRobot-v0 scene and task, validated: their one definition.

    Both envs take exactly these fields; their signatures and the Arguments table are generated
    from them. The simulator's part is :attr:`sim`, a :class:`rrrobot_gym.simulation.SimConfig`.
    """

    frame_skip: int = _keyword(15, "integrator steps per control step; `dt` = `frame_skip` x the step")
    timestep: float | str = _keyword(
        DEFAULT_TIMESTEP,
        "s, the fixed integration step, or `\"auto\"`: a step derived from the gains, masses and model "
        "(`rrrobot_gym.simulation.SimConfig`)",
        shown="`1/300`",
    )
    integrator: str = _keyword("rk4", "fixed-step integrator, one of `rrrobot_gym.simulation.INTEGRATORS`")
    backend: str = _keyword(
        "auto",
        '`"numba"`: the compiled stepper (numba installed; servo legs and rk4); `"numpy"`: the numpy one; '
        '`"auto"`: numba where it applies (`rrrobot_gym.simulation.BACKENDS`)',
    )
    model: str = _keyword("plane", '`"plane"` (rolling on a plane) or `"pivot"` (the paper\'s Pivoting Dynamics model)')
    robot: RobotParams | None = _keyword(
        None, "geometry, masses, gravity, damping (`rrrobot_gym.params.RobotParams`); None: the paper's robot",
        shown="`RobotParams()`",
    )
    num_legs: int | None = _keyword(
        None, "legs, 1 to 6, in the family's default placement on the rim (`rrrobot_gym.params.default_legs`); "
        "None: the robot's (2)"
    )
    shell_axes: tuple | None = _keyword(
        None, "m, (a, b, c): the shell's semi-axes along body x, y, z, an ellipsoid; None: the robot's (the sphere, "
        "r = 0.12)"
    )
    kp: float = _keyword(PDGains.kp, "N m/rad, leg servo stiffness")
    kd: float = _keyword(PDGains.kd, "N m s/rad, leg servo damping")
    damping: float | None = _keyword(None, "N m s/rad, body damping k (<= 0); None keeps `robot.damping` (-0.01)")
    legs: str = _keyword(
        "servo",
        '`"servo"`: the PD servo drives the legs (the paper\'s model); `"kinematic"`: the legs follow a smooth '
        "path to each target exactly (no stiff servo in the integration)",
    )
    torque_limit: float | None = _keyword(
        SERVO.torque_limit,
        "N m, the leg motors' stall torque (servo legs); None: unlimited, the paper's ideal servo",
    )
    leg_rate_limit: float | None = _keyword(
        SERVO.leg_rate_limit,
        "rad/s, the leg motors' no-load speed (needs `torque_limit`), also the profile's top speed; None: unlimited",
    )
    leg_accel_limit: float | None = _keyword(
        SERVO.leg_accel_limit,
        "rad/s^2, the servo's motion profile: its reference moves towards each action's target with its rate "
        "changing by at most this much a second (`step_targets`); None: it goes straight to the target",
    )
    forward_reward_weight: float = _keyword(1.0, "reward per cm/s along the commanded heading")
    ctrl_cost_weight: float = _keyword(0.01, "cost per unit \\|action\\|^2 (>= 0)")
    reset_noise_scale: float = _keyword(
        0.01, "rad, rad/s: half-width of the uniform start noise (>= 0, below pi/2: no start past the rim)"
    )
    exclude_current_positions_from_observation: bool = _keyword(
        True, "leave the contact point (x, y) out of the observation"
    )
    target_direction: float | None = _keyword(
        None, "rad, the commanded heading, from +X towards +Y; None draws one per episode"
    )
    friction_coefficient: float | None = _keyword(1.0, "grip of the floor (plane model); None: unlimited (no slip)")
    max_slip_velocity: float = _keyword(0.02, "m/s: a step whose slip or hop exceeds this leaves the model")
    max_liftoff_time: float = _keyword(
        0.005, "s: a spell without ground contact longer than this leaves the model (>= 0)"
    )
    contact_quadrature: str = _keyword(
        "rectangle", 'plane model: how the lift-off and slip measures integrate the step record: `"rectangle"`, '
        "each sample for its whole integration step (as the shipped policy and the searches were judged); "
        '`"trapezoid"`, the force a line between samples, which converges with the step '
        "(`rrrobot_gym.validity.QUADRATURES`)"
    )
    healthy_reward: float = _keyword(0.0, "reward for each step that does not terminate the episode (`reward_survive`, >= 0)")
    clock_frequency: float | None = _keyword(
        None, "rad/s: append (sin, cos)(clock_frequency t), t the episode time, to the observation; None: no clock. "
        "Below pi / `dt` (a faster clock, seen once a step, aliases to a slower one)"
    )
    terminate_outside_model: bool = _keyword(True, "end the episode when the robot leaves the model (see Episode End)")
    action_hold: str = _keyword("linear", '`"linear"`: targets ramp over each step; `"zero_order"`: jump and hold')
    randomize: str | dict | None = _keyword(
        None, 'domain randomization, a new robot drawn at every reset: `"default"` (the ranges of '
        "`task.RANDOMIZATIONS`, see Domain Randomization), a dict of some of them {name: (low, high)}, or None"
    )

    def __post_init__(self):
        def put(name, value):
            object.__setattr__(self, name, value)

        frame_skip = self.frame_skip
        if isinstance(frame_skip, bool) or not isinstance(frame_skip, (int, np.integer)):
            raise TypeError(f"frame_skip must be an integer, got {frame_skip!r}")
        if frame_skip < 1:
            raise ValueError(f"frame_skip must be a positive integer, got {frame_skip}")
        if frame_skip > MAX_SAMPLES:
            raise ValueError(f"frame_skip must be at most {MAX_SAMPLES:.0e}, got {frame_skip}: a step's record keeps "
                             "every integration step, as simulate keeps at most that many samples")
        put("frame_skip", int(frame_skip))
        if self.robot is None:
            put("robot", RobotParams())
        elif not isinstance(self.robot, RobotParams):
            raise TypeError(f"robot must be a rrrobot_gym.params.RobotParams, got {type(self.robot).__name__}")
        robot = self.robot
        if self.num_legs is not None or self.shell_axes is not None:  # (a layout of their own: the family's default)
            family = {"num_legs": robot.num_legs if self.num_legs is None else self.num_legs, "legs": None}
            if self.shell_axes is not None:
                family.update(shell_axes=self.shell_axes, radius=None)
            try:
                robot = dataclasses.replace(robot, **family)
            except (TypeError, ValueError) as error:
                raise type(error)(str(error).replace("RobotParams.", "")) from None
            put("num_legs", robot.num_legs)
            put("shell_axes", robot.shell_axes if self.shell_axes is not None else None)
        if self.damping is not None:
            put("damping", _real("damping", self.damping))
            robot = dataclasses.replace(robot, damping=self.damping)
        if not isinstance(self.timestep, str):
            put("timestep", _real("timestep", self.timestep, positive=True))
        _choice("legs", self.legs, LEG_MODES)
        for name in ("kp", "kd"):
            put(name, _real(name, getattr(self, name)))
        for name in ("torque_limit", "leg_rate_limit"):
            if getattr(self, name) is not None:
                put(name, _real(name, getattr(self, name)))
        if self.leg_accel_limit is not None:
            put("leg_accel_limit", _real("leg_accel_limit", self.leg_accel_limit, positive=True))
        if self.target_direction is not None:
            put("target_direction", check_radians("target_direction", _real("target_direction", self.target_direction)))
        # SimConfig checks the model, the integrator, the timestep and the motor limits.
        put("_sim", SimConfig(model=self.model, robot=robot, gains=PDGains(kp=self.kp, kd=self.kd),
                              integrator=self.integrator, backend=self.backend, timestep=self.timestep,
                              legs=self.legs, torque_limit=self.torque_limit, leg_rate_limit=self.leg_rate_limit))
        put("forward_reward_weight", _real("forward_reward_weight", self.forward_reward_weight, weight=True))
        put("ctrl_cost_weight", _real("ctrl_cost_weight", self.ctrl_cost_weight, minimum=0.0, weight=True))
        put("reset_noise_scale", _real("reset_noise_scale", self.reset_noise_scale, minimum=0.0))
        if self.reset_noise_scale >= dynamics.TILT_LIMIT:  # (a tilt is below pi/2 while both tilting angles are)
            raise ValueError(
                f"reset_noise_scale must be below pi/2 ({dynamics.TILT_LIMIT:.4g}), got {self.reset_noise_scale!r}: "
                "start angles drawn from U(-s, s) could tip the robot past the rim, where the model ends"
            )
        for name in ("exclude_current_positions_from_observation", "terminate_outside_model"):
            put(name, _flag(name, getattr(self, name)))
        if self.friction_coefficient is not None:
            put("friction_coefficient", _real("friction_coefficient", self.friction_coefficient, positive=True))
        put("max_slip_velocity", _real("max_slip_velocity", self.max_slip_velocity, positive=True))
        put("max_liftoff_time", _real("max_liftoff_time", self.max_liftoff_time, minimum=0.0))
        put("healthy_reward", _real("healthy_reward", self.healthy_reward, minimum=0.0, weight=True))
        if self.clock_frequency is not None:
            put("clock_frequency", _real("clock_frequency", self.clock_frequency, positive=True))
            if self.clock_frequency >= math.pi / self.dt:
                raise ValueError(
                    f"clock_frequency must be below pi / dt = {math.pi / self.dt:.4g} rad/s (dt = {self.dt:.4g} s, the "
                    f"control step), got {self.clock_frequency!r}: seen once a step, a faster clock aliases to a slower one"
                )
        _choice("action_hold", self.action_hold, ACTION_HOLDS)
        put("_ranges", randomization_ranges(self.randomize, self))
        _choice("contact_quadrature", self.contact_quadrature, validity.QUADRATURES)
        params = _kernel_params_of(self)
        params.setflags(write=False)
        put("_kernel_params", params)

    @property
    def sim(self) -> SimConfig:
        """The simulator's configuration built from the physics keywords."""
        return self._sim

    @property
    def dt(self) -> float:
        """s, one control step: frame_skip integrator steps of sim.step."""
        return self.frame_skip * self.sim.step

    @property
    def num_robot_legs(self) -> int:
        """The robot's legs: the action's size, a state's 9 + 2 x this."""
        return self.sim.robot.num_legs

    @property
    def observation_size(self) -> int:
        size = 11 + 2 * self.num_robot_legs + (0 if self.exclude_current_positions_from_observation else 2)
        return size + (2 if self.clock_frequency is not None else 0)

    @property
    def kernel_params(self) -> np.ndarray:
        """The scene's scalars as the task's kernels read them (:data:`TASK_PARAMS`; read-only)."""
        return self._kernel_params

    @property
    def ranges(self) -> dict:
        """{name: :class:`Range`} of what :func:`draw_robots` varies ({} without ``randomize``)."""
        return self._ranges

    def to_kwargs(self) -> dict:
        """The env keywords that rebuild this config (``make_task_config(**config.to_kwargs())``)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


def config_to_json(config: TaskConfig) -> dict:
    """Every env keyword of ``config`` as JSON-able values (``robot`` as a dict of its fields)."""
    kwargs = config.to_kwargs()
    kwargs["robot"] = dataclasses.asdict(config.robot)
    return kwargs


def kwargs_from_json(data: dict) -> dict:
    """The env keywords saved by :func:`config_to_json` (a subset is fine: the rest default)."""
    kwargs = dict(data)
    if isinstance(kwargs.get("robot"), dict):
        kwargs["robot"] = RobotParams(**kwargs["robot"])
    return kwargs


KEYWORDS = tuple(f.name for f in dataclasses.fields(TaskConfig))
"""The env keywords, in order: the fields of :class:`TaskConfig`."""


def make_task_config(**kwargs) -> TaskConfig:
    """Validate the env keywords (the fields of :class:`TaskConfig`) and collect them: a TypeError
    for an unknown keyword or a wrong type, a ValueError for a bad value, naming the keyword."""
    unknown = [name for name in kwargs if name not in KEYWORDS]
    if unknown:
        hints = []
        for name in unknown:
            close = difflib.get_close_matches(name, KEYWORDS, n=1)
            hints.append(f"{name!r}" + (f" (did you mean {close[0]!r}?)" if close else ""))
        raise TypeError(f"RRRobot-v0 got unknown keyword argument(s) {', '.join(hints)}; it takes {', '.join(KEYWORDS)}")
    return TaskConfig(**kwargs)


def arguments_table(extra_rows=()) -> str:
    """The Markdown Arguments table of the env keywords (plus ``extra_rows``: (name, type, default, doc))."""
    rows = [
        (f"`{f.name}`", f"**{f.type.replace('|', chr(92) + '|')}**", f.metadata["shown"] or _shown(f.default), f.metadata["doc"])
        for f in dataclasses.fields(TaskConfig)
    ]
    rows += [(f"`{name}`", f"**{kind}**", default, doc) for name, kind, default, doc in extra_rows]
    header = ("Parameter", "Type", "Default", "Description")
    widths = [max(len(row[i]) for row in rows + [header]) for i in range(3)]
    lines = [
        "| " + " | ".join(h.ljust(w) for h, w in zip(header[:3], widths)) + " | Description |",
        "|" + "|".join("-" * (w + 2) for w in widths) + "|-------------|",
    ]
    lines += ["| " + " | ".join(c.ljust(w) for c, w in zip(row[:3], widths)) + f" | {row[3]} |" for row in rows]
    return "\n".join(lines)


def _shown(default) -> str:
    return f'`"{default}"`' if isinstance(default, str) else f"`{default!r}`"


def signature_with_keywords(function, *, before=(), after=()) -> inspect.Signature:
    """``function``'s signature with its ``**kwargs`` replaced by the env keywords, between its
    keyword-only parameters named in ``before`` and ``after`` (e.g. ``render_mode``)."""
    own = [p for p in inspect.signature(function).parameters.values() if p.kind is not inspect.Parameter.VAR_KEYWORD]
    positional = [p for p in own if p.kind is not inspect.Parameter.KEYWORD_ONLY]
    keyword_only = {p.name: p for p in own if p.kind is inspect.Parameter.KEYWORD_ONLY}
    params = positional + [keyword_only.pop(n) for n in before] + [
        inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, default=f.default, annotation=f.type)
        for f in dataclasses.fields(TaskConfig)
    ]
    params += [keyword_only.pop(n) for n in after] + list(keyword_only.values())
    return inspect.Signature(params)


# ---------------------------------------------------------------------------
# Spaces


def single_action_space(config: TaskConfig) -> spaces.Box:
    """One number a leg, in [-1, 1]."""
    return spaces.Box(-1.0, 1.0, shape=(config.num_robot_legs,), dtype=np.float32)


def single_observation_space(config: TaskConfig) -> spaces.Box:
    """Unit vectors and the commanded direction are bounded by 1; rates, angles and positions are not."""
    low = np.full(config.observation_size, -np.inf, dtype=np.float32)
    high = np.full(config.observation_size, np.inf, dtype=np.float32)
    legs = config.num_robot_legs
    bounded = np.r_[0:6, 9 + 2 * legs : 11 + 2 * legs]
    if config.clock_frequency is not None:
        bounded = np.r_[bounded, config.observation_size - 2 : config.observation_size]
    low[bounded], high[bounded] = -1.0, 1.0
    return spaces.Box(low, high, dtype=np.float32)


# ---------------------------------------------------------------------------
# Actions


def check_actions(action, shape) -> np.ndarray:
    """``action`` as float64 of the given shape, clipped to [-1, 1]; a wrong shape or a NaN/inf
    entry (a caller's bug, where an out-of-range value is an ordinary policy output) raises."""
    try:
        arr = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"action must be an array of numbers of shape {shape}, got {action!r}") from None
    if arr.shape != tuple(shape):
        raise ValueError(f"action must have shape {tuple(shape)}, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"action contains NaN or inf: {arr.tolist()}")
    # (ndarray methods, not np.clip/np.all: their dispatch costs more than the work at N = 1)
    return arr.clip(-1.0, 1.0)


def check_observations(observation, size: int) -> np.ndarray:
    """``observation`` ((size,) or (n, size)) as float64 for a policy of ``size`` inputs, or a
    ValueError naming a wrong shape or a NaN/inf entry."""
    observation = np.asarray(observation, dtype=np.float64)
    if observation.ndim not in (1, 2) or observation.shape[-1] != size:
        raise ValueError(
            f"observations must have shape ({size},) or (n, {size}) for this policy, got {observation.shape}"
        )
    if not np.all(np.isfinite(observation)):
        raise ValueError("observations contain NaN or inf")
    return observation


def action_to_leg_targets(action):
    """rad, the leg target angles of actions in [-1, 1] (affine: -1 -> -pi/4, 0 -> pi/2, +1 -> 5pi/4)."""
    return _LEG_TARGET_MID + _LEG_TARGET_HALF_RANGE * np.asarray(action, dtype=np.float64)


def leg_targets_to_action(leg_targets):
    """The inverse of :func:`action_to_leg_targets` (not clipped): script a gait through the env."""
    return (np.asarray(leg_targets, dtype=np.float64) - _LEG_TARGET_MID) / _LEG_TARGET_HALF_RANGE


# ---------------------------------------------------------------------------
# Start state


def draw_start(rng: np.random.Generator, config: TaskConfig):
    """One robot's start noise (6 + 2L,) U(-s, s), s = reset_noise_scale, then its heading (rad; drawn
    U(-pi, pi) if ``config.target_direction`` is None) from ``rng``: the single env and each
    sub-env draw alike. :func:`start_states` turns the noise into states."""
    noise = draw_noise(rng, config.reset_noise_scale, config.num_robot_legs)
    target = float(rng.uniform(-math.pi, math.pi)) if config.target_direction is None else config.target_direction
    return noise, target


def draw_noise(rng: np.random.Generator, scale: float, num_legs: int = 2) -> np.ndarray:
    """One robot's start noise (6 + 2L,), U(-scale, scale), for :func:`start_states`."""
    return rng.uniform(-scale, scale, size=6 + 2 * num_legs)


def start_states(noise):
    """States (N, 9 + 2L): the paper's start (at rest at the origin, upright, legs vertical) plus
    noise (N, 6 + 2L) on the paper's attitude angles (rad, 0:3), the leg angles (rad, 3:3 + L), the
    body angular velocity (rad/s, body frame, 3 + L:6 + L) and the leg rates (rad/s, 6 + L:)."""
    noise = np.asarray(noise, dtype=np.float64)
    legs = (noise.shape[1] - 6) // 2
    fields = dynamics.state_fields(legs)
    states = np.zeros((len(noise), fields.size))
    states[:, fields.quat] = dynamics.quat_from_paper_angles(noise[:, 0:3])
    states[:, fields.leg_angles] = 0.5 * math.pi + noise[:, 3 : 3 + legs]
    states[:, fields.body_rate] = noise[:, 3 + legs : 6 + legs]
    states[:, fields.leg_rates] = noise[:, 6 + legs :]
    return states


def parse_reset_options(options, num_envs: int | None, num_legs: int = 2):
    """Validate ``reset(options=...)`` for robots of ``num_legs`` legs: (states or None, targets or
    None). ``num_envs`` None is the single env (one state, one heading); a vector env takes one
    state or one heading for all, or one each."""
    if options is None:
        return None, None
    if not isinstance(options, dict):
        raise TypeError(f"options must be a dict, got {type(options).__name__}")
    unknown = set(options) - set(RESET_OPTIONS)
    if unknown:
        raise ValueError(f"unknown reset option(s) {sorted(unknown)}: expected some of {list(RESET_OPTIONS)}")
    states = targets = None
    if options.get("state") is not None:
        size = dynamics.state_fields(num_legs).size
        try:
            states = check_state(options["state"], num_legs)
        except ValueError as error:
            raise ValueError(f"options['state']: {error}") from None
        if num_envs is None:
            if states.ndim != 1:
                raise ValueError(f"options['state'] must have shape ({size},), got {states.shape}")
        else:
            states = np.broadcast_to(states, (num_envs, size)).copy() if states.ndim == 1 else states
            if states.shape != (num_envs, size):
                raise ValueError(f"options['state'] must have shape ({size},) or ({num_envs}, {size}), got {states.shape}")
        start_tilt = np.max(dynamics.tilt(states))
        if start_tilt >= dynamics.TILT_LIMIT:
            raise ValueError(
                f"options['state'] starts at tilt {start_tilt:.4g} rad, at or past the rim limit "
                f"{dynamics.TILT_LIMIT:.4g} rad where the model ends"
            )
    if options.get("target_direction") is not None:
        value = options["target_direction"]
        if num_envs is None:
            targets = check_radians("options['target_direction']", _real("options['target_direction']", value))
        else:
            targets = headings("options['target_direction']", value, num_envs)
    return states, targets


def headings(label: str, value, num_envs: int) -> np.ndarray:
    """(num_envs,) finite headings, rad, from a number (every sub-env's; also as one-element
    array) or ``num_envs`` numbers, or an error naming ``label``."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{label} must be a number or {num_envs} numbers (rad), got {value!r}") from None
    if array.shape not in ((), (1,), (num_envs,)):
        raise ValueError(f"{label} must be a number or {num_envs} numbers (rad), got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{label} must be finite, got {value!r}")
    check_radians(label, array)
    return np.array(np.broadcast_to(array, (num_envs,)))


def check_radians(label: str, headings):
    """``headings`` (rad; a number or an array of finite ones), or a ValueError naming ``label``
    where one lies more than a full turn from 0: degrees given where radians were meant."""
    beyond = np.abs(headings) > 2.0 * np.pi
    if np.any(beyond):
        first = float(np.asarray(headings)[beyond].flat[0]) if np.ndim(headings) else float(headings)
        raise ValueError(f"{label} is in radians: {first!r} is more than a full turn (2 pi) from 0; "
                         f"for degrees, convert with np.deg2rad({first!r})")
    return headings


def check_start_states(states, config: TaskConfig) -> None:
    """Raise ValueError where a reset's ``options['state']`` (N, 13) gives a non-finite float32
    observation: values beyond float32's range."""
    observations = observe(states, np.zeros(len(states)), config, np.zeros(len(states)))
    bad = np.flatnonzero(~np.isfinite(observations).all(axis=1))
    if bad.size:
        which = "" if len(states) == 1 else f" of sub-env(s) {bad.tolist()}"
        raise ValueError(
            f"options['state']{which} gives a non-finite observation: a value beyond float32's range (3.4e38)"
        )


# ---------------------------------------------------------------------------
# Observation, reward, termination


def observe(states, targets, config: TaskConfig, times=None, rows=None, heading=None) -> np.ndarray:
    """Observations (N, config.observation_size) float32 (layout :data:`OBSERVATION_FIELDS`) of
    states (N, 13), targets (N,) rad and ``times`` (N,) s since each episode began (for the clock):
    :func:`observe_into` on the batch. ``rows`` and ``heading``: the states' :func:`rotation_rows`
    and the targets' :func:`heading_vectors`, if the caller already has them."""
    rows = rotation_rows(states) if rows is None else rows
    cos_t, sin_t = heading_vectors(targets) if heading is None else heading
    times = np.zeros(len(states)) if times is None else np.asarray(times, dtype=float)
    # Filled by rows, then transposed: writing columns of (N, size) is a strided write, slower.
    obs = np.empty((config.observation_size, len(states)), dtype=np.float32)
    # A blown-up state may overflow float32; finite_rows() catches that, so no warning here.
    with np.errstate(over="ignore", invalid="ignore"):
        observe_into(obs, states.T, rows, cos_t, sin_t, times, config.kernel_params)
    return obs.T.copy()


def mirror_observations(observations, config: TaskConfig) -> np.ndarray:
    """Observations (..., observation_size) of the mirror image of the scene, for a robot with that
    symmetry (:func:`rrrobot_gym.dynamics.mirror_legs`): ``observe(mirror_states(s), -t)`` ==
    ``mirror_observations(observe(s, t))`` (exactly where no leg is flipped: a flipped leg's angle
    becomes pi - angle in float32) (:func:`rrrobot_gym.dynamics.mirror_states`; actions:
    :func:`mirror_actions`). Vectors' y entries and the body rate's x and z change sign, each leg
    takes its image's angle and rate; positions' y changes sign; a gait clock keeps its entries."""
    obs = np.asarray(observations, dtype=np.float32)
    if obs.shape[-1:] != (config.observation_size,):
        raise ValueError(f"observations must end in {config.observation_size} entries, got shape {obs.shape}")
    robot = config.sim.robot
    legs = _mirror_legs(robot)
    num_legs = robot.num_legs
    out = obs.copy()
    for m in (1, 4, 6, 8, 10 + 2 * num_legs):  # up and heading in the body (y), the body rate (x, z), the heading's sin
        out[..., m] = -obs[..., m]
    if not config.exclude_current_positions_from_observation:
        out[..., 12 + 2 * num_legs] = -obs[..., 12 + 2 * num_legs]
    for k, (j, flipped) in enumerate(legs):
        angle, rate = obs[..., 9 + k], obs[..., 9 + num_legs + k]
        out[..., 9 + j] = np.float32(math.pi) - angle if flipped else angle
        out[..., 9 + num_legs + j] = -rate if flipped else rate
    return out


def mirror_actions(actions, robot: RobotParams | None = None) -> np.ndarray:
    """The mirror image of actions (..., L): each leg takes its image's target (a flipped leg's
    negated: its target pi - target, the actions' middle being pi/2)."""
    robot = RobotParams() if robot is None else robot
    actions = np.asarray(actions)
    if actions.shape[-1:] != (robot.num_legs,):
        raise ValueError(f"actions must end in {robot.num_legs} entries (one per leg), got shape {actions.shape}")
    out = actions.copy()
    for k, (j, flipped) in enumerate(_mirror_legs(robot)):
        out[..., j] = -actions[..., k] if flipped else actions[..., k]
    return out


def _mirror_legs(robot: RobotParams):
    """:func:`rrrobot_gym.dynamics.mirror_legs`, or a ValueError for a robot without the symmetry."""
    legs = dynamics.mirror_legs(robot)
    if legs is None:
        raise ValueError("this robot has no mirror symmetry in its x-z plane (its legs are not in mirrored pairs): "
                         "the heading mirror does not apply to it")
    return legs


def rotation_rows(states):
    """Rows of R(quat) of states (N, 13) (:func:`rrrobot_gym.dynamics.rotation_rows`): Python
    floats for one robot (numpy's per-call overhead would dominate), (N,) arrays for a batch."""
    if len(states) == 1:
        return dynamics.rotation_rows(*states[0, 2:6].tolist())
    return dynamics.rotation_rows(states[:, 2], states[:, 3], states[:, 4], states[:, 5])


def heading_vectors(targets):
    """cos and sin of the headings ``targets`` (N,) rad (:func:`rrrobot_gym.numerics.sincos`, the same
    bits on every CPU): Python floats for one robot (as :func:`rotation_rows`), (N,) arrays for a batch."""
    targets = float(targets[0]) if len(targets) == 1 else np.asarray(targets, dtype=float)
    sin_t, cos_t = sincos(targets)
    return cos_t, sin_t


def upright_contact_points(states, config: TaskConfig, rows=None):
    """(N, 2) m: where the contact point would be if the shell rolled back upright without slip
    (:func:`upright_pose`). ``rows``: the states' :func:`rotation_rows`, if already computed."""
    rows = rotation_rows(states) if rows is None else rows
    points = np.empty((len(states), 2))  # (cheaper than np.stack for one robot)
    points[:, 0], points[:, 1], _ = upright_pose(states[:, 0], states[:, 1], rows, config.kernel_params)
    return points


def reset_info(states, targets, config: TaskConfig, rows=None, draws=None):
    """The info of a start: (N,) arrays keyed as in :data:`RESET_INFO_KEYS` (``rows``: the
    states' :func:`rotation_rows`, if already computed), and with ``draws`` (:func:`draw_robots`)
    each drawn quantity as ``"randomized_" + name``."""
    rows = rotation_rows(states) if rows is None else rows
    x_upright, y_upright, tilt = upright_pose(states[:, 0], states[:, 1], rows, config.kernel_params)
    return {
        **{"randomized_" + name: values.copy() for name, values in (draws or {}).items()},
        "x_position": states[:, 0].copy(),
        "y_position": states[:, 1].copy(),
        "x_upright": x_upright,
        "y_upright": y_upright,
        "tilt": np.array(tilt, dtype=float, ndmin=1),  # (a copy; (1,) from one robot's float)
        "target_direction": np.array(targets, dtype=np.float64),
    }


def step_outcome(
    states_before, states_after, targets, actions, failed, config: TaskConfig, measures, elapsed, upright_before=None,
    rows_after=None, heading=None,
):
    """Reward (N,), terminated (N,) and info (dict of (N,) arrays, :data:`STEP_INFO_KEYS`) of one
    control step: :func:`outcome` on the batch, the RRRobotEnv docstring's Rewards and Episode End.
    A ``failed`` robot (numerical blow-up; its ``states_after`` is its last finite state) gets
    reward 0 and terminates. ``upright_before`` (N, 2), ``rows_after`` and ``heading``: the
    :func:`upright_contact_points` of ``states_before``, the :func:`rotation_rows` of
    ``states_after`` and the targets' :func:`heading_vectors`, if the caller already has them.
    """
    info = reset_info(states_after, targets, config, rows_after)
    before = upright_contact_points(states_before, config) if upright_before is None else upright_before
    cos_t, sin_t = heading_vectors(targets) if heading is None else heading
    failed = np.array(failed, dtype=bool)
    values = outcome(
        states_before[:, 0], states_before[:, 1], states_after[:, 0], states_after[:, 1], before[:, 0], before[:, 1],
        info["x_upright"], info["y_upright"], cos_t, sin_t, effort(np.asarray(actions, dtype=float).T), failed,
        info["tilt"], measures["leg_clearance"], measures["liftoff_time"], measures["slip_velocity"],
        np.asarray(elapsed, dtype=float), config.kernel_params,
    )  # fmt: skip
    n = len(states_after)
    reward, outside, terminated, reason = (np.array(np.broadcast_to(v, (n,))) for v in values[1:])
    for key, value in zip(OUTCOME_KEYS, values[0]):
        info[key] = np.array(np.broadcast_to(value, (n,)), dtype=float)
    info.update((key, measures[key]) for key in MEASURE_KEYS)  # (N,) float64 arrays (validity.step_measures)
    info["numerical_failure"] = failed
    info["outside_model"] = outside
    info["termination"] = np.array(TERMINATIONS)[reason.astype(int)]
    return reward.astype(float), terminated, info


def failed_measures(num_robots: int) -> dict:
    """The measures reported for robots whose step failed numerically (NaN; they terminate anyway)."""
    return {key: np.full(num_robots, np.nan) for key in MEASURE_KEYS}


def step_targets(actions, previous_targets, previous_rates, config: TaskConfig, t: float = 0.0):
    """The servo's reference over one control step from ``t``: (the leg-target source the
    integrator follows, the reference at the step's end (rad), its rate over the step (rad/s)),
    each target and rate array shaped as ``actions`` ((2,) or (N, 2)).

    Each action names a target angle (:func:`action_to_leg_targets`). With no
    ``leg_accel_limit`` the reference ends the step there. With one, a motion profile moves it
    from ``previous_targets`` at ``previous_rates``: its rate heads for the fastest that can
    still stop at the target, steps of dt slowing it by a dt each (sqrt(2 a |error| + (a dt / 2)^2)
    - a dt / 2; at most ``leg_rate_limit`` and the error over a step), changing by at most a dt
    per step, a the limit. ``action_hold`` "linear" ramps the reference through the step at that
    rate; "zero_order" holds its end.
    """
    end, rates = servo_reference(np.asarray(actions, dtype=np.float64), previous_targets, previous_rates,
                                 config.kernel_params)
    return held_targets(previous_targets, end, config, t), end, rates


def profile_rates(error, previous_rates, dt, accel_limit, rate_limit):
    """The motion profile's rate over a step (:func:`step_targets`) of a reference ``error`` (rad)
    short of its target, at ``previous_rates`` (rad/s) before, with ``accel_limit`` (rad/s^2) and a
    top speed ``rate_limit`` (rad/s, inf: none); floats or arrays. Also compiled (:data:`KERNELS`)."""
    size = np.abs(error)
    half = 0.5 * accel_limit * dt  # (the continuous sqrt(2 a e) overshoots by up to half a step)
    wanted = np.minimum(np.minimum(np.sqrt(2.0 * accel_limit * size + half * half) - half, size / dt), rate_limit)
    change = accel_limit * dt
    return np.minimum(np.maximum(np.copysign(wanted, error), previous_rates - change), previous_rates + change)


def held_targets(start, end, config: TaskConfig, t: float = 0.0):
    """The leg-target source of a control step from ``t`` whose reference goes from ``start`` to
    ``end`` (rad): a ramp (``action_hold`` "linear") or ``end`` held ("zero_order")."""
    if config.action_hold == "linear":
        return RampTargets(start, end, t, config.dt)
    return HeldTargets(end)


def advance_and_check(states, held, t: float, config: TaskConfig, contact_lost, workers=1, draws=None):
    """One control step of ``states`` ((13,) or (N, 13)) from ``t``, the legs' servo following
    ``held`` (:func:`step_targets`). ``contact_lost`` (N,) s: how long each shell had been off the
    ground when the step began.

    Returns (states after, measures: (N,) arrays keyed :data:`MEASURE_KEYS` from the step's
    :class:`rrrobot_gym.simulation.StepRecord`, contact_lost after); raises
    :data:`NUMERICAL_FAILURES`. ``draws``: the robots' randomized quantities (:func:`draw_robots`).
    """
    physics, friction = robot_physics(draws or {})
    kwargs = {} if physics is None else {"robots": physics}
    states, record = advance(config.sim, states, t, config.dt, held, check=False, record=True, workers=workers, **kwargs)
    with np.errstate(all="ignore"):
        measures, contact_lost = validity.step_measures(
            record, config.sim, config.friction_coefficient if friction is None else friction, contact_lost,
            config.contact_quadrature, **kwargs,
        )
    return states, measures, contact_lost


STARTUP_GRACE = 0.1
"""s: slipping is allowed for this long into an episode (the paper's start, legs leaving vertical
abruptly, makes even the Table II gaits slip at up to 0.63 m/s for an instant)."""


def finite_rows(states, observations):
    """True for robots whose state and float32 observation (which a huge state overflows) are finite."""
    if len(states) < FINITE_BY_DOT_MIN:
        return np.isfinite(states).all(axis=1) & np.isfinite(observations).all(axis=1)
    # A row's dot product with zeros is NaN if any entry is inf or NaN: one pass over the batch.
    with np.errstate(invalid="ignore"):
        zeros_state, zeros_obs = np.zeros(states.shape[1]), np.zeros(observations.shape[1], observations.dtype)
        return np.isfinite(np.einsum("ij,j->i", states, zeros_state)) & np.isfinite(
            np.einsum("ij,j->i", observations, zeros_obs)
        )


FINITE_BY_DOT_MIN = 256
"""Batches from this size on are checked by :func:`finite_rows`' dot products (faster for large batches)."""


# ---------------------------------------------------------------------------
# The task's arithmetic, written once: every function below takes one robot's floats (the compiled
# step calls them robot by robot, rrrobot_gym.compiled compiles them from this source) or a batch's
# arrays (the numpy functions above call them), and uses only operations that round the same on
# every CPU (rrrobot_gym.numerics), so both give the same bits anywhere.

TASK_PARAMS = ("dt", "h", "n_steps", "accel_limit", "profile_rate_limit", "linear", "plane", "max_slip_velocity",
               "max_liftoff_time", "forward_scale", "ctrl_cost_weight", "healthy_reward", "terminate_outside_model",
               "axis_a", "axis_b", "axis_c", "clock_frequency", "positions", "grace", "tilt_limit")  # fmt: skip
"""The scalars the kernels read from one array (:attr:`TaskConfig.kernel_params`), in this order: 0 or
1 for flags; an accel limit or clock frequency of 0: none; a profile rate limit of inf: none."""
(_DT, _H, _N_STEPS, _ACCEL_LIMIT, _PROFILE_RATE_LIMIT, _LINEAR, _PLANE, _MAX_SLIP, _MAX_LIFTOFF, _FORWARD_SCALE,
 _CTRL_COST, _HEALTHY, _TERMINATE_OUTSIDE, _AXIS_A, _AXIS_B, _AXIS_C, _CLOCK, _POSITIONS, _GRACE,
 _TILT_LIMIT) = range(len(TASK_PARAMS))  # fmt: skip
OUTCOME_KEYS = ("x_velocity", "y_velocity", "forward_velocity", "reward_forward", "reward_ctrl", "reward_survive")
"""The info entries of :func:`outcome`'s first value, in order."""


def _kernel_params_of(config: TaskConfig) -> np.ndarray:
    """:data:`TASK_PARAMS` of a config, as the kernels read them."""
    n_steps, h = simulation._substeps(config.dt, config.sim.step)
    values = dict(
        dt=config.dt, h=h, n_steps=n_steps, accel_limit=config.leg_accel_limit or 0.0,
        profile_rate_limit=np.inf if config.leg_rate_limit is None else config.leg_rate_limit,
        linear=config.action_hold == "linear", plane=config.sim.model == "plane", max_slip_velocity=config.max_slip_velocity,
        max_liftoff_time=config.max_liftoff_time, forward_scale=config.forward_reward_weight * FORWARD_VELOCITY_UNIT,
        ctrl_cost_weight=config.ctrl_cost_weight, healthy_reward=config.healthy_reward,
        terminate_outside_model=config.terminate_outside_model, axis_a=config.sim.robot.shell_axes[0],
        axis_b=config.sim.robot.shell_axes[1], axis_c=config.sim.robot.shell_axes[2],
        clock_frequency=config.clock_frequency or 0.0, positions=not config.exclude_current_positions_from_observation,
        grace=STARTUP_GRACE - 1e-9, tilt_limit=dynamics.TILT_LIMIT,
    )  # fmt: skip
    return np.array([float(values[name]) for name in TASK_PARAMS])


def servo_reference(action, start, previous_rate, p):
    """(end, rate): the servo's reference at the end of a control step (rad) and its rate over the
    step (rad/s), from an ``action`` in [-1, 1] (its target, :func:`action_to_leg_targets`), the
    reference's ``start`` and its ``previous_rate``: :func:`step_targets`' motion profile."""
    goal = _LEG_TARGET_MID + _LEG_TARGET_HALF_RANGE * action
    dt = p[_DT]
    if p[_ACCEL_LIMIT] > 0.0:
        rate = profile_rates(goal - start, previous_rate, dt, p[_ACCEL_LIMIT], p[_PROFILE_RATE_LIMIT])
        return start + rate * dt, rate
    return goal, (goal - start) / dt


def observe_into(o, c, rows, cos_t, sin_t, time, p):
    """The observation (layout :data:`OBSERVATION_FIELDS`) into ``o`` (float32, entries first) of a
    state's components ``c``, their :func:`rotation_rows`, the heading's cos and sin and the
    episode's ``time`` (s, for the clock)."""
    for m in range(3):
        o[m] = rows[2][m]
        # (R^T d)_m = R_0m d_x + R_1m d_y, with d horizontal.
        o[3 + m] = rows[0][m] * cos_t + rows[1][m] * sin_t
    for m in range(6):  # (in float32, where a unit vector's rounding could pass 1)
        o[m] = np.minimum(np.maximum(o[m], -1.0), 1.0)
    legs = (len(c) - 9) // 2
    for m in range(3):
        o[6 + m] = c[6 + legs + m]
    for m in range(legs):
        o[9 + m], o[9 + legs + m] = c[6 + m], c[9 + legs + m]
    o[9 + 2 * legs], o[10 + 2 * legs] = cos_t, sin_t
    end = 11 + 2 * legs
    if p[_POSITIONS] > 0.0:
        o[end], o[end + 1] = c[0], c[1]
        end = end + 2
    if p[_CLOCK] > 0.0:  # a gait clock: with it a sinusoidal gait is a linear function of the observation
        o[end], o[end + 1] = sincos(p[_CLOCK] * time)


# Gauss-Legendre's 8 nodes and weights on [0, 1], for the shell's meridian arc (upright_pose)
_ARC_NODES = (0.019855071751231856, 0.10166676129318664, 0.2372337950418355, 0.4082826787521751,
              0.5917173212478249, 0.7627662049581645, 0.8983332387068134, 0.9801449282487681)
_ARC_WEIGHTS = (0.05061426814518813, 0.11119051722668724, 0.15685332293894363, 0.18134189168918100,
                0.18134189168918100, 0.15685332293894363, 0.11119051722668724, 0.05061426814518813)


def upright_pose(x, y, rows, p):
    """(x, y) of the upright contact point (m) and the tilt (rad) of a contact point (x, y) and its
    attitude's :func:`rotation_rows`, for the shell of ``p``'s semi-axes.

    The upright contact point is where the contact point would be if the shell rolled back
    upright without slip along its meridian: by the meridian's arc from the contact to the bottom
    pole, against the body axis's horizontal lean b_h = (R[0, 2], R[1, 2]), |b_h| = sin(tilt). On a
    sphere that arc is r tilt, so the point is p - r (tilt / sin(tilt)) b_h. It stays put while the
    shell rocks or tips over, and moves only with net travel."""
    lean_x, lean_y, cos_tilt = rows[0][2], rows[1][2], rows[2][2]
    sin_tilt = np.sqrt(lean_x * lean_x + lean_y * lean_y)
    tilt = arctan2(sin_tilt, cos_tilt)
    # the contact in the body, s = -A n / sqrt(n^T A n), n = rows[2]; its meridian's ellipse
    a, b, c = p[_AXIS_A], p[_AXIS_B], p[_AXIS_C]
    nx, ny = rows[2][0], rows[2][1]
    anx, bny = a * a * nx, b * b * ny
    h = np.sqrt(anx * anx + bny * bny)  # the horizontal part of A n (the contact's, times sqrt(n^T A n))
    off_pole = h > 1e-12 * c
    safe = select(off_pole, h, 1.0)
    # the contact's horizontal direction in the body (any one at the pole, where the arc is 0)
    ux, uy = select(off_pole, anx / safe, 1.0), select(off_pole, bny / safe, 0.0)
    rho = 1.0 / np.sqrt((ux * ux) / (a * a) + (uy * uy) / (b * b))  # the equator's radius that way
    # the contact's angle from the pole on the meridian (rho sin beta, -c cos beta): tan beta = h / (rho c n_z)
    beta = arctan2(h, rho * c * cos_tilt)
    if anywhere((a != c) | (b != c)):  # an ellipsoid's meridian: its arc by quadrature
        arc = 0.0
        for j in range(8):
            t = beta * _ARC_NODES[j]
            st, ct = sincos(t)
            arc = arc + _ARC_WEIGHTS[j] * np.sqrt(rho * rho * (ct * ct) + c * c * (st * st))
        arc = arc * beta
    else:  # a sphere's: a circle's arc
        arc = c * beta
    # arc / sin(tilt) -> the pole's radius of curvature as the shell comes upright (lean undefined)
    leaning = sin_tilt > 1e-9
    scale = select(leaning, arc / select(leaning, sin_tilt, 1.0), select(off_pole, rho * rho / c, a * a / c))
    return x - scale * lean_x, y - scale * lean_y, tilt


def effort(actions):
    """The sum of the squares of one robot's actions, leg by leg (``actions`` (legs,) or (legs, N))."""
    total = actions[0] * actions[0]
    for k in range(1, len(actions)):
        total = total + actions[k] * actions[k]
    return total


def outcome(x_before, y_before, x_after, y_after, upright_x_before, upright_y_before, upright_x, upright_y, cos_t,
            sin_t, action_effort, failed, tilt, leg_clearance, liftoff_time, slip_velocity, elapsed, p):
    """(the step's velocities and reward terms (:data:`OUTCOME_KEYS`), the reward, outside the
    model, terminated, why (an index into :data:`TERMINATIONS`)): the RRRobotEnv docstring's
    Rewards and Episode End, from the contact point and upright contact point before
    and after (m), the heading's cos and sin, :func:`effort`, whether the step ``failed``
    numerically, the tilt after and the step's measures, and ``elapsed`` (s) at its start."""
    dt = p[_DT]
    x_velocity = select(failed, 0.0, (x_after - x_before) / dt)
    y_velocity = select(failed, 0.0, (y_after - y_before) / dt)
    forward = select(failed, 0.0, ((upright_x - upright_x_before) * cos_t + (upright_y - upright_y_before) * sin_t) / dt)
    reward_forward = select(failed, 0.0, p[_FORWARD_SCALE] * forward)
    reward_ctrl = select(failed, 0.0, -p[_CTRL_COST] * action_effort)
    beside = leg_clearance <= 0.0  # a leg tip at or below the floor
    lifted = slipped = beside & False
    if p[_PLANE] > 0.0:
        # Slip and lift-off leave the model from the end of the start-up grace, where slip is forgiven.
        started = elapsed >= p[_GRACE]
        lifted, slipped = started & (liftoff_time > p[_MAX_LIFTOFF]), started & (slip_velocity > p[_MAX_SLIP])
        # Travel the floor could not have given earns nothing (else a policy learns to kick and
        # fall), nor does travel in the grace (a kick off the start).
        unearned = (liftoff_time > p[_MAX_LIFTOFF]) | (slip_velocity > p[_MAX_SLIP]) | (elapsed < p[_GRACE])
        reward_forward = select(unearned, 0.0, reward_forward)
    outside = select(failed, False, beside | lifted | slipped)
    tilted = tilt >= p[_TILT_LIMIT]
    reason = select(tilted, 2.0, 0.0)
    if p[_TERMINATE_OUTSIDE] > 0.0:
        reason = select(tilted, reason, select(beside, 3.0, select(lifted, 4.0, select(slipped, 5.0, 0.0))))
    reason = select(failed, 1.0, reason)  # (TERMINATIONS' order)
    terminated = reason > 0.0
    reward_survive = select(terminated, 0.0, p[_HEALTHY])
    terms = (x_velocity, y_velocity, forward, reward_forward, reward_ctrl, reward_survive)
    return terms, reward_forward + reward_ctrl + reward_survive, outside, terminated, reason


KERNELS = (profile_rates, servo_reference, observe_into, upright_pose, effort, outcome)
"""This module's functions :mod:`rrrobot_gym.compiled` compiles into the env's step (with
:func:`fused_step`, which calls them robot by robot)."""


INFO_ROWS = RESET_INFO_KEYS + OUTCOME_KEYS + MEASURE_KEYS + ("termination",)
"""The rows of :func:`fused_step`'s float info (its flags: numerical_failure, outside_model)."""
_physics = None  # (the compiled step's physics, given to its compiled copy by rrrobot_gym.compiled)
_quaternion_rows = dynamics.rotation_rows
_SUMMARY_ROWS = compiled.SUMMARY_ROWS


def fused_step(before, last_obs, previous_targets, previous_rates, applied, actions, heading, targets, elapsed,
               obs_times, contact_lost, upright_before, p, scene, torque_limit, rate_limit, robot, layout, friction, mass,
               y, ends, rates, obs, info, flags, rewards, terminated, lost_after):
    """One control step of the robots ``before`` (N, 13) into the arrays from ``y`` on, the env's
    whole step robot by robot (:class:`CompiledTask`): the kernels above, the physics (compiled
    lanes, with the record) and :func:`rrrobot_gym.validity.record_measures`. The caller makes
    the output arrays (numba's boxing of arrays it returns costs more than the caller's np.empty);
    ``scene``, ``torque_limit``, ``rate_limit``, ``robot`` and ``layout`` are the physics' (the shared
    scene's constants and gains in one array, or each robot's own; the legs'); ``friction`` (N,) the floors' grip
    (used where ``limited``), ``mass`` (N,) the robots'. Only compiled (``rrrobot_gym.compiled``)."""
    n, legs = before.shape[0], previous_targets.shape[1]
    dt, h, n_steps = p[_DT], p[_H], int(p[_N_STEPS])
    linear = p[_LINEAR] > 0.0
    params = np.empty((n, 4 * legs if linear else legs))
    for i in range(n):
        for j in range(legs):
            start = previous_targets[i, j]
            end, rate = servo_reference(applied[i, j], start, previous_rates[i, j], p)
            ends[i, j], rates[i, j] = end, rate
            if linear:  # control.RampTargets' parameters: start, end, change, slope
                change = end - start
                params[i, j], params[i, legs + j], params[i, 2 * legs + j], params[i, 3 * legs + j] = (
                    start, end, change, change / dt)
            else:
                params[i, j] = end
    y[:] = before
    rows = np.empty((n_steps, 3 * legs + 5, n))
    summary = np.empty((_SUMMARY_ROWS, n))
    _physics(y, h, n_steps, scene, torque_limit, rate_limit, linear, params, dt, layout, rows, summary, robot)
    size = last_obs.shape[1]
    limited = not np.isnan(friction[0]) if n else False
    out = np.empty(len(INFO_ROWS))
    for i in range(n):
        cos_t, sin_t = heading[0, i], heading[1, i]
        failed = False
        for j in range(y.shape[1]):
            if not np.isfinite(y[i, j]):
                failed = True
        if not failed:
            r = _quaternion_rows(y[i, 2], y[i, 3], y[i, 4], y[i, 5])
            observe_into(obs[i], y[i], r, cos_t, sin_t, obs_times[i], p)
            for j in range(size):
                if not np.isfinite(obs[i, j]):
                    failed = True
        if failed:  # the last finite state and observation, the servo's reference kept
            y[i] = before[i]
            obs[i] = last_obs[i]
            ends[i], rates[i] = previous_targets[i], previous_rates[i]
            r = _quaternion_rows(y[i, 2], y[i, 3], y[i, 4], y[i, 5])
            nan = np.nan
            measures = (nan, nan, nan, nan, nan, nan, nan, nan, nan, contact_lost[i])
        elif limited:
            measures = record_measures(
                rows[:, legs + 3, i], rows[:, legs + 4, i], summary[0, i], summary[1, i], summary[2, i], summary[3, i],
                summary[4, i], summary[5, i], contact_lost[i], friction[i], mass[i], h, p[_PLANE] > 0.0, legs)  # fmt: skip
        else:
            measures = record_measures(
                rows[:, legs + 3, i], rows[:, legs + 4, i], summary[0, i], summary[1, i], summary[2, i], summary[3, i],
                summary[4, i], summary[5, i], contact_lost[i], None, mass[i], h, p[_PLANE] > 0.0, legs)  # fmt: skip
        x_up, y_up, tilt = upright_pose(y[i, 0], y[i, 1], r, p)
        terms, reward, outside, done, reason = outcome(
            before[i, 0], before[i, 1], y[i, 0], y[i, 1], upright_before[i, 0], upright_before[i, 1], x_up, y_up, cos_t,
            sin_t, effort(actions[i]), failed, tilt, measures[5], measures[3], measures[4], elapsed[i], p)  # fmt: skip
        out[0], out[1], out[2], out[3], out[4], out[5] = y[i, 0], y[i, 1], x_up, y_up, tilt, targets[i]
        for m in range(len(terms)):
            out[6 + m] = terms[m]
        for m in range(9):
            out[6 + len(terms) + m] = measures[m]
        out[len(out) - 1] = reason
        lost_after[i] = measures[9]
        rewards[i] = reward
        terminated[i] = done
        flags[0, i], flags[1, i] = failed, outside
        for m in range(len(INFO_ROWS)):
            info[m, i] = out[m]


class CompiledTask:
    """One control step of N robots, task and physics, in one compiled call (:func:`fused_step`):
    the servo's motion profile (:func:`step_targets`), :func:`advance_and_check`, the observation
    (:func:`observe`) and :func:`step_outcome`, robot by robot, each calling the same kernels as
    these numpy functions, which the envs run where it does not apply (:meth:`applies`)."""

    def __init__(self, config: TaskConfig, num_envs: int):
        self.config = config
        sim = config.sim
        self._params = config.kernel_params
        k, gains, self._layout = compiled._scene(sim.robot, sim.model, sim.gains)
        self._shared = np.array([*k, *gains], dtype=float)
        self.set_robots({}, num_envs)

    @staticmethod
    def applies(config: TaskConfig, workers: int = 1) -> bool:
        """True where the compiled step covers the scene: the compiled stepper's (one worker), a fixed
        timestep and the rectangle quadrature."""
        return (workers == 1 and simulation.takes_compiled(config.sim) and not isinstance(config.timestep, str)
                and config.contact_quadrature == "rectangle")  # fmt: skip

    def set_robots(self, draws: dict, num_envs: int) -> None:
        """The robots to step from now on: :func:`draw_robots`' draws ({} for the env's own)."""
        sim = self.config.sim
        physics, friction = robot_physics(draws)
        if physics is None:
            self._robot = (sim.torque_limit, sim.leg_rate_limit, np.empty(0))
            self._mass = np.full(num_envs, sim.robot.total_mass)
        else:
            values = simulation.robot_values(sim, physics, num_envs)
            robot, limits = compiled.robot_rows(simulation._robot_scene(sim, values), num_envs)
            self._robot = (*limits, robot)
            self._mass = simulation.total_mass(sim, values)
        momentum = dynamics.integrates_momentum(sim.model)
        kernel = None if physics is not None else compiled.specialised(sim.robot, sim.model, momentum)
        self._step = compiled.task_stepper(physics is not None, fused_step, validity.KERNELS + KERNELS, sim.robot.num_legs,
                                           kernel, momentum)  # fmt: skip
        grip = self.config.friction_coefficient if friction is None else friction
        # (NaN: unlimited grip, the same for every robot)
        self._friction = np.array(np.broadcast_to(np.nan if grip is None else grip, (num_envs,)), dtype=float)

    def step(self, states, observations, leg_targets, leg_target_rates, applied, actions, heading, targets, elapsed,
             times, contact_lost, upright):
        """One control step: (states, leg targets, their rates, observations, float info (rows
        :data:`INFO_ROWS`), flags (numerical_failure, outside_model), rewards, terminated,
        contact_lost after), each with a leading or trailing axis of N robots. A failed robot keeps
        its state, observation (``observations``, the last) and servo reference."""
        n, legs = len(states), self.config.num_robot_legs
        out = (np.empty((n, 9 + 2 * legs)), np.empty((n, legs)), np.empty((n, legs)),
               np.empty((n, self.config.observation_size), dtype=np.float32), np.empty((len(INFO_ROWS), n)),
               np.empty((2, n), dtype=bool), np.empty(n), np.empty(n, dtype=bool), np.empty(n))  # fmt: skip
        self._step(states, observations, leg_targets, leg_target_rates, applied, actions, heading, targets, elapsed,
                   times, contact_lost, upright, self._params, self._shared, *self._robot, self._layout, self._friction,
                   self._mass, *out)  # fmt: skip
        return out


def compiled_info(values, flags, robot=None) -> dict:
    """:meth:`CompiledTask.step`'s info as :func:`step_outcome`'s: (N,) arrays keyed
    :data:`STEP_INFO_KEYS`, or one ``robot``'s Python floats, bools and str (the single env's info)."""
    if robot is None:
        rows, (failed, outside) = dict(zip(INFO_ROWS, values)), flags
        termination = np.array(TERMINATIONS)[rows["termination"].astype(int)]
    else:
        rows, (failed, outside) = dict(zip(INFO_ROWS, values[:, robot].tolist())), flags[:, robot].tolist()
        termination = TERMINATIONS[int(rows["termination"])]
    rows.update(numerical_failure=failed, outside_model=outside, termination=termination)
    return {key: rows[key] for key in STEP_INFO_KEYS}
