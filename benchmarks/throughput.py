"""Env steps per second of RRRobot-v0: the single env and the batched vector env.

    python -m benchmarks.throughput [--quick] [--json FILE]

An env step is one control step (0.05 s of robot time) of one robot, with everything a
step does: the physics with its step record (the torques applied and the ground force at
every integration step), the model checks read from that record, the observation, reward
and info. Measured beside the bare physics (``advance`` over the same 0.05 s with the same
ramped targets, no record, one process), so the env's own cost is a ratio from one run;
rows with ``workers=2`` are the vector env on both cores against that one-process physics.
Medians of repeats.
"""

from __future__ import annotations

import time

import gymnasium
import numpy as np

import rrrobot_gym  # noqa: F401  (registers the env)
from rrrobot_gym.control import RampTargets
from rrrobot_gym.envs.vector import RRRobotVectorEnv
from rrrobot_gym.simulation import advance

from ._common import machine, markdown_table, median_time, parser, write_json


def _gentle_actions(rng, shape, steps):
    """Smooth leg targets near vertical: the robot stays inside the model, so no resets muddle the timing."""
    phase = rng.uniform(0, 2 * np.pi, shape)
    k = np.arange(steps)[:, None, None] if len(shape) == 2 else np.arange(steps)[:, None]
    return (0.05 * np.sin(0.4 * k + phase)).astype(np.float32)


def single_env(steps: int, repeats: int, rng, **env_kwargs) -> dict:
    env = gymnasium.make("RRRobot-v0", **env_kwargs)
    actions = _gentle_actions(rng, (2,), steps)

    def run():
        env.reset(seed=0)
        for action in actions:
            env.step(action)

    seconds = median_time(run, repeats)
    bare_state = env.unwrapped.state.copy()
    config = env.unwrapped.config
    targets = RampTargets(np.full(2, 0.5 * np.pi), np.full(2, 0.6 * np.pi), 0.0, config.dt)

    def physics():
        state = bare_state
        for _ in range(steps):
            state = advance(config.sim, state, 0.0, config.dt, targets, check=False)

    physics_seconds = median_time(physics, repeats)
    name = "single (gymnasium.make)"
    return {"env": name, "num_envs": 1, "env_steps_per_s": steps / seconds,
            "physics_only_steps_per_s": steps / physics_seconds}


def vector_env(num_envs: int, steps: int, repeats: int, rng, workers: int = 1, **env_kwargs) -> dict:
    env = RRRobotVectorEnv(num_envs=num_envs, max_episode_steps=None, workers=workers, **env_kwargs)
    actions = _gentle_actions(rng, (num_envs, 2), steps)

    def run():
        env.reset(seed=0)
        for action in actions:
            env.step(action)

    seconds = median_time(run, repeats)
    states = env.states.copy()
    targets = RampTargets(np.full((num_envs, 2), 0.5 * np.pi), np.full((num_envs, 2), 0.6 * np.pi), 0.0, env.dt)

    def physics():
        s = states
        for _ in range(steps):
            s = advance(env.config.sim, s, 0.0, env.dt, targets, check=False)

    physics_seconds = median_time(physics, repeats)
    name = "vector (make_vec)" + (f", workers={workers}" if workers > 1 else "")
    return {"env": name, "num_envs": num_envs, "env_steps_per_s": num_envs * steps / seconds,
            "physics_only_steps_per_s": num_envs * steps / physics_seconds}


def main(argv=None):
    args = parser(__doc__.split("\n\n")[0]).parse_args(argv)
    rng = np.random.default_rng(0)
    repeats = 3 if args.quick else 5
    single_steps = 100 if args.quick else 400
    rows = [single_env(single_steps, repeats, rng)]
    sizes = (1, 8, 16, 64, 256) if args.quick else (1, 8, 16, 64, 256, 4096)
    for n in sizes:
        steps = max(5, min(200, 20_000 // n)) if args.quick else max(10, min(400, 200_000 // n))
        rows.append(vector_env(n, steps, repeats, rng))
        if n >= 256:  # both cores, beside one (the physics column stays one process)
            rows.append(vector_env(n, steps, repeats, rng, workers=2))
    table = markdown_table(
        ["env", "N", "env steps/s", "physics alone (advance), steps/s", "env / physics throughput"],
        [[r["env"], r["num_envs"], f"{r['env_steps_per_s']:,.0f}", f"{r['physics_only_steps_per_s']:,.0f}",
          f"{r['env_steps_per_s'] / r['physics_only_steps_per_s']:.0%}"] for r in rows],
    )
    print(table)
    write_json(args.json, {"machine": machine(), "results": rows, "time": time.time()})
    return rows


if __name__ == "__main__":
    main()
