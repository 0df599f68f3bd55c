"""rl-zoo3 on RRRobot-v0: the hyperparameter modules rrrobot_gym.zoo.<algo> build train.py's model."""

import argparse
import importlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rrrobot_gym import hyperparams as hp, training

ROOT = Path(__file__).resolve().parents[1]


def zoo_model(algo, tmp_path, **custom):
    """The model rl-zoo3's ExperimentManager builds for --conf-file rrrobot_gym.zoo.<algo>, on two robots."""
    from rl_zoo3.exp_manager import ExperimentManager

    args = argparse.Namespace(env="RRRobot-v0")  # (rl-zoo3 writes it to args.yml and reads nothing else of it)
    manager = ExperimentManager(args, algo, "RRRobot-v0", str(tmp_path), n_timesteps=0, eval_freq=-1,
                                config=f"rrrobot_gym.zoo.{algo}", hyperparams={"n_envs": 2, **custom},
                                device="cpu", seed=0, verbose=0)
    model, _ = manager.setup_experiment()
    return manager, model


@pytest.mark.parametrize("algo", list(hp.ALGORITHMS))
def test_the_zoo_file_builds_the_model_train_py_builds(algo, tmp_path):
    pytest.importorskip("rl_zoo3")
    from stable_baselines3.common.vec_env import VecNormalize

    from rrrobot_gym.envs import RRRobotSB3VecEnv

    small = {} if algo == "ppo" else {"buffer_size": 1000}
    manager, zoo = zoo_model(algo, tmp_path, **small)
    argv = ["--algo", algo, "--num-envs", "2"] + ([] if algo == "ppo" else ["--buffer-size", "1000"])
    args = training.parse_args(argv)
    ours = hp.algorithm_class(algo)("MlpPolicy", VecNormalize(RRRobotSB3VecEnv(num_envs=2)),
                                    **training.algorithm_kwargs(args))
    assert type(zoo) is type(ours)
    names = ["gamma", "batch_size"] + (["n_steps", "n_epochs", "gae_lambda", "ent_coef"] if algo == "ppo" else
                                       ["learning_starts", "tau", "gradient_steps"])  # fmt: skip
    for name in names:
        assert getattr(zoo, name) == getattr(ours, name), name
    for progress in (1.0, 0.5, 0.0):  # the same learning rate all along the run
        assert zoo.lr_schedule(progress) == pytest.approx(ours.lr_schedule(progress)), progress
    # the same networks: shapes and activations, layer by layer
    shapes = [[tuple(p.shape) for p in model.policy.parameters()] for model in (zoo, ours)]
    assert shapes[0] == shapes[1]
    kinds = [[type(m).__name__ for m in model.policy.modules() if not list(m.children())] for model in (zoo, ours)]
    assert kinds[0] == kinds[1]
    if algo == "ppo":
        assert zoo.clip_range(1.0) == ours.clip_range(1.0) and np.allclose(zoo.policy.log_std.detach(), hp.LOG_STD_INIT)
    else:
        assert zoo.train_freq == ours.train_freq
    if algo in ("sac", "tqc"):
        assert (zoo.ent_coef, zoo.use_sde) == (ours.ent_coef, ours.use_sde)
    if algo == "td3":
        noise = np.std([zoo.action_noise() for _ in range(4000)], axis=0)
        assert np.allclose(noise, hp.defaults("td3")["action_noise"], rtol=0.1)
    # normalisation as train.py's, with the algorithm's gamma; the training env train.py's
    assert manager.normalize and manager.normalize_kwargs == hp.vecnormalize_kwargs(gamma=args.gamma)
    assert manager.env_kwargs == training.train_env_kwargs(args)
    assert manager.n_envs == 2 and manager.n_timesteps == hp.defaults(algo)["total_timesteps"]


def test_each_zoo_module_is_its_algorithm_s_defaults():
    for algo in hp.ALGORITHMS:
        settings = importlib.import_module(f"rrrobot_gym.zoo.{algo}").hyperparams["RRRobot-v0"]
        defaults = hp.defaults(algo)
        assert (settings["n_envs"], settings["n_timesteps"]) == (defaults["num_envs"], defaults["total_timesteps"])
        assert f"net_arch=[{defaults['net_arch'].replace(',', ', ')}]" in settings["policy_kwargs"]
        assert settings["env_kwargs"]["max_slip_velocity"] == pytest.approx(0.02 - hp.SLIP_MARGIN)


@pytest.mark.slow
def test_rl_zoo3_trains_and_enjoys_a_short_run(tmp_path):
    pytest.importorskip("rl_zoo3")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    common = ["--algo", "ppo", "--env", "RRRobot-v0", "--gym-packages", "rrrobot_gym", "-f", str(tmp_path),
              "--device", "cpu"]
    # the README's command, on 4 robots for 2 rollouts
    trained = subprocess.run([sys.executable, "-m", "rl_zoo3.train", *common, "--conf-file", "rrrobot_gym.zoo.ppo",
                              "-n", "128", "--hyperparams", "n_envs:4", "--eval-freq", "-1", "--seed", "3"],
                             cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)  # fmt: skip
    assert trained.returncode == 0, trained.stdout[-3000:] + trained.stderr[-3000:]
    run = tmp_path / "ppo" / "RRRobot-v0_1"
    assert (run / "RRRobot-v0.zip").is_file() and (run / "RRRobot-v0" / "vecnormalize.pkl").is_file()
    from stable_baselines3 import PPO

    assert PPO.load(run / "RRRobot-v0.zip", device="cpu").num_timesteps == 128
    enjoyed = subprocess.run([sys.executable, "-m", "rl_zoo3.enjoy", *common, "--exp-id", "1", "--no-render",
                              "-n", "60"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert enjoyed.returncode == 0, enjoyed.stdout[-3000:] + enjoyed.stderr[-3000:]
    assert "Loading running average" in enjoyed.stdout  # (replayed with train.py's observation normalisation)
