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

The other algorithms of ``train.py --algo`` (:data:`ALGORITHMS`: SAC, TD3, TQC) take the same
constants where they share a setting and :data:`ALGO_DEFAULTS` where theirs differ;
:func:`algorithm_kwargs` gives any algorithm's keywords, and :mod:`rrrobot_gym.zoo` rl-zoo3's
hyperparameters, both from these numbers.
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


ALGORITHMS = {
    "ppo": ("stable_baselines3", "PPO"),
    "sac": ("stable_baselines3", "SAC"),
    "td3": ("stable_baselines3", "TD3"),
    "tqc": ("sb3_contrib", "TQC"),
}
"""``train.py --algo``'s choices, {name: (module, class)}: SB3's PPO (the default), SAC and TD3, and
sb3-contrib's TQC (SAC with truncated quantile critics, the `train` extra's sb3-contrib)."""

# The off-policy algorithms' own settings (SAC, TD3, TQC; PPO has none of them):
BUFFER_SIZE = 1_000_000
"""transitions the replay buffer holds."""
LEARNING_STARTS = 10_000
"""env steps of uniformly random actions before the first update."""
TRAIN_FREQ = 1
"""batched env steps (each num_envs transitions) between updates."""
GRADIENT_STEPS = 1
"""gradient steps an update (-1: one a transition collected)."""
TAU = 0.005
"""the target networks' soft-update rate."""
ACTION_NOISE = 0.2
"""TD3: the standard deviation of its Gaussian exploration noise, in action units (0.1, the usual
choice, left its worst heading at 0 mm/s for five minutes; 0.2 reached 35 mm/s: docs/notes/algorithms.md)."""
USE_SDE = False
"""SAC, TQC: explore with generalized state-dependent noise (gSDE; then --log-std-init sets its scale)."""

COMMON_SETTINGS = ("learning_rate", "learning_rate_final", "gamma", "batch_size", "net_arch", "activation")
OFF_POLICY_SETTINGS = (*COMMON_SETTINGS, "buffer_size", "learning_starts", "train_freq", "gradient_steps", "tau")
SETTINGS = {
    "ppo": (*COMMON_SETTINGS, "n_steps", "n_epochs", "gae_lambda", "clip_range", "ent_coef", "log_std_init"),
    "sac": (*OFF_POLICY_SETTINGS, "ent_coef", "use_sde", "log_std_init"),
    "td3": (*OFF_POLICY_SETTINGS, "action_noise"),
    "tqc": (*OFF_POLICY_SETTINGS, "ent_coef", "use_sde", "log_std_init"),
}
"""The settings (``train.py`` options, :func:`algorithm_kwargs`'s keywords) each algorithm takes;
every algorithm also takes ``num_envs`` and ``total_timesteps``."""

_OFF_POLICY = {"num_envs": 64, "total_timesteps": 5_000_000, "batch_size": 256, "learning_rate": 3e-4,
               "learning_rate_final": None, "net_arch": "128,128", "gradient_steps": 4, "eval_freq": 50_000,
               "checkpoint_freq": 500_000, "torch_threads": 1}
ALGO_DEFAULTS = {
    "ppo": {},
    "sac": {**_OFF_POLICY, "ent_coef": "auto_0.05"},
    "td3": {**_OFF_POLICY},
    "tqc": {**_OFF_POLICY, "ent_coef": "auto_0.05"},
}
"""``train.py``'s defaults where an algorithm's differ from the constants above (PPO's, which also
has :data:`MODEL_DEFAULTS`), in its options' terms. The off-policy three: SB3's usual minibatches
of 256 and constant learning rate of 3e-4, PPO's 128 x 128 networks, 64 robots at once with four
gradient steps each batched step (one per 16 transitions: on this CPU a gradient step costs
7-26 ms, so updates, not the env, bound their wall time), evaluations every 50,000 steps and
one torch thread (their minibatches gain nothing from a second, and on a busy machine two made
SAC's updates ten times slower). SAC and TQC learn their entropy coefficient from 0.05, not
SB3's 1: from 1 the policy stood still for the first minutes. The pilots behind these are in
docs/notes/algorithms.md; they were run on the plane model only."""


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


def check_algorithm(algo: str) -> None:
    """ValueError unless ``algo`` is a key of :data:`ALGORITHMS`."""
    if algo not in ALGORITHMS:
        raise ValueError(f"algo must be one of {', '.join(ALGORITHMS)}, got {algo!r}")


def algorithm_class(algo: str):
    """The class of ``algo`` (:data:`ALGORITHMS`), imported; ImportError saying what to install."""
    import importlib

    check_algorithm(algo)
    module, name = ALGORITHMS[algo]
    try:
        return getattr(importlib.import_module(module), name)
    except ImportError:
        raise ImportError(f"--algo {algo} needs {module}: pip install 'rrrobot_gym[train]'") from None


