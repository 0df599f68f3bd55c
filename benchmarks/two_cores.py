"""What two cores can give on this machine, before and after our code splits the work.

    python -m benchmarks.two_cores [--quick] [--json FILE] [--num-envs 64 4096]

The physics of one control step (``advance`` with its record, N robots, ramped targets)
runs in one process while the other core idles (*alone*), then in two independent
processes started together, nothing shared or shipped between them:

- each on the whole batch of N: the pair's total rate over the lone rate is what the
  machine's two cores give side by side (the *machine ceiling*: below 2 where the vCPUs
  share a core, caches or memory bandwidth);
- each on half the batch: the rate of a perfect two-way split of one batch, with no cost
  of sending work or results (the *split ceiling*: below the machine's where a batch of
  N/2 costs more than half of N, numpy's per-call overhead);

and beside them ``advance(..., workers=2)``, our split (numba threads with the compiled
stepper, worker processes on numpy). Medians of rounds; each round measures every case back to
back, so all see the same machine.

Then the whole env, as a user runs it: two ``make_vec`` envs of N robots, ``workers=1`` and
``workers=2``, stepped in alternation with the same actions (each env step of one timed next to
one of the other, so both see the same machine), their physics, checks, observation, reward and
info; the speed-up is the median over rounds of each round's ratio.
"""

from __future__ import annotations

import multiprocessing
import statistics
import time

import numpy as np

from rrrobot_gym.control import RampTargets
from rrrobot_gym.envs.vector import RRRobotVectorEnv
from rrrobot_gym.simulation import SimConfig, advance, initial_state, takes_compiled

from ._common import gentle_actions, machine, markdown_table, parser, write_json


def _batch(num_envs: int):
    config = SimConfig()
    state = np.repeat(initial_state()[None], num_envs, axis=0)
    targets = RampTargets(state[:, 6:8], state[:, 6:8] + 0.1, 0.0, 0.05)
    return config, state, targets


def _seconds(num_envs: int, calls: int, workers: int = 1) -> float:
    config, state, targets = _batch(num_envs)
    advance(config, state, 0.0, 0.05, targets, check=False, record=True, workers=workers)  # warm up
    start = time.perf_counter()
    for _ in range(calls):
        advance(config, state, 0.0, 0.05, targets, check=False, record=True, workers=workers)
    return time.perf_counter() - start


def _worker(num_envs: int, calls: int, barrier, results):
    _batch(num_envs)  # imports and first-call costs before the start line
    barrier.wait()
    results.put(_seconds(num_envs, calls))


def _concurrent_seconds(num_envs: int, calls: int, processes: int) -> list:
    """Each process's seconds for ``calls`` advances of N robots, all started together."""
    context = multiprocessing.get_context("fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn")
    barrier = context.Barrier(processes)
    results = context.Queue()
    workers = [context.Process(target=_worker, args=(num_envs, calls, barrier, results)) for _ in range(processes)]
    for worker in workers:
        worker.start()
    seconds = [results.get() for _ in workers]
    for worker in workers:
        worker.join()
    return seconds


