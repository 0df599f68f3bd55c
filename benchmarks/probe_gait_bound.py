"""Probe (removed after use; docs/notes/randomized_robustness.md): the fastest sinusoidal gait of
one randomized robot, searched for that robot alone, against the same search on the nominal robot.

A plane robot's physics does not depend on its heading, so a gait's speed along its own direction
(|displacement| / 50 s from the paper's start) on a robot bounds what that gait family gives it on
every heading.

    python -m benchmarks.probe_gait_bound --model plane --heading 90 --robots 15 8 --evaluations 20000
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from benchmarks.probe_specialist import fixed_ranges
from rrrobot_gym.agents.gaits import GaitAgent
from rrrobot_gym.evaluation import COMPASS_DEG, robot_seeds, run_episodes
from rrrobot_gym.gait_search import load_gaits

SHIPPED_GAITS = ("agents/searched/plane_own.json", "agents/searched/pivot_own.json")


def own_speeds(gaits, model, seed):
    """{name: (mm/s along its own direction over 50 s, ended)} of ``gaits`` on robot ``seed`` (None: nominal)."""
    agents = {g.name: GaitAgent(g, dt=0.05) for g in gaits}
    kwargs = {} if seed is None else {"randomize": "default", "robot_seeds": [seed]}
    out = {}
    for name, agent in agents.items():
        run = run_episodes({name: agent}, model, [0.0], 50.0, 0, **kwargs)[name]
        path = run["xy"][:, 0]
        valid = np.all(np.isfinite(path), axis=1)
        out[name] = (float(np.linalg.norm(path[valid][-1] - path[0]) / run["times"][-1] * 1e3), bool(run["terminated"][0]))
    return out


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--model", default="plane")
    parser.add_argument("--heading", type=float, default=90.0)
    parser.add_argument("--robots", type=int, nargs="*", default=[])
    parser.add_argument("--evaluations", type=int, default=20000)
    parser.add_argument("--out", default="/work/runs/gait_bound")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    seeds = robot_seeds(0, COMPASS_DEG.index(args.heading), 16)
    shipped = [g for f in SHIPPED_GAITS for g in load_gaits(f)]
    for label in ["nominal", *args.robots]:
        seed = None if label == "nominal" else seeds[label]
        command = [sys.executable, "-m", "rrrobot_gym", "gait-search", "--model", args.model, "--objective", "own",
                   "--evaluations", str(args.evaluations), "--seed", "0", "--no-progress",
                   "--out", str(out / f"{args.model}_{label}.json")]
        if seed is not None:
            ranges = {k: [v.low, v.high] for k, v in fixed_ranges(seed, args.model).items()}
            command += ["--env", "randomize=" + json.dumps(ranges)]
        subprocess.run(command, check=True)
        found = load_gaits(out / f"{args.model}_{label}.json")
        row = {"robot": label, "seed": seed, "searched_for_it": own_speeds(found, args.model, seed),
               "shipped_gaits": own_speeds(shipped, args.model, seed)}
        print(json.dumps(row), flush=True)
        with open(out / f"{args.model}_rows.jsonl", "a") as f:
            f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
