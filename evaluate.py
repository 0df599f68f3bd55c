"""Score a learned PPO policy and the paper's gaits on the same RRRobot-v0 evaluation: the
command line of :mod:`rrrobot_gym.evaluation` (``python evaluate.py --help``), with the
policies shipped in this repository's agents/ as its defaults."""

from pathlib import Path

from rrrobot_gym.evaluation import main

AGENTS = Path(__file__).resolve().parent / "agents"

if __name__ == "__main__":
    main(default_policy=AGENTS / "pretrained" / "best_model.zip",
         default_pivot_policy=AGENTS / "pretrained_pivot" / "best_model.zip")
