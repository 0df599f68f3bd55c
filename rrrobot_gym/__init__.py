"""rrrobot_gym: simulator and RL environment for the RRRobot's legless locomotion.

Importing the package registers the Gymnasium environment ``RRRobot-v0`` (Gymnasium 1.x has
no plugin entry points); ``gymnasium.make("rrrobot_gym:RRRobot-v0")`` imports it for you.
The entry points are strings, so the env modules load only when an env is made.
"""

import gymnasium as _gymnasium

ENV_ID = "RRRobot-v0"

if ENV_ID not in _gymnasium.registry:
    _gymnasium.register(
        id=ENV_ID,
        entry_point="rrrobot_gym.envs.rrrobot_v0:RRRobotEnv",
        vector_entry_point="rrrobot_gym.envs.vector:RRRobotVectorEnv",
        # 1000 control steps of dt = 0.05 s: 50 s, the length of the paper's runs.
        max_episode_steps=1000,
    )
