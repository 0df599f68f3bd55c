"""RK4 in the body's locked rate: what the default integrator would gain by following it (a probe).

    python -m benchmarks.locked_rate [--quick] [--json FILE] [--markdown FILE] [--workers W]

The shipped exponential step integrates the locked rate Lambda = Omega + M_omega^-1 (c_1 phidot_1
+ c_2 phidot_2) (``dynamics.locked_share``) instead of the body rate Omega: the leg torques do
not act on it, so a new target's torque step is not in the body's rows. This asks what the same
change of variable does for RK4 at its own steps, with nothing else changed: RK4's tableau (the
probe's ETDRK4-B with A = 0, which is RK4 exactly: ``tests/test_integrators.py``) on
``derivative_kernel(locked=True)``, converting to Lambda and back at each env step as ``advance``
does, against the shipped RK4 (``advance``, Omega) at the same steps.

- gaits: the six Table II cases (both models, gaits 1-3; 50 s, --quick 10 s), in env steps of
  0.05 s, against ``simulate_reference`` (DOP853, rtol = atol = 1e-10);
- policy: the shipped policy's leg-target ramps along four headings (the same length), replayed
  control step by control step from t = 0 as the envs step (``benchmarks.policy_replay``; needs
  the ``train`` extra), against the reference solved control step by control step.

Worst max contact error over the path. Errors only: the probe takes its phi-functions from
scipy's expm even where A = 0, so its CPU time says nothing about a stepper's (there is no
shipped RK4 in the locked rate; the compiled ETDRK4-B's lanes lost ~20-30 % of their speed to the
locked rate's terms, ``benchmarks.exponential_step``).
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

import numpy as np

from rrrobot_gym.control import RampTargets, table2_gait
from rrrobot_gym.simulation import SimConfig, advance, initial_state

from . import exp_rosenbrock as probe
from ._common import contact_error, fmt, machine, markdown_table, parser, reference, write_json

ENV_STEP = 0.05
STEPS = (15, 12, 10)
"""RK4 steps an env step: 1/300 s (the default), 1/240 s and 1/200 s."""
HEADINGS = (0.0, 90.0, 180.0, 270.0)


def _locked_step(problem, state, t0, n):
    """``state`` after one env step of n RK4 steps in the locked rate (time as the 14th row)."""
    u = probe.env_step(problem, np.append(state, t0), probe.Setting("rk4", "servo", (1,) * n), ENV_STEP)
    return u[:-1]


def gait_case(job):
    """Worst contact error (m) of one case at n steps an env step, body rate or locked rate."""
    (model, gait), n, locked, duration = job
    config = SimConfig(model=model, timestep=ENV_STEP / n, backend="numpy")
    problem = probe.Problem(SimConfig(model=model), table2_gait(gait), locked=True) if locked else None
    states = [initial_state()]
    for i in range(round(duration / ENV_STEP)):
        t0 = i * ENV_STEP
        state = states[-1]
        states.append(_locked_step(problem, state, t0, n) if locked else advance(config, state, t0, ENV_STEP, table2_gait(gait)))
    return float(contact_error(np.array(states), reference(SimConfig(model=model), table2_gait(gait), duration, ENV_STEP)).max())


def policy_episode(job):
    """Contact points (n + 1, 2) of one policy episode's ramps at n steps a control step."""
    config, start, starts, ends, n, locked = job
    state, out = start.copy(), [start[:2].copy()]
    step_config = replace(config, timestep=ENV_STEP / n, backend="numpy")
    for a, b in zip(starts, ends):
        targets = RampTargets(a, b, 0.0, ENV_STEP)
        if locked:
            state = _locked_step(probe.Problem(config, targets, locked=True), state, 0.0, n)
        else:
            state = advance(step_config, state, 0.0, ENV_STEP, targets, check=False)
        out.append(state[:2].copy())
    return np.array(out)


def main(argv=None):
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--markdown", metavar="FILE", help="write the tables as Markdown")
    p.add_argument("--workers", type=int, default=2, help="processes (errors do not depend on it)")
    args = p.parse_args(argv)
    duration = 10.0 if args.quick else 50.0
    cases = probe.CASES
    for model, gait in cases:  # fill the reference cache before the workers read it
        reference(SimConfig(model=model), table2_gait(gait), duration, ENV_STEP)
    from agents.ppo import load_ppo_agent

    from .policy_replay import MODEL, replay, rollouts

    _, start, starts, ends, dt, sim = rollouts(load_ppo_agent(MODEL), HEADINGS, round(duration / ENV_STEP))
    assert abs(dt - ENV_STEP) < 1e-12
    ref, _ = replay(sim, start, starts, ends, dt, reference=True)
    settings = [(n, locked) for n in STEPS for locked in (False, True)]
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        gaits = list(pool.map(gait_case, [(case, n, locked, duration) for n, locked in settings for case in cases]))
        paths = list(pool.map(policy_episode, [(sim, start[j], starts[j], ends[j], n, locked) for n, locked in settings
                                               for j in range(len(HEADINGS))]))  # fmt: skip
    rows = []
    for i, (n, locked) in enumerate(settings):
        per_case = gaits[i * len(cases) : (i + 1) * len(cases)]
        path = np.stack(paths[i * len(HEADINGS) : (i + 1) * len(HEADINGS)], axis=1)
        rows.append({"steps_per_env_step": n, "step_s": ENV_STEP / n, "rate": "locked" if locked else "body",
                     "evals_per_env_step": 4 * n, "gaits_max_m": max(per_case),
                     "per_case_max_m": {f"{m}_gait{g}": e for (m, g), e in zip(cases, per_case)},
                     "policy_max_m": float(contact_error(path, ref).max())})  # fmt: skip
        r = rows[-1]
        print(f"RK4 1/{1 / r['step_s']:.0f} s, {r['rate']} rate: gaits {r['gaits_max_m'] * 1e3:.3g} mm, "
              f"policy {r['policy_max_m'] * 1e3:.3g} mm", flush=True)  # fmt: skip
    table = markdown_table(
        ["RK4 step", "evaluations / env step", "variable", f"gaits, worst max contact error, {duration:g} s (mm)",
         f"shipped policy's ramps, {len(HEADINGS)} headings (mm)"],
        [[f"1/{1 / r['step_s']:.0f} s", r["evals_per_env_step"], "Lambda (locked rate)" if r["rate"] == "locked" else "Omega",
          fmt(r["gaits_max_m"] * 1e3), fmt(r["policy_max_m"] * 1e3)] for r in rows],
    )  # fmt: skip
    print(table)
    if args.markdown:
        with open(args.markdown, "w") as fh:
            fh.write(f"`python -m benchmarks.locked_rate{' --quick' if args.quick else ''}`, {duration:g} s\n\n{table}\n")
    write_json(args.json, {"machine": machine(), "duration_s": duration, "rows": rows})


if __name__ == "__main__":
    main()
