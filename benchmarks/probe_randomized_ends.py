"""Probe (removed after its answer, docs/notes/randomized_robustness.md): why a policy's randomized
episodes end. Replays the robots that ended in an ``evaluate.py --randomize N --json`` record with
the policy alone and prints, for each, the step it ended at and that step's envelope measures.

    python -m benchmarks.probe_randomized_ends RECORD.json [--policy agents/pretrained/best_model.zip]
"""

import argparse
import json

import numpy as np

from rrrobot_gym.agents import load_ppo_agent
from rrrobot_gym.evaluation import physics_on, run_episodes

KEYS = ("leg_clearance", "slip_velocity", "liftoff_time", "tilt", "normal_force", "leg_rate_peak")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("record")
    p.add_argument("--policy", default="agents/pretrained/best_model.zip")
    p.add_argument("--agent", default="ppo", help="the agent's name in the record")
    args = p.parse_args()
    section = json.load(open(args.record))["randomized"][0]
    agent = load_ppo_agent(args.policy)
    headings, seeds = [], []
    for k, heading in enumerate(section["agents"][args.agent]["headings"]):
        for j, ended in enumerate(heading["ended"]):
            if ended:
                headings.append(heading["heading_deg"])
                seeds.append(section["robots"][k]["seeds"][j])
    run = run_episodes({"ppo": agent}, section["model"], headings, section["duration_s"], section["seed"],
                       info_keys=KEYS, randomize=section["ranges"], robot_seeds=seeds,
                       **physics_on(section["model"], {"ppo": agent}, None))["ppo"]
    for i, heading in enumerate(headings):
        last = np.flatnonzero(np.isfinite(run["slip_velocity"][:, i]))[-1]
        draws = {name: round(float(values[i]), 3) for name, values in run["draws"].items()
                 if name in ("leg_rate_limit", "torque_limit", "action_delay", "leg_length", "damping")}
        print(f"{heading:5.0f} deg ended {bool(run['terminated'][i])} at {last * 0.05:5.2f} s:",
              " ".join(f"{key} {run[key][last, i]:.4g}" for key in KEYS), draws)


if __name__ == "__main__":
    main()
