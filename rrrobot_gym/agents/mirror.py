"""A policy that runs the headings on the robot's -Y side as mirror images of the +Y side's.

A robot with legs in mirrored pairs (the paper's, and the family's default placements of 2, 4
and 6 legs; :func:`rrrobot_gym.dynamics.mirror_legs`), the ground, the task and the paper's
start are symmetric in the world's x-z plane once each leg takes its image's place
(:func:`rrrobot_gym.dynamics.mirror_states`), so along a heading t
with sin t < 0 a mirrored policy is shown the mirror image of the observation
(:func:`rrrobot_gym.envs.task.mirror_observations`) and its action is mirrored back: its network
only sees headings in [0, pi]. ``train.py --mirror`` wraps SB3's VecEnv in
:func:`make_mirrored_vec_env` and writes ``mirror.json``, from which
``rrrobot_gym.agents.load_ppo_agent`` returns a :class:`MirroredAgent`. Its model zips name
:class:`MirroredPolicy` as their policy class, so SB3's ``PPO.load``, which would run the network
unmirrored, refuses them.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..dynamics import mirror_legs
from ..envs.task import make_task_config, mirror_actions, mirror_observations, observation_fields

MIRROR_FILE = "mirror.json"


def sin_index(config) -> int:
    """Where the observation holds the sine of the commanded heading (world frame)."""
    return dict((name, start) for name, start, _ in observation_fields(config.num_robot_legs))["target_direction_world"] + 1


def has_mirror(config) -> bool:
    """True if the robot of ``config`` (a TaskConfig) has the mirror symmetry the heading mirror needs."""
    return mirror_legs(config.sim.robot) is not None


SIN_TOLERANCE = 1e-6
"""Headings within this (in sine) of 0 or pi are their own mirror images and are not mirrored
(pi held as -pi has sine -1.2e-16)."""


def mirrored_rows(observations, config):
    """(n,) bool: the rows whose commanded heading points to -Y (sin < 0); 0 and pi are not."""
    return np.asarray(observations)[..., sin_index(config)] < -SIN_TOLERANCE


def to_policy_frame(observations, flip, config):
    """Observations (n, size) with the ``flip`` rows mirrored."""
    out = np.array(observations, dtype=np.float32)
    if flip.any():
        out[flip] = mirror_observations(out[flip], config)
    return out


def to_env_frame(actions, flip, config):
    """Actions (n, L) with the ``flip`` rows mirrored back (each leg its image's)."""
    out = np.array(actions, dtype=np.float32)
    if flip.any():
        out[flip] = mirror_actions(out[flip], config.sim.robot)
    return out


def make_mirrored_vec_env(venv, config):
    """SB3 VecEnv ``venv`` (of the env made with :class:`TaskConfig` ``config``) as a mirrored
    policy sees it."""
    from stable_baselines3.common.vec_env import VecEnvWrapper

    class MirroredVecEnv(VecEnvWrapper):
        """The wrapper of :func:`make_mirrored_vec_env`."""

        def __init__(self):
            super().__init__(venv)
            self.flip = np.zeros(venv.num_envs, dtype=bool)

        def _view(self, observations):
            self.flip = mirrored_rows(observations, config)
            return to_policy_frame(observations, self.flip, config)

        def reset(self):
            return self._view(self.venv.reset())

        def step_async(self, actions):
            self.venv.step_async(to_env_frame(actions, self.flip, config))

        def step_wait(self):
            observations, rewards, dones, infos = self.venv.step_wait()
            for i in np.flatnonzero(dones):
                # (PPO bootstraps a truncated episode's value from it: in its episode's frame)
                final = np.asarray(infos[i]["terminal_observation"])[None]
                infos[i]["terminal_observation"] = to_policy_frame(final, mirrored_rows(final, config), config)[0]
            return self._view(observations), rewards, dones, infos

    return MirroredVecEnv()


class MirroredAgent:
    """A policy trained mirrored (a :class:`rrrobot_gym.agents.ppo.PPOAgent`), with SB3's ``predict`` on the
    env's own observations."""

    name = "ppo"
    closed_loop = True

    def __init__(self, policy):
        self.policy = policy
        self.env_config, self.env_kwargs = policy.env_config, policy.env_kwargs
        self.config = make_task_config(**self.env_config)

    @property
    def model(self):
        """The SB3 model inside (its ``num_timesteps``, its ``policy``)."""
        return self.policy.model

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        observation = self.policy.check_observation(observation)
        single = observation.ndim == 1
        obs = observation[None] if single else observation
        flip = mirrored_rows(obs, self.config)
        actions, _ = self.policy.predict(to_policy_frame(obs, flip, self.config), deterministic=deterministic)
        actions = to_env_frame(actions, flip, self.config)
        return (actions[0] if single else actions), state


class MirroredPolicy:
    """The policy class a mirrored run's model zips name (train.py --mirror). The network was shown
    headings in [0, pi] only, each heading towards -Y as its mirror image, so run alone it acts
    wrongly towards -Y; SB3's ``PPO.load`` builds the class a zip names, and this one refuses, naming
    the loader. ``rrrobot_gym.agents.load_ppo_agent`` reads the network as SB3's ``ActorCriticPolicy``
    and mirrors those headings."""

    refusal = ("this PPO model runs headings towards -Y as mirror images of +Y ones (train.py --mirror), which "
               "PPO.load cannot do: load it with rrrobot_gym.agents.load_ppo_agent(path), which also applies its "
               "vecnormalize.pkl")

    def __init__(self, *args, **kwargs):
        raise RuntimeError(self.refusal)


def save_mirror(run_dir):
    """Write ``mirror.json`` into ``run_dir``: its policies are run mirrored."""
    record = {"mirror": "x-z plane", "rule": "headings with sin < 0 run as the mirror images of their reflections"}
    (Path(run_dir) / MIRROR_FILE).write_text(json.dumps(record, indent=2) + "\n")


def is_mirrored(run_dir) -> bool:
    return (Path(run_dir) / MIRROR_FILE).exists()
