"""Where robot-by-robot integration on Python floats stops beating numpy's batched path.

    python -m benchmarks.row_crossover [--quick] [--json FILE]

``advance`` integrates a batch of at most ``simulation.ROW_BY_ROW_MAX`` robots one robot at a
time on floats (each with its own ramp, ``RampTargets.robot(i)``), larger batches as arrays.
For each batch size, one control step with its record on each path, timed in pairs (the two
see the same machine); the median of 15 pairs' time ratios (rows / arrays): below 1 the
robot-by-robot path is faster. This is what sets ``ROW_BY_ROW_MAX``.
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from rrrobot_gym import simulation
from rrrobot_gym.control import RampTargets
from rrrobot_gym.simulation import SimConfig, advance, initial_state

from ._common import machine, markdown_table, parser, write_json


def crossover_ratio(n: int, pairs: int) -> float:
    """Median over ``pairs`` of (robot-by-robot time / batched time) for one recorded control step of n robots."""
    config, states = SimConfig(), initial_state(n)
    ramp = RampTargets(np.full((n, 2), 0.5 * np.pi), np.full((n, 2), 0.6 * np.pi), 0.0, 0.05)
    kept = simulation.ROW_BY_ROW_MAX
    ratios = []
    try:
        for _ in range(pairs):
            seconds = []
            for row_by_row_max in (n, 0):  # robot by robot, then batched
                simulation.ROW_BY_ROW_MAX = row_by_row_max
                start = time.perf_counter()
                advance(config, states, 0.0, 0.05, ramp, check=False, record=True)
                seconds.append(time.perf_counter() - start)
            ratios.append(seconds[0] / seconds[1])
    finally:
        simulation.ROW_BY_ROW_MAX = kept
    return statistics.median(ratios)


def main(argv=None):
    args = parser(__doc__.split("\n\n")[0]).parse_args(argv)
    sizes = (8, 16, 24) if args.quick else (8, 12, 16, 20, 24, 32)
    rows = [{"num_robots": n, "rows_over_batched_time": crossover_ratio(n, 5 if args.quick else 15)} for n in sizes]
    print(markdown_table(["N", "robot-by-robot time / batched time"],
                         [[r["num_robots"], f"{r['rows_over_batched_time']:.2f}"] for r in rows]))  # fmt: skip
    print(f"ROW_BY_ROW_MAX = {simulation.ROW_BY_ROW_MAX}")
    write_json(args.json, {"machine": machine(), "results": rows, "time": time.time()})


if __name__ == "__main__":
    main()
