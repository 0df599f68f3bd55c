"""Gymnasium environments: RRRobot-v0, its native batched vector env and an SB3 adapter.

``RRRobotSB3VecEnv`` is imported on first use, so the package does not need
Stable-Baselines3 (or torch) unless the adapter is asked for.
"""

from .rrrobot_v0 import RRRobotEnv
from .vector import RRRobotVectorEnv

__all__ = ["RRRobotEnv", "RRRobotVectorEnv", "RRRobotSB3VecEnv"]


def __getattr__(name):
    if name == "RRRobotSB3VecEnv":
        from .sb3 import RRRobotSB3VecEnv

        return RRRobotSB3VecEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