def measure(num_envs: int, calls: int, rounds: int) -> dict:
    alone, pair, halves, split = [], [], [], []
    for _ in range(rounds):
        (one,) = _concurrent_seconds(num_envs, calls, 1)
        alone.append(num_envs * calls / one)
        pair.append(2 * num_envs * calls / max(_concurrent_seconds(num_envs, calls, 2)))
        halves.append(num_envs * calls / max(_concurrent_seconds(num_envs // 2, calls, 2)))
        split.append(num_envs * calls / _seconds(num_envs, calls, workers=2))

    def over_alone(rates):
        return statistics.median(r / a for a, r in zip(alone, rates))

    return {
        "num_envs": num_envs,
        "alone_env_steps_per_s": statistics.median(alone),
        "two_whole_batches_env_steps_per_s": statistics.median(pair),
        "machine_ceiling": over_alone(pair),
        "perfect_split_env_steps_per_s": statistics.median(halves),
        "split_ceiling": over_alone(halves),
        "workers2_env_steps_per_s": statistics.median(split),
        "workers2_speedup": over_alone(split),
    }


def _backend(sim: SimConfig) -> str:
    """The backend ``advance`` takes for this config ("auto" resolved; the env's ramps are targets it knows)."""
    return "numba" if takes_compiled(sim) else "numpy"


def measure_env(num_envs: int, steps: int, rounds: int) -> dict:
    """The vector env with ``workers=1`` and ``workers=2``, each step timed beside the other's."""
    envs = {workers: RRRobotVectorEnv(num_envs=num_envs, max_episode_steps=None, workers=workers) for workers in (1, 2)}
    actions = gentle_actions(np.random.default_rng(0), (num_envs, 2), steps)
    for env in envs.values():  # warm up: numba compiles (or loads) each stepper on its first call
        env.reset(seed=0)
        env.step(actions[0])
    one, two, ratios = [], [], []
    for _ in range(rounds):
        spent = {workers: 0.0 for workers in envs}
        for env in envs.values():
            env.reset(seed=0)
        for action in actions:
            for workers, env in envs.items():
                start = time.perf_counter()
                env.step(action)
                spent[workers] += time.perf_counter() - start
        one.append(num_envs * steps / spent[1])
        two.append(num_envs * steps / spent[2])
        ratios.append(spent[1] / spent[2])
    return {
        "num_envs": num_envs,
        "backend": _backend(envs[1].config.sim),
        "env_workers1_steps_per_s": statistics.median(one),
        "env_workers2_steps_per_s": statistics.median(two),
        "env_workers2_speedup": statistics.median(ratios),
        "env_workers2_speedup_range": [min(ratios), max(ratios)],
    }


def main(argv=None) -> None:
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--num-envs", type=int, nargs="+", default=[64, 4096], help="batch sizes")
    p.add_argument("--env-only", action="store_true", help="measure only the env with workers=1 against workers=2")
    args = p.parse_args(argv)
    rounds = 3 if args.quick else 5
    rows, env_rows = [], []
    for num_envs in args.num_envs:
        calls = max(2, round((4 if args.quick else 12) * 4096 / max(num_envs, 256)))
        env_rows.append(measure_env(num_envs, 2 * calls, 2 * rounds - 1))
        if not args.env_only:
            rows.append(measure(num_envs, calls, rounds))
    print(
        markdown_table(
            ["N", "backend", "env, workers=1 (env steps/s)", "env, workers=2", "speed-up (median; range)"],
            [[r["num_envs"], r["backend"], f"{r['env_workers1_steps_per_s']:,.0f}",
              f"{r['env_workers2_steps_per_s']:,.0f}",
              f"{r['env_workers2_speedup']:.2f}x ({r['env_workers2_speedup_range'][0]:.2f}-"
              f"{r['env_workers2_speedup_range'][1]:.2f})"]
             for r in env_rows],
        )  # fmt: skip
    )
    if args.env_only:
        write_json(args.json, {"machine": machine(), "rounds": 2 * rounds - 1, "env_rows": env_rows})
        return
    print(
        markdown_table(
            ["N", "alone (env steps/s)", "machine ceiling: 2 x N at once", "split ceiling: 2 x N/2 at once",
             "advance workers=2"],
            [[r["num_envs"], f"{r['alone_env_steps_per_s']:,.0f}",
              f"{r['two_whole_batches_env_steps_per_s']:,.0f} ({r['machine_ceiling']:.2f}x)",
              f"{r['perfect_split_env_steps_per_s']:,.0f} ({r['split_ceiling']:.2f}x)",
              f"{r['workers2_env_steps_per_s']:,.0f} ({r['workers2_speedup']:.2f}x)"]
             for r in rows],
        )  # fmt: skip
    )
    write_json(args.json, {"machine": machine(), "rounds": rounds, "rows": rows, "env_rounds": 2 * rounds - 1,
                           "env_rows": env_rows})


if __name__ == "__main__":
    main()
