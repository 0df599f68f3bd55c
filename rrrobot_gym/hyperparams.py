"""Tuned PPO hyperparameters for RRRobot-v0, declared once: ``train.py``'s defaults.

SB3's PPO defaults (``n_steps=2048`` per env, minibatches of 64) suit a single env; with a
batched env ours take short rollouts from many robots and large minibatches. They are the best
of a sweep for the wall time to the searched gaits' speed (``train.py --sweep``,
docs/training/sweep):

    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize
    from rrrobot_gym.envs import RRRobotSB3VecEnv
    from rrrobot_gym.hyperparams import ppo_hyperparams, vecnormalize_kwargs

    venv = VecNormalize(RRRobotSB3VecEnv(num_envs=256, healthy_reward=1.0), **vecnormalize_kwargs())
    model = PPO("MlpPolicy", venv, **ppo_hyperparams(num_envs=256))
    model.learn(1_000_000)

Save the VecNormalize statistics beside the model and evaluate with
``training=False, norm_reward=False``. ``train.py`` also runs a goal-conditioned policy mirrored
(:mod:`rrrobot_gym.agents.mirror`) and keeps the evaluation with the best worst heading.
"""

from __future__ import annotations

from .params import whole_number

TOTAL_TIMESTEPS = 12_000_000
"""env steps of a training run (5.5 minutes from a fresh clone on the 2-core EPYC, 7.0-9.7 in
docs/training/seeds: the shared host's speed varies); the learning rate falls to
LEARNING_RATE_FINAL over them."""
NUM_ENVS = 256
"""robots simulated together in the batched env."""
N_STEPS = 16
"""control steps per env per rollout (0.8 s of robot time): 4,096 steps a rollout, one minibatch."""
MAX_BATCH_SIZE = 4096
"""minibatch size, capped at one rollout (n_steps x num_envs) for small batches of envs."""
N_EPOCHS = 5
"""passes over each rollout."""
GAMMA = 0.99
"""per 0.05 s control step: a horizon of about 100 steps, 5 s, several gait periods."""
GAE_LAMBDA = 0.95
CLIP_RANGE = 0.2
ENT_COEF = 1e-3
"""a small entropy bonus."""
LEARNING_RATE = 5e-4
"""Adam's learning rate at the start of a run ..."""
LEARNING_RATE_FINAL = 0.0
"""... falling linearly to this at its end (:class:`LinearRate`)."""
NET_ARCH = (128, 128)
"""hidden layer sizes of the policy and value networks."""
ACTIVATION = "relu"
"""their activation, a key of ACTIVATIONS: ReLU costs a fraction of tanh (SB3's default for PPO) on
this CPU, where torch's tanh of a 4,096 x 128 minibatch takes as long as its 128 x 128 layer, and
learned more per step: 5 of 5 seeds at the bar against 1 of 5 (docs/notes/time_to_target.md)."""
ACTIVATIONS = {"tanh": "Tanh", "relu": "ReLU"}
"""--activation's choices, the torch.nn module of each: ReLU, the default, and tanh, SB3's, which the shipped
policies and the earlier settings of benchmarks.time_to_target were trained with."""
SLIP_MARGIN = 0.005
"""m/s, training only: the training robots leave the model at the env's ``max_slip_velocity`` less
this, so the policy keeps a margin from the hop that ends an episode (the robot's own envelope
judges it everywhere else). On randomized robots a servo faster than the nominal swings a policy
trained at the edge past it: over ten models the margin took the median share of episodes that end
from 6.1 % to 4.3 % and the worst heading's P10 from 45 to 62 mm/s, at the same nominal speed
(docs/notes/randomized_robustness.md)."""
LOG_STD_INIT = -2.0
"""initial log std of the Gaussian policy: std 0.14 in action units, so the servo targets barely
jitter at first and early episodes do not end by leaving the model."""
MODEL_DEFAULTS = {
    "plane": {},
    "pivot": {"total_timesteps": 20_000_000, "n_steps": 64, "learning_rate": 3e-4, "ent_coef": 0.0, "activation": "tanh"},
}
"""``train.py``'s defaults where a model's differ from the above (which were tuned on the plane). The
pivot's are the settings of the shipped pivot policy (agents/pretrained_pivot/args.json). One pivot
run of each on validation robots: with the plane's, worst heading 90.3-91.0 mm/s and 5.9-7.0 % of
randomized episodes ended; with these, 91.1-93.9 mm/s and 2.7-3.1 % (best and final model;
docs/notes/randomized_robustness.md)."""


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


def learning_rate_schedule(start: float, final: float | None):
    """SB3's ``learning_rate``: ``start`` falling linearly to ``final`` (a :class:`LinearRate`), or
    the constant ``start`` when ``final`` is None."""
    return start if final is None else LinearRate(start, final)


def check_activation(activation: str) -> None:
    """ValueError unless ``activation`` is a key of :data:`ACTIVATIONS`."""
    if activation not in ACTIVATIONS:
        raise ValueError(f"activation must be one of {', '.join(ACTIVATIONS)}, got {activation!r}")


def ppo_hyperparams(num_envs: int = NUM_ENVS, *, learning_rate: float = LEARNING_RATE,
                    learning_rate_final: float | None = LEARNING_RATE_FINAL, n_steps: int = N_STEPS,
                    batch_size: int | None = None, n_epochs: int = N_EPOCHS, gamma: float = GAMMA,
                    gae_lambda: float = GAE_LAMBDA, clip_range: float = CLIP_RANGE, ent_coef: float = ENT_COEF,
                    net_arch=NET_ARCH, activation: str = ACTIVATION, log_std_init: float = LOG_STD_INIT) -> dict:
    """Keyword arguments for ``stable_baselines3.PPO("MlpPolicy", venv, **...)`` on ``num_envs``
    robots, on the CPU: the constants above, each overridden by its keyword (``batch_size`` None:
    min(MAX_BATCH_SIZE, n_steps num_envs); ``learning_rate_final`` None: a constant rate)."""
    import torch

    num_envs = whole_number("num_envs", num_envs)
    check_activation(activation)
    return {
        "learning_rate": learning_rate_schedule(learning_rate, learning_rate_final),
        "n_steps": n_steps,
        "batch_size": min(MAX_BATCH_SIZE, n_steps * num_envs) if batch_size is None else batch_size,
        "n_epochs": n_epochs,
        "gamma": gamma,
        "gae_lambda": gae_lambda,
        "clip_range": clip_range,
        "ent_coef": ent_coef,
        "policy_kwargs": {"net_arch": [int(n) for n in net_arch],
                          "activation_fn": getattr(torch.nn, ACTIVATIONS[activation]), "log_std_init": log_std_init},
        "device": "cpu",
    }


def vecnormalize_kwargs(gamma: float = GAMMA) -> dict:
    """Keyword arguments for ``VecNormalize(venv, ...)`` while training: observations and
    rewards normalised, the reward's return scale with PPO's ``gamma``."""
    return {"norm_obs": True, "norm_reward": True, "gamma": gamma}
