"""The paper's Table II gaits as agents: leg targets for RRRobot-v0, one control step at a time.

By default (``action_hold="linear"``) the env ramps the leg targets over each control
step from the last action's to the new one's, so a gait agent commands the gait's angles
at the end of each step and the env draws the gait piecewise linearly. For an env with
``action_hold="zero_order"`` (targets jump and are held) sample at mid-step instead
(``sample_fraction=0.5``): a hold lags by half a step, and mid-step sampling cancels it.
"""

from __future__ import annotations

import numpy as np

from rrrobot_gym.control import Gait, table2_gait
from rrrobot_gym.envs.task import leg_targets_to_action

GAIT_AGENT_NAMES = ("gait1", "gait1-swapped", "gait2", "gait2-swapped", "gait3", "gait3-swapped")


class GaitAgent:
    """A scripted gait with the ``predict`` interface of a Stable-Baselines3 policy.

    ``gait`` is any leg-target law with ``angles(times) -> (T, 2)`` rad: a Table II
    :class:`~rrrobot_gym.control.Gait` (one amplitude) or a searched
    :class:`~rrrobot_gym.gait_search.SinusoidGait` (one amplitude a leg).

    The recurrent ``state`` is each env's count of control steps since its episode
    started (an int array, one entry per env); ``episode_start`` resets it. Observations
    are not used: the gait is open loop, as in the paper.
    """

    def __init__(self, gait: Gait, dt: float = 0.05, name: str | None = None, sample_fraction: float = 1.0):
        if not callable(getattr(gait, "angles", None)):
            raise TypeError(
                "gait must have an angles(times) method giving (T, 2) leg targets, such as "
                f"rrrobot_gym.control.Gait or rrrobot_gym.gait_search.SinusoidGait; got {type(gait).__name__}"
            )
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive number of seconds (the env's control step), got {dt}")
        self.gait = gait
        self.dt = float(dt)
        self.name = name or gait.name
        self.sample_fraction = float(sample_fraction)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        observation = np.asarray(observation)
        single = observation.ndim == 1
        n = 1 if single else observation.shape[0]
        steps = np.zeros(n, dtype=np.int64) if state is None else np.asarray(state, dtype=np.int64).copy()
        if steps.shape != (n,):
            raise ValueError(f"state must hold one step count per env, shape ({n},), got {steps.shape}")
        if episode_start is not None:
            steps[np.asarray(episode_start, dtype=bool).reshape(n)] = 0
        targets = self.gait.angles((steps + self.sample_fraction) * self.dt)
        actions = np.clip(leg_targets_to_action(targets), -1.0, 1.0).astype(np.float32)
        return (actions[0] if single else actions), steps + 1


def gait_agent(name: str, dt: float = 0.05) -> GaitAgent:
    """The agent called ``name``: one of :data:`GAIT_AGENT_NAMES`."""
    if name not in GAIT_AGENT_NAMES:
        raise ValueError(f"unknown gait agent {name!r}: expected one of {', '.join(GAIT_AGENT_NAMES)}")
    number = int(name[4])
    return GaitAgent(table2_gait(number, swapped=name.endswith("-swapped")), dt=dt, name=name)
