"""rl-zoo3 hyperparameters of TQC for RRRobot-v0: ``--conf-file rrrobot_gym.zoo.tqc`` (:mod:`rrrobot_gym.zoo`)."""

from . import zoo_hyperparams

hyperparams = zoo_hyperparams("tqc")
