"""rl-zoo3 hyperparameters of TD3 for RRRobot-v0: ``--conf-file rrrobot_gym.zoo.td3`` (:mod:`rrrobot_gym.zoo`)."""

from . import zoo_hyperparams

hyperparams = zoo_hyperparams("td3")
