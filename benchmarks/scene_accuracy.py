"""Accuracy of the env's own scene: restarted 5 s windows of the shipped policies and of random actions.

    python -m benchmarks.scene_accuracy [--quick] [--json FILE] [--models MODEL ...] [--actions KIND ...] [--robots NAME ...]

RRRobot-v0 runs a servo by default (0.5 N m stall, 10 rad/s no-load, a 60 rad/s^2 motion
profile), and the motor's clip puts kinks in the right-hand side, where RK4 loses its order;
``benchmarks.work_precision`` measures the paper's ideal servo only. Here, on each model
(``--models``, default both), the env at its defaults (``RRRobot-v0``'s servo, RK4 at 1/300 s, the
nominal robot, from the paper's start, episodes not ended by leaving the model; the tilt limit
still ends one) is rolled out closed loop for 45 s (--quick: 5 s) with each kind of actions
(``--actions``): ``policy``, the shipped PPO policy of the model along 0, 45, 90, 135 and 180 deg
(the policies run the other headings as mirror images of these); ``random``, uniform random
actions on 5 robots. ``--robots`` adds members of the family (:data:`ROBOTS`: an oblate shell, four
legs), with random actions (they have no shipped policy). The rollout keeps the states and the servo's references (the ramps the
motion profile made). From the states at 0, 10, 20, 30 and 40 s (--quick: 0 s) the next 5 s are
replayed open loop on the recorded references: with RK4 at each step of STEPS_S (the default
first), and with ``simulate_reference`` (DOP853, rtol = atol = 1e-10, the same servo, solved control
step by control step, since the references' rates jump there).

Reported, per model, kind of actions and step: the largest contact error against the reference
in each window (over its robots and its 100 control steps) and the derivative evaluations per
env step; whether the replay at the env's step reproduces the env's states to the bit (checked);
and each window's amplification, how far its reference path's contact point has moved at the
window's end per rad added to leg 1's angle at its start (RK4 at 1/9000 s, a start 1e-8 rad off):
the open-loop path's own sensitivity, which sets how small the step's local errors must be.
"""

from __future__ import annotations

import hashlib
import pickle
import time
from dataclasses import replace

import numpy as np

import rrrobot_gym  # noqa: F401  (registers RRRobot-v0)
from rrrobot_gym.control import RampTargets
from rrrobot_gym.envs.vector import RRRobotVectorEnv
from rrrobot_gym.simulation import SimConfig, advance, simulate_reference

from ._common import (
    CACHE_DIR,
    POLICIES,
    contact_error,
    fmt,
    machine,
    markdown_table,
    parser,
    write_json,
)

MODELS = ("plane", "pivot")
ROBOTS = {"paper": {}, "oblate-2": {"shell_axes": (0.12, 0.12, 0.09)}, "sphere-4": {"num_legs": 4},
          "oblate-4": {"shell_axes": (0.12, 0.12, 0.09), "num_legs": 4}}  # fmt: skip
"""The robots ``--robots`` names: the paper's (default), and family members (env keywords)."""
ACTIONS = ("policy", "random")
POLICY_HEADINGS_DEG = (0.0, 45.0, 90.0, 135.0, 180.0)
"""The policy's headings: the shipped policies run 225-315 deg as mirror images of 135-45 deg."""
RANDOM_ROBOTS = 5
WINDOW_STARTS_S = (0.0, 10.0, 20.0, 30.0, 40.0)
WINDOW_S = 5.0
STEPS_S = (1 / 300, 1 / 400, 1 / 600, 1 / 1200, 1 / 3000)
"""RK4 steps replayed; 1/300 s is the default (``rrrobot_gym.simulation.DEFAULT_TIMESTEP``)."""
SENSITIVITY_STEP_S = 1 / 9000
PERTURBATION_RAD = 1e-8
"""Leg 1's start offset of the amplification's run: its deviation stays linear in it over 5 s on
both models (the pivot's policy windows amplify it about 10^5 times), and stands far above the
rounding of RK4 at SENSITIVITY_STEP_S."""


