"""Long stress tests of numerical stability (short versions: ``tests/test_stress.py``).

    python -m benchmarks.stress [--quick] [--json FILE]

Scenes (10^4 robots for 10^3 control steps of 0.05 s; --quick: 500 robots, 50 steps):
random and bang-bang leg targets on both models, with servo and kinematic legs;
very stiff and very soft gains; tiny and heavy masses; starts close to the tilt
limit; spinning starts. Each reports: finite or not (or the NumericalFailure
message), the worst quaternion-norm error, robots that crossed the tilt limit,
the fastest body and leg rates seen, and wall time. The energy books (E(t) - E(0)
against the work of servo and damping) are kept on 500 robots for 100 steps with
steps 10x finer than the default (see ``tests/stress_scenes.py``, which the short tests share).

Then the thresholds: at the default step, the stiffest kp and the lightest leg
tip the servo's stability check accepts, and the spin rate at which advance()
fails; these are what break first.
"""

from __future__ import annotations

import math
import time

import numpy as np

from rrrobot_gym.control import HeldTargets
from rrrobot_gym.params import PDGains, RobotParams
from rrrobot_gym.simulation import NumericalFailure, SimConfig, advance, initial_state, stable_step_limit

from tests.stress_scenes import bang_bang_targets, random_targets, run_scene, start_states

from ._common import fmt, machine, markdown_table, parser, write_json


