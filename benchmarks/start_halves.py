"""What ``start_halves`` costs: env steps with it against env steps without, side by side.

    python -m benchmarks.start_halves [--quick] [--json FILE] [--num-envs 1 64 4096] [--halves 2]
        [--substeps 15]
    python -m benchmarks.start_halves --accuracy [--quick] [--json FILE]

For each batch size (1: the single ``gymnasium.make`` env; more: the vector env), two envs of
the same scene, one with ``start_halves`` (default 2) and one without, step the same gentle
actions; each step of one is timed next to a step of the other, in alternation, so both see
the same machine. Reported: the medians of the repeats' env steps/s and of their ratio. The
physics alone would cost (15 + 2 halves) / 15 = 1.13x at two halves; an env step, whose task
code is the same either way, less (the compiled stepper takes the graded schedule in one call).
``--substeps n`` gives the graded env n substeps a control step (``frame_skip`` n, the step
0.05 s / n, so the same 0.05 s control step): at 13 and two halves it makes the same 60
derivative evaluations a step as the default.

``--accuracy`` measures instead what a graded start buys on the Table II gaits: both models,
the three gaits, 50 s from the paper's start (--quick: 10 s) in env steps of 0.05 s (an
``advance`` call each, as the envs make them), against ``simulate_reference`` (DOP853, rtol =
atol = 1e-10) at the same instants, for the default and the graded settings of ACCURACY_SETTINGS
(the same 60 derivative evaluations an env step, 48, and two halves on the default step),
and for the default with only its first env step taken finely (FINE_FIRST); then, model by
model, RK4 at the fewest substeps its servo's stability allows and one more, with and without
that fine first step.
"""

from __future__ import annotations

import statistics
import time

import gymnasium
import numpy as np

import rrrobot_gym  # noqa: F401  (registers the env)
from rrrobot_gym.control import table2_gait
from rrrobot_gym.envs.vector import RRRobotVectorEnv
from rrrobot_gym.simulation import SimConfig, initial_state

from ._common import contact_error, fmt, gentle_actions, machine, markdown_table, parser, reference, write_json
from .work_precision import ENV_STEP, run_steps

ACCURACY_SETTINGS = ((15, 0), (14, 1), (13, 2), (10, 2), (15, 2))
"""--accuracy: (substeps a 0.05 s control step, start_halves); 4 (substeps + halves) evaluations a
step: the default's 60, 48 and 68."""


def make(num_envs: int, halves: int, substeps: int = 15):
    kwargs = {"start_halves": halves, "terminate_outside_model": False}
    if substeps != 15:
        kwargs.update(frame_skip=substeps, timestep=0.05 / substeps)
    if num_envs == 1:
        return gymnasium.make("RRRobot-v0", **kwargs).unwrapped
    return RRRobotVectorEnv(num_envs=num_envs, **kwargs)


def paired(num_envs: int, halves: int, steps: int, repeats: int, substeps: int = 15):
    """(steps/s without, steps/s with, ratio of times with / without): medians over repeats."""
    plain, graded = make(num_envs, 0), make(num_envs, halves, substeps)
    if abs(graded.dt - plain.dt) > 1e-15:
        raise ValueError(f"the envs' control steps differ: {graded.dt} and {plain.dt} s")
    shape = (num_envs, 2) if num_envs > 1 else (1, 2)
    actions = gentle_actions(np.random.default_rng(0), shape, steps)
    rates_plain, rates_graded, ratios = [], [], []
    for _ in range(repeats + 1):  # the first round warms up (numba compiles, caches fill)
        plain.reset(seed=0)
        graded.reset(seed=0)
        t_plain = t_graded = 0.0
        for action in actions:
            action = action if num_envs > 1 else action[0]
            start = time.perf_counter()
            plain.step(action)
            middle = time.perf_counter()
            graded.step(action)
            t_plain += middle - start
            t_graded += time.perf_counter() - middle
        rates_plain.append(steps * num_envs / t_plain)
        rates_graded.append(steps * num_envs / t_graded)
        ratios.append(t_graded / t_plain)
    return (statistics.median(rates_plain[1:]), statistics.median(rates_graded[1:]), statistics.median(ratios[1:]))


FINE_FIRST = 120
"""--accuracy's last rows: the first env step alone in this many substeps (1/2400 s), the rest at
the default, to show where the default's error on the gaits is made; then the same at RK4's
fewest substeps a model's servo allows (STABLE_SUBSTEPS), with and without the fine first step."""
STABLE_SUBSTEPS = {"plane": 7, "pivot": 3}
"""The fewest RK4 substeps a 0.05 s step within the servo's stability limit (1/138 s plane, 1/54 s pivot)."""


