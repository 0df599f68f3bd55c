"""What ``start_halves`` costs: env steps with it against env steps without, side by side.

    python -m benchmarks.start_halves [--quick] [--json FILE] [--num-envs 1 64 4096] [--halves 2]

For each batch size (1: the single ``gymnasium.make`` env; more: the vector env), two envs of
the same scene, one with ``start_halves`` (default 2) and one without, step the same gentle
actions; each step of one is timed next to a step of the other, in alternation, so both see
the same machine. Reported: the medians of the repeats' env steps/s and of their ratio. The
physics alone would cost (15 + 2 halves) / 15 = 1.13x at two halves; the rest is the graded
call's overhead (two uniform integrations and the record joined from them, whose summary is
then computed with numpy instead of in the compiled stepper).
"""

from __future__ import annotations

import statistics
import time

import gymnasium
import numpy as np

import rrrobot_gym  # noqa: F401  (registers the env)
from rrrobot_gym.envs.vector import RRRobotVectorEnv

from ._common import gentle_actions, machine, markdown_table, parser, write_json


def make(num_envs: int, halves: int):
    kwargs = {"start_halves": halves, "terminate_outside_model": False}
    if num_envs == 1:
        return gymnasium.make("RRRobot-v0", **kwargs).unwrapped
    return RRRobotVectorEnv(num_envs=num_envs, **kwargs)


def paired(num_envs: int, halves: int, steps: int, repeats: int):
    """(steps/s without, steps/s with, ratio of times with / without): medians over repeats."""
    plain, graded = make(num_envs, 0), make(num_envs, halves)
    shape = (num_envs, 2) if num_envs > 1 else (1, 2)
    actions = gentle_actions(np.random.default_rng(0), shape, steps)
    rates_plain, rates_graded, ratios = [], [], []
    for _ in range(repeats + 1):  # the first round warms up (numba compiles, caches fill)
        plain.reset(seed=0)
        graded.reset(seed=0)
        t_plain = t_graded = 0.0
        for action in actions:
            action = action if num_envs > 1 else action[0]
            start = time.perf_counter()
            plain.step(action)
            middle = time.perf_counter()
            graded.step(action)
            t_plain += middle - start
            t_graded += time.perf_counter() - middle
        rates_plain.append(steps * num_envs / t_plain)
        rates_graded.append(steps * num_envs / t_graded)
        ratios.append(t_graded / t_plain)
    return (statistics.median(rates_plain[1:]), statistics.median(rates_graded[1:]), statistics.median(ratios[1:]))


def main(argv=None):
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--num-envs", nargs="+", type=int, default=[1, 64, 4096])
    p.add_argument("--halves", type=int, default=2)
    args = p.parse_args(argv)
    steps, repeats = (20, 3) if args.quick else (100, 7)
    rows = []
    for n in args.num_envs:
        without, with_halves, ratio = paired(n, args.halves, steps if n < 4096 else max(5, steps // 10), repeats)
        rows.append({"num_envs": n, "steps_per_s": without, "steps_per_s_start_halves": with_halves, "time_ratio": ratio})
        print(f"N={n}: {without:,.0f} env steps/s without, {with_halves:,.0f} with start_halves={args.halves}: "
              f"{ratio:.2f}x the time", flush=True)  # fmt: skip
    print(
        markdown_table(
            ["N", "env steps/s", f"with start_halves={args.halves}", "time ratio"],
            [[r["num_envs"], f"{r['steps_per_s']:,.0f}", f"{r['steps_per_s_start_halves']:,.0f}", f"{r['time_ratio']:.2f}x"]
             for r in rows],
        )  # fmt: skip
    )
    write_json(args.json, {"machine": machine(), "halves": args.halves, "steps": steps, "repeats": repeats, "rows": rows})


if __name__ == "__main__":
    main()
