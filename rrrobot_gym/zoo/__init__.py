"""rl-zoo3 hyperparameters for RRRobot-v0, made from :mod:`rrrobot_gym.hyperparams`: one module an algorithm.

    python -m rl_zoo3.train --algo ppo --env RRRobot-v0 --gym-packages rrrobot_gym --conf-file rrrobot_gym.zoo.ppo
    python -m rl_zoo3.enjoy --algo ppo --env RRRobot-v0 --gym-packages rrrobot_gym -f logs --load-best

rl-zoo3 reads ``--conf-file``'s ``hyperparams`` ({env id: settings}) for the ``--algo`` it trains,
so each of ``rrrobot_gym.zoo.ppo``, ``.sac``, ``.td3`` and ``.tqc`` holds :func:`zoo_hyperparams`
of its algorithm: the model's keywords ``train.py --algo A`` builds
(:func:`rrrobot_gym.hyperparams.algorithm_kwargs`) in rl-zoo3's terms, its number of robots and
steps, ``VecNormalize`` as train.py's, and train.py's training env keywords (``env_kwargs``:
randomized robots, the survival reward, the slip margin). The numbers are never written twice.

What train.py adds (README, "rl-zoo3"): the batched env (rl-zoo3 steps its ``n_envs`` robots one
by one in a ``DummyVecEnv``), the heading mirror (``--mirror``), and evaluations on the nominal
robot along fixed compass headings that keep the model with the best worst heading; rl-zoo3's
evaluations draw a random heading an episode on the env's default keywords and keep the best mean
return.
"""

from __future__ import annotations

import copy

from .. import hyperparams as hp

ENV_ID = "RRRobot-v0"


class Settings(dict):
    """{env id: settings}, each read as a fresh copy: rl-zoo3 deletes keys from the settings it
    reads, and the module holding them is imported once a process."""

    def __getitem__(self, key):
        return copy.deepcopy(dict.__getitem__(self, key))


def _learning_rate(rate):
    """rl-zoo3's form of an SB3 learning rate: a number, or "lin_<start>" for a rate falling to 0."""
    if isinstance(rate, hp.LinearRate):
        if rate.final != 0.0:
            raise ValueError(f"rl-zoo3's linear schedules fall to 0: a rate falling to {rate.final:g} has no form there")
        return f"lin_{rate.start!r}"
    return float(rate)


def _policy_kwargs(policy_kwargs: dict) -> str:
    """The policy keywords as the Python text rl-zoo3 evaluates (``nn`` is torch.nn there)."""
    parts = []
    for name, value in policy_kwargs.items():
        parts.append(f"{name}=nn.{value.__name__}" if name == "activation_fn" else f"{name}={value!r}")
    return f"dict({', '.join(parts)})"


def zoo_hyperparams(algo: str) -> Settings:
    """``{"RRRobot-v0": settings}``: rl-zoo3's hyperparameters of ``algo`` (module docstring)."""
    from ..training import parse_args, train_env_kwargs

    defaults = hp.defaults(algo)
    settings = {"policy": "MlpPolicy", "n_envs": defaults["num_envs"], "n_timesteps": defaults["total_timesteps"]}
    for name, value in hp.algorithm_kwargs(algo).items():
        if name == "device":  # (rl-zoo3's --device)
            continue
        if name == "learning_rate":
            value = _learning_rate(value)
        elif name == "policy_kwargs":
            value = _policy_kwargs(value)
        elif name == "action_noise":
            settings.update(noise_type="normal", noise_std=float(defaults["action_noise"]))  # (its NormalActionNoise)
            continue
        settings[name] = value
    normalize = {key: value for key, value in hp.vecnormalize_kwargs().items() if key != "gamma"}  # (rl-zoo3 sets it)
    settings["normalize"] = f"dict({', '.join(f'{key}={value!r}' for key, value in normalize.items())})"
    settings["env_kwargs"] = train_env_kwargs(parse_args(["--algo", algo]))
    return Settings({ENV_ID: settings})
