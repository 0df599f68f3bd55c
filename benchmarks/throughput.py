"""Env steps per second of RRRobot-v0: the single env and the batched vector env.

    python -m benchmarks.throughput [--quick] [--json FILE] [--family]

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

``--family`` instead times robots of the family side by side (the paper's, more legs, ellipsoid
shells) in the vector env at N = 64 and the single env, each member's run in turn within every
repeat, and reports each one's env steps/s and its ratio to the paper robot's.
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
    actions = gentle_actions(rng, env.action_space.shape, steps)
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
    actions = gentle_actions(rng, env.action_space.shape, steps)
    env.reset(seed=0)
    targets = RampTargets(np.full((num_envs, 2), 0.5 * np.pi), np.full((num_envs, 2), 0.6 * np.pi), 0.0, env.dt)
    physics = _physics(env.config, env.states, targets)
    _warm_up(env, actions, physics)
    seconds, physics_seconds, ratio = _paired(env, actions, physics, repeats)
    name = "vector (make_vec)" + (f", workers={workers}" if workers > 1 else "")
    return {"env": name, "backend": env.config.sim.backend, "num_envs": num_envs, "env_steps_per_s": num_envs * steps / seconds,
            "physics_only_steps_per_s": num_envs * steps / physics_seconds, "env_over_physics": ratio}


FAMILY = {"paper robot (sphere, 2 legs)": {}, "sphere, 3 legs": {"num_legs": 3}, "sphere, 4 legs": {"num_legs": 4},
          "oblate (0.12, 0.12, 0.09), 2 legs": {"shell_axes": (0.12, 0.12, 0.09)},
          "oblate (0.12, 0.12, 0.09), 4 legs": {"shell_axes": (0.12, 0.12, 0.09), "num_legs": 4},
          "sphere, 6 legs": {"num_legs": 6}}  # fmt: skip
"""The members ``--family`` times (env keywords), the paper's robot first."""


def family_rows(num_envs: int, steps: int, repeats: int) -> list:
    """Env steps/s of each :data:`FAMILY` member at ``num_envs`` (0: the single env), medians of
    ``repeats`` rounds in which every member runs its ``steps`` in turn, and each over the paper's."""
    envs, actions = {}, {}
    for name, kwargs in FAMILY.items():
        env = (gymnasium.make("RRRobot-v0", **kwargs) if num_envs == 0 else
               RRRobotVectorEnv(num_envs=num_envs, max_episode_steps=None, **kwargs))  # fmt: skip
        shape = env.action_space.shape
        actions[name] = gentle_actions(np.random.default_rng(0), shape, steps)
        env.reset(seed=0)
        env.step(actions[name][0])  # (numba compiles each leg count's steppers on its first step)
        envs[name] = env
    seconds = {name: [] for name in FAMILY}
    for _ in range(repeats):
        for name, env in envs.items():
            env.reset(seed=0)
            start = time.perf_counter()
            for action in actions[name]:
                env.step(action)
            seconds[name].append(time.perf_counter() - start)
    robots = max(num_envs, 1)
    rates = {name: robots * steps / statistics.median(times) for name, times in seconds.items()}
    paper = rates[next(iter(FAMILY))]
    return [{"member": name, "num_envs": robots, "env": "single" if num_envs == 0 else "vector",
             "env_steps_per_s": rate, "over_paper_robot": rate / paper} for name, rate in rates.items()]  # fmt: skip


def family_main(args):
    rows = []
    for num_envs, steps in ((0, 50 if args.quick else 300), (64, 20 if args.quick else 150)):
        rows += family_rows(num_envs, steps, 3 if args.quick else 5)
    table = markdown_table(["member", "env", "N", "env steps/s", "over the paper robot"],
                           [[r["member"], r["env"], r["num_envs"], f"{r['env_steps_per_s']:,.0f}",
                             f"{r['over_paper_robot']:.2f}"] for r in rows])  # fmt: skip
    print(table)
    write_json(args.json, {"machine": machine(), "results": rows, "time": time.time()})
    return rows


def main(argv=None):
    p = parser(__doc__.split("\n\n")[0])
    p.add_argument("--family", action="store_true", help="time members of the robot family side by side instead")
    default = ["numba", "numpy"] if compiled.available() else ["numpy"]
    p.add_argument("--backends", nargs="+", choices=("numba", "numpy"), default=default,
                   help=f"simulator backends to measure, in turn (default: {' '.join(default)})")  # fmt: skip
    args = p.parse_args(argv)
    if args.family:
        return family_main(args)
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
