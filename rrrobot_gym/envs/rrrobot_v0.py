"""RRRobot-v0: directional legless locomotion, one robot (the Gymnasium single env)."""

from __future__ import annotations

import gymnasium
import numpy as np
from gymnasium.error import DependencyNotInstalled
from gymnasium.utils import EzPickle

from . import render, task

RENDER_MODES = ("human", "rgb_array")
RENDER_ARGUMENTS = (
    ("render_mode", "str \\| None", "`None`", '`"rgb_array"` or `"human"`'),
    ("width", "int", "`800`", "pixels of a rendered frame (a top view and a side view)"),
    ("height", "int", "`400`", "pixels of a rendered frame"),
)
"""The envs' own keywords (name, type, default, doc), after the task's in the Arguments table."""


class RRRobotEnv(gymnasium.Env, EzPickle):
    r"""
    ## Description
    The RRRobot of Balasubramanian, Rizzi and Mason, "Legless Locomotion: Models and
    Experimental Demonstration": a hemispherical shell (radius 0.12 m, open side up) with two
    short legs pinned on its rim that never touch the ground. Swinging the legs rocks and twists
    the shell, and rolling without slip turns that into travel of about a centimetre a second.
    The dynamics are the paper's equations of motion, rolling on a plane or pivoting (`model`),
    from the project's one implementation in `rrrobot_gym.dynamics`.

    The task is directional locomotion along a commanded heading `target_direction` (rad in the
    world XY plane, from +X towards +Y), fixed by the keyword or drawn anew each episode. The
    paper's Table II gaits go sideways (Gait 1, along -Y), a little (Gait 2: along +X on the
    pivot model; on the plane its path bends clockwise and ends mostly along -Y) and on a
    counter-clockwise circle (Gait 3); a policy has to find such gaits and steer them.

    ## Action Space
    A `Box(-1, 1, (L,), float32)`, L = `num_legs` (2, the paper's robot, by default). Each entry sets a leg's target angle for the end of the control
    step (`dt` = `frame_skip` x `timestep` = 0.05 s by default), affinely: -1 is -pi/4 rad, 0 is
    pi/2 (vertical, the rest pose), +1 is 5 pi/4, from 45 degrees below horizontal pointing
    forward to 45 degrees below horizontal pointing back (leg angle 0 is horizontal along the
    body's +X, pi/2 straight up; the Table II gaits span -0.3 .. 1.87 rad). With
    `action_hold="linear"` (default) the target ramps there from the last step's, and the PD servo
    (`kp`, `kd`) tracks the ramp and its rate: a new action steps only the rate term, by `kd` times
    the change of slope, never the angle term, whose torque step would make the shell hop or slip.
    `"zero_order"` jumps to the target and holds it with target rate 0. What the servo tracks is
    not the action's target itself but its motion profile's reference (see The Servo). Actions outside [-1, 1]
    are clipped (the control cost uses the clipped action); a wrong shape, NaN or inf raises a
    `ValueError`. `rrrobot_gym.envs.task.leg_targets_to_action` inverts the map (to script a gait).

    | Num | Action                             | Min | Max | Target angle min | Target angle max | Type (Unit) |
    |-----|------------------------------------|-----|-----|------------------|------------------|-------------|
    | 0   | target angle of leg 1 (at body -Y) | -1  | 1   | -pi/4            | 5 pi/4           | angle (rad) |
    | 1   | target angle of leg 2 (at body +Y) | -1  | 1   | -pi/4            | 5 pi/4           | angle (rad) |
    | k-1 | target angle of leg k (k <= L)     | -1  | 1   | -pi/4            | 5 pi/4           | angle (rad) |

    With `num_legs` L the default placement (`rrrobot_gym.params.default_legs`) spreads the legs
    evenly around the rim, leg k at -90 + (k - 1) 360 / L degrees from body +X, each hinge axis
    tangent to the rim; the two-leg row labels hold for L = 2.

    ## Observation Space
    A `Box(low, high, (11 + 2L,), float32)` ((15,) for the paper's two legs): unit vectors lie in [-1, 1], the rest is unbounded. The
    attitude enters as two unit vectors in body coordinates (z up when upright, legs at -Y and
    +Y), world up and the commanded heading: together they fix the attitude relative to the task
    with no singularity, and they do not change when the whole scene turns about the vertical,
    which the dynamics do not notice either. Upright, the heading in the body is
    (cos(target_direction - yaw), sin(target_direction - yaw), 0), yaw the body's heading.

    | Num | Observation                                                    | Min  | Max | Type (Unit)              |
    |-----|----------------------------------------------------------------|------|-----|--------------------------|
    | 0   | world up (+Z) in body coordinates, x                           | -1   | 1   | unit vector (-)          |
    | 1   | world up (+Z) in body coordinates, y                           | -1   | 1   | unit vector (-)          |
    | 2   | world up (+Z) in body coordinates, z (cos of the tilt)         | -1   | 1   | unit vector (-)          |
    | 3   | commanded heading in body coordinates, x                       | -1   | 1   | unit vector (-)          |
    | 4   | commanded heading in body coordinates, y                       | -1   | 1   | unit vector (-)          |
    | 5   | commanded heading in body coordinates, z                       | -1   | 1   | unit vector (-)          |
    | 6   | body angular velocity about body x                             | -Inf | Inf | angular velocity (rad/s) |
    | 7   | body angular velocity about body y                             | -Inf | Inf | angular velocity (rad/s) |
    | 8   | body angular velocity about body z                             | -Inf | Inf | angular velocity (rad/s) |
    | 9   | leg 1 angle (0 horizontal along body +X, pi/2 up)              | -Inf | Inf | angle (rad)              |
    | 10  | leg 2 angle (9 + k - 1: leg k's, k <= L)                       | -Inf | Inf | angle (rad)              |
    | 11  | leg 1 angular rate (9 + L: leg 1's, 9 + L + k - 1: leg k's)    | -Inf | Inf | angular velocity (rad/s) |
    | 12  | leg 2 angular rate                                             | -Inf | Inf | angular velocity (rad/s) |
    | 13  | commanded heading in world coordinates, cos(target_direction)  | -1   | 1   | unit vector (-)          |
    | 14  | commanded heading in world coordinates, sin(target_direction)  | -1   | 1   | unit vector (-)          |
    | excluded (15) | contact point x                                      | -Inf | Inf | position (m)             |
    | excluded (16) | contact point y                                      | -Inf | Inf | position (m)             |

    The rows' numbers are the two-leg robot's; with L legs the L angles start at 9, the L rates
    at 9 + L, the world heading at 9 + 2L, the contact point at 11 + 2L
    (`rrrobot_gym.envs.task.observation_fields(L)` names every entry).
    `exclude_current_positions_from_observation=False` appends the contact point (x, y) as entries
    15 and 16 (it is in `info` as `x_position`, `y_position` either way); a `clock_frequency`
    appends (sin, cos)(clock_frequency t), t the episode time (s), after them.

    ## Rewards
    The reward is ***reward*** *=* *forward_reward - ctrl_cost + healthy_reward*:

    - *forward_reward* (`info["reward_forward"]`) =
      $w_{forward} \times 100 \times \frac{(q_{after} - q_{before}) \cdot d}{dt}$, the velocity
      **in cm/s** along the heading d = (cos, sin)(target_direction) of the *upright contact
      point* $q = p - r \frac{tilt}{\sin(tilt)} (R_{02}, R_{12})$: where the contact point p would
      be if the shell rolled back upright without slip, $(R_{02}, R_{12})$ being the horizontal
      lean of the body's z axis. q is p when upright, so over a walk both cover the same net
      distance, but q stays put while the shell rocks or tips over: the raw contact point would
      pay ~0.19 m (r pi/2, about 380 reward) for rolling onto the rim towards the heading.
      At about 1 cm/s a good step earns about 1 and a 1000-step episode about 1000.
      $w_{forward}$ is `forward_reward_weight`. Over an episode the term sums to
      $w_{forward} \times 100 / dt$ times q's net travel (m) along d, less the steps that earn
      nothing: on the plane, a step that slips or hops past `max_slip_velocity` or lifts off for
      longer than `max_liftoff_time`, and every step in the first 0.1 s (see Episode End),
      whether or not it ends the episode.
    - *ctrl_cost* (`info["reward_ctrl"]` = -ctrl_cost) = $w_{control} \times \|action\|_2^2$ of
      the clipped action, $w_{control}$ = `ctrl_cost_weight` (default 0.01: at most 0.02 a step;
      action 0, the rest pose in the middle of the legs' range, costs nothing).
    - *healthy_reward* (`info["reward_survive"]`): `healthy_reward` (default 0; `train.py` uses 1)
      for each step that does not terminate the episode (one truncated by the time limit earns it).

    `info` also holds `x_position`, `y_position` (m, p), `x_velocity`, `y_velocity` (m/s, p's
    displacement over the step / dt), `x_upright`, `y_upright` (m, q), `forward_velocity` (m/s,
    q's velocity along d), `tilt` (rad, between body z and world z), `target_direction` (rad),
    `numerical_failure` (bool), and the model-validity measures of `rrrobot_gym.validity`, each the
    worst over the step, measured whether or not `terminate_outside_model` is set: `normal_force`
    (N, the ground's push on the shell), `friction_ratio` (the friction coefficient no-slip
    rolling needs), `leg_clearance` (m, the lower leg tip's height), `slip_velocity` (m/s),
    `liftoff_fraction` (of the step), `liftoff_time` (s, the longest spell off the ground),
    `torque_rms`, `torque_peak` (N m, the leg torques applied), `leg_rate_peak` (rad/s),
    `outside_model` (bool) and `termination` (str: why the step ended the episode, "" if it did
    not; see Episode End). `reset()`'s info holds `x_position`, `y_position`, `x_upright`,
    `y_upright`, `tilt` and `target_direction`.

    ## Starting State
    The paper's start, at rest at the origin, upright, legs vertical (pi/2), plus uniform noise
    $\mathcal{U}(-s, s)$, $s$ = `reset_noise_scale` (default 0.01), on the paper's three attitude
    angles (rad), both leg angles (rad), the body angular velocity (rad/s) and both leg rates
    (rad/s); then, if `target_direction` is None, a heading drawn uniformly from [-pi, pi). All
    randomness comes from the env's `np_random`. `reset(options={"state": s,
    "target_direction": a})` starts from the exact (13,) state `s` (layout
    `rrrobot_gym.dynamics.STATE_FIELDS`; no noise; tilt below pi/2) and/or along heading `a`.

    ## The Servo
    By default each leg has a motor a robot of this size could carry (`task.SERVO`): the PD law
    (`kp`, `kd`) limited to a torque falling linearly from 0.5 N m at rest (`torque_limit`) to 0 at
    10 rad/s (`leg_rate_limit`), a hobby servo's class, and a motion profile (`leg_accel_limit`,
    60 rad/s^2): each step the reference heads for the action's target at the fastest rate from
    which it can still stop there, at most `leg_rate_limit`, its rate changing by at most
    `leg_accel_limit` x `dt` (`task.step_targets`), as smart servos limit their profile's
    acceleration. The registered id is the benchmark task, so its defaults are this robot; the
    paper's ideal servo is `torque_limit=None, leg_rate_limit=None, leg_accel_limit=None`
    (`task.IDEAL_SERVO`), which `rrrobot figures` and the Table I and II reproductions use.
    A full-torque swing of a 57 g tip at 0.1 m pushes the 0.52 kg shell with about 5 N, its own
    weight: without the profile, random actions (`env.action_space.sample()`) make the shell hop
    or slip within 0.15-0.25 s and nearly every episode ends outside the model. With it a random
    policy's plane episodes last about 2 s in median (pivot: about 20 s; seeds 0-39,
    `tests/test_servo_profile.py`), and still end only by the physical checks below.

    ## Domain Randomization
    `randomize="default"` draws a new robot at every reset, from the episode's own generator
    (seeded by `reset(seed=...)`), uniformly in these ranges (a dict of some of the names,
    `{name: (low, high)}`, varies only those):

    {randomization_table}

    The draws are in the reset's `info` as `randomized_<name>` (the vector env: at a sub-env's
    autoreset too). Observation noise is Gaussian, per step, on entries 0-12; an action delay of
    1 applies the previous step's action. `train.py` trains with the default ranges and evaluates
    the nominal robot; `evaluate.py --randomize N` scores agents over N drawn robots per heading.

    ## Episode End
    ### Termination
    1. The tilt reaches pi/2 (`rrrobot_gym.dynamics.TILT_LIMIT`), checked after each control step:
       the rim touches the ground and the rolling model ends.
    2. A numerical failure: the integration produced a non-finite state (a step too large for the
       gains or timestep). `info["numerical_failure"]` is True, the reward 0, the observation the
       last finite one (the state is not advanced) and the step's measures NaN: the env never
       returns a NaN observation or reward.
    3. The robot left the model (`info["outside_model"]`, if `terminate_outside_model`, the
       default): without this check a policy free to whip its legs earns speeds no real robot
       could reach. A leg tip reached the ground (leg contact is not modelled), or, on the plane
       and from 0.1 s into the episode (before, the paper's own start, legs leaving vertical
       abruptly, slips at up to 0.63 m/s), the floor could not give the force rolling needs:
       the shell was off the ground (normal force <= 0) for longer than `max_liftoff_time`
       (default 0.005 s), or the impulse the floor could not give over the step (a pull, or grip
       beyond `friction_coefficient`, default 1.0, None unlimited) per unit mass,
       `info["slip_velocity"]`, exceeds `max_slip_velocity` (default 0.02 m/s): the shell would
       slip or hop that fast. The force is sampled when the action starts to act and after every
       integration step. By default (`contact_quadrature="rectangle"`) a sample stands for its
       whole integration step, so where the force spikes for less than a step (a new action's
       servo kick) the slip measure grows with the step, to about twice the missing impulse at
       the default step; `"trapezoid"` takes the force as a line between samples, and its slip
       and lift-off measures converge with the step (down to about 1/200 s).

    `info["termination"]` names the cause, the info entry that crossed its limit: `"numerical_failure"`,
    `"tilt"`, `"leg_clearance"`, `"liftoff_time"` or `"slip_velocity"` (the first of these where
    several did at once; `rrrobot_gym.envs.task.TERMINATIONS`), and `""` for a step that did not
    terminate, a truncated one included.

    ### Truncation
    `gymnasium.make`'s `TimeLimit` truncates after the registered `max_episode_steps`, 1000
    control steps: 50 s at the default `dt`, the length of the paper's runs. The env itself never
    truncates.

    ## Arguments
    ```python
    import gymnasium as gym
    import rrrobot_gym  # registers RRRobot-v0

    env = gym.make("RRRobot-v0", model="pivot", target_direction=0.5 * 3.14159, ...)
    ```

    The keywords are the fields of `rrrobot_gym.envs.task.TaskConfig` (this table and the
    signature are generated from them), then the rendering keywords:

    {arguments_table}

    Unknown keywords raise a `TypeError`, invalid values a `ValueError`, at construction.
    `gymnasium.make_vec("RRRobot-v0", num_envs=N)` gives the native batched
    `rrrobot_gym.envs.RRRobotVectorEnv`, which takes the same keywords.

    ## Version History
    * v0: Initial version.
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 20}

    def __init__(self, *, render_mode: str | None = None, width: int = 800, height: int = 400, **kwargs):
        # The env keywords are the fields of task.TaskConfig (see __signature__ below).
        self.config = task.make_task_config(**kwargs)
        EzPickle.__init__(self, render_mode=render_mode, width=width, height=height, **kwargs)
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(f"unknown render_mode {render_mode!r}: expected None or one of {', '.join(RENDER_MODES)}")
        self.render_mode = render_mode
        self._frame_size = render.check_frame_size(width, height)
        self.metadata = {**type(self).metadata, "render_fps": max(1, round(1.0 / self.dt))}
        self.action_space = task.single_action_space(self.config)
        self.observation_space = task.single_observation_space(self.config)

        self.state = None  # (13,) float64, see rrrobot_gym.dynamics.STATE_FIELDS
        self.episode_target_direction = None  # rad, this episode's commanded heading
        self.time = 0.0  # s since the episode began
        self.leg_targets = None  # (L,) rad, the servo's reference at the end of the last step
        self.leg_target_rates = None  # (L,) rad/s, its rate over the last step (task.step_targets)
        self.robot_draws = {}  # {name: (1,) array}: this episode's randomized robot (task.draw_robots)
        self._last_action = None  # (L,) the last action, for a randomized action delay
        self.contact_lost = 0.0  # s, how long the shell has been off the ground (normal force <= 0)
        self._observation = None  # the last observation returned, float32
        self._upright = (None, None)  # (the state, its upright contact point (1, 2)), reused by the next step
        self._path = None  # contact points so far, kept only when rendering
        self._heading = (None, None, None)  # (a heading, its (2, 1) cos and sin, (1,) itself), for the compiled step
        self._viewer = None
        self._no_window = False  # human mode where no window can open: warned once, nothing shown
        self.compiled_task = task.CompiledTask(self.config, 1) if task.CompiledTask.applies(self.config) else None
        """The step in one compiled call (:class:`rrrobot_gym.envs.task.CompiledTask`), where it applies;
        None: the numpy task code, its reference (a caller may set None to run that)."""

    @property
    def dt(self) -> float:
        """s, one control step: frame_skip x timestep."""
        return self.config.dt

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        option_state, option_target = task.parse_reset_options(options, None, self.config.num_robot_legs)
        if option_state is not None:  # (before anything changes, the generator too: a refused reset keeps the env)
            task.check_start_states(option_state[None], self.config)
        super().reset(seed=seed)
        noise, target = task.draw_start(self.np_random, self.config)
        state = task.start_states(noise[None])[0] if option_state is None else option_state
        heading = target if option_target is None else option_target
        self.robot_draws = task.draw_robots([self.np_random], self.config)
        if self.compiled_task is not None:
            self.compiled_task.set_robots(self.robot_draws, 1)
        observation = task.observe(state[None], np.array([heading]), self.config, np.zeros(1))[0]
        self.state = state
        self.episode_target_direction = heading
        self.time = 0.0
        self.leg_targets = self.state[self.config.sim.fields.leg_angles].copy()
        self.leg_target_rates = np.zeros(self.config.num_robot_legs)
        self._last_action = task.leg_targets_to_action(self.leg_targets).clip(-1.0, 1.0)
        self.contact_lost = 0.0
        self._observation = observation
        if self.render_mode is not None:
            self._path = [(float(self.state[0]), float(self.state[1]))]
        if self.render_mode == "human":
            self.render()
        return self._noisy(self._observation), self._reset_info()

    def step(self, action):
        if self.state is None:
            raise RuntimeError("RRRobotEnv.step() called before reset()")
        action = task.check_actions(action, (self.config.num_robot_legs,))
        before = self.state
        applied = task.delayed_actions(action, self._last_action, self.robot_draws)
        self._last_action = action
        # (the last step's upright contact point, unless the state was replaced since)
        upright = self._upright[1] if self._upright[0] is before else None
        if self.compiled_task is None:
            observation, reward, terminated, info = self._task_step(before, action, applied, upright)
        else:
            target = self.episode_target_direction
            if self._heading[0] != target:  # (once an episode: its sine and cosine cost as much as a step's Python)
                self._heading = (target, np.array(task.heading_vectors([target])).reshape(2, 1), np.array([target]))
            if upright is None:
                upright = task.upright_contact_points(before[None], self.config)
            after, targets, rates, observations, values, flags, rewards, terminations, lost = self.compiled_task.step(
                before[None], self._observation[None], self.leg_targets[None], self.leg_target_rates[None],
                applied[None], action[None], self._heading[1], self._heading[2],
                np.array([self.time]), np.array([self.time + self.dt]), np.array([self.contact_lost]), upright,
            )  # fmt: skip
            self.state, observation, self.leg_targets, self.leg_target_rates = after[0], observations[0], targets[0], rates[0]
            self.contact_lost = float(lost[0])
            info = task.compiled_info(values, flags, robot=0)
            reward, terminated = rewards[0].item(), terminations[0].item()
        self._observation = observation
        self.time += self.dt
        self._upright = (self.state, np.array([[info["x_upright"], info["y_upright"]]]))
        if self._path is not None:
            self._path.append((info["x_position"], info["y_position"]))
        if self.render_mode == "human":
            self.render()
        return self._noisy(observation), reward, terminated, False, info

    def _task_step(self, before, action, applied, upright):
        """The numpy task code's step (the reference of :attr:`compiled_task`): (observation, reward,
        terminated, info); updates the state, the servo's reference and contact_lost."""
        held, targets, rates = task.step_targets(applied, self.leg_targets, self.leg_target_rates, self.config)
        after, observation, measures, contact_lost = self._advance(before, held)
        failed = after is None
        if failed:
            after, observation, measures = before, self._observation, task.failed_measures(1)
        else:
            self.contact_lost = float(contact_lost[0])
        rewards, terminations, infos = task.step_outcome(
            before[None], after[None], self._targets_array(), action[None], np.array([failed]), self.config,
            measures, np.array([self.time]), upright_before=upright,
        )
        self.state = after
        if not failed:
            self.leg_targets, self.leg_target_rates = targets, rates
        info = {key: value.item() for key, value in infos.items()}  # Python floats and bools
        return observation, rewards[0].item(), terminations[0].item(), info

    def _advance(self, state, held):
        """(new state, observation, step measures, contact_lost) after one control step, or Nones on a
        numerical failure."""
        try:
            # A (13,) state takes the simulator's Python-float path; from t = 0, as the vector env
            # steps, so the ramp's (t - t0) rounds alike and the two give the same states to the bit.
            after, measures, contact_lost = task.advance_and_check(state, held, 0.0, self.config, self.contact_lost,
                                                                   draws=self.robot_draws)
        except task.NUMERICAL_FAILURES:
            return None, None, None, None
        observation = self._observe(after, self.time + self.dt)
        if not task.finite_rows(after[None], observation[None])[0]:
            return None, None, None, None
        return after, observation, measures, contact_lost

    def _noisy(self, observation):
        """A copy of ``observation`` with this robot's observation noise, if randomized."""
        return task.noisy(observation[None], self.robot_draws, self.np_random, self.config.num_robot_legs)[0].copy()

    def _targets_array(self):
        return np.array([self.episode_target_direction])

    def _observe(self, state, time=0.0):
        return task.observe(state[None], self._targets_array(), self.config, np.array([time]))[0]

    def _reset_info(self):
        infos = task.reset_info(self.state[None], self._targets_array(), self.config, draws=self.robot_draws)
        info = {key: value.item() for key, value in infos.items()}
        self._upright = (self.state, np.array([[info["x_upright"], info["y_upright"]]]))
        return info

    def render(self):
        if self.render_mode is None:
            gymnasium.logger.warn(
                "render() called without a render_mode; pass render_mode='rgb_array' or 'human' to the constructor"
            )
            return None
        if self.state is None:
            raise RuntimeError("RRRobotEnv.render() called before reset()")
        frame = render.draw_frame(self.state, self._path, self.episode_target_direction, self.config.sim.robot,
                                  self.time, *self._frame_size)
        if self.render_mode == "rgb_array":
            return frame
        if self._viewer is None and not self._no_window:
            try:
                self._viewer = render.HumanViewer("RRRobot-v0")
            except (RuntimeError, ImportError, DependencyNotInstalled) as error:
                # Headless (a CI server, gymnasium's check_env trying every declared mode):
                # say why once and go on without a window, as the env does with no render_mode.
                gymnasium.logger.warn(f"{error} Nothing is shown.")
                self._no_window = True
        if self._viewer is not None:
            self._viewer.show(frame, self.metadata["render_fps"])
        return None

    def close(self):
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None


RRRobotEnv.__init__.__signature__ = task.signature_with_keywords(
    RRRobotEnv.__init__, after=("render_mode", "width", "height"))
if RRRobotEnv.__doc__:  # (python -OO strips docstrings)
    RRRobotEnv.__doc__ = RRRobotEnv.__doc__.replace(
        "{arguments_table}", task.arguments_table(RENDER_ARGUMENTS).replace("\n", "\n    ")
    ).replace("{randomization_table}", task.randomization_table().replace("\n", "\n    "))
