"""RRRobot-v0 as a native batched Gymnasium VectorEnv: N robots in one (N, 13) numpy state.

The robots step together through :func:`rrrobot_gym.simulation.advance`, and the task comes
from :mod:`rrrobot_gym.envs.task`, as in the single env. Sub-env i has its own generator,
seeded ``seed + i`` as in ``SyncVectorEnv``, so it reproduces ``RRRobotEnv`` reset with
``seed + i`` (to about 1e-12: the single env integrates on Python floats).

Autoreset is ``AutoresetMode.SAME_STEP`` (Stable-Baselines3's convention): a finished sub-env
is reset within the same ``step``, its returned observation starts the next episode, the last
one's observation and info are in ``info["final_obs"]`` and ``info["final_info"]`` (masks
``"_final_obs"``, ``"_final_info"``), and its top-level info is its reset info.
"""

from __future__ import annotations

import numpy as np
import gymnasium
from gymnasium.utils import EzPickle, seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .. import simulation
from ..params import whole_number
from . import render, task


class RRRobotVectorEnv(VectorEnv, EzPickle):
    """N RRRobot-v0 robots stepped together (``gymnasium.make_vec("RRRobot-v0", num_envs=N)``).

    Takes the keywords of :class:`rrrobot_gym.envs.RRRobotEnv` (see its docstring for the
    spaces, reward and episode end) plus ``num_envs``, ``max_episode_steps`` (control steps
    before truncation; None never truncates) and ``workers`` (numba threads sharing the robots,
    bit-identical to one; the compiled stepper only; it pays for large batches).
    ``render_mode="rgb_array"`` renders one frame per sub-env.

    ``reset(seed=...)`` takes None, an int (sub-env i gets ``seed + i``) or a list of N
    seeds (None keeps that sub-env's generator). The batch's own generator (``np_random``: the
    observation noise of randomized robots) is seeded by an int; a list keeps it, so seed it too
    (``env.np_random = ...``, as the SB3 adapter and :func:`rrrobot_gym.evaluation.run_episodes` do).
    ``reset(options=...)`` takes "state", a (13,) or (N, 13) start, and "target_direction", a
    number or (N,) headings.

    Attributes ``states`` (N, 13), ``episode_target_directions`` (N,) rad and
    ``episode_steps`` (N,) expose the batch; of these only a heading may be written
    (``per_env_settable``): it takes effect in the next step. In a step's info without resets,
    every key's mask is one read-only all-True array.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20, "autoreset_mode": AutoresetMode.SAME_STEP}
    per_env_attributes = ("states", "leg_targets", "leg_target_rates", "contact_lost", "episode_target_directions",
                          "episode_steps")
    """Attributes that are arrays with one row per sub-env (what the SB3 adapter's ``get_attr`` indexes)."""
    per_env_settable = ("episode_target_directions",)
    """The per-env attributes a caller may write, row by row (the SB3 adapter's ``set_attr``); the
    others are the simulation's state, which ``reset(options=...)`` sets."""
    per_env_methods = ("render",)
    """Methods that return one result per sub-env (what the SB3 adapter's ``env_method`` indexes)."""

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = 1000,
        *,
        workers: int = 1,
        render_mode: str | None = None,
        width: int = 800,
        height: int = 400,
        **kwargs,
    ):
        # The env keywords are the fields of task.TaskConfig (see __signature__ below).
        EzPickle.__init__(self, num_envs=num_envs, max_episode_steps=max_episode_steps, workers=workers,
                          render_mode=render_mode, width=width, height=height, **kwargs)
        whole_number("num_envs", num_envs)
        self.max_episode_steps = max_episode_steps
        self.workers = whole_number("workers", workers)
        self.config = task.make_task_config(**kwargs)
        if self.workers > 1 and not simulation.takes_compiled(self.config.sim):
            raise ValueError(
                f"workers={self.workers} shares the robots among numba's threads, and this env runs on numpy "
                f"(backend {self.config.backend!r}, legs {self.config.legs!r}"
                f"{'' if simulation.compiled.available() else ', numba not installed'}): use workers=1"
            )
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"unknown render_mode {render_mode!r} for the vector env: expected None or 'rgb_array' "
                "(for a window, use the single env with render_mode='human')"
            )
        self.num_envs = int(num_envs)
        samples = self.config.frame_skip * self.num_envs
        if samples > simulation.MAX_SAMPLES:
            raise ValueError(
                f"frame_skip x num_envs must be at most {simulation.MAX_SAMPLES:.0e}, got {self.config.frame_skip} x "
                f"{self.num_envs}: a step's record keeps every integration step of every robot ({samples:.3g} samples, "
                "~88 bytes each)")
        self.render_mode = render_mode
        self._frame_size = render.check_frame_size(width, height)
        self.metadata = {**type(self).metadata, "render_fps": max(1, round(1.0 / self.dt))}

        self.single_action_space = task.single_action_space(self.config)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.single_observation_space = task.single_observation_space(self.config)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)

        self.states = None
        self.leg_targets = None  # (N, L) rad, the servo's reference at the end of the last step
        self.leg_target_rates = None  # (N, L) rad/s, its rate over the last step (task.step_targets)
        self.robot_draws = {}  # {name: (N,) array}: each sub-env's randomized robot (task.draw_robots)
        self._last_actions = None  # (N, L), for a randomized action delay
        self.contact_lost = None  # (N,) s, how long each shell has been off the ground
        self.episode_target_directions = None
        self.episode_steps = np.zeros(self.num_envs, dtype=np.int64)
        self._every = np.ones(self.num_envs, dtype=bool)  # the masks of a step without resets, shared
        self._every.flags.writeable = False
        self._observations = None
        self._generators = [None] * self.num_envs
        self._paths = None
        self._upright = None  # (N, 2) m, the upright contact points of self.states (task.upright_contact_points)
        self._headings = None  # (headings (N,), their (cos, sin)): see heading_vectors
        self.compiled_task = task.CompiledTask(self.config, self.num_envs) if task.CompiledTask.applies(
            self.config, self.workers) else None
        """The step in one compiled call (:class:`rrrobot_gym.envs.task.CompiledTask`), where it applies;
        None: the numpy task code, its reference (a caller may set None to run that)."""

    @property
    def dt(self) -> float:
        """s, one control step: frame_skip x timestep."""
        return self.config.dt

    @property
    def episode_target_directions(self) -> np.ndarray | None:
        """(N,) rad, each sub-env's commanded heading (None before the first reset). A caller may
        write it whole or row by row; it takes effect in the next step, which checks it."""
        return self._episode_target_directions

    @episode_target_directions.setter
    def episode_target_directions(self, value):
        self._episode_target_directions = (
            None if value is None else task.headings("episode_target_directions", value, self.num_envs)
        )

    @property
    def max_episode_steps(self) -> int | None:
        """Control steps before an episode is truncated (None: never); checked when written."""
        return self._max_episode_steps

    @max_episode_steps.setter
    def max_episode_steps(self, value):
        self._max_episode_steps = None if value is None else whole_number("max_episode_steps (or None)", value)

    # ------------------------------------------------------------------
    # reset

    def reset(self, *, seed=None, options=None):
        seeds = self._seed_list(seed)
        option_states, option_targets = task.parse_reset_options(options, self.num_envs, self.config.num_robot_legs)
        if option_states is not None:  # (before anything changes, the generators too: a refused reset keeps the env)
            task.check_start_states(option_states, self.config)
        super().reset(seed=int(seed) if isinstance(seed, (int, np.integer)) else None)  # (Gymnasium takes ints only)
        for i, sub_seed in enumerate(seeds):
            if sub_seed is not None or self._generators[i] is None:
                self._generators[i], _ = seeding.np_random(sub_seed)
        states, targets = self._draw_starts(np.arange(self.num_envs))
        states = states if option_states is None else option_states
        targets = targets if option_targets is None else option_targets
        observations = task.observe(states, targets, self.config, np.zeros(self.num_envs))
        self.states = states
        legs = self.config.sim.fields.leg_angles
        self.leg_targets = self.states[:, legs].copy()
        self.leg_target_rates = np.zeros((self.num_envs, self.config.num_robot_legs))
        self._last_actions = task.leg_targets_to_action(self.leg_targets).clip(-1.0, 1.0)
        self.contact_lost = np.zeros(self.num_envs)
        self.episode_target_directions = targets
        self.episode_steps = np.zeros(self.num_envs, dtype=np.int64)
        self._observations = observations
        self.robot_draws = task.draw_robots(self._generators, self.config)
        if self.compiled_task is not None:
            self.compiled_task.set_robots(self.robot_draws, self.num_envs)
        if self.render_mode is not None:
            self._paths = [[(float(x), float(y))] for x, y in self.states[:, 0:2]]
        info = self._reset_info(np.arange(self.num_envs))
        self._upright = _upright_points(info)
        masks = {key: np.ones(self.num_envs, dtype=bool) for key in info}
        return (task.noisy(self._observations, self.robot_draws, self.np_random, self.config.num_robot_legs).copy(),
                _with_masks(info, masks))

    def _seed_list(self, seed):
        if seed is None:
            return [None] * self.num_envs
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            return [whole_number("seed", seed, minimum=0) + i for i in range(self.num_envs)]
        try:
            seeds = list(seed)
        except TypeError:
            raise TypeError(f"seed must be None, an int or a list of {self.num_envs} ints, got {seed!r}") from None
        if len(seeds) != self.num_envs:
            raise ValueError(f"seed list must have num_envs={self.num_envs} entries, got {len(seeds)}")
        # (checked before any generator is reseeded; numpy integers become ints, as Gymnasium's seeding wants)
        return [None if s is None else whole_number(f"seed[{i}] (or None)", s, minimum=0) for i, s in enumerate(seeds)]

    def _draw_starts(self, indices):
        """Start states (len, 9 + 2L) and headings (len,) for the sub-envs ``indices``, each from its own generator."""
        draws = [task.draw_start(self._generators[i], self.config) for i in indices]
        noise = np.array([noise for noise, _ in draws]).reshape(len(indices), 6 + 2 * self.config.num_robot_legs)
        targets = np.array([target for _, target in draws], dtype=np.float64)
        return task.start_states(noise), targets

    def _reset_info(self, indices):
        return task.reset_info(self.states[indices], self.episode_target_directions[indices], self.config,
                               draws={name: values[indices] for name, values in self.robot_draws.items()})

    # ------------------------------------------------------------------
    # step

    def step(self, actions):
        if self.states is None:
            raise RuntimeError("RRRobotVectorEnv.step() called before reset()")
        actions = task.check_actions(actions, (self.num_envs, self.config.num_robot_legs))
        before = self.states
        targets = self.episode_target_directions
        # The headings' cos and sin and the new states' rotations, computed once for both
        # the observation and the step's outcome.
        heading = self.heading_vectors(targets)
        applied = task.delayed_actions(actions, self._last_actions, self.robot_draws)
        self._last_actions = actions
        if self.compiled_task is None:
            after, observations, rewards, terminated, info = self._task_step(before, targets, heading, applied, actions)
        else:
            (after, self.leg_targets, self.leg_target_rates, observations, values, flags, rewards, terminated,
             self.contact_lost) = self.compiled_task.step(
                before, self._observations, self.leg_targets, self.leg_target_rates, applied, actions, heading,
                targets, self.episode_steps * self.dt, (self.episode_steps + 1) * self.dt, self.contact_lost, self._upright)
            info = task.compiled_info(values, flags)
        self.episode_steps += 1
        if self.max_episode_steps is None:
            truncated = np.zeros(self.num_envs, dtype=bool)
        else:
            truncated = self.episode_steps >= self.max_episode_steps
        self.states = after
        self._observations = observations
        if self._paths is not None:
            for path, (x, y) in zip(self._paths, after[:, 0:2].tolist()):
                path.append((x, y))
        done = terminated | truncated
        if done.any():
            masks = dict(zip(info, np.ones((len(info), self.num_envs), dtype=bool)))  # (rows: an array each)
            observations = self._autoreset(done, observations, info, masks)
        else:
            masks = dict.fromkeys(info, self._every)
        # (the next step's upright points before: a reset sub-env's info is its new start's)
        self._upright = _upright_points(info)
        observations = task.noisy(observations, self.robot_draws, self.np_random, self.config.num_robot_legs)
        return observations.copy(), rewards, terminated, truncated, _with_masks(info, masks)

    def _task_step(self, before, targets, heading, applied, actions):
        """The numpy task code's step (the reference of :attr:`compiled_task`): (states after,
        observations, rewards, terminated, info); updates the servo's reference and contact_lost."""
        _, leg_targets, rates = task.step_targets(applied, self.leg_targets, self.leg_target_rates, self.config)
        after, measures, failed, contact_lost = self._advance(before, self.leg_targets, leg_targets, self.contact_lost,
                                                              self.robot_draws)
        rows = task.rotation_rows(after)
        observations = task.observe(after, targets, self.config, (self.episode_steps + 1) * self.dt, rows, heading)
        failed |= ~task.finite_rows(after, observations)
        if failed.any():
            # A failed robot keeps its last finite state and observation (never NaN out).
            after[failed] = before[failed]
            observations[failed] = self._observations[failed]
            rows = None  # (the rows of the states restored: computed afresh)

        elapsed = self.episode_steps * self.dt
        rewards, terminated, info = task.step_outcome(
            before, after, targets, actions, failed, self.config, measures, elapsed, upright_before=self._upright,
            rows_after=rows, heading=heading,
        )
        self.leg_targets = np.where(failed[:, None], self.leg_targets, leg_targets)
        self.leg_target_rates = np.where(failed[:, None], self.leg_target_rates, rates)
        self.contact_lost = np.where(failed, self.contact_lost, contact_lost)
        return after, observations, rewards, terminated, info

    def heading_vectors(self, targets):
        """(2, N): the cos and sin rows of the headings ``targets`` (N,), kept while the headings stay
        the same (they change at resets and by ``set_attr``, in place: compared by value each step)."""
        kept = self._headings
        if kept is None or not np.array_equal(kept[0], targets):
            targets = task.headings("episode_target_directions", targets, self.num_envs)  # (a caller may write rows)
            kept = self._headings = (targets, np.reshape(task.heading_vectors(targets), (2, -1)))
        return kept[1]

    def _advance(self, states, start_targets, end_targets, contact_lost, draws):
        """(new states, step measures, failed mask, contact_lost) of one control step, the servo's
        reference going from ``start_targets`` to ``end_targets`` (N, 2). ``advance`` raises for
        the whole batch on one robot's blow-up, so the batch is then split in halves and each
        retried until the failed robots are isolated."""
        try:
            # Overflow in a blowing-up robot is expected here and reported per robot, not warned about.
            with np.errstate(all="ignore"):
                after, measures, lost = task.advance_and_check(
                    states, task.held_targets(start_targets, end_targets, self.config), 0.0, self.config, contact_lost,
                    workers=self.workers, draws=draws,
                )
            return after, measures, np.zeros(len(states), dtype=bool), lost
        except task.NUMERICAL_FAILURES:
            if len(states) == 1:
                failed = task.failed_measures(1)
                return states.copy(), failed, np.ones(1, dtype=bool), contact_lost.copy()
        half = len(states) // 2
        (states_0, measures_0, failed_0, lost_0), (states_1, measures_1, failed_1, lost_1) = [
            self._advance(states[rows], start_targets[rows], end_targets[rows], contact_lost[rows],
                          {name: values[rows] for name, values in draws.items()})
            for rows in (slice(None, half), slice(half, None))
        ]
        measures = {key: np.concatenate([measures_0[key], measures_1[key]]) for key in measures_0}
        return (np.concatenate([states_0, states_1]), measures, np.concatenate([failed_0, failed_1]),
                np.concatenate([lost_0, lost_1]))

    def _autoreset(self, done, observations, info, masks):
        """Reset the finished sub-envs in place (SAME_STEP); returns the new observations."""
        indices = np.flatnonzero(done)
        final_obs = np.full(self.num_envs, None, dtype=object)
        for i in indices:
            final_obs[i] = observations[i].copy()
        final_info = {}
        for key, values in info.items():
            final_info[key] = np.where(done, values, np.zeros((), dtype=values.dtype))
            final_info["_" + key] = done.copy()

        states, targets = self._draw_starts(indices)
        self.states[indices] = states
        legs = self.config.sim.fields.leg_angles
        self.leg_targets[indices] = states[:, legs]
        self.leg_target_rates[indices] = 0.0
        self._last_actions[indices] = task.leg_targets_to_action(states[:, legs]).clip(-1.0, 1.0)
        for name, values in task.draw_robots([self._generators[i] for i in indices], self.config).items():
            self.robot_draws[name][indices] = values
        if self.compiled_task is not None and self.robot_draws:
            self.compiled_task.set_robots(self.robot_draws, self.num_envs)
        self.contact_lost[indices] = 0.0
        self.episode_target_directions[indices] = targets
        self.episode_steps[indices] = 0
        observations[indices] = task.observe(states, targets, self.config, np.zeros(len(indices)))
        self._observations[indices] = observations[indices]
        if self._paths is not None:
            for i in indices:
                self._paths[i] = [(float(self.states[i, 0]), float(self.states[i, 1]))]

        # The top-level info of a reset sub-env is its reset info, as in SyncVectorEnv.
        reset_info = self._reset_info(indices)
        for key in info:
            if key in reset_info:
                info[key][indices] = reset_info[key]
            else:
                info[key][indices] = 0
                masks[key][indices] = False
        for key in reset_info.keys() - info.keys():  # (the randomized robot's draws: at resets only)
            info[key], masks[key] = np.zeros(self.num_envs), done.copy()
            info[key][indices] = reset_info[key]
        info["final_obs"] = final_obs
        masks["final_obs"] = done.copy()
        info["final_info"] = final_info
        masks["final_info"] = done.copy()
        return observations

    # ------------------------------------------------------------------

    def render(self):
        if self.render_mode is None:
            gymnasium.logger.warn("render() called without a render_mode; pass render_mode='rgb_array'")
            return None
        if self.states is None:
            raise RuntimeError("RRRobotVectorEnv.render() called before reset()")
        return tuple(
            render.draw_frame(self.states[i], self._paths[i], float(self.episode_target_directions[i]),
                              self.config.sim.robot, float(self.episode_steps[i] * self.dt), *self._frame_size)
            for i in range(self.num_envs)
        )


RRRobotVectorEnv.__init__.__signature__ = task.signature_with_keywords(
    RRRobotVectorEnv.__init__, before=("workers",), after=("render_mode", "width", "height")
)


def _upright_points(info):
    """(N, 2) m: the upright contact points an info reports (``x_upright``, ``y_upright``), copied."""
    points = np.empty((len(info["x_upright"]), 2))
    points[:, 0], points[:, 1] = info["x_upright"], info["y_upright"]
    return points


def _with_masks(info, masks):
    """Gymnasium's vector info layout: each key followed by its boolean mask "_key"."""
    out = {}
    for key, value in info.items():
        out[key] = value
        out["_" + key] = masks[key]
    return out
