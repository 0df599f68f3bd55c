"""Env steps per second of RRRobot-v0: the single env and the batched vector env.

    python -m benchmarks.throughput [--quick] [--json FILE]

An env step is one control step (0.05 s of robot time) of one robot, with everything a
step does: the physics with its step record (the torques applied and the ground force at
every integration step), the model checks read from that record, the observation, reward
and info. Measured beside the bare physics (``advance`` over the same 0.05 s with the same
ramped targets, no record, one process), each env step timed next to one physics step, in
alternation, so the env's own cost is a ratio of two measures that saw the same machine;
rows with ``workers=2`` are the vector env on both cores against that one-process physics.
Medians of repeats (the ratio: the median of each repeat's ratio). Each backend
(``--backends``, default: numba, if installed, and numpy) is measured in turn, after one
warm-up step (numba compiles on its first).
"""

from __future__ import annotations

import statistics
import time

import gymnasium
import numpy as np

import rrrobot_gym  # noqa: F401  (registers the env)
from rrrobot_gym import compiled
from rrrobot_gym.control import RampTargets
from rrrobot_gym.envs.vector import RRRobotVectorEnv
from rrrobot_gym.simulation import advance

from ._common import gentle_actions, machine, markdown_table, parser, write_json


def _paired(env, actions, physics_step, repeats: int):
    """(env seconds, physics seconds, env / physics throughput) for one run of ``actions``: medians
    over ``repeats``. Each env step is timed next to one ``physics_step()``, alternately, so the two
    see the same machine (its speed drifts by tens of per cent within minutes here)."""
    env_seconds, physics_seconds, ratios = [], [], []
    for _ in range(repeats):
        env.reset(seed=0)
        spent_env = spent_physics = 0.0
        for action in actions:
            start = time.perf_counter()
            env.step(action)
            middle = time.perf_counter()
            physics_step()
            spent_env += middle - start
            spent_physics += time.perf_counter() - middle
        env_seconds.append(spent_env)
        physics_seconds.append(spent_physics)
        ratios.append(spent_physics / spent_env)
    return statistics.median(env_seconds), statistics.median(physics_seconds), statistics.median(ratios)


def _physics(config, state, targets):
    """One control step of the bare physics (no record, no checks), advancing its own copy of ``state``."""
    current = np.array(state)

    def step():
        nonlocal current
        current = advance(config.sim, current, 0.0, config.dt, targets, check=False)

    return step


def _warm_up(env, actions, physics_step):
    """One env step and one physics step before timing (numba compiles on the first call)."""
    env.reset(seed=0)
    env.step(actions[0])
    physics_step()


def single_env(steps: int, repeats: int, rng, **env_kwargs) -> dict:
    env = gymnasium.make("RRRobot-v0", **env_kwargs)
    actions = gentle_actions(rng, (2,), steps)
    env.reset(seed=0)
    config = env.unwrapped.config
    targets = RampTargets(np.full(2, 0.5 * np.pi), np.full(2, 0.6 * np.pi), 0.0, config.dt)
    physics = _physics(config, env.unwrapped.state, targets)
    _warm_up(env, actions, physics)
    seconds, physics_seconds, ratio = _paired(env, actions, physics, repeats)
    return {"env": "single (gymnasium.make)", "backend": config.sim.backend, "num_envs": 1, "env_steps_per_s": steps / seconds,
            "physics_only_steps_per_s": steps / physics_seconds, "env_over_physics": ratio}


def vector_env(num_envs: int, steps: int, repeats: int, rng, workers: int = 1, **env_kwargs) -> dict:
    env = RRRobotVectorEnv(num_envs=num_envs, max_episode_steps=None, workers=workers, **env_kwargs)
    actions = gentle_actions(rng, (num_envs, 2), steps)
    env.reset(seed=0)
    targets = RampTargets(np.full((num_envs, 2), 0.5 * np.pi), np.full((num_envs, 2), 0.6 * np.pi), 0.0, env.dt)
    physics = _physics(env.config, env.states, targets)
    _warm_up(env, actions, physics)
    seconds, physics_seconds, ratio = _paired(env, actions, physics, repeats)
    name = "vector (make_vec)" + (f", workers={workers}" if workers > 1 else "")
    return {"env": name, "backend": env.config.sim.backend, "num_envs": num_envs, "env_steps_per_s": num_envs * steps / seconds,
            "physics_only_steps_per_s": num_envs * steps / physics_seconds, "env_over_physics": ratio}


def main(argv=None):
    p = parser(__doc__.split("\n\n")[0])
    default = ["numba", "numpy"] if compiled.available() else ["numpy"]
    p.add_argument("--backends", nargs="+", choices=("numba", "numpy"), default=default,
                   help=f"simulator backends to measure, in turn (default: {' '.join(default)})")  # fmt: skip
    args = p.parse_args(argv)
    rng = np.random.default_rng(0)
    repeats = 3 if args.quick else 5
    single_steps = 50 if args.quick else 400
    rows = []
    for backend in args.backends:
        rows.append(single_env(single_steps, repeats, rng, backend=backend))
        sizes = (1, 8, 16, 64, 256) if args.quick else (1, 8, 16, 64, 256, 4096)
        for n in sizes:
            steps = max(5, min(50, 5_000 // n)) if args.quick else max(10, min(400, 200_000 // n))
            if backend == "numba":  # ~10x faster: more steps for the same timing resolution
                steps = min(4 * steps, 1000)
            rows.append(vector_env(n, steps, repeats, rng, backend=backend))
            if n >= 64 and backend == "numba":  # both cores (numba's threads), beside one thread
                rows.append(vector_env(n, steps, repeats, rng, workers=2, backend=backend))
    table = markdown_table(
        ["env", "backend", "N", "env steps/s", "physics alone (advance), steps/s", "env / physics throughput"],
        [[r["env"], r["backend"], r["num_envs"], f"{r['env_steps_per_s']:,.0f}", f"{r['physics_only_steps_per_s']:,.0f}",
          f"{r['env_over_physics']:.0%}"] for r in rows],
    )
    print(table)
    write_json(args.json, {"machine": machine(), "results": rows, "time": time.time()})
    return rows


if __name__ == "__main__":
    main()
