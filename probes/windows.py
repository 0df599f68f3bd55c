"""Probe: restarted 5 s windows of the shipped policies against DOP853 (throwaway)."""
import math, time, sys, pickle
from dataclasses import replace
from pathlib import Path
import numpy as np
from rrrobot_gym.agents.ppo import load_ppo_agent
from rrrobot_gym.envs.vector import RRRobotVectorEnv
from rrrobot_gym.control import RampTargets
from rrrobot_gym.simulation import advance, simulate_reference

ROOT = Path(__file__).resolve().parent.parent
AGENTS = {"plane": ROOT / "agents/pretrained/best_model.zip", "pivot": ROOT / "agents/pretrained_pivot/best_model.zip"}

def rollout(model, headings, steps, agent=None, seed=0):
    kwargs = dict(agent.env_config) if agent else {}
    kwargs.update(model=model, terminate_outside_model=False, randomize=None, reset_noise_scale=0.0)
    env = RRRobotVectorEnv(num_envs=len(headings), max_episode_steps=None, **kwargs)
    obs, _ = env.reset(seed=seed, options={"target_direction": np.radians(headings)})
    rng = np.random.default_rng(seed)
    states, starts, ends = [env.states.copy()], [], []
    for _ in range(steps):
        if agent:
            a, _ = agent.predict(obs, deterministic=True)
        else:
            a = rng.uniform(-1, 1, (len(headings), 2)).astype(np.float32)
        starts.append(env.leg_targets.copy())
        obs, _, term, _, _ = env.step(a)
        if np.any(term):
            raise RuntimeError(f"terminated at step {len(ends)}: {np.flatnonzero(term)}")
        ends.append(env.leg_targets.copy())
        states.append(env.states.copy())
    dt = env.dt; sim = env.config.sim
    env.close()
    return np.array(states), np.array(starts), np.array(ends), dt, sim

def windows(states, starts, ends, dt, at_s=(0, 10, 20, 30, 40), length_s=5.0):
    n = round(length_s / dt)
    w0, ws, we = [], [], []
    for t in at_s:
        k = round(t / dt)
        if k + n > len(starts):
            continue
        w0.append(states[k]); ws.append(starts[k:k + n]); we.append(ends[k:k + n])
    # (W, N, ...) -> robots = W*N
    start = np.concatenate(w0)
    s = np.concatenate([x.transpose(1, 0, 2) for x in ws])  # (R, n, 2)
    e = np.concatenate([x.transpose(1, 0, 2) for x in we])
    return start, s, e

def replay(config, start, starts, ends, dt, reference=False, stepper=None, **kw):
    state = start.copy()
    out = [state.copy()]
    for i in range(starts.shape[1]):
        targets = RampTargets(starts[:, i], ends[:, i], 0.0, dt)
        if reference:
            state = simulate_reference(config, targets, dt, state=state, sample_dt=dt, **kw).states[-1]
        elif stepper is not None:
            state = stepper(config, state, dt, targets)
        else:
            state = advance(config, state, 0.0, dt, targets, check=False)
        out.append(state.copy())
    return np.array(out)

def err(a, b):
    return np.hypot(a[..., 0] - b[..., 0], a[..., 1] - b[..., 1])

if __name__ == "__main__":
    model = sys.argv[1]
    headings = [0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0]
    agent = load_ppo_agent(AGENTS[model])
    t = time.time()
    roll = rollout(model, headings, 900, agent)
    print("rollout", time.time() - t)
    states, starts, ends, dt, sim = roll
    start, s, e = windows(states, starts, ends, dt)
    print(start.shape, s.shape, sim)
    t = time.time()
    ref = replay(sim, start, s, e, dt, reference=True)
    print("ref", time.time() - t)
    pickle.dump(dict(roll=roll, start=start, s=s, e=e, ref=ref), open(f"/tmp/acc_{model}.pkl", "wb"))
    for h in (1/300, 1/600, 1/1200):
        p = replay(replace(sim, timestep=h), start, s, e, dt)
        er = err(p, ref).max(axis=0)
        print(f"1/{1/h:.0f}", (er.reshape(-1, len(headings)) * 1e3).round(3))
