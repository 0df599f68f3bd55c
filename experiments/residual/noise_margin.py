"""How close to the envelope does the plane turn-then-run baseline run? Add white noise of each
given standard deviation (action units) to its actions and report when each of the 8 compass
headings' episode ends (50 s, the paper's start, the env's own checks) and which check ended it.

    python experiments/residual/noise_margin.py 0 0.001 0.003 0.01
    python experiments/residual/noise_margin.py --base agents/searched/turn_then_run_robust.json 0 0.001 0.003 0.01
"""

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from rrrobot_gym.agents.residual import combine  # noqa: E402
from rrrobot_gym.agents.turn_then_run import load_turn_then_run_agent  # noqa: E402
from rrrobot_gym.envs.vector import RRRobotVectorEnv  # noqa: E402

HEADINGS = np.radians(np.arange(0, 360, 45.0))


def ends(sigma, seed=1, steps=1000, base_file=ROOT / "agents" / "searched" / "turn_then_run.json"):
    base = load_turn_then_run_agent(base_file)
    env = RRRobotVectorEnv(num_envs=len(HEADINGS), max_episode_steps=None, reset_noise_scale=0.0)
    obs, _ = env.reset(seed=0, options={"target_direction": HEADINGS})
    rng = np.random.default_rng(seed)
    state, start = None, np.ones(len(HEADINGS), dtype=bool)
    end, why = np.full(len(HEADINGS), np.nan), [""] * len(HEADINGS)
    for k in range(steps):
        actions, state = base.predict(obs, state, start)
        start[:] = False
        obs, _, terminated, _, info = env.step(combine(actions, rng.normal(0.0, 1.0, actions.shape) * sigma, 1.0))
        for i in np.flatnonzero(terminated & np.isnan(end)):
            final = info["final_info"]
            end[i] = (k + 1) * env.dt
            why[i] = f"slip {final['slip_velocity'][i]:.3f} m/s" if final["outside_model"][i] else "other"
    return end, why


if __name__ == "__main__":
    args = sys.argv[1:]
    base_file = ROOT / "agents" / "searched" / "turn_then_run.json"
    if args[:1] == ["--base"]:
        base_file, args = Path(args[1]), args[2:]
    for sigma in [float(s) for s in args]:
        end, why = ends(sigma, base_file=base_file)
        cells = ", ".join(f"{d:.0f} deg: " + (f"{t:.2f} s ({w})" if np.isfinite(t) else "ran 50 s")
                          for d, t, w in zip(np.degrees(HEADINGS), end, why))
        print(f"sigma {sigma}: {cells}", flush=True)
