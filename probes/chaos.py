"""Closed-loop speeds of a shipped policy from starts 1e-12 apart: the spread a step change must beat."""
import sys
import numpy as np
from rrrobot_gym.agents.ppo import load_ppo_agent
from rrrobot_gym.envs.vector import RRRobotVectorEnv
from rrrobot_gym.simulation import initial_state
from benchmarks._common import POLICIES

def speeds(agent, model, headings, step, skip, offset, duration=50.0):
    kw = {**agent.env_kwargs, "timestep": step, "frame_skip": skip}
    env = RRRobotVectorEnv(num_envs=len(headings), max_episode_steps=None, model=model, reset_noise_scale=0.0, **kw)
    start = initial_state(len(headings))
    start[:, 6] += offset
    obs, _ = env.reset(seed=0, options={"state": start, "target_direction": np.radians(headings)})
    xy0 = env.states[:, :2].copy()
    for _ in range(round(duration / env.dt)):
        a, _ = agent.predict(obs, deterministic=True)
        obs, _, term, _, _ = env.step(a)
        assert not term.any()
    d = env.states[:, :2] - xy0
    h = np.radians(headings)
    return (d[:, 0] * np.cos(h) + d[:, 1] * np.sin(h)) / duration * 1e3

if __name__ == "__main__":
    model = sys.argv[1]
    agent = load_ppo_agent(POLICIES[model])
    headings = (0.0, 45.0, 90.0, 135.0, 180.0)
    for step, skip in ((1 / 300, 15), (1 / 3000, 150)):
        s = np.array([speeds(agent, model, headings, step, skip, k * 1e-12) for k in range(6)])
        print(f"{model} 1/{1/step:.0f} s, leg 1 starting k x 1e-12 rad off the paper's start, k = 0..5 (rows); mm/s:")
        print(np.round(s, 2))
        print("spread (max - min) / mean, %:", np.round((s.max(0) - s.min(0)) / s.mean(0) * 100, 3))
