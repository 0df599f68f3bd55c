"""The same robot and leg targets in rrrobot_gym and in MuJoCo, side by side in one run.

    python -m benchmarks.vs_mujoco [--quick] [--json FILE] [--policy]

Needs ``mujoco`` (the ``bench`` extra); the MuJoCo model is ``benchmarks.mujoco_peer``.
1. Accuracy against cost, N = 1: the three Table II gaits (50 s; --quick 10 s) at several steps in
   both; the contact error against our rtol 1e-10 reference (every 0.05 s) and the wall time.
2. Batched throughput, one thread each: N robots under gait 1, our ``advance`` against
   ``mujoco.rollout``; env steps/s = N x (T / 0.05 s) / wall time.
3. Equal accuracy: MuJoCo's cheapest swept step no worse than our default, and the throughput ratio.
``--policy`` instead (needs the ``train`` extra too) replays the shipped plane policy's leg targets
from its ``RRRobot-v0`` rollouts along 0, 90 and 180 deg open loop in MuJoCo (friction 1.0 as the
env's, RK4 at 0.5 ms, each step holding the ramp at its midpoint): the speed along the heading in
both, and the largest distance between the two contact paths.
"""

from __future__ import annotations

import math
import time

import numpy as np

from rrrobot_gym.control import table2_gait
from rrrobot_gym.envs.task import make_task_config
from rrrobot_gym.simulation import SimConfig, advance, initial_state

from ._common import contact_error, fmt, machine, markdown_table, median_time, parser, reference, write_json
from .work_precision import ENV_STEP, run_steps

OUR_SETTINGS = {
    "plane": [("rk4 1/200 s", 1 / 200), ("rk4 1/300 s (default)", 1 / 300), ("rk4 1/600 s", 1 / 600)],
    "pivot": [("rk4 1/140 s (auto)", "auto"), ("rk4 1/300 s (default)", 1 / 300), ("rk4 1/600 s", 1 / 600)],
}
MUJOCO_STEPS = (1 / 300, 1 / 1000, 1 / 3000)
POLICY_HEADINGS_DEG = (0.0, 90.0, 180.0)
POLICY_MUJOCO_STEP = 0.0005


def mujoco_run(model: str, gait: int, duration: float, dt: float):
    """(contact path sampled every 0.05 s as (T, 2), wall seconds) of one MuJoCo robot."""
    from .mujoco_peer import MujocoRobot

    robot = MujocoRobot(model, timestep=dt)
    every = round(ENV_STEP / dt)
    start = time.perf_counter()
    out = robot.step_gait(gait, duration, record_every=every)
    wall = time.perf_counter() - start
    return np.stack([out["x"], out["y"]], axis=-1), wall


def ours_batched(config: SimConfig, num_robots: int, duration: float, repeats: int) -> float:
    """s of wall time to advance num_robots robots by ``duration`` s of robot time under gait 1."""
    gait = table2_gait(1)
    state0 = initial_state(num_robots)
    n_env = round(duration / ENV_STEP)

    def run():
        s = state0
        for i in range(n_env):
            s = advance(config, s, i * ENV_STEP, ENV_STEP, gait, check=False)

    run()
    return median_time(run, repeats)


def mujoco_batched(model: str, num_robots: int, duration: float, dt: float, repeats: int):
    """(median wall seconds, method) of num_robots MuJoCo robots for ``duration`` s under gait 1, one thread."""
    from .mujoco_peer import compile_model, rollout_batch

    m = compile_model(model, timestep=dt)
    runs = [rollout_batch(m, num_robots, round(duration / dt), gait=1, nthread=1) for _ in range(repeats)]
    return float(np.median([wall for wall, _ in runs])), runs[-1][1]


