"""Train a PPO policy for directional locomotion on RRRobot-v0: the command line of
:mod:`rrrobot_gym.training` (``python train.py --help``)."""

from rrrobot_gym.training import main

if __name__ == "__main__":
    main()
