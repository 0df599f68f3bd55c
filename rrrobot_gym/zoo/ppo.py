"""rl-zoo3 hyperparameters of PPO for RRRobot-v0: ``--conf-file rrrobot_gym.zoo.ppo`` (:mod:`rrrobot_gym.zoo`)."""

from . import zoo_hyperparams

hyperparams = zoo_hyperparams("ppo")
