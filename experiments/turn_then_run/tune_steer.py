"""Heading correction, step 2: a grid over the steering gains through the agent itself.

Each combination is the agent of the model's shipped file (``agents/searched/turn_then_run.json``
or ``turn_then_run_pivot.json``) without its heading-correction keys, then with the combination's
keys set, reading its yaw from the observation,
run 50 s along the 8 compass headings from the paper's start and from start-noise seeds 1 and 2
(noise drawn as final_eval.py draws it), all in one batched env under the model's physics
(``common.PHYSICS``). Speed as final_eval.py scores it: the upright contact point's displacement
along the heading / 50 s; also the direction of travel over the last 10 s minus the heading.

    python tune_steer.py [--model pivot] grid.json [out.json]   # default out: tune_steer[_pivot].json

grid.json: {"steer_param": [...], "steer_gain": [...], "steer_integral": [...], "steer_limit": [...]}
(every combination; the uncorrected agent is always added first); an optional "seeds" entry
(null = the paper's start) replaces the default [null, 1, 2].
"""
import itertools, json, shutil, sys, tempfile, time
from pathlib import Path
import numpy as np
from common import *
from rrrobot_gym.agents.turn_then_run import load_turn_then_run_agent
from rrrobot_gym.envs.vector import RRRobotVectorEnv
from rrrobot_gym.envs import task

DUR, DT = 50.0, 0.05
FILE = AGENT_FILE   # turn_then_run.json, turn_then_run_pivot.json, or with --run-gait plane_own_robust.json turn_then_run_robust.json
SEEDS = [None, 1, 2]
HEADS = np.arange(0, 360, 45.0)
STEER_KEYS = ("steer_gain", "steer_integral", "steer_limit", "steer_param", "steer_after_s", "run_at_once_below_deg")


def load_with(c):
    """The shipped file's agent with the steering keys of c (through the loader's own checks)."""
    spec = json.loads(FILE.read_text())
    for key in STEER_KEYS:  # the uncorrected agent, whatever the shipped file holds now
        spec.pop(key, None)
    spec.update(c)
    with tempfile.TemporaryDirectory() as d:
        shutil.copy(FILE.with_name(spec["run_gait_file"]), d)
        path = Path(d) / "ttr.json"
        path.write_text(json.dumps(spec))
        return load_turn_then_run_agent(path)


def evaluate_combos(combos, seeds=SEEDS, heads=HEADS, dur=DUR):
    agents = [load_with(c) for c in combos]
    cases = [(h, s) for s in seeds for h in heads]
    m = len(cases)
    n = m * len(agents)
    starts = np.tile(start_states(1, [s for h, s in cases]), (len(agents), 1))
    targets = np.tile(np.radians([h for h, s in cases]), len(agents))
    env = RRRobotVectorEnv(num_envs=n, max_episode_steps=None, model=MODEL, reset_noise_scale=0.0, **PHYSICS)
    obs, _ = env.reset(seed=0, options={"state": starts, "target_direction": targets})
    radius = env.config.sim.robot.radius
    steps = int(round(dur / env.dt))
    up = [task.upright_contact_points(env.states, radius)]
    alive = np.ones(n, bool)
    end_s = np.full(n, dur)
    states = [None] * len(agents)
    for k in range(steps):
        actions = np.empty((n, 2), np.float32)
        for a, agent in enumerate(agents):
            rows = slice(a * m, (a + 1) * m)
            actions[rows], states[a] = agent.predict(obs[rows], state=states[a], episode_start=np.full(m, k == 0))
        obs, _, terminated, _, info = env.step(actions)
        u = task.upright_contact_points(env.states, radius)
        ending = terminated & alive
        if ending.any():
            fin = info["final_info"]
            u[ending, 0], u[ending, 1] = fin["x_upright"][ending], fin["y_upright"][ending]
            end_s[ending] = (k + 1) * env.dt
        u = np.where(alive[:, None] | ending[:, None], u, up[-1])
        alive &= ~terminated
        up.append(u)
    env.close()
    up = np.array(up)
    disp = up[-1] - up[0]
    speed = (disp[:, 0] * np.cos(targets) + disp[:, 1] * np.sin(targets)) / dur
    last = up[-1] - up[-1 - int(round(10.0 / DT))]
    off = np.degrees((np.arctan2(last[:, 1], last[:, 0]) - targets + np.pi) % (2 * np.pi) - np.pi)
    rows = []
    for a, c in enumerate(combos):
        r = slice(a * m, (a + 1) * m)
        sp, ended = speed[r].reshape(len(seeds), len(heads)), ~alive[r]
        rows.append(dict(combo=c, speed_mps=sp.tolist(), last10s_dir_off_deg=off[r].reshape(len(seeds), len(heads)).tolist(),
                         ended=int(ended.sum()), end_s=end_s[r][ended].tolist(),
                         paper_start_worst=float(sp[0].min()), paper_start_mean=float(sp[0].mean()),
                         worst=float(sp.min()), mean=float(sp.mean()), max_abs_dir_off_deg=float(np.abs(off[r]).max())))
    return rows


if __name__ == "__main__":
    grid = json.load(open(sys.argv[1]))
    SEEDS = grid.pop("seeds", SEEDS)
    out = sys.argv[2] if len(sys.argv) > 2 else out_name("tune_steer")
    keys = list(grid)
    combos = [{}] + [dict(zip(keys, v)) for v in itertools.product(*(grid[k] for k in keys))]
    t0 = time.time()
    rows = []
    for i in range(0, len(combos), 12):
        rows += evaluate_combos(combos[i:i + 12], seeds=SEEDS)
        print(f"{len(rows)}/{len(combos)} combos, {time.time() - t0:.0f} s", flush=True)
    rows.sort(key=lambda r: (r["ended"], -r["worst"], -r["mean"]))
    json.dump(dict(model=MODEL, physics=PHYSICS, file=str(FILE.relative_to(ROOT)), seeds=SEEDS, headings=HEADS.tolist(),
                   duration=DUR, grid=grid, wall_s=time.time() - t0, rows=rows), open(out, "w"), indent=1)
    base = next(r for r in rows if r["combo"] == {})
    for r in [base] + rows[:10]:
        print(r["combo"], "ended", r["ended"], "worst %.1f mean %.1f | paper start worst %.1f mean %.1f | dir off %.0f" % (
            1e3 * r["worst"], 1e3 * r["mean"], 1e3 * r["paper_start_worst"], 1e3 * r["paper_start_mean"], r["max_abs_dir_off_deg"]),
            "paper:", np.round(1e3 * np.array(r["speed_mps"][0]), 1).tolist())
