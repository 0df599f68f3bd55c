"""Gymnasium environments: RRRobot-v0."""

from .rrrobot_v0 import RRRobotEnv

__all__ = ["RRRobotEnv"]
