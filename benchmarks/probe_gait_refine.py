"""Probe (removed after use; docs/notes/randomized_robustness.md): CMA-ES refinement of a shipped 50 s gait on one
randomized robot, scored exactly as the evaluation scores that robot (50 s from the paper's start, own direction)."""

from __future__ import annotations

import argparse
import json
import time

import cma
import numpy as np

from rrrobot_gym.agents.gaits import GaitAgent
from rrrobot_gym.evaluation import COMPASS_DEG, robot_seeds, run_episodes
from rrrobot_gym.gait_search import PARAMETER_NAMES, SinusoidGait, load_gaits

FILES = {"plane": "agents/searched/pivot_own_50s.json", "pivot": "agents/searched/pivot_own_50s.json"}


def speeds(params_list, model, seed, ramp_s):
    agents = {f"g{i}": GaitAgent(SinusoidGait.from_dict(dict(zip(PARAMETER_NAMES, p)), name=f"g{i}", ramp_s=ramp_s), dt=0.05)
              for i, p in enumerate(params_list)}
    kwargs = {} if seed is None else {"randomize": "default", "robot_seeds": [seed]}
    runs = run_episodes(agents, model, [0.0], 50.0, 0, **kwargs)
    out = []
    for name in agents:
        run = runs[name]
        path = run["xy"][:, 0]
        valid = np.all(np.isfinite(path), axis=1)
        ended = bool(run["terminated"][0])
        out.append(0.0 if ended else float(np.linalg.norm(path[valid][-1] - path[0]) / run["times"][-1] * 1e3))
    return out


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--model", default="plane")
    parser.add_argument("--robot", default="8")
    parser.add_argument("--start", type=int, default=1, help="index of the shipped pivot_own gait to start from")
    parser.add_argument("--generations", type=int, default=40)
    parser.add_argument("--sigma", type=float, default=0.05)
    args = parser.parse_args()
    seed = None if args.robot == "nominal" else robot_seeds(0, COMPASS_DEG.index(90.0), 16)[int(args.robot)]
    data = json.load(open(FILES[args.model]))
    ramp_s = data.get("ramp_s", 0.0)
    lows = np.array([data["bounds"][k][0] for k in PARAMETER_NAMES])
    highs = np.array([data["bounds"][k][1] for k in PARAMETER_NAMES])
    start = load_gaits(FILES[args.model])[args.start].as_array()
    scale = highs - lows
    x0 = (start - lows) / scale
    first = speeds([start], args.model, seed, ramp_s)[0]
    es = cma.CMAEvolutionStrategy(x0, args.sigma, {"popsize": 16, "bounds": [0, 1], "seed": 1, "verbose": -9})
    best, best_x = first, start
    t0 = time.time()
    for g in range(args.generations):
        xs = es.ask()
        params = [lows + scale * np.asarray(x) for x in xs]
        fs = speeds(params, args.model, seed, ramp_s)
        es.tell(xs, [-f for f in fs])
        i = int(np.argmax(fs))
        if fs[i] > best:
            best, best_x = fs[i], params[i]
        print(f"gen {g} best-of-gen {fs[i]:.2f} best {best:.2f} ({time.time() - t0:.0f} s)", flush=True)
    print(json.dumps({"model": args.model, "robot": args.robot, "start_gait": args.start, "start_mmps": first,
                      "refined_mmps": best, "params": dict(zip(PARAMETER_NAMES, map(float, best_x)))}), flush=True)


if __name__ == "__main__":
    main()