def rollout(model: str, actions: str, duration: float, seed: int = 0, robot: str = "paper"):
    """The closed-loop run a window restarts from: (states (T + 1, N, 13), the references' ramp
    starts and ends (T, N, 2), each robot's end time (N,) s (inf: ran to the end), the control
    step (s), the simulator config)."""
    if actions == "policy":
        from rrrobot_gym.agents.ppo import load_ppo_agent

        agent = load_ppo_agent(POLICIES[model])
        kwargs, directions = dict(agent.env_config), np.radians(POLICY_HEADINGS_DEG)
    else:
        agent, kwargs, directions = None, {}, np.zeros(RANDOM_ROBOTS)
    kwargs.update(model=model, randomize=None, reset_noise_scale=0.0, terminate_outside_model=False, **ROBOTS[robot])
    env = RRRobotVectorEnv(num_envs=len(directions), max_episode_steps=None, **kwargs)
    obs, _ = env.reset(seed=seed, options={"target_direction": directions})
    rng = np.random.default_rng(seed)
    steps = round(duration / env.dt)
    states, starts, ends = [env.states.copy()], [], []
    ended = np.full(len(directions), np.inf)
    for i in range(steps):
        if agent is None:
            action = rng.uniform(-1.0, 1.0, env.action_space.shape).astype(np.float32)
        else:
            action, _ = agent.predict(obs, deterministic=True)
        starts.append(env.leg_targets.copy())
        obs, _, terminated, _, _ = env.step(action)
        ends.append(env.leg_targets.copy())
        states.append(env.states.copy())
        ended[terminated & np.isinf(ended)] = (i + 1) * env.dt  # (autoreset: what follows is another episode)
    dt, sim = env.dt, env.config.sim
    env.close()
    return np.array(states), np.array(starts), np.array(ends), ended, dt, sim


def windows(states, starts, ends, ended, dt: float, at_s, length_s: float = WINDOW_S):
    """The windows of the runs that fit before their robot's episode ended: (start states (W, 13),
    ramp starts (W, n, 2), ramp ends (W, n, 2), their (robot, start s) (W, 2))."""
    n = round(length_s / dt)
    picked = [(robot, t) for t in at_s for robot in range(states.shape[1])
              if round(t / dt) + n <= len(starts) and t + length_s <= ended[robot] + 1e-9]  # fmt: skip
    if not picked:
        raise ValueError("no window fits in the runs (every robot's episode ended first)")
    k = [round(t / dt) for _, t in picked]
    rows = [robot for robot, _ in picked]
    return (np.array([states[i, r] for i, r in zip(k, rows)]), np.array([starts[i : i + n, r] for i, r in zip(k, rows)]),
            np.array([ends[i : i + n, r] for i, r in zip(k, rows)]), np.array(picked))  # fmt: skip


def replay(config: SimConfig, start, ramp_starts, ramp_ends, dt: float, reference: bool = False):
    """States (n + 1, W, 13) of the windows replayed control step by control step on their
    references, each step from t = 0 as the envs call ``advance``; ``reference``: DOP853."""
    state = start.copy()
    out = [state.copy()]
    for i in range(ramp_starts.shape[1]):
        targets = RampTargets(ramp_starts[:, i], ramp_ends[:, i], 0.0, dt)
        if reference:
            state = simulate_reference(config, targets, dt, state=state, sample_dt=dt).states[-1]
        else:
            state = advance(config, state, 0.0, dt, targets, check=False)
        out.append(state.copy())
    return np.array(out)


def cached_reference(config: SimConfig, start, ramp_starts, ramp_ends, dt: float):
    """:func:`replay` with the reference, kept in CACHE_DIR by its inputs (minutes of DOP853 each)."""
    key = hashlib.sha256(repr((config, dt)).encode())
    for array in (start, ramp_starts, ramp_ends):
        key.update(np.ascontiguousarray(array).tobytes())
    path = CACHE_DIR / f"scene-{key.hexdigest()[:20]}.pkl"
    if path.exists():
        return pickle.loads(path.read_bytes())
    states = replay(config, start, ramp_starts, ramp_ends, dt, reference=True)
    CACHE_DIR.mkdir(parents=True, exist_ok=True)
    path.write_bytes(pickle.dumps(states))
    return states


def amplification(config: SimConfig, start, ramp_starts, ramp_ends, dt: float):
    """m/rad per window: the contact's deviation at the window's end when leg 1 starts
    PERTURBATION_RAD further, over PERTURBATION_RAD (RK4 at SENSITIVITY_STEP_S)."""
    fine = replace(config, timestep=SENSITIVITY_STEP_S)
    perturbed = start.copy()
    perturbed[:, 6] += PERTURBATION_RAD
    base = replay(fine, start, ramp_starts, ramp_ends, dt)[-1]
    moved = replay(fine, perturbed, ramp_starts, ramp_ends, dt)[-1]
    return contact_error(moved, base) / PERTURBATION_RAD


def per_window(values, picked, at_s):
    """The largest of ``values`` (W,) in each window start of ``at_s`` (None where none fitted)."""
    return [float(values[picked[:, 1] == t].max()) if np.any(picked[:, 1] == t) else None for t in at_s]