def policy_rows(duration: float) -> list:
    """The shipped plane policy's open-loop replay in MuJoCo against its rollout here, per heading."""
    from rrrobot_gym.agents.ppo import load_ppo_agent

    from .mujoco_peer import MujocoRobot
    from .policy_replay import MODEL, rollout

    agent = load_ppo_agent(MODEL)
    friction = make_task_config(**agent.env_config).friction_coefficient
    rows = []
    for heading in POLICY_HEADINGS_DEG:
        states, starts, ends, dt, _ = rollout(agent, heading, round(duration / ENV_STEP))
        per_step = round(dt / POLICY_MUJOCO_STEP)
        middle = (np.arange(per_step) + 0.5) / per_step
        targets = starts[:, None] + (ends - starts)[:, None] * middle[None, :, None]
        rates = np.broadcast_to(((ends - starts) / dt)[:, None], targets.shape)
        controls = np.concatenate([targets, rates], axis=-1).reshape(-1, 4)
        start = states[0]
        robot = MujocoRobot("plane", timestep=POLICY_MUJOCO_STEP, friction=friction)
        robot.reset(quat=start[2:6], phi=start[6:8], omega=start[8:11], phidot=start[11:13])
        out = robot.step_gait(None, len(starts) * dt, record_every=per_step, controls=controls)
        theirs = np.stack([out["x"], out["y"]], axis=-1) - [out["x"][0], out["y"][0]]
        ours = states[:, :2] - start[:2]
        direction = np.array([math.cos(math.radians(heading)), math.sin(math.radians(heading))])
        seconds = len(starts) * dt
        rows.append({"heading_deg": heading, "friction": friction, "mujoco_step_s": POLICY_MUJOCO_STEP,
                     "ours_speed_mps": float(ours[-1] @ direction / seconds),
                     "mujoco_speed_mps": float(theirs[-1] @ direction / seconds),
                     "max_path_distance_m": float(np.max(np.hypot(*(theirs - ours).T))),
                     "distance_travelled_m": float(np.hypot(*ours[-1]))})  # fmt: skip
        rows[-1]["speed_difference"] = rows[-1]["mujoco_speed_mps"] / rows[-1]["ours_speed_mps"] - 1.0
        print(rows[-1], flush=True)
    return rows


def policy_main(args, duration: float):
    policy = policy_rows(duration)
    text = markdown_table(
        ["heading (deg)", "rrrobot_gym (mm/s)", f"MuJoCo, friction {policy[0]['friction']:g} (mm/s)", "difference",
         f"largest distance between the paths, {duration:g} s (mm)", "distance travelled (m)"],
        [[fmt(r["heading_deg"]), f"{r['ours_speed_mps'] * 1e3:.2f}", f"{r['mujoco_speed_mps'] * 1e3:.2f}",
          f"{r['speed_difference']:+.2%}", fmt(r["max_path_distance_m"] * 1e3), fmt(r["distance_travelled_m"])]
         for r in policy],
    )  # fmt: skip
    print()
    print(text)
    write_json(args.json, {"machine": machine(), "duration_s": duration, "policy": policy, "table": text})