def gait_errors(substeps: int, halves: int, duration: float, fine_first: int = 0, models=("plane", "pivot")) -> dict:
    """Max contact error (m) over the path of each Table II gait on each model, in env steps of
    0.05 s (with ``fine_first``, the first of them in that many substeps)."""
    out = {}
    for model in models:
        config = SimConfig(model=model, timestep=0.05 / substeps, start_halves=halves)
        first = SimConfig(model=model, timestep=0.05 / fine_first) if fine_first else None
        for number in (1, 2, 3):
            gait = table2_gait(number)
            states, _ = run_steps(config, gait, initial_state(), round(duration / ENV_STEP), first=first)
            ref = reference(SimConfig(model=model), gait, duration, 0.05)
            out[f"{model} gait {number}"] = float(contact_error(states, ref).max())
    return out


def accuracy(args):
    duration = 10.0 if args.quick else 50.0
    runs = [(n, k, 0, ("plane", "pivot")) for n, k in ACCURACY_SETTINGS] + [(15, 0, FINE_FIRST, ("plane", "pivot"))]
    for model in ("plane", "pivot"):
        for substeps in (STABLE_SUBSTEPS[model], STABLE_SUBSTEPS[model] + 1):
            runs += [(substeps, 0, 0, (model,)), (substeps, 0, FINE_FIRST, (model,))]
    rows = []
    for substeps, halves, fine_first, models in runs:
        errors = gait_errors(substeps, halves, duration, fine_first, models)
        label = f"1/{20 * substeps} s" + (f", the first env step at 1/{20 * fine_first} s" if fine_first else "")
        label += f" ({models[0]} only)" if len(models) == 1 else ""
        rows.append({"setting": label, "substeps": substeps, "start_halves": halves, "first_env_step_substeps": fine_first or None,
                     "evals_per_env_step": 4 * (substeps + halves), "contact_max_m": errors, "worst_m": max(errors.values())})  # fmt: skip
        print(f"{label}, start_halves={halves}: worst {rows[-1]['worst_m'] * 1e3:.3g} mm", flush=True)
    names = list(rows[0]["contact_max_m"])
    print(
        markdown_table(
            ["step", "start_halves", "evaluations / env step", "worst (mm)"] + names,
            [[r["setting"], r["start_halves"], r["evals_per_env_step"], fmt(r["worst_m"] * 1e3)]
             + [fmt(r["contact_max_m"][k] * 1e3) if k in r["contact_max_m"] else "-" for k in names] for r in rows],
        )  # fmt: skip
    )
    write_json(args.json, {"machine": machine(), "duration_s": duration, "accuracy_rows": rows})


def main(argv=None):
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--num-envs", nargs="+", type=int, default=[1, 64, 4096])
    p.add_argument("--halves", type=int, default=2)
    p.add_argument("--substeps", type=int, default=15, help="the graded env's substeps a 0.05 s control step (default 15)")
    p.add_argument("--accuracy", action="store_true", help="the gaits' contact error at ACCURACY_SETTINGS instead of time")
    args = p.parse_args(argv)
    if args.substeps < 1:
        p.error(f"--substeps must be a positive integer, got {args.substeps}")
    if args.accuracy:
        return accuracy(args)
    steps, repeats = (20, 3) if args.quick else (100, 7)
    label = f" at {args.substeps} substeps" if args.substeps != 15 else ""
    rows = []
    for n in args.num_envs:
        without, with_halves, ratio = paired(n, args.halves, steps if n < 4096 else max(5, steps // 10), repeats, args.substeps)
        rows.append({"num_envs": n, "steps_per_s": without, "steps_per_s_start_halves": with_halves, "time_ratio": ratio})
        print(f"N={n}: {without:,.0f} env steps/s without, {with_halves:,.0f} with start_halves={args.halves}{label}: "
              f"{ratio:.2f}x the time", flush=True)  # fmt: skip
    print(
        markdown_table(
            ["N", "env steps/s", f"with start_halves={args.halves}{label}", "time ratio"],
            [[r["num_envs"], f"{r['steps_per_s']:,.0f}", f"{r['steps_per_s_start_halves']:,.0f}", f"{r['time_ratio']:.2f}x"]
             for r in rows],
        )  # fmt: skip
    )
    write_json(args.json, {"machine": machine(), "halves": args.halves, "substeps": args.substeps, "steps": steps, "repeats": repeats,
                           "rows": rows})  # fmt: skip


if __name__ == "__main__":
    main()