def measure(model: str, actions: str, duration: float, at_s, robot: str = "paper") -> dict:
    """Every step's errors on one model, kind of actions and robot (the module docstring)."""
    began = time.perf_counter()
    states, ramp_starts, ramp_ends, ended, dt, sim = rollout(model, actions, duration, robot=robot)
    start, w_starts, w_ends, picked = windows(states, ramp_starts, ramp_ends, ended, dt, at_s)
    reference = cached_reference(sim, start, w_starts, w_ends, dt)
    gain = amplification(sim, start, w_starts, w_ends, dt)
    result = {
        "model": model, "actions": actions, "robot": robot, "config": repr(sim), "control_step_s": dt,
        "robots": POLICY_HEADINGS_DEG if actions == "policy" else RANDOM_ROBOTS,
        "windows": [[int(robot), float(t)] for robot, t in picked], "ended_s": [float(t) for t in ended],
        "amplification_m_per_rad": {"per_window_max": per_window(gain, picked, at_s), "median": float(np.median(gain))},
        "rows": [],
    }  # fmt: skip
    for step in STEPS_S:
        config = replace(sim, timestep=step)
        path = replay(config, start, w_starts, w_ends, dt)
        err = contact_error(path, reference).max(axis=0)  # (W,): each window's largest
        row = {"step_s": step, "default": step == sim.step, "evals_per_env_step": 4 * round(dt / step),
               "per_window_max_m": per_window(err, picked, at_s), "max_m": float(err.max()),
               "per_robot_window_m": err.tolist()}  # fmt: skip
        if step == sim.step:
            k = [round(t / dt) for t in picked[:, 1]]
            rows = picked[:, 0].astype(int)
            env_path = np.array([states[np.array(k) + i, rows] for i in range(path.shape[0])])
            row["reproduces_env"] = bool(np.array_equal(path, env_path))
            result["reproduces_env"] = row["reproduces_env"]
        result["rows"].append(row)
    result["seconds"] = time.perf_counter() - began
    return result


def step_label(row) -> str:
    return f"1/{1 / row['step_s']:.0f} s" + (" (default)" if row["default"] else "")


def table(results, at_s) -> str:
    header = ["model", "robot", "actions", "RK4 step", "evaluations / env step"] + [f"{t:g} s" for t in at_s] + ["max"]
    lines = []
    for r in results:
        robot = r.get("robot", "paper")
        for row in r["rows"]:
            cells = [fmt(v * 1e3) if v is not None else "-" for v in row["per_window_max_m"]]
            lines.append([r["model"], robot, r["actions"], step_label(row), row["evals_per_env_step"], *cells,
                          fmt(row["max_m"] * 1e3)])  # fmt: skip
        gain = r["amplification_m_per_rad"]["per_window_max"]
        lines.append([r["model"], robot, r["actions"], "amplification (m/rad)", "",
                      *(fmt(v) if v is not None else "-" for v in gain), ""])  # fmt: skip
    return markdown_table(header, lines)


def main(argv=None):
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--models", nargs="+", default=list(MODELS), choices=MODELS, help="the dynamic models (default: both)")
    p.add_argument("--actions", nargs="+", default=list(ACTIONS), choices=ACTIONS,
                   help="the runs' actions: the shipped policy of the model, uniform random actions (default: both)")
    p.add_argument("--robots", nargs="+", default=["paper"], choices=tuple(ROBOTS),
                   help="the robots: the paper's (default) and family members, these with random actions only")
    args = p.parse_args(argv)
    for flag, values in (("--models", args.models), ("--actions", args.actions), ("--robots", args.robots)):
        if len(set(values)) < len(values):
            p.error(f"{flag} names one twice: {' '.join(values)}")
    at_s = WINDOW_STARTS_S[:1] if args.quick else WINDOW_STARTS_S
    duration = at_s[-1] + WINDOW_S
    results = []
    runs = [(model, actions, robot) for robot in args.robots for model in args.models for actions in args.actions
            if robot == "paper" or actions == "random"]  # (only the paper's robot has shipped policies)
    for model, actions, robot in runs:
        r = measure(model, actions, duration, at_s, robot)
        results.append(r)
        worst = ", ".join(f"{step_label(row)} {row['max_m'] * 1e3:.3g}" for row in r["rows"])
        print(f"{model} {robot} {actions}: {len(r['windows'])} windows; max contact error (mm): {worst}; the replay at "
              f"the env's step reproduces its states to the bit: {r['reproduces_env']} ({r['seconds']:.0f} s)",
              flush=True)  # fmt: skip
    print(f"\nMax contact error (mm) of {WINDOW_S:g} s windows restarted at each time, against the reference:\n")
    print(table(results, at_s))
    write_json(args.json, {"machine": machine(), "window_s": WINDOW_S, "window_starts_s": list(at_s),
                           "perturbation_rad": PERTURBATION_RAD, "results": results})  # fmt: skip


if __name__ == "__main__":
    main()
