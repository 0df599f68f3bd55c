"""The paper's Table II gaits as agents: leg targets for RRRobot-v0, one control step at a time.

By default (``action_hold="linear"``) the env ramps the leg targets over each control
step from the last action's to the new one's, so a gait agent commands the gait's angles
at the end of each step and the env draws the gait piecewise linearly. For an env with
``action_hold="zero_order"`` (targets jump and are held) sample at mid-step instead
(``sample_fraction=0.5``): a hold lags by half a step, and mid-step sampling cancels it.
"""

from __future__ import annotations

import numpy as np

from ..control import Gait, table2_gait
from ..params import real_number
from ..envs.task import TaskConfig, leg_targets_to_action

GAIT_AGENT_NAMES = ("gait1", "gait1-swapped", "gait2", "gait2-swapped", "gait3", "gait3-swapped")


class GaitAgent:
    """A scripted gait with the ``predict`` interface of a Stable-Baselines3 policy.

    ``gait`` is any leg-target law with ``angles(times) -> (T, 2)`` rad (a Table II
    :class:`~rrrobot_gym.control.Gait` or a searched :class:`~rrrobot_gym.gait_search.SinusoidGait`),
    commanded at ``(steps + sample_fraction) * dt``: ``dt`` (s) must be the control step of the env
    the agent acts in (:meth:`for_env` takes it from the env). The recurrent ``state`` is each env's
    count of control steps since its episode started; ``episode_start`` resets it. Observations are
    not used: the gait is open loop, as in the paper.
    """

    def __init__(self, gait: Gait, dt: float, name: str | None = None, sample_fraction: float = 1.0):
        if not callable(getattr(gait, "angles", None)):
            raise TypeError(
                "gait must have an angles(times) method giving (T, 2) leg targets, such as "
                f"rrrobot_gym.control.Gait or rrrobot_gym.gait_search.SinusoidGait; got {type(gait).__name__}"
            )
        dt, sample_fraction = real_number("dt", dt), real_number("sample_fraction", sample_fraction)
        if dt <= 0:
            raise ValueError(f"dt must be a positive number of seconds (the env's control step), got {dt}")
        if not 0.0 <= sample_fraction <= 1.0:
            raise ValueError(
                f"sample_fraction must be in [0, 1] (where in a control step the gait is sampled), got {sample_fraction}"
            )
        self.gait = gait
        self.dt = dt
        self.name = name or gait.name
        self.sample_fraction = sample_fraction

    @classmethod
    def for_env(cls, gait: Gait, env, **kwargs) -> "GaitAgent":
        """The agent for ``env`` (a single or vector RRRobot env, wrapped or not): its ``dt``,
        and mid-step sampling for ``action_hold="zero_order"`` (see the module docstring)."""
        base = getattr(env, "unwrapped", env)
        if "sample_fraction" not in kwargs and base.config.action_hold == "zero_order":
            kwargs["sample_fraction"] = 0.5
        return cls(gait, dt=base.dt, **kwargs)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        observation = np.asarray(observation)
        single = observation.ndim == 1
        n = 1 if single else observation.shape[0]
        if state is None:
            steps = np.zeros(n, dtype=np.int64)
        else:
            counts = np.asarray(state, dtype=float)
            if counts.shape != (n,):
                raise ValueError(f"state must hold one step count per env, shape ({n},), got {counts.shape}")
            if not np.all((counts >= 0) & (counts == np.floor(counts)) & np.isfinite(counts)):
                raise ValueError(f"state must hold whole step counts >= 0, got {state!r}")
            steps = counts.astype(np.int64)
        if episode_start is not None:
            steps[np.asarray(episode_start, dtype=bool).reshape(n)] = 0
        targets = self.gait.angles((steps + self.sample_fraction) * self.dt)
        actions = np.clip(leg_targets_to_action(targets), -1.0, 1.0).astype(np.float32)
        return (actions[0] if single else actions), steps + 1


DEFAULT_DT = TaskConfig().dt
"""s, the control step of RRRobot-v0 with its default keywords (frame_skip x timestep)."""


def gait_agent(name: str, dt: float | None = None, *, env=None) -> GaitAgent:
    """The agent called ``name`` (one of :data:`GAIT_AGENT_NAMES`) for ``env`` or a control step ``dt``.

    Pass the env it will act in (``env=``), or its ``dt``; with neither, the default
    RRRobot-v0's step (:data:`DEFAULT_DT`, computed from the env's defaults): right only for
    an env with default ``frame_skip`` and ``timestep``.
    """
    if name not in GAIT_AGENT_NAMES:
        raise ValueError(f"unknown gait agent {name!r}: expected one of {', '.join(GAIT_AGENT_NAMES)}")
    if env is not None and dt is not None:
        raise TypeError("pass env or dt, not both")
    gait = table2_gait(int(name[4]), swapped=name.endswith("-swapped"))
    if env is not None:
        return GaitAgent.for_env(gait, env, name=name)
    return GaitAgent(gait, dt=DEFAULT_DT if dt is None else dt, name=name)
