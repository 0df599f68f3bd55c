"""A learned residual on top of a scripted base agent (the turn-then-run baseline).

Each step the base agent (:mod:`rrrobot_gym.agents.turn_then_run`) chooses its action and the
policy adds a bounded correction,

    action = clip(base_action + scale * clip(residual, -1, 1), -1, 1)

so an untrained policy already runs the base agent, and training moves the legs' targets within
``scale`` action units (one unit is 0.75 pi rad) of the base's. The policy observes the env's
observation and the base agent's :data:`FEATURES`: its action, its gait clock (sin, cos of the
phase) and whether it is turning or running (blending is neither). ``train.py --residual-on``
wraps SB3's VecEnv (:func:`make_residual_vec_env`) and writes ``residual.json``, from which
``rrrobot_gym.agents.load_ppo_agent`` returns a :class:`ResidualAgent`. Its model zips name
:class:`ResidualPolicy` as their policy class, so SB3's ``PPO.load``, which would give the residual
alone, refuses them.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np

from ..envs.task import check_observations, make_task_config

from .turn_then_run import RUN, TURN, load_turn_then_run_agent

FEATURES = ("base_action_1", "base_action_2", "base_clock_sin", "base_clock_cos", "base_turning", "base_running")
RESIDUAL_FILE = "residual.json"


def base_features(state, actions):
    """The policy's extra observation (n, len(FEATURES)) from the base agent's state and actions."""
    phase = state["phase"]
    return np.column_stack([
        actions, np.sin(phase), np.cos(phase), state["mode"] == TURN, state["mode"] == RUN,
    ]).astype(np.float32)  # fmt: skip


def combine(base_actions, residual, scale):
    """The action sent to the env: the base's plus ``scale`` times the clipped residual."""
    residual = np.clip(np.asarray(residual, dtype=np.float64), -1.0, 1.0)
    return np.clip(np.asarray(base_actions, dtype=np.float64) + scale * residual, -1.0, 1.0).astype(np.float32)


def check_scale(scale):
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not (0.0 < scale <= 2.0):
        raise ValueError(f"residual scale must be a number in (0, 2] action units, got {scale!r}")
    return float(scale)


def make_residual_vec_env(venv, base, scale):
    """SB3 VecEnv ``venv`` with the policy's actions taken as residuals on ``base`` (a
    turn-then-run agent) and its observations extended by :data:`FEATURES`."""
    from gymnasium import spaces
    from stable_baselines3.common.vec_env import VecEnvWrapper

    scale = check_scale(scale)
    space = venv.observation_space
    extra = len(FEATURES)
    observation_space = spaces.Box(
        np.concatenate([space.low, np.full(extra, -1.0, dtype=space.dtype)]),
        np.concatenate([space.high, np.full(extra, 1.0, dtype=space.dtype)]),
        dtype=space.dtype,
    )

    class ResidualVecEnv(VecEnvWrapper):
        """The wrapper of :func:`make_residual_vec_env`."""

        def __init__(self):
            super().__init__(venv, observation_space=observation_space)
            self.base, self.scale = base, scale
            self.base_state, self.base_actions = None, None

        def _extend(self, observations, starting):
            self.base_actions, self.base_state = self.base.predict(
                observations, state=self.base_state, episode_start=starting
            )
            return np.concatenate([observations, base_features(self.base_state, self.base_actions)], axis=1)

        def reset(self):
            observations = self.venv.reset()
            self.base_state = None
            return self._extend(observations, np.ones(self.num_envs, dtype=bool))

        def step_async(self, actions):
            self.venv.step_async(combine(self.base_actions, actions, self.scale))

        def step_wait(self):
            observations, rewards, dones, infos = self.venv.step_wait()
            for i in np.flatnonzero(dones):
                # (PPO bootstraps a truncated episode's value from it: the base's next step, thrown away)
                final = infos[i]["terminal_observation"][None]
                actions, state = self.base.predict(final, state=self.base.state_rows(self.base_state, [i]))
                infos[i]["terminal_observation"] = np.concatenate([final, base_features(state, actions)], axis=1)[0]
            return self._extend(observations, dones), rewards, dones, infos

    return ResidualVecEnv()


class ResidualAgent:
    """A trained residual policy (a :class:`rrrobot_gym.agents.ppo.PPOAgent` over the extended observation)
    on its base agent, with SB3's ``predict``; ``state`` is the base agent's."""

    name = "ppo"
    closed_loop = True

    def __init__(self, policy, base, scale):
        self.policy, self.base, self.scale = policy, base, check_scale(scale)
        self.env_config, self.env_kwargs = policy.env_config, policy.env_kwargs
        self.observation_size = make_task_config(**self.env_config).observation_size  # (the env's, before FEATURES)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        observation = check_observations(observation, self.observation_size)
        single = observation.ndim == 1
        obs = observation[None] if single else observation
        base_actions, state = self.base.predict(obs, state=state, episode_start=episode_start)
        extended = np.concatenate([obs, base_features(state, base_actions)], axis=1)
        residual, _ = self.policy.predict(extended, deterministic=deterministic)
        actions = combine(base_actions, residual, self.scale)
        return (actions[0] if single else actions), state


class ResidualPolicy:
    """The policy class a residual run's model zips name (train.py --residual-on). The network gives
    only a correction to a base agent it does not hold; SB3's ``PPO.load`` builds the class a zip
    names, and this one refuses, naming the loader. ``rrrobot_gym.agents.load_ppo_agent`` reads the
    network as SB3's ``ActorCriticPolicy`` and adds the base agent's action."""

    refusal = ("this PPO model is a residual on a scripted base agent (train.py --residual-on), which PPO.load "
               "cannot run: load it with rrrobot_gym.agents.load_ppo_agent(path), which adds its base agent and "
               "applies its vecnormalize.pkl")

    def __init__(self, *args, **kwargs):
        raise RuntimeError(self.refusal)


def save_residual(run_dir, base_path, scale):
    """Write ``residual.json`` into ``run_dir`` with copies of the base agent's file and the
    gait file it names, so the run directory alone rebuilds the agent."""
    run_dir, base_path = Path(run_dir), Path(base_path)
    load_turn_then_run_agent(base_path)  # refuse a bad base file before training starts
    spec = json.loads(base_path.read_text())
    base_dir = run_dir / "residual_base"
    base_dir.mkdir(exist_ok=True)
    shutil.copy(base_path, base_dir / base_path.name)
    shutil.copy(base_path.parent / spec["run_gait_file"], base_dir / spec["run_gait_file"])
    record = {"base": f"residual_base/{base_path.name}", "scale": check_scale(scale), "base_source": str(base_path)}
    (run_dir / RESIDUAL_FILE).write_text(json.dumps(record, indent=2) + "\n")


def run_directory(model_path):
    """The directory of the train.py run a model zip belongs to: the zip's own directory, or the
    one above for a checkpoint (``RUN/checkpoints/ppo_N_steps.zip``)."""
    directory = Path(model_path).parent
    return directory.parent if directory.name == "checkpoints" else directory


def load_base(model_dir, dt=None):
    """(base agent, scale) of a run directory holding ``residual.json``, or None without one.
    Raises ValueError naming the file if it cannot be read."""
    path = Path(model_dir) / RESIDUAL_FILE
    if not path.exists():
        return None
    try:
        spec = json.loads(path.read_text())
        return load_turn_then_run_agent(Path(model_dir) / spec["base"], dt=dt), check_scale(spec["scale"])
    except (OSError, KeyError, TypeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: {type(exc).__name__}: {exc}") from None