def main(argv=None):
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--policy", action="store_true",
                   help="replay the shipped plane policy's leg targets in MuJoCo instead of the gaits")  # fmt: skip
    args = p.parse_args(argv)
    try:
        import mujoco  # noqa: F401
    except ImportError:
        raise SystemExit("benchmarks.vs_mujoco needs the optional dependency mujoco: pip install mujoco")
    duration = 10.0 if args.quick else 50.0
    if args.policy:
        return policy_main(args, duration)
    gaits = (1, 2, 3)
    mj_steps = MUJOCO_STEPS[:2] if args.quick else MUJOCO_STEPS
    accuracy = []
    for model in ("plane", "pivot"):
        refs = {g: reference(SimConfig(model=model), table2_gait(g), duration, ENV_STEP) for g in gaits}
        for name, step in OUR_SETTINGS[model]:
            config = SimConfig(model=model, timestep=step)
            errs, walls = [], []
            for g in gaits:
                states, _ = run_steps(config, table2_gait(g), initial_state(), round(duration / ENV_STEP))
                walls.append(median_time(lambda: run_steps(config, table2_gait(g), initial_state(), 20), 3) * duration / 1.0)
                errs.append(float(contact_error(states, refs[g]).max()))
            accuracy.append({"model": model, "simulator": "rrrobot_gym", "setting": name, "step_s": config.step,
                             "max_contact_error_m": max(errs), "wall_s_per_run": float(np.mean(walls))})  # fmt: skip
            print(accuracy[-1], flush=True)
        for dt in mj_steps:
            errs, walls = [], []
            for g in gaits:
                xy, wall = mujoco_run(model, g, duration, dt)
                n = min(len(xy), len(refs[g]))
                errs.append(float(np.max(np.hypot(*(xy[:n] - refs[g][:n, :2]).T))))
                walls.append(wall)
            accuracy.append({"model": model, "simulator": "mujoco", "setting": f"RK4 1/{1 / dt:.0f} s", "step_s": dt,
                             "max_contact_error_m": max(errs), "wall_s_per_run": float(np.mean(walls))})  # fmt: skip
            print(accuracy[-1], flush=True)

    # Batched throughput, one thread each, same robot time and gait.
    num_robots = 1024 if args.quick else 4096
    batch_time = 0.25
    repeats = 3
    throughput = []
    for model in ("plane", "pivot"):
        for name, step in OUR_SETTINGS[model][:2]:
            wall = ours_batched(SimConfig(model=model, timestep=step), num_robots, batch_time, repeats)
            throughput.append({"model": model, "simulator": "rrrobot_gym", "setting": name,
                               "env_steps_per_s": num_robots * batch_time / ENV_STEP / wall})  # fmt: skip
            print(throughput[-1], flush=True)
        for dt in mj_steps:
            wall, method = mujoco_batched(model, num_robots, batch_time, dt, repeats)
            throughput.append({"model": model, "simulator": "mujoco", "setting": f"RK4 1/{1 / dt:.0f} s ({method}, 1 thread)",
                               "step_s": dt, "env_steps_per_s": num_robots * batch_time / ENV_STEP / wall})  # fmt: skip
            print(throughput[-1], flush=True)

    # Equal accuracy: MuJoCo's cheapest step at least as accurate as our default; and the same step.
    verdict = []
    for model in ("plane", "pivot"):
        ours = next(r for r in accuracy if r["model"] == model and "default" in r["setting"])
        ours_tp = next(r for r in throughput if r["model"] == model and "default" in r["setting"])
        same = next(r for r in throughput if r["model"] == model and r["simulator"] == "mujoco"
                    and abs(r["step_s"] - 1 / 300) < 1e-12)  # fmt: skip
        same_acc = next(r for r in accuracy if r["model"] == model and r["simulator"] == "mujoco"
                        and abs(r["step_s"] - 1 / 300) < 1e-12)  # fmt: skip
        verdict.append(f"{model}, same step 1/300 s: error {ours['max_contact_error_m'] * 1e3:.3g} mm (ours) vs "
                       f"{same_acc['max_contact_error_m'] * 1e3:.3g} mm (MuJoCo); {ours_tp['env_steps_per_s']:.3g} vs "
                       f"{same['env_steps_per_s']:.3g} env steps/s, ratio {ours_tp['env_steps_per_s'] / same['env_steps_per_s']:.1f}x")  # fmt: skip
        good = [r for r in accuracy if r["model"] == model and r["simulator"] == "mujoco"
                and r["max_contact_error_m"] <= ours["max_contact_error_m"]]  # fmt: skip
        if not good:
            best = min((r for r in accuracy if r["model"] == model and r["simulator"] == "mujoco"),
                       key=lambda r: r["max_contact_error_m"])  # fmt: skip
            verdict.append(f"{model}: no swept MuJoCo step reaches our default's error "
                           f"({ours['max_contact_error_m'] * 1e3:.3g} mm); MuJoCo's best is "
                           f"{best['max_contact_error_m'] * 1e3:.3g} mm at {best['setting']}")  # fmt: skip
            continue
        cheapest = max(good, key=lambda r: r["step_s"])
        mj_tp = next(r for r in throughput if r["model"] == model and r["simulator"] == "mujoco"
                     and abs(r["step_s"] - cheapest["step_s"]) < 1e-12)  # fmt: skip
        verdict.append(f"{model}, equal or better accuracy: our default ({ours['max_contact_error_m'] * 1e3:.3g} mm) vs MuJoCo {cheapest['setting']} "
                       f"({cheapest['max_contact_error_m'] * 1e3:.3g} mm): {ours_tp['env_steps_per_s']:.3g} vs "
                       f"{mj_tp['env_steps_per_s']:.3g} env steps/s at N={num_robots}, ratio "
                       f"{ours_tp['env_steps_per_s'] / mj_tp['env_steps_per_s']:.2f}x")  # fmt: skip

    t1 = markdown_table(
        ["model", "simulator", "setting", f"max contact error, {duration:g} s (mm)", "wall s per run (N=1)"],
        [[r["model"], r["simulator"], r["setting"], fmt(r["max_contact_error_m"] * 1e3), fmt(r["wall_s_per_run"])]
         for r in accuracy],  # fmt: skip
    )
    t2 = markdown_table(
        ["model", "simulator", "setting", f"env steps/s, N={num_robots}, 1 thread"],
        [[r["model"], r["simulator"], r["setting"], fmt(r["env_steps_per_s"])] for r in throughput],
    )
    text = f"{t1}\n\n{t2}\n\n" + "\n".join("- " + v for v in verdict)
    print()
    print(text)
    write_json(args.json, {"machine": machine(), "duration_s": duration, "accuracy": accuracy,
                           "throughput": throughput, "verdict": verdict, "table": text})  # fmt: skip


if __name__ == "__main__":
    main()
