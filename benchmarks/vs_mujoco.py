"""The same robot and leg targets in rrrobot_gym and in MuJoCo, side by side in one run.

    python -m benchmarks.vs_mujoco [--quick] [--json FILE] [--closed-loop | --policy [--model MODEL] | --family]

Needs ``mujoco`` (the ``bench`` extra); the MuJoCo model is ``benchmarks.mujoco_peer``.
1. Accuracy against cost, N = 1: the three Table II gaits (50 s; --quick 10 s) at several steps in
   both; the contact error against our rtol 1e-10 reference (every 0.05 s) and the wall time.
2. Batched throughput, one thread each: N robots under gait 1, our ``advance`` against
   ``mujoco.rollout``; env steps/s = N x (T / 0.05 s) / wall time.
3. Equal accuracy: MuJoCo's cheapest swept step no worse than our default, and the throughput ratio.
``--closed-loop`` instead (needs the ``train`` extra too) runs each shipped PPO policy (plane,
pivot; ``--model`` one of them) from the paper's start along the 8 compass headings (--quick: 0 and
180 deg, 10 s) here, as evaluate.py does, and closed loop in MuJoCo: every control step the
observation of MuJoCo's state (``task.observe``), the policy's action, the env's own leg targets
(``task.step_targets``), and the env's servo (PD law and motor limits, from the policy's env
keywords) at every RK4 stage (0.5 ms; the plane on a floor of the env's friction). Reported: the
speed along the heading in both, their ratio, whether either left the model (here the env's
termination; in MuJoCo a leg tip at the floor or the tilt pi/2) and the largest distance between
the contact paths. ``--policy``: the same, MuJoCo replaying our env's actions open loop.
``--family`` instead checks the MuJoCo peer of the robot family (ellipsoid shells, 1-6 legs), and
rrrobot_gym's own simulator (RK4 at the default step), against the sympy oracle
``tests/family_oracle.py`` integrated by scipy (DOP853, rtol 1e-10): members of
the family under a PD servo on the gait phi_k = pi/2 + 0.3 sin(8 t + 2 pi k / L), 5 s (--quick:
one member, 2 s), both models, from the paper's start and from a tilted, spinning one; the
largest contact-point distance and attitude difference, at several MuJoCo steps (and, on the
plane, contact time constants).
"""

from __future__ import annotations

import importlib.util
import math
import time

import numpy as np

from rrrobot_gym import dynamics
from rrrobot_gym.control import limit_torque, pd_torque, table2_gait
from rrrobot_gym.envs import task
from rrrobot_gym.evaluation import COMPASS_DEG, run_episodes, score
from rrrobot_gym.params import RobotParams
from rrrobot_gym.simulation import SimConfig, advance, initial_state

from ._common import (
    POLICIES,
    ROOT,
    contact_error,
    fmt,
    machine,
    markdown_table,
    median_time,
    parser,
    reference,
    write_json,
)
from .work_precision import ENV_STEP, run_steps

OUR_SETTINGS = {
    "plane": [("rk4 1/200 s", 1 / 200), ("rk4 1/300 s (default)", 1 / 300), ("rk4 1/600 s", 1 / 600)],
    "pivot": [("rk4 1/140 s (auto)", "auto"), ("rk4 1/300 s (default)", 1 / 300), ("rk4 1/600 s", 1 / 600)],
}
MUJOCO_STEPS = (1 / 300, 1 / 1000, 1 / 3000)
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


def servo(sim, held):
    """The leg torques (t, angles, rates) -> (tau1, tau2) of rrrobot_gym's servo following the leg-target
    source ``held``: the PD law, then the motor's limits (``sim``'s torque_limit and leg_rate_limit)."""
    gains, limit, rate_limit = sim.gains, sim.torque_limit, sim.leg_rate_limit
    return lambda t, angles, rates: limit_torque(pd_torque(gains, angles, rates, held.leg_targets(t)), rates, limit, rate_limit)