def scenes(rng, n, steps):
    """(name, config, state, policy, n_control_steps)."""
    out = []
    for model in ("plane", "pivot"):
        out.append((f"{model}, random targets", SimConfig(model=model), start_states(rng, n), random_targets(rng, n, n_steps=steps), steps))
        out.append((f"{model}, bang-bang targets", SimConfig(model=model), start_states(rng, n), bang_bang_targets(n), steps))
        out.append((f"{model}, kinematic legs, bang-bang, auto step", SimConfig(model=model, legs="kinematic", timestep="auto"),
                    start_states(rng, n), bang_bang_targets(n), steps))  # fmt: skip
        near = start_states(rng, n, max_tilt=0.0)
        tilt = np.radians(rng.uniform(80.0, 89.9, n))
        near[:, 2], near[:, 3], near[:, 4], near[:, 5] = np.cos(tilt / 2), np.sin(tilt / 2), 0.0, 0.0
        out.append((f"{model}, start tilted 80-89.9 deg", SimConfig(model=model), near, random_targets(rng, n, n_steps=steps), steps))
        spin = start_states(rng, n)
        spin[:, 10] = rng.uniform(-50.0, 50.0, n)
        out.append((f"{model}, spinning start (|Omega_z| <= 50 rad/s)", SimConfig(model=model), spin,
                    random_targets(rng, n, n_steps=steps), steps))  # fmt: skip
    # Extreme parameters (plane): stiff servos need tiny auto steps, so fewer robots and steps.
    small_n, small_steps = max(20, n // 50), max(2, steps // 50)
    out.append(("plane, very stiff gains kp=200 kd=5, auto step", SimConfig(gains=PDGains(kp=200.0, kd=5.0), timestep="auto"),
                start_states(rng, small_n), random_targets(rng, small_n, n_steps=small_steps), small_steps))  # fmt: skip
    out.append(("plane, very soft gains kp=1e-3 kd=1e-5", SimConfig(gains=PDGains(kp=1e-3, kd=1e-5)), start_states(rng, n),
                random_targets(rng, n, n_steps=steps), steps))  # fmt: skip
    out.append(("plane, tiny leg tips 0.1 g, auto step", SimConfig(robot=RobotParams(mass_tip=1e-4), timestep="auto"),
                start_states(rng, small_n), random_targets(rng, small_n, n_steps=small_steps), small_steps))  # fmt: skip
    out.append(("plane, heavy 1 kg tips and bottom", SimConfig(robot=RobotParams(mass_tip=1.0, mass_bottom=1.0)),
                start_states(rng, n), random_targets(rng, n, n_steps=steps), steps))  # fmt: skip
    out.append(("plane, top-heavy 3 kg tips, auto step", SimConfig(robot=RobotParams(mass_tip=3.0), timestep="auto"),
                start_states(rng, n), random_targets(rng, n, n_steps=steps), steps))  # fmt: skip
    return out


def largest_accepted(make, lo, hi, iters=40, log=True):
    """Bisect the largest x in [lo, hi] for which make(x) constructs without ValueError (monotone)."""
    for _ in range(iters):
        mid = math.sqrt(lo * hi) if log else 0.5 * (lo + hi)
        try:
            make(mid)
            lo = mid
        except ValueError:
            hi = mid
    return lo


def failing_spin_rate(model: str) -> float:
    """rad/s: the smallest spin about the body z axis at which 1 s of advance() fails (default step)."""
    lo, hi = 10.0, 5000.0
    for _ in range(25):
        mid = math.sqrt(lo * hi)
        state = initial_state(2)
        state[:, 10] = mid
        try:
            advance(SimConfig(model=model), state, 0.0, 1.0, HeldTargets([1.0, 2.0]))
            lo = mid
        except NumericalFailure:
            hi = mid
    return hi


def main(argv=None):
    args = parser(__doc__.splitlines()[0]).parse_args(argv)
    n, steps = (500, 50) if args.quick else (10_000, 1000)
    rng = np.random.default_rng(7)
    rows = []
    for name, config, state, policy, n_steps in scenes(rng, n, steps):
        start = time.perf_counter()
        try:
            r = run_scene(config, state, policy, n_steps)
            row = {"scene": name, "robots": len(state), "control_steps": n_steps, "step_s": config.step,
                   "finite": r.finite, "max_quat_norm_error": r.max_quat_norm_error,
                   "crossed_tilt_limit": r.crossed_tilt_limit, "max_body_rate": r.max_body_rate,
                   "max_leg_rate": r.max_leg_rate, "failure": ""}  # fmt: skip
        except NumericalFailure as exc:
            row = {"scene": name, "robots": len(state), "control_steps": n_steps, "step_s": config.step,
                   "finite": False, "failure": str(exc)}  # fmt: skip
        row["wall_s"] = time.perf_counter() - start
        rows.append(row)
        print(row, flush=True)

    energy = []
    e_n, e_steps = (50, 10) if args.quick else (500, 100)
    for model in ("plane", "pivot"):
        for label, policy in (("random", random_targets(rng, e_n, n_steps=e_steps)), ("bang-bang", bang_bang_targets(e_n))):
            r = run_scene(SimConfig(model=model), start_states(rng, e_n), policy, e_steps, energy_refinement=10)
            energy.append({"model": model, "targets": label, "robots": e_n, "control_steps": e_steps,
                           "energy_balance_error": r.energy_balance_error,
                           "max_energy_gain_over_work_J": r.max_energy_gain_over_work})  # fmt: skip
            print(energy[-1], flush=True)

    robot, gains = RobotParams(), PDGains()
    thresholds = {
        "plane_max_kp_at_default_step": largest_accepted(lambda kp: SimConfig(gains=PDGains(kp=kp, kd=gains.kd)), 2.0, 1e5),
        "plane_max_kd_at_default_step": largest_accepted(lambda kd: SimConfig(gains=PDGains(kp=gains.kp, kd=kd)), 0.05, 100.0),
        "plane_min_tip_mass_at_default_step_kg": 1.0 / largest_accepted(
            lambda inv: SimConfig(robot=RobotParams(mass_tip=1.0 / inv)), 1.0 / robot.mass_tip, 1e6),
        "plane_stability_limit_default_s": stable_step_limit("plane", robot, gains),
        "pivot_stability_limit_default_s": stable_step_limit("pivot", robot, gains),
        "plane_failing_spin_rate_rad_s": failing_spin_rate("plane"),
        "pivot_failing_spin_rate_rad_s": failing_spin_rate("pivot"),
    }  # fmt: skip
    print(thresholds, flush=True)

    t1 = markdown_table(
        ["scene", "robots x control steps", "step", "finite", "max abs(norm q - 1)", "crossed tilt limit",
         "max abs(Omega) (rad/s)", "max leg rate (rad/s)", "wall s"],
        [[r["scene"], f"{r['robots']} x {r['control_steps']}", f"1/{1 / r['step_s']:.0f} s",
          "yes" if r["finite"] else "NO: " + r["failure"][:160], fmt(r.get("max_quat_norm_error", math.nan), 2),
          r.get("crossed_tilt_limit", ""), fmt(r.get("max_body_rate", math.nan)), fmt(r.get("max_leg_rate", math.nan)),
          fmt(r["wall_s"])] for r in rows],
    )  # fmt: skip
    t2 = markdown_table(
        ["model", "targets", "robots x steps", "max abs(E - E0 - W) / max scale", "max (E - E0 - W) (J)"],
        [[e["model"], e["targets"], f"{e['robots']} x {e['control_steps']}", fmt(e["energy_balance_error"], 2),
          fmt(e["max_energy_gain_over_work_J"], 2)] for e in energy],
    )  # fmt: skip
    t3 = markdown_table(["threshold (default gains, masses and 1/300 s step unless varied)", "value"],
                        [[k, fmt(v, 4)] for k, v in thresholds.items()])  # fmt: skip
    text = f"{t1}\n\n{t2}\n\n{t3}"
    print()
    print(text)
    write_json(args.json, {"machine": machine(), "scenes": rows, "energy": energy, "thresholds": thresholds, "table": text})


if __name__ == "__main__":
    main()
