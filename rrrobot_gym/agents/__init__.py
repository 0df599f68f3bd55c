"""Agents for RRRobot-v0 that share Stable-Baselines3's ``predict`` interface.

``predict(observation, state=None, episode_start=None, deterministic=True)`` returns
``(actions, state)``, so scripted gaits and trained PPO policies are scored by the same
evaluation code (``evaluate.py``, or SB3's ``evaluate_policy``).
"""

from .gaits import GAIT_AGENT_NAMES, GaitAgent, gait_agent
from .ppo import PPOAgent, load_ppo_agent
from .searched import load_gait_agents
from .turn_then_run import TurnThenRunAgent, load_turn_then_run_agent

__all__ = ["GAIT_AGENT_NAMES", "GaitAgent", "gait_agent", "PPOAgent", "load_ppo_agent", "load_gait_agents",
           "TurnThenRunAgent", "load_turn_then_run_agent"]