def defaults(algo: str) -> dict:
    """``train.py``'s default of each setting of ``algo`` (:data:`SETTINGS`), ``num_envs`` and
    ``total_timesteps``: the constants above, with :data:`ALGO_DEFAULTS` where the algorithm's differ."""
    check_algorithm(algo)
    base = {"num_envs": NUM_ENVS, "total_timesteps": TOTAL_TIMESTEPS, "learning_rate": LEARNING_RATE,
            "learning_rate_final": LEARNING_RATE_FINAL, "gamma": GAMMA, "batch_size": MAX_BATCH_SIZE,
            "net_arch": ",".join(map(str, NET_ARCH)), "activation": ACTIVATION, "n_steps": N_STEPS,
            "n_epochs": N_EPOCHS, "gae_lambda": GAE_LAMBDA, "clip_range": CLIP_RANGE, "ent_coef": ENT_COEF,
            "log_std_init": LOG_STD_INIT, "buffer_size": BUFFER_SIZE, "learning_starts": LEARNING_STARTS,
            "train_freq": TRAIN_FREQ, "gradient_steps": GRADIENT_STEPS, "tau": TAU, "action_noise": ACTION_NOISE,
            "use_sde": USE_SDE}
    values = {**base, **ALGO_DEFAULTS[algo]}
    return {name: values[name] for name in ("num_envs", "total_timesteps", *SETTINGS[algo])}


def algorithm_kwargs(algo: str, num_envs: int | None = None, **settings) -> dict:
    """Keyword arguments for ``algorithm_class(algo)("MlpPolicy", venv, **...)`` on ``num_envs``
    robots (None: the algorithm's default), on the CPU: :func:`defaults`, each overridden by its
    keyword (a setting of ``SETTINGS[algo]``; ``net_arch`` as "256,256" or a sequence). PPO's are
    :func:`ppo_hyperparams`'s. TypeError names a setting the algorithm does not take."""
    values = defaults(algo)
    unknown = sorted(set(settings) - set(SETTINGS[algo]))
    if unknown:
        raise TypeError(f"{algo} does not take {', '.join(unknown)} (it takes {', '.join(SETTINGS[algo])})")
    values.update(settings)
    num_envs = whole_number("num_envs", values["num_envs"] if num_envs is None else num_envs)
    net_arch = values["net_arch"]
    values["net_arch"] = [int(n) for n in (net_arch.split(",") if isinstance(net_arch, str) else net_arch)]
    values.pop("num_envs"), values.pop("total_timesteps")
    if algo == "ppo":
        if "batch_size" not in settings:  # (ppo_hyperparams: one minibatch a rollout, at most MAX_BATCH_SIZE)
            values.pop("batch_size")
        return ppo_hyperparams(num_envs, **values)
    return _off_policy_kwargs(algo, **values)


def _off_policy_kwargs(algo, *, learning_rate, learning_rate_final, gamma, batch_size, net_arch, activation,
                       buffer_size, learning_starts, train_freq, gradient_steps, tau, ent_coef=None, use_sde=False,
                       log_std_init=None, action_noise=None) -> dict:
    """SAC's, TD3's or TQC's keywords (:func:`algorithm_kwargs`)."""
    import numpy as np
    import torch

    check_activation(activation)
    policy_kwargs = {"net_arch": list(net_arch), "activation_fn": getattr(torch.nn, ACTIVATIONS[activation])}
    kwargs = {"learning_rate": learning_rate_schedule(learning_rate, learning_rate_final), "buffer_size": buffer_size,
              "learning_starts": learning_starts, "batch_size": batch_size, "tau": tau, "gamma": gamma,
              "train_freq": train_freq, "gradient_steps": gradient_steps, "policy_kwargs": policy_kwargs,
              "device": "cpu"}
    if algo == "td3":
        from stable_baselines3.common.noise import NormalActionNoise

        if action_noise:  # (the env's two actions)
            kwargs["action_noise"] = NormalActionNoise(np.zeros(2), np.full(2, float(action_noise)))
    else:
        kwargs.update(ent_coef=ent_coef, use_sde=use_sde, use_sde_at_warmup=use_sde)
        if use_sde:
            policy_kwargs["log_std_init"] = log_std_init
    return kwargs


def vecnormalize_kwargs(gamma: float = GAMMA) -> dict:
    """Keyword arguments for ``VecNormalize(venv, ...)`` while training: observations and
    rewards normalised, the reward's return scale with PPO's ``gamma``."""
    return {"norm_obs": True, "norm_reward": True, "gamma": gamma}
