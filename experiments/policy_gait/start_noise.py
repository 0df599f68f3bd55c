"""A policy from noisy starts: 50 s along the 8 compass headings from each of several start-noise
seeds (the env's own reset noise, as in training), deterministic actions; how many episodes end,
and the speed along the heading (contact point displacement / 50 s) of those that do not.

    python experiments/policy_gait/start_noise.py [POLICY_ZIP] [SEEDS]   # default: the shipped policy, 4 seeds

On the model the policy was trained on, under its motor limits.
"""
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from rrrobot_gym.agents import load_ppo_agent  # noqa: E402
from rrrobot_gym.evaluation import COMPASS_DEG  # noqa: E402
from rrrobot_gym.envs.vector import RRRobotVectorEnv  # noqa: E402

policy = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "agents" / "pretrained" / "best_model.zip"
n_seeds = int(sys.argv[2]) if len(sys.argv) > 2 else 4
agent = load_ppo_agent(policy)
ended_any, speeds = 0, []
for seed in range(n_seeds):
    env = RRRobotVectorEnv(num_envs=len(COMPASS_DEG), max_episode_steps=None, model=agent.env_config.get("model", "plane"),
                           **agent.env_kwargs)
    headings = np.radians(COMPASS_DEG)
    obs, _ = env.reset(seed=1000 + seed, options={"target_direction": headings})
    start = env.states[:, 0:2].copy()
    ended = np.zeros(len(headings), dtype=bool)
    state = None
    for k in range(int(round(50.0 / env.dt))):
        actions, state = agent.predict(obs, state=state, episode_start=np.full(len(headings), k == 0), deterministic=True)
        obs, _, terminated, _, _ = env.step(actions)
        ended |= terminated
    d = env.states[:, 0:2] - start
    speed = (d[:, 0] * np.cos(headings) + d[:, 1] * np.sin(headings)) / 50.0
    env.close()
    ended_any += int(ended.sum())
    speeds += list(speed[~ended])
    print(f"seed {1000 + seed}: ended {ended.sum()} of 8; speeds (mm/s) " + " ".join(f"{1e3 * v:.1f}" for v in speed))
print(f"{ended_any} of {8 * n_seeds} ended; the rest {1e3 * min(speeds):.1f}-{1e3 * max(speeds):.1f} mm/s")
