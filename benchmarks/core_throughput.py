"""Throughput of the simulator core: robot-steps per second against the batch size N.

    python -m benchmarks.core_throughput [--quick] [--json FILE] [--profile]

One "env step" is 0.05 s of robot time (the environment's control step) for one
robot: ``advance(config, state, t, 0.05, targets)`` on N robots does N env steps.
Each call gets new random held leg targets (what an RL policy sends). Reported per
setting and N: median wall time per call over repeats, env steps/s (N / time),
physics steps/s (integration steps x N / time) and the time per derivative
evaluation. Settings: the defaults (servo legs, RK4, 1/300 s) and the options that
skip work (``timestep="auto"``, kinematic legs, RK3), on both models. No Gymnasium
env is involved: this is the ceiling an env built on ``advance`` can reach.
"""

from __future__ import annotations

import cProfile
import math
import pstats

import numpy as np

from rrrobot_gym import compiled
from rrrobot_gym.control import HeldTargets
from rrrobot_gym.simulation import SimConfig, advance, check_state, check_targets, initial_state

from ._common import fmt, machine, markdown_table, median_time, parser, write_json

ENV_STEP = 0.05
EVALS_PER_STEP = {"rk4": 4}


def setting_list(quick: bool):
    """(name, config, workers) of each setting measured."""
    out = [
        ("plane, defaults, numpy (servo, rk4 1/300 s)", SimConfig(model="plane", backend="numpy"), 1),
        ("pivot, defaults, numpy (servo, rk4 1/300 s)", SimConfig(model="pivot", backend="numpy"), 1),
        ("plane, defaults, numba", SimConfig(model="plane", backend="numba"), 1),
        ("pivot, defaults, numba", SimConfig(model="pivot", backend="numba"), 1),
        ("plane, defaults, numba, workers=2 (threads)", SimConfig(model="plane", backend="numba"), 2),
        ("pivot, servo, timestep=auto, numba", SimConfig(model="pivot", timestep="auto", backend="numba"), 1),
        ("plane, kinematic legs, rk4 1/20 s (numpy)", SimConfig(model="plane", legs="kinematic", timestep=ENV_STEP), 1),
        ("pivot, kinematic legs, rk4 1/20 s (numpy)", SimConfig(model="pivot", legs="kinematic", timestep=ENV_STEP), 1),
    ]
    if not compiled.available():
        out = [s for s in out if s[1].backend != "numba"]
    if quick:  # the plane defaults, one thread, on each backend
        out = [s for s in out if s[0].startswith("plane, defaults,") and s[2] == 1]
    return out


def random_state(num_robots: int, rng) -> np.ndarray:
    state = initial_state(num_robots)
    state[:, 6:8] += rng.uniform(-0.5, 0.5, (num_robots, 2))
    return state


def measure(config: SimConfig, num_robots: int, repeats: int, calls: int, rng, check: bool = False, workers: int = 1) -> dict:
    state = random_state(num_robots, rng) if num_robots > 1 else random_state(1, rng)[0]
    shape = (num_robots, 2) if num_robots > 1 else (2,)
    targets = [HeldTargets(rng.uniform(0.0, math.pi, shape)) for _ in range(calls)]
    box = {"state": state}

    def run():
        s = box["state"]
        for i in range(calls):
            s = advance(config, s, i * ENV_STEP, ENV_STEP, targets[i], check=check, workers=workers)
        box["state"] = s

    run()  # warm up (first-call allocations, heap tuning, numba's compilation)
    per_call = median_time(run, repeats) / calls
    n_steps = math.ceil(ENV_STEP / config.step - 1e-9)
    evals = n_steps * EVALS_PER_STEP[config.integrator]
    return {
        "num_robots": num_robots,
        "seconds_per_env_step_call": per_call,
        "env_steps_per_s": num_robots / per_call,
        "physics_steps_per_s": n_steps * num_robots / per_call,
        "us_per_derivative_eval": per_call / evals * 1e6,
        "integration_steps_per_env_step": n_steps,
    }


def profile(config: SimConfig, num_robots: int, calls: int, rng, top: int = 12):
    state = random_state(num_robots, rng) if num_robots > 1 else random_state(1, rng)[0]
    targets = HeldTargets(rng.uniform(0.0, math.pi, (num_robots, 2) if num_robots > 1 else (2,)))
    prof = cProfile.Profile()
    prof.enable()
    for i in range(calls):
        state = advance(config, state, i * ENV_STEP, ENV_STEP, targets, check=False)
    prof.disable()
    print(f"\n== cProfile, {num_robots} robot(s), {calls} env steps ==")
    pstats.Stats(prof).sort_stats("tottime").print_stats(top)


def main(argv=None):
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--profile", action="store_true", help="print cProfile tables for N = 1 and N = 4096")
    args = p.parse_args(argv)
    sizes = (1, 16, 256, 4096)
    repeats = 3 if args.quick else 7
    rng = np.random.default_rng(0)
    results = []
    for name, config, workers in setting_list(args.quick):
        for n in sizes:
            calls = {1: 40, 16: 10, 256: 5, 4096: 2}[n]
            if args.quick:
                calls = max(1, calls // 2)
            rec = measure(config, n, repeats, calls, rng, workers=workers)
            rec["setting"] = name
            results.append(rec)
            print(f"{name:42s} N={n:5d}: {rec['env_steps_per_s']:10.0f} env steps/s, "
                  f"{rec['physics_steps_per_s']:10.0f} physics steps/s, "
                  f"{rec['us_per_derivative_eval']:8.1f} us/derivative", flush=True)  # fmt: skip

    # The validation advance() does when check=True (what a caller pays for safety).
    checks = []
    for n in (1, 4096):
        config = SimConfig()
        on = measure(config, n, repeats, 4 if n > 1 else 40, rng, check=True)
        off = measure(config, n, repeats, 4 if n > 1 else 40, rng, check=False)
        state = random_state(n, rng)
        targets = HeldTargets(rng.uniform(0.0, math.pi, (n, 2)))
        t_check = median_time(lambda: (check_state(state), check_targets(targets, state)), repeats)
        checks.append({"num_robots": n, "env_steps_per_s_check_on": on["env_steps_per_s"],
                       "env_steps_per_s_check_off": off["env_steps_per_s"], "input_checks_s": t_check})  # fmt: skip

    header = ["setting"] + [f"N={n} env steps/s" for n in sizes] + ["us / derivative at N=4096"]
    rows = []
    for name, _, _ in setting_list(args.quick):
        recs = {r["num_robots"]: r for r in results if r["setting"] == name}
        rows.append([name] + [fmt(recs[n]["env_steps_per_s"]) for n in sizes] + [fmt(recs[4096]["us_per_derivative_eval"])])
    text = markdown_table(header, rows)
    text += "\n\n" + markdown_table(
        ["N", "env steps/s, check=True", "env steps/s, check=False", "check_state() and check_targets() alone (us)"],
        [[c["num_robots"], fmt(c["env_steps_per_s_check_on"]), fmt(c["env_steps_per_s_check_off"]),
          fmt(c["input_checks_s"] * 1e6)] for c in checks],  # fmt: skip
    )
    print()
    print(text)
    if args.profile:
        profile(SimConfig(), 1, 200, rng)
        profile(SimConfig(), 4096, 3, rng)
    write_json(args.json, {"machine": machine(), "results": results, "check_cost": checks, "table": text})


if __name__ == "__main__":
    main()
