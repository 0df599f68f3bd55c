"""What the env's opt-in ``contact_quadrature="trapezoid"`` costs beside the default rectangle rule.

    python -m benchmarks.contact_quadrature [--quick] [--json FILE] [--num-envs 64 4096]

The quadrature only reads the step record (``rrrobot_gym.validity.step_measures``); it costs
anything only in the steps where some robot's samples lose contact or need more grip than the
floor gives (otherwise both rules skip to 0). So this steps two vector envs, one per rule, with
the same actions, alternately, one env step each: ``--actions gentle`` (the legs near vertical,
nothing lost: the usual case) and ``random`` (uniform actions with the targets held, as PPO's
first updates send them: most steps lift some robot off or slip it, and with
``terminate_outside_model=False`` no episode ends, so both envs stay in step). Medians over
rounds of the per-round ratio of env steps/s.
"""

from __future__ import annotations

import statistics
import time

import numpy as np

import rrrobot_gym  # noqa: F401  (registers the env)
from rrrobot_gym.envs.vector import RRRobotVectorEnv

from ._common import gentle_actions, machine, markdown_table, parser, write_json


def _actions(kind: str, rng, num_envs: int, steps: int) -> np.ndarray:
    if kind == "gentle":
        return gentle_actions(rng, (num_envs, 2), steps)
    return rng.uniform(-1.0, 1.0, (steps, num_envs, 2)).astype(np.float32)


def measure(num_envs: int, kind: str, steps: int, rounds: int) -> dict:
    """Env steps/s of each rule (medians) and their ratio, trapezoid / rectangle (median per round)."""
    kwargs = {"action_hold": "zero_order"} if kind == "random" else {}
    envs = {rule: RRRobotVectorEnv(num_envs=num_envs, terminate_outside_model=False, contact_quadrature=rule, **kwargs)
            for rule in ("rectangle", "trapezoid")}  # fmt: skip
    actions = _actions(kind, np.random.default_rng(0), num_envs, steps)
    rates = {rule: [] for rule in envs}
    ratios, outside = [], []
    for _ in range(rounds):
        seconds = dict.fromkeys(envs, 0.0)
        for env in envs.values():
            env.reset(seed=0)
            env.step(actions[0])  # (numba compiles on a first step)
        lost = 0
        for a in actions:
            for rule, env in envs.items():
                start = time.perf_counter()
                _, _, _, _, info = env.step(a)
                seconds[rule] += time.perf_counter() - start
            lost += int((info["liftoff_time"] > 0).any() or (info["slip_velocity"] > 0).any())
        outside.append(lost / len(actions))
        for rule in envs:
            rates[rule].append(num_envs * len(actions) / seconds[rule])
        ratios.append(rates["trapezoid"][-1] / rates["rectangle"][-1])
    return {"num_envs": num_envs, "actions": kind, "steps": steps, "rounds": rounds,
            "rectangle_steps_per_s": statistics.median(rates["rectangle"]),
            "trapezoid_steps_per_s": statistics.median(rates["trapezoid"]),
            "ratio": statistics.median(ratios), "share_of_steps_with_loss": statistics.median(outside)}  # fmt: skip


def main(argv=None):
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--num-envs", nargs="+", type=int, default=[64, 4096])
    p.add_argument("--actions", nargs="+", choices=("gentle", "random"), default=["gentle", "random"])
    args = p.parse_args(argv)
    rounds = 3 if args.quick else 7
    rows = []
    for num_envs in args.num_envs:
        for kind in args.actions:
            steps = max(20, min(400, 200_000 // num_envs)) // (4 if args.quick else 1)
            rows.append(measure(num_envs, kind, steps, rounds))
            r = rows[-1]
            print(f"N = {num_envs}, {kind}: rectangle {r['rectangle_steps_per_s']:,.0f}, trapezoid "
                  f"{r['trapezoid_steps_per_s']:,.0f} env steps/s, ratio {r['ratio']:.3f} "
                  f"({r['share_of_steps_with_loss']:.0%} of steps lose contact or grip somewhere)", flush=True)  # fmt: skip
    print(markdown_table(
        ["N", "actions", "rectangle (env steps/s)", "trapezoid (env steps/s)", "trapezoid / rectangle", "steps with a loss"],
        [[r["num_envs"], r["actions"], f"{r['rectangle_steps_per_s']:,.0f}", f"{r['trapezoid_steps_per_s']:,.0f}",
          f"{r['ratio']:.3f}", f"{r['share_of_steps_with_loss']:.0%}"] for r in rows],
    ))  # fmt: skip
    write_json(args.json, {"machine": machine(), "rows": rows})


if __name__ == "__main__":
    main()