def mujoco_episode(agent, config, heading_deg: float, steps: int, actions=None):
    """(contact path (k + 1, 2) every control step, s at which it left the model or None) of one
    MuJoCo episode from the paper's start. Each step's action comes from the policy on the
    observation of MuJoCo's state (``task.observe``; closed loop) or from ``actions`` (open loop);
    the env's own ``step_targets`` turns it into the step's leg targets, and the servo acts at
    every RK4 stage. It leaves the model where a leg tip reaches the floor or the tilt pi/2."""
    from .mujoco_peer import MujocoRobot

    if config.sim.robot != RobotParams() or config.sim.legs != "servo":
        raise ValueError(f"the MuJoCo peer is the paper's robot with servo legs, not {config.sim!r}")
    robot = MujocoRobot(config.model, timestep=POLICY_MUJOCO_STEP, friction=config.friction_coefficient, servo="torque")
    heading = np.array([math.radians(heading_deg)])
    targets, rates = robot.state()[dynamics.LEG_ANGLES], np.zeros(2)  # as the env's reset
    path = [robot.contact_xy()]
    for i in range(steps):
        if actions is None:
            obs = task.observe(robot.state()[None], heading, config, np.array([i * config.dt]))
            action = agent.predict(obs, deterministic=True)[0][0]
        else:
            action = actions[i]
        held, targets, rates = task.step_targets(task.check_actions(action, (2,)), targets, rates, config)
        lowest_tip, tilt = robot.run_servo(servo(config.sim, held), config.dt)
        path.append(robot.contact_xy())
        if lowest_tip <= 0.0 or tilt >= dynamics.TILT_LIMIT:
            return np.array(path), (i + 1) * config.dt
    return np.array(path), None


def policy_rows(duration: float, headings, closed_loop: bool, models=("plane", "pivot")) -> list:
    """Each shipped policy along each heading (deg), here (``evaluation.run_episodes``, as evaluate.py
    runs it) and in MuJoCo (:func:`mujoco_episode`, closed loop or replaying our actions)."""
    from rrrobot_gym.agents.ppo import load_ppo_agent

    rows = []
    for model in models:
        path = POLICIES[model]
        agent = load_ppo_agent(path)
        config = task.make_task_config(**agent.env_config)
        steps = task.control_steps("duration", duration, config.dt)
        run = run_episodes({"ppo": agent}, config.model, headings, duration)["ppo"]
        for i, ours in enumerate(score(run, headings)):
            heading = ours["heading_deg"]
            ours_path = run["xy"][:, i][np.isfinite(run["xy"][:, i, 0])]
            actions = None if closed_loop else task.leg_targets_to_action(run["leg_targets"][: len(ours_path) - 1, i])
            start = time.perf_counter()
            theirs, ended = mujoco_episode(agent, config, heading, steps if closed_loop else len(actions), actions)
            wall = time.perf_counter() - start
            direction = np.array([math.cos(math.radians(heading)), math.sin(math.radians(heading))])
            n = min(len(theirs), len(ours_path))
            row = {"model": config.model, "heading_deg": heading, "policy": str(path.relative_to(ROOT)),
                   "torque_limit": config.torque_limit, "leg_rate_limit": config.leg_rate_limit,
                   "friction": config.friction_coefficient, "mujoco_step_s": POLICY_MUJOCO_STEP,
                   "ours_speed_mps": ours["speed_mps"],
                   "ours_ended_s": (len(ours_path) - 1) * config.dt if ours["terminated"] else None,
                   "mujoco_speed_mps": float((theirs[-1] - theirs[0]) @ direction / (steps * config.dt)),
                   "mujoco_ended_s": ended, "max_path_distance_m": float(np.max(np.hypot(*(theirs[:n] - ours_path[:n]).T))),
                   "distance_travelled_m": float(np.hypot(*(ours_path[-1] - ours_path[0]))), "mujoco_wall_s": wall}  # fmt: skip
            row["speed_ratio"] = row["mujoco_speed_mps"] / row["ours_speed_mps"] if row["ours_speed_mps"] else math.nan
            rows.append(row)
            print(row, flush=True)
    return rows


def policy_main(args, closed_loop: bool):
    duration = 10.0 if args.quick else 50.0
    headings = (0.0, 180.0) if args.quick else COMPASS_DEG
    rows = policy_rows(duration, headings, closed_loop, args.model or tuple(POLICIES))

    def ended(when):
        return "no" if when is None else f"at {when:.2f} s"

    text = markdown_table(
        ["model", "heading (deg)", "rrrobot_gym (mm/s)", "MuJoCo (mm/s)", "ratio", "ended (ours / MuJoCo)",
         f"largest distance between the paths, {duration:g} s (mm)"],
        [[r["model"], fmt(r["heading_deg"]), f"{r['ours_speed_mps'] * 1e3:.2f}", f"{r['mujoco_speed_mps'] * 1e3:.2f}",
          f"{r['speed_ratio']:.4f}", f"{ended(r['ours_ended_s'])} / {ended(r['mujoco_ended_s'])}",
          fmt(r["max_path_distance_m"] * 1e3)] for r in rows],
    )  # fmt: skip
    print()
    print(text)
    write_json(args.json, {"machine": machine(), "duration_s": duration, "loop": "closed" if closed_loop else "open",
                           "rows": rows, "table": text})  # fmt: skip


