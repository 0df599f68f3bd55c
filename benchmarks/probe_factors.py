"""Probe (removed after use): what makes a slow randomized robot slow. The shipped policy runs the
robot as drawn, then with one quantity at a time set back to the nominal robot's, and with only
that quantity drawn.

    python -m benchmarks.probe_factors --model plane --heading 90 --robots 8 15
"""

from __future__ import annotations

import argparse
import json

from benchmarks.probe_specialist import SHIPPED, fixed_ranges
from rrrobot_gym.agents import load_ppo_agent
from rrrobot_gym.envs import task
from rrrobot_gym.evaluation import COMPASS_DEG, robot_seeds, run_episodes, score


def speed(agent, model, heading, ranges):
    run = run_episodes({"a": agent}, model, [heading], 50.0, 0, randomize=ranges)["a"]
    return round(score(run, [heading])[0]["speed_mps"] * 1e3, 2)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--model", default="plane")
    parser.add_argument("--heading", type=float, default=90.0)
    parser.add_argument("--robots", type=int, nargs="*", default=[8, 15])
    args = parser.parse_args()
    agent = load_ppo_agent(SHIPPED[args.model])
    seeds = robot_seeds(0, COMPASS_DEG.index(args.heading), 16)
    for index in args.robots:
        drawn = {k: (v.low, v.high) for k, v in fixed_ranges(seeds[index], args.model).items()}
        nominal = {k: ((1.0, 1.0) if task.RANDOMIZATIONS["default"][k].scale else (0.0, 0.0)) for k in drawn}
        nominal["friction_coefficient"] = (1.0, 1.0)
        row = {"robot": index, "drawn": {k: round(v[0], 3) for k, v in drawn.items()},
               "as_drawn": speed(agent, args.model, args.heading, drawn),
               "nominal": speed(agent, args.model, args.heading, nominal),
               "this_one_nominal": {}, "only_this_drawn": {}}
        for name in drawn:
            row["this_one_nominal"][name] = speed(agent, args.model, args.heading, drawn | {name: nominal[name]})
            row["only_this_drawn"][name] = speed(agent, args.model, args.heading, nominal | {name: drawn[name]})
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
