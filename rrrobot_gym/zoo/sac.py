"""rl-zoo3 hyperparameters of SAC for RRRobot-v0: ``--conf-file rrrobot_gym.zoo.sac`` (:mod:`rrrobot_gym.zoo`)."""

from . import zoo_hyperparams

hyperparams = zoo_hyperparams("sac")
