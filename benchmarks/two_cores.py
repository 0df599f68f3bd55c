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

and beside them ``advance(..., workers=2)``, our split in worker processes. Medians of
rounds; each round measures every case back to back, so all see the same machine.
"""

from __future__ import annotations

import multiprocessing
import statistics
import time

import numpy as np

from rrrobot_gym.control import RampTargets
from rrrobot_gym.simulation import SimConfig, advance, initial_state

from ._common import machine, markdown_table, parser, write_json


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


def main(argv=None) -> None:
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--num-envs", type=int, nargs="+", default=[64, 4096], help="batch sizes")
    args = p.parse_args(argv)
    rounds = 3 if args.quick else 5
    rows = []
    for num_envs in args.num_envs:
        calls = max(2, round((4 if args.quick else 12) * 4096 / max(num_envs, 256)))
        rows.append(measure(num_envs, calls, rounds))
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
    write_json(args.json, {"machine": machine(), "rounds": rounds, "rows": rows})


if __name__ == "__main__":
    main()
