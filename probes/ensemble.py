"""Closed-loop speeds of a shipped policy over K starts 1e-9 rad apart, at 1/300 s and 1/3000 s:
the ensemble means a step change moves, against the spread a start moves (numba, one batch)."""
import sys, time
import numpy as np
from rrrobot_gym.agents.ppo import load_ppo_agent
from rrrobot_gym.envs.vector import RRRobotVectorEnv
from rrrobot_gym.simulation import initial_state
from benchmarks._common import POLICIES

NOISE = 0.01  # the env's own reset noise: starts that differ from the first instant (1e-9 apart, the runs
# kept together for seconds and chose one regime for the whole ensemble)

def speeds(agent, model, headings, step, skip, starts, duration=50.0, offset=1e-9, noise=NOISE):
    kw = {**agent.env_kwargs, "timestep": step, "frame_skip": skip}
    h = np.repeat(np.radians(headings), starts)
    env = RRRobotVectorEnv(num_envs=len(h), max_episode_steps=None, model=model,
                           reset_noise_scale=noise, **{k: v for k, v in kw.items() if k != "reset_noise_scale"})
    if noise:
        obs, _ = env.reset(seed=0, options={"target_direction": h})
    else:
        start = initial_state(len(h))
        start[:, 6] += np.tile(np.arange(starts), len(headings)) * offset
        obs, _ = env.reset(seed=0, options={"state": start, "target_direction": h})
    xy0 = env.states[:, :2].copy()
    ended = np.zeros(len(h), bool)
    for _ in range(round(duration / env.dt)):
        a, _ = agent.predict(obs, deterministic=True)
        obs, _, term, _, _ = env.step(a)
        ended |= term
    d = env.states[:, :2] - xy0
    v = (d[:, 0] * np.cos(h) + d[:, 1] * np.sin(h)) / duration * 1e3
    v[ended] = np.nan
    return v.reshape(len(headings), starts)

if __name__ == "__main__":
    model, starts = sys.argv[1], int(sys.argv[2])
    agent = load_ppo_agent(POLICIES[model])
    headings = (0.0, 45.0, 90.0, 135.0, 180.0)
    out = {}
    for step, skip in ((1 / 300, 15), (1 / 3000, 150)):
        t = time.time()
        out[step] = speeds(agent, model, headings, step, skip, starts)
        print(f"1/{1/step:.0f} s: {time.time() - t:.0f} s, {np.isnan(out[step]).sum()} ended", flush=True)
    a, b = out[1 / 300], out[1 / 3000]
    for i, hd in enumerate(headings):
        ma, mb = np.nanmean(a[i]), np.nanmean(b[i])
        se = np.sqrt(np.nanvar(a[i], ddof=1) / starts + np.nanvar(b[i], ddof=1) / starts)
        print(f"{hd:5g} deg: 1/300 s mean {ma:.2f} (runs {np.nanmin(a[i]):.2f}-{np.nanmax(a[i]):.2f}, sd {np.nanstd(a[i], ddof=1):.2f}); "
              f"1/3000 s mean {mb:.2f} (runs {np.nanmin(b[i]):.2f}-{np.nanmax(b[i]):.2f}, sd {np.nanstd(b[i], ddof=1):.2f}); "
              f"means differ {100 * (ma / mb - 1):+.3f} % +- {100 * se / mb:.3f} % (1 se); paper's start {a[i, 0]:.2f} vs {b[i, 0]:.2f}")
