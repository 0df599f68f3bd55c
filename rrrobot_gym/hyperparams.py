"""Tuned PPO hyperparameters for RRRobot-v0: what ``train.py`` trains the shipped policy with.

SB3's PPO defaults suit a single env: with a batched env they make each update tiny and
slow (``n_steps=2048`` per env, minibatches of 64: at 16 envs ``learn(2000)`` runs 32,768
steps, 512 minibatches an epoch, 192 s on this project's 2-core machine). Ours take short
rollouts from many robots and large minibatches:

    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize
    from rrrobot_gym.envs import RRRobotSB3VecEnv
    from rrrobot_gym.hyperparams import ppo_hyperparams, vecnormalize_kwargs

    venv = VecNormalize(RRRobotSB3VecEnv(num_envs=64, healthy_reward=1.0), **vecnormalize_kwargs())
    model = PPO("MlpPolicy", venv, **ppo_hyperparams(num_envs=64))
    model.learn(1_000_000)

Save the VecNormalize statistics beside the model and evaluate with
``training=False, norm_reward=False``. The same values are ``train.py``'s defaults (a
test keeps the two equal); ``train.py`` also runs a goal-conditioned policy mirrored
(:mod:`rrrobot_gym.agents.mirror`: headings towards -Y as mirror images of those towards +Y, built on :func:`rrrobot_gym.dynamics.mirror_states`) and keeps the evaluation with the best
worst heading.
"""

from __future__ import annotations

N_STEPS = 256
"""control steps per env per rollout (12.8 s of robot time)."""
MAX_BATCH_SIZE = 4096
"""minibatch size, capped at one rollout (n_steps x num_envs) for small batches of envs."""
GAMMA = 0.99
"""per 0.05 s control step: a horizon of about 100 steps, 5 s, several gait periods."""
LEARNING_RATE = 3e-4
"""Adam's learning rate at the start of a run ..."""
LEARNING_RATE_FINAL = 0.0
"""... falling linearly to this at its end (:class:`LinearRate`)."""


class LinearRate:
    """A learning rate falling linearly from ``start`` to ``final`` over a run: SB3 calls it with
    the fraction of the run still to go (1 at the start, 0 at the end)."""

    def __init__(self, start: float, final: float):
        self.start, self.final = float(start), float(final)

    def __call__(self, progress_remaining: float) -> float:
        return self.final + (self.start - self.final) * progress_remaining

    def __eq__(self, other):
        return isinstance(other, LinearRate) and (self.start, self.final) == (other.start, other.final)

    def __repr__(self):
        return f"{self.start:g} to {self.final:g}"


def ppo_hyperparams(num_envs: int = 64) -> dict:
    """Keyword arguments for ``stable_baselines3.PPO("MlpPolicy", venv, **...)`` on ``num_envs`` robots.

    n_steps 256, batch_size min(4096, 256 num_envs), n_epochs 10, learning rate 3e-4 falling
    linearly to 0 over the run (``learn``'s total_timesteps), gamma 0.99, GAE lambda 0.95, clip
    0.2, no entropy bonus, two hidden layers of 128 and an initial log std of -2 (std 0.14 in
    action units: the servo targets barely jitter at first, so early episodes do not end by
    leaving the model), on the CPU.
    """
    if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
        raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
    return {
        "learning_rate": LinearRate(LEARNING_RATE, LEARNING_RATE_FINAL),
        "n_steps": N_STEPS,
        "batch_size": min(MAX_BATCH_SIZE, N_STEPS * num_envs),
        "n_epochs": 10,
        "gamma": GAMMA,
        "gae_lambda": 0.95,
        "clip_range": 0.2,
        "ent_coef": 0.0,
        "policy_kwargs": {"net_arch": [128, 128], "log_std_init": -2.0},
        "device": "cpu",
    }


def vecnormalize_kwargs() -> dict:
    """Keyword arguments for ``VecNormalize(venv, ...)`` while training: observations and
    rewards normalised, the reward's return scale with PPO's gamma."""
    return {"norm_obs": True, "norm_reward": True, "gamma": GAMMA}