FAMILY_MEMBERS = (("oblate (0.12, 0.12, 0.09), 2 legs", (0.12, 0.12, 0.09), 2),
                  ("sphere 0.12, 4 legs", (0.12, 0.12, 0.12), 4),
                  ("triaxial (0.13, 0.11, 0.10), 3 legs", (0.13, 0.11, 0.10), 3))  # fmt: skip
"""(name, shell semi-axes (m), number of legs) of the family members checked; legs at the family's
default placement (``family_oracle.default_legs``), the paper's masses. Each stands upright (a
prolate (0.12, 0.10, 0.15) does not: it rolls over sideways, docs/notes/family_checks.md)."""
FAMILY_MUJOCO = {"pivot": ((1e-3, 0.004), (5e-4, 0.004)),
                 "plane": ((1e-3, 0.004), (5e-4, 0.004), (5e-4, 0.001), (2.5e-4, 5e-4))}  # fmt: skip
"""Per model, the MuJoCo (step s, contact time constant s) swept; 0.004 s is the paper robot's contact."""


def family_oracle():
    """The sympy oracle of the family, ``tests/family_oracle.py`` (a test module, not the package's)."""
    spec = importlib.util.spec_from_file_location("family_oracle", ROOT / "tests" / "family_oracle.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def family_start(num_legs: int, tilted: bool) -> np.ndarray:
    """The paper's start (upright at rest at the origin, legs along v), or tilted 0.3 rad about a
    skew horizontal axis and turning at (0.5, -0.8, 1.5) rad/s (body frame): the gait alone only
    yaws the symmetric members, so the tilted start makes them rock and roll."""
    state = np.zeros(9 + 2 * num_legs)
    state[2] = 1.0
    state[6 : 6 + num_legs] = math.pi / 2
    if tilted:
        axis = np.array([1.0, 0.5, 0.0]) / math.hypot(1.0, 0.5)
        state[2], state[3:6] = math.cos(0.15), math.sin(0.15) * axis
        state[6 + num_legs : 9 + num_legs] = (0.5, -0.8, 1.5)
    return state


def _attitude_difference(quat_a, quat_b) -> np.ndarray:
    """rad, the angle of the rotation between two attitudes (..., 4): |R_a - R_b| (Frobenius) is
    2 sqrt(2) sin(angle / 2), exact for small angles where the arccos of the trace is not."""
    from .mujoco_peer import _quat_to_mat

    rot_a = _quat_to_mat(quat_a / np.linalg.norm(quat_a, axis=-1, keepdims=True))
    rot_b = _quat_to_mat(quat_b / np.linalg.norm(quat_b, axis=-1, keepdims=True))
    chord = np.sqrt(np.sum((rot_a - rot_b) ** 2, axis=(-2, -1))) / (2.0 * math.sqrt(2.0))
    return 2.0 * np.arcsin(np.clip(chord, 0.0, 1.0))


def _ours(axes, num_legs: int, model: str, start, duration: float, sample_dt: float) -> np.ndarray:
    """rrrobot_gym's run of the family's test gait (:func:`rrrobot_gym.simulation.simulate`, RK4 at
    the default step, the servo evaluated at every stage as the peer's is): states (T, 9 + 2L)."""
    from rrrobot_gym.control import Gait
    from rrrobot_gym.simulation import SimConfig, simulate

    gait = Gait(amplitude=0.3, frequency=8.0, phase=tuple(2.0 * math.pi * np.arange(1, num_legs + 1) / num_legs),
                offset=(math.pi / 2,) * num_legs)  # (mujoco_peer.sinusoid_servo's)
    config = SimConfig(model=model, robot=RobotParams(shell_axes=axes, num_legs=num_legs))
    return simulate(config, gait, duration, state=start, sample_dt=sample_dt).states


def family_rows(quick: bool) -> list:
    """The MuJoCo peer of each family member against the oracle (module docstring, ``--family``)."""
    from .mujoco_peer import simulate_family, sinusoid_servo

    oracle = family_oracle()
    duration, sample_dt = (2.0, 0.05) if quick else (5.0, 0.05)
    members = FAMILY_MEMBERS[:1] if quick else FAMILY_MEMBERS
    rows = []
    for name, axes, num_legs in members:
        robot = dict(shell_axes=axes, legs=oracle.default_legs(num_legs, axes), mass_bottom=RobotParams().mass_bottom)
        torque = sinusoid_servo(num_legs)
        for model in ("plane", "pivot"):
            for tilted in (False, True):
                start = family_start(num_legs, tilted)
                times = np.arange(round(duration / sample_dt) + 1) * sample_dt
                wall = time.perf_counter()
                _, ref = oracle.oracle_simulate(start, torque, duration, model=model, t_eval=times, rtol=1e-10,
                                                atol=1e-10, **robot)  # fmt: skip
                oracle_wall = time.perf_counter() - wall
                ours = _ours(axes, num_legs, model, start, duration, sample_dt)
                ours_row = {"ours_max_contact_distance_m": float(np.max(np.hypot(*(ours[:, :2] - ref[:, :2]).T))),
                            "ours_max_attitude_difference_rad": float(np.max(_attitude_difference(ours[:, 2:6], ref[:, 2:6])))}
                for step, timeconst in FAMILY_MUJOCO[model][:2] if quick else FAMILY_MUJOCO[model]:
                    wall = time.perf_counter()
                    _, states, _, tilt = simulate_family(model, torque, duration, timestep=step, sample_dt=sample_dt,
                                                         state=start, contact_timeconst=timeconst, **robot)  # fmt: skip
                    row = {"member": name, "shell_axes": axes, "num_legs": num_legs, "model": model,
                           "start": "tilted, spinning" if tilted else "paper's (at rest)", "mujoco_step_s": step,
                           "contact_timeconst_s": timeconst if model == "plane" else None,
                           "max_contact_distance_m": float(np.max(np.hypot(*(states[:, :2] - ref[:, :2]).T))),
                           "max_attitude_difference_rad": float(np.max(_attitude_difference(states[:, 2:6], ref[:, 2:6]))),
                           "max_leg_angle_difference_rad": float(np.max(np.abs(states[:, 6 : 6 + num_legs] - ref[:, 6 : 6 + num_legs]))),
                           "travel_m": float(np.hypot(*(ref[-1, :2] - ref[0, :2]))), "largest_tilt_rad": tilt,
                           "oracle_wall_s": oracle_wall, "mujoco_wall_s": time.perf_counter() - wall, **ours_row}  # fmt: skip
                    rows.append(row)
                    print(row, flush=True)
    return rows


def family_main(args):
    rows = family_rows(args.quick)
    duration = 2.0 if args.quick else 5.0
    text = markdown_table(
        ["member", "model", "start", "MuJoCo step (ms)", "contact time constant (ms)", "travel (mm)", "largest tilt (rad)",
         f"MuJoCo: largest contact distance, {duration:g} s (mm)", "MuJoCo: largest attitude difference (rad)",
         "rrrobot_gym RK4 1/300 s: contact (mm)", "rrrobot_gym: attitude (rad)"],
        [[r["member"], r["model"], r["start"], fmt(r["mujoco_step_s"] * 1e3),
          "-" if r["contact_timeconst_s"] is None else fmt(r["contact_timeconst_s"] * 1e3), f"{r['travel_m'] * 1e3:.1f}",
          f"{r['largest_tilt_rad']:.3f}", f"{r['max_contact_distance_m'] * 1e3:.2g}", f"{r['max_attitude_difference_rad']:.2g}",
          f"{r['ours_max_contact_distance_m'] * 1e3:.2g}", f"{r['ours_max_attitude_difference_rad']:.2g}"]
         for r in rows],
    )  # fmt: skip
    print()
    print(text)
    write_json(args.json, {"machine": machine(), "duration_s": duration, "rows": rows, "table": text})


def main(argv=None):
    p = parser(__doc__.splitlines()[0])
    loop = p.add_mutually_exclusive_group()
    loop.add_argument("--closed-loop", action="store_true",
                      help="run the shipped policies closed loop in MuJoCo instead of the gaits")  # fmt: skip
    loop.add_argument("--policy", action="store_true",
                      help="replay the shipped policies' actions from our env open loop in MuJoCo instead of the gaits")  # fmt: skip
    loop.add_argument("--family", action="store_true",
                      help="check the MuJoCo peer of the robot family against the sympy oracle instead")  # fmt: skip
    p.add_argument("--model", choices=tuple(POLICIES), action="append",
                   help="with --closed-loop or --policy: this model's policy only (repeatable; default both)")  # fmt: skip
    args = p.parse_args(argv)
    try:
        import mujoco  # noqa: F401
    except ImportError:
        raise SystemExit("benchmarks.vs_mujoco needs the optional dependency mujoco: pip install mujoco")
    if args.closed_loop or args.policy:
        return policy_main(args, args.closed_loop)
    if args.family:
        return family_main(args)
    duration = 10.0 if args.quick else 50.0
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
