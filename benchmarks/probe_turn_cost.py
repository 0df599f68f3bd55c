"""Probe (removed after use; docs/notes/plane_nominal.md): where a plane policy loses speed on a heading.

Its speed along each heading over the 50 s episode, over the first 10 s and over the last 40 s, nominal
robot from the paper's start, as evaluate.py runs it:

    python -m benchmarks.probe_turn_cost agents/pretrained/best_model.zip
"""

from __future__ import annotations

import sys

import numpy as np

from rrrobot_gym.agents import load_ppo_agent
from rrrobot_gym.evaluation import run_episodes

HEADINGS_DEG = [0.0, 45.0, 90.0, 180.0]


def main():
    for path in sys.argv[1:]:
        run = run_episodes({"a": load_ppo_agent(path)}, "plane", HEADINGS_DEG, 50.0, 0)["a"]
        t, xy = run["times"], run["xy"]
        i10 = np.searchsorted(t, 10.0)
        for j, heading in enumerate(HEADINGS_DEG):
            along = (xy[:, j] - xy[0, j]) @ np.array([np.cos(np.radians(heading)), np.sin(np.radians(heading))])
            print(f"{path} {heading:5.0f} deg: 50 s {along[-1] / t[-1] * 1e3:6.2f}, first 10 s "
                  f"{along[i10] / t[i10] * 1e3:6.2f}, last 40 s {(along[-1] - along[i10]) / (t[-1] - t[i10]) * 1e3:6.2f} mm/s")


if __name__ == "__main__":
    main()
