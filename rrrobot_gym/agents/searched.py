"""Gaits found by ``rrrobot gait-search`` (:mod:`rrrobot_gym.gait_search`) as agents.

    from rrrobot_gym.agents.searched import load_gait_agents
    agents = load_gait_agents("agents/searched/plane_own.json")   # {name: GaitAgent}

Each agent commands its gait's angles at the end of each control step, as the search
scored it. The file's ``env_kwargs`` (the env the gait was searched in) are kept on the
agent as ``search_env_kwargs`` for reference; they are not applied to the env an agent
is evaluated in (evaluate.py runs every agent in one env).
"""

from __future__ import annotations

import json
from pathlib import Path

from ..envs.task import make_task_config
from ..gait_search import load_gaits

from .gaits import GaitAgent


def load_gait_agents(path) -> dict:
    """{name: GaitAgent} for every gait in a gait-search JSON file, best first.

    The control step is the one the gaits were searched with (the file's ``frame_skip``
    and ``timestep`` env keywords, else the env's defaults). Raises ValueError naming
    the problem for a file that is not a gait-search result.
    """
    gaits = load_gaits(path)
    env_kwargs = json.loads(Path(path).read_text()).get("env_kwargs") or {}
    step_kwargs = {k: env_kwargs[k] for k in ("frame_skip", "timestep") if k in env_kwargs}
    try:
        dt = make_task_config(**step_kwargs).dt
    except (TypeError, ValueError) as exc:
        raise ValueError(f"gait file {path}: bad env_kwargs: {exc}") from None
    agents = {}
    for gait in gaits:
        agent = GaitAgent(gait, dt=dt, name=gait.name)
        agent.search_env_kwargs = dict(env_kwargs)
        # the robot it was searched for: evaluate.py runs it (and every agent beside it) on that robot
        agent.env_kwargs = {k: env_kwargs[k] for k in ("num_legs", "shell_axes") if k in env_kwargs}
        agents[gait.name] = agent
    return agents
