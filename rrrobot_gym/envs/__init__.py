"""Gymnasium environments: RRRobot-v0 and its native batched vector env."""

from .rrrobot_v0 import RRRobotEnv
from .vector import RRRobotVectorEnv

__all__ = ["RRRobotEnv", "RRRobotVectorEnv"]
