"""Probe (removed after use; docs/notes/randomized_robustness.md): how fast can a policy be on one
randomized robot if it is trained for that robot alone?

The shipped policy is fine-tuned (train.py --resume) on one fixed robot of evaluate.py's
``--randomize`` draw (its heading slot's seed), at that heading only, then scored on exactly that
robot as evaluate.py scores it. A specialist bounds what one policy for all robots can reach there.

    python -m benchmarks.probe_specialist --model plane --heading 90 --robots 8 15 12 --steps 3000000
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from rrrobot_gym import training
from rrrobot_gym.agents import load_ppo_agent
from rrrobot_gym.envs import task
from rrrobot_gym.evaluation import COMPASS_DEG, robot_seeds, run_episodes, spread

SHIPPED = {"plane": "agents/pretrained/best_model.zip", "pivot": "agents/pretrained_pivot/best_model.zip"}
# The shipped policies are mirrored (headings towards -Y run as mirror images), which a --direction-deg
# specialist may not be: a copy without mirror.json is the same policy on the +Y headings probed here.
UNMIRRORED = {"plane": "/work/runs/unmirrored_pretrained/best_model.zip",
              "pivot": "/work/runs/unmirrored_pretrained_pivot/best_model.zip"}


def fixed_ranges(seed: int, model: str):
    """The default ranges narrowed to the one robot ``seed`` draws (as the env draws it)."""
    from rrrobot_gym.envs.rrrobot_v0 import RRRobotEnv

    env = RRRobotEnv(model=model, randomize="default", reset_noise_scale=0.0)
    _, info = env.reset(seed=seed)
    ranges = {}
    for name, (low, high, scale) in task.RANDOMIZATIONS["default"].items():
        value = float(np.asarray(info["randomized_" + name]).ravel()[0])
        factor = value / task.nominal(name, env.unwrapped.config) if scale else value
        ranges[name] = task.Range(factor, factor, scale)
    env.close()
    return ranges


def score(agent, model, heading, seed):
    run = run_episodes({"a": agent}, model, [heading], 50.0, 0, randomize="default", robot_seeds=[seed])["a"]
    return spread(run, heading)["speeds_mps"][0] * 1000.0, bool(run["terminated"][0])


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--model", default="plane")
    parser.add_argument("--heading", type=float, default=90.0)
    parser.add_argument("--robots", type=int, nargs="*", default=[])
    parser.add_argument("--nominal", action="store_true", help="also a specialist on the nominal robot")
    parser.add_argument("--steps", type=int, default=3_000_000)
    parser.add_argument("--lr", default="0.0003")
    parser.add_argument("--eval-seed", type=int, default=0)
    parser.add_argument("--out", default="/work/runs/specialist")
    args = parser.parse_args()
    shipped = load_ppo_agent(SHIPPED[args.model])
    assert 0 < args.heading < 180, "the probe fine-tunes the unmirrored half (+Y headings)"
    slot = COMPASS_DEG.index(args.heading)
    seeds = robot_seeds(args.eval_seed, slot, 16)
    jobs = [(i, seeds[i]) for i in args.robots] + ([("nominal", None)] if args.nominal else [])
    results = []
    for label, seed in jobs:
        if seed is None:
            randomize = "none"
        else:
            task.RANDOMIZATIONS["probe"] = fixed_ranges(seed, args.model)
            randomize = "probe"
        run_dir = training.main([
            "--model", args.model, "--resume", UNMIRRORED[args.model], "--direction-deg", str(args.heading), "--no-mirror",
            "--randomize", randomize, "--total-timesteps", str(args.steps), "--learning-rate", args.lr,
            "--eval-freq", str(10 * args.steps), "--runs-dir", args.out, "--exp-name", f"{args.model}{label}",
            "--no-progress-bar", "--checkpoint-freq", str(10 * args.steps),
        ])
        specialist = load_ppo_agent(Path(run_dir) / "final_model.zip")
        if seed is None:
            from rrrobot_gym.evaluation import evaluate
            before = after = None
            recs = run_episodes({"s": shipped, "t": specialist}, args.model, [args.heading], 50.0, 0)
            from rrrobot_gym.evaluation import score as score_run
            before = score_run(recs["s"], [args.heading])[0]["speed_mps"] * 1000
            after = score_run(recs["t"], [args.heading])[0]["speed_mps"] * 1000
            row = {"robot": "nominal", "shipped_mmps": before, "specialist_mmps": after}
        else:
            before, ended_before = score(shipped, args.model, args.heading, seed)
            after, ended_after = score(specialist, args.model, args.heading, seed)
            row = {"robot": label, "seed": seed, "shipped_mmps": before, "shipped_ended": ended_before,
                   "specialist_mmps": after, "specialist_ended": ended_after,
                   "ranges": {k: v.low for k, v in task.RANDOMIZATIONS["probe"].items()}}
        row["run_dir"] = str(run_dir)
        print(json.dumps(row), flush=True)
        results.append(row)
    Path(args.out).mkdir(parents=True, exist_ok=True)
    (Path(args.out) / f"{args.model}_{args.heading:g}.json").write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
