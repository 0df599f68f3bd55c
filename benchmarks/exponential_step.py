"""The exponential step (``integrator="etdrk4b"``) against RK4: error, evaluations, CPU time, energy.

    python -m benchmarks.exponential_step [--quick] [--json FILE] [--markdown FILE] [--policy] [--workers W]

Five parts, each the shipped steppers through :func:`rrrobot_gym.simulation.advance`:

- gaits: the six Table II cases (both models, gaits 1-3, 50 s from the paper's start; --quick:
  10 s), in env steps of 0.05 s, against ``simulate_reference`` (DOP853, rtol = atol = 1e-10):
  RK4 at the default 1/300 s, and ETDRK4-B at 1/60, 1/80 and 1/100 s, each with its first env
  step in three times as many steps (the legs start from rest onto moving targets, the one stiff
  transient of a gait) and at 1/80 s without, and graded: at 1/60 and 1/80 s with
  ``start_halves=1`` (16 and 20 evaluations), at 1/120 s with 2 and 3, and at 1/220 s with 4 (the first steps of every env step in halves, as the
  policy's rows below want; the last at 60 evaluations, the default's count). Worst contact error
  over the path, and CPU time of one robot's run on the numpy backend and on the compiled one
  (which must give the same states to the bit);
- batches: one env step (0.05 s of leg-target ramps) of N = 64 and 4096 robots, median wall time
  (REPEATS runs, ROUNDS rounds alternating the steppers), ETDRK4-B at several steps against RK4 at
  1/300 s on numpy and compiled, side by side;
- energy: a servo without damping (kd = 0) holding fixed targets on a robot without damping,
  started off its targets, tilted and spinning. Nothing drains or feeds energy, so the body's
  energy plus the servo's spring energy kp/2 |phi - target|^2 is conserved; its largest relative
  drift over the run, per method and step (the servo works all along, unlike
  ``benchmarks.work_precision``'s book with the servo off, where ETDRK4-B's A is the legs' phi' = phidot alone);
- env: the env with its checks (``benchmarks.throughput``'s single env and vector env at N = 64
  and 4096), RK4 at the default and ETDRK4-B at about RK4's cost in batches, alternating;
- ``--policy``: the env's slip measure (``info["slip_velocity"]``) on the shipped policy's first
  2 s at several steps. It sums the record's samples, each standing for a whole step, and where a
  new ramp kicks the servo the grip needed jumps past the floor's and falls back within a
  millisecond, so the one sample at the kick makes the measure, in proportion to the step.
  And the shipped policy's leg-target ramps along four headings (50 s; --quick: 10 s), replayed
  control step by control step (``benchmarks.policy_replay``): every new ramp kicks the servo,
  the path where the exponential step's order is not reached at 16 evaluations. Uniform and
  graded (``start_halves``) steps of both methods.
"""

from __future__ import annotations

import math
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

import numpy as np

from rrrobot_gym import compiled, dynamics
from rrrobot_gym.control import HeldTargets, RampTargets, table2_gait
from rrrobot_gym.params import PDGains, RobotParams
from rrrobot_gym.simulation import SimConfig, advance, initial_state

from ._common import contact_error, fmt, machine, markdown_table, median_time, parser, reference, write_json
from .work_precision import ENV_STEP, run_steps

CASES = [(model, gait) for model in ("plane", "pivot") for gait in (1, 2, 3)]
FIRST_FACTOR = 3
"""The first env step is taken in FIRST_FACTOR times the method's steps (where marked)."""
GAIT_SETTINGS = [("rk4", 15, False, 0), ("etdrk4b", 3, True, 0), ("etdrk4b", 4, True, 0), ("etdrk4b", 5, True, 0),
                 ("etdrk4b", 4, False, 0), ("etdrk4b", 3, False, 1), ("etdrk4b", 4, False, 1), ("etdrk4b", 6, False, 2),
                 ("etdrk4b", 6, False, 3),
                 ("etdrk4b", 11, False, 4)]  # fmt: skip
"""(integrator, steps an env step, fine first env step, ``start_halves``: the first steps of every
env step in halves, which costs 4 evaluations more each)."""
BATCHES = (64, 4096)
REPEATS = 5
ROUNDS = 3
"""Batches: each stepper timed REPEATS times (median) in each of ROUNDS rounds, the steppers
alternating, and the median of the rounds kept."""
BATCH_SETTINGS = [("rk4", 15, 0), ("etdrk4b", 4, 0), ("etdrk4b", 3, 1), ("etdrk4b", 4, 1), ("etdrk4b", 6, 2), ("etdrk4b", 6, 3),
                  ("etdrk4b", 11, 4)]  # fmt: skip
"""(integrator, steps an env step, ``start_halves``) timed compiled; RK4 and ETDRK4-B at 1/80 s on numpy too."""
ENERGY_SETTINGS = [("rk4", 15), ("rk4", 30), ("etdrk4b", 4), ("etdrk4b", 6), ("etdrk4b", 15)]
ENV_SETTINGS = [("rk4", 15, 0), ("etdrk4b", 6, 2), ("etdrk4b", 6, 3)]
"""(integrator, steps a control step, ``start_halves``) of the env rows: the default, and ETDRK4-B at about its cost in batches."""
POLICY_SETTINGS = [("rk4", 15, 0), ("rk4", 15, 2), ("etdrk4b", 4, 0), ("etdrk4b", 4, 1), ("etdrk4b", 3, 1), ("etdrk4b", 6, 2),
                   ("etdrk4b", 6, 3), ("etdrk4b", 8, 0), ("etdrk4b", 8, 2), ("etdrk4b", 15, 0), ("etdrk4b", 11, 4)]  # fmt: skip
"""(integrator, steps a control step, ``start_halves``)."""


def _config(model: str, integrator: str, n: int, **kwargs) -> SimConfig:
    return SimConfig(model=model, integrator=integrator, timestep=ENV_STEP / n, backend="numpy", **kwargs)


def _label(integrator: str, n: int, halves: int, step: float = ENV_STEP) -> str:
    return f"{integrator} 1/{n / step:.0f} s" + (f", start_halves={halves}" if halves else "")


def _step_text(row) -> str:
    return f"1/{1 / row['step_s']:.0f} s" + (f", start_halves={row['start_halves']}" if row.get("start_halves") else "")


def _run(config: SimConfig, first: SimConfig, targets, duration: float):
    """(states every env step, CPU s) of one robot's run (work_precision.run_steps), the first env
    step taken in ``first``'s steps, after one untimed step that compiles or loads the compiled stepper."""
    advance(first, initial_state(), 0.0, ENV_STEP, targets)
    return run_steps(config, targets, initial_state(), round(duration / ENV_STEP), first=first)


def gait_case(job):
    """(worst contact error over the path (m), CPU s on numpy, CPU s compiled or None) of one gait
    case in one setting; the compiled run must give the numpy (float stepper's) states to the bit."""
    (integrator, n, fine_first, halves), (model, gait), duration = job
    config = _config(model, integrator, n, start_halves=halves)
    first = _config(model, integrator, FIRST_FACTOR * n) if fine_first else config
    targets = table2_gait(gait)
    states, cpu = _run(config, first, targets, duration)
    compiled_cpu = None
    if compiled.available():
        fast, compiled_cpu = _run(replace(config, backend="numba"), replace(first, backend="numba"), targets, duration)
        if not np.array_equal(fast, states):
            raise AssertionError(f"the compiled {integrator} run differs from the float stepper's ({model} gait {gait})")
    return float(contact_error(states, reference(SimConfig(model=model), targets, duration, ENV_STEP)).max()), cpu, compiled_cpu


def gait_rows(duration: float, workers: int, settings=GAIT_SETTINGS):
    for model, gait in CASES:  # fill the reference cache before the workers read it
        reference(SimConfig(model=model), table2_gait(gait), duration, ENV_STEP)
    jobs = [(setting, case, duration) for setting in settings for case in CASES]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        results = list(pool.map(gait_case, jobs))
    rows = []
    for i, (integrator, n, fine_first, halves) in enumerate(settings):
        per_case = results[i * len(CASES) : (i + 1) * len(CASES)]
        rows.append({
            "integrator": integrator, "step_s": ENV_STEP / n, "start_halves": halves, "evals_per_env_step": 4 * (n + halves),
            "first_env_step_evals": 4 * n * FIRST_FACTOR if fine_first else 4 * (n + halves),
            "contact_max_m": max(e for e, _, _ in per_case),
            "per_case_max_m": {f"{m}_gait{g}": e for (m, g), (e, _, _) in zip(CASES, per_case)},
            "cpu_s_per_run": sum(c for _, c, _ in per_case) / len(per_case),
            "compiled_cpu_s_per_run": None if per_case[0][2] is None else sum(c for _, _, c in per_case) / len(per_case),
        })  # fmt: skip
        r = rows[-1]
        print(f"gaits: {_label(integrator, n, halves)}{' (fine first env step)' if fine_first else ''}: worst "
              f"{r['contact_max_m'] * 1e3:.3g} mm, {r['cpu_s_per_run']:.2f} CPU s a run (numpy), "
              f"{r['compiled_cpu_s_per_run'] or float('nan'):.3f} (compiled)", flush=True)  # fmt: skip
    return rows


def batch_rows(settings=BATCH_SETTINGS, numpy_other=("etdrk4b", 4)):
    """Wall time of one env step of N robots per stepper (medians, side by side), and its ratio to
    RK4 at the default step on numpy and compiled: compiled per ``settings``, on numpy RK4 and
    ``numpy_other`` (integrator, steps an env step)."""
    rng = np.random.default_rng(0)
    rows = []
    for n in BATCHES:
        state = initial_state(n)
        ramp = RampTargets(state[:, 6:8], state[:, 6:8] + rng.uniform(-0.5, 0.5, (n, 2)), 0.0, ENV_STEP)
        configs = {"rk4 1/300 s, numpy": SimConfig(backend="numpy"),
                   _label(*numpy_other, 0) + ", numpy": _config("plane", *numpy_other)}  # fmt: skip
        if compiled.available():
            for integrator, steps, halves in settings:
                config = replace(_config("plane", integrator, steps, start_halves=halves), backend="numba")
                configs[_label(integrator, steps, halves) + ", compiled"] = config
        for config in configs.values():
            advance(config, state, 0.0, ENV_STEP, ramp)  # warm: compile, caches, allocator
        rounds = {label: [] for label in configs}
        for _ in range(ROUNDS):
            for label, config in configs.items():
                rounds[label].append(median_time(lambda: advance(config, state, 0.0, ENV_STEP, ramp, check=False), REPEATS))
        times = {label: float(np.median(values)) for label, values in rounds.items()}
        base = times["rk4 1/300 s, numpy"]
        compiled_base = times.get("rk4 1/300 s, compiled")
        for (label, seconds), config in zip(times.items(), configs.values()):
            rows.append({"num_robots": n, "stepper": label, "evals_per_env_step": 4 * (round(ENV_STEP / config.timestep)
                         + config.start_halves), "median_s": seconds, "env_steps_per_s": n / seconds,
                         "speed_vs_rk4_numpy": base / seconds,
                         "speed_vs_rk4_compiled": None if compiled_base is None else compiled_base / seconds})  # fmt: skip
            print(f"batch N = {n}: {label}: {n / seconds:,.0f} env steps/s ({base / seconds:.2f}x RK4 numpy"
                  + ("" if compiled_base is None else f", {compiled_base / seconds:.2f}x RK4 compiled") + ")", flush=True)
    return rows


def env_rows(settings=ENV_SETTINGS):
    """The env with its checks (``benchmarks.throughput``'s single env and vector env at N = 64 and
    4096, compiled) per ``settings`` (ENV_SETTINGS by default), ROUNDS rounds alternating the settings, medians; ratios to
    the default (RK4) per env."""
    from .throughput import single_env, vector_env

    measures = (("single", lambda rng, kw: single_env(300, 3, rng, **kw)), ("N = 64", lambda rng, kw: vector_env(64, 100, 3, rng, **kw)),
                ("N = 4096", lambda rng, kw: vector_env(4096, 10, 3, rng, **kw)))  # fmt: skip
    rates = {}
    for _ in range(ROUNDS):
        for integrator, n, halves in settings:
            kwargs = {"backend": "numba", "integrator": integrator, "timestep": ENV_STEP / n, "frame_skip": n, "start_halves": halves}
            for name, measure in measures:
                rates.setdefault((integrator, n, halves, name), []).append(measure(np.random.default_rng(0), kwargs)["env_steps_per_s"])
    rows = []
    for (integrator, n, halves, name), values in rates.items():
        rate, base = float(np.median(values)), float(np.median(rates[("rk4", 15, 0, name)]))
        rows.append({"integrator": integrator, "step_s": ENV_STEP / n, "start_halves": halves, "evals_per_env_step": 4 * (n + halves),
                     "env": name, "env_steps_per_s": rate, "vs_default": rate / base})  # fmt: skip
        print(f"env {name}: {_label(integrator, n, halves)}: {rate:,.0f} env steps/s ({rate / base:.2f}x the default)", flush=True)
    return rows


def spring_energy(config: SimConfig, state, targets) -> np.ndarray:
    """The conserved energy of an undamped servo on an undamped robot: body and legs plus kp/2 |phi - target|^2."""
    spring = 0.5 * config.gains.kp * np.sum((state[..., 6:8] - np.asarray(targets)) ** 2, axis=-1)
    return dynamics.total_energy(state, config.robot, config.model) + spring


def energy_rows(duration: float, settings=ENERGY_SETTINGS):
    rows = []
    targets = (0.5 * math.pi, 0.5 * math.pi)
    start = initial_state(leg_angles=(1.2, 2.0))
    tilt = 0.3
    start[dynamics.QUAT] = (math.cos(tilt / 2), math.sin(tilt / 2) * 0.8, math.sin(tilt / 2) * 0.6, 0.0)
    start[dynamics.BODY_RATE] = (0.3, -0.2, 1.0)
    for model in ("plane", "pivot"):
        for integrator, n in settings:
            config = _config(model, integrator, n, robot=RobotParams(damping=0.0), gains=PDGains(kp=2.0, kd=0.0))
            state, energy0, drift = start.copy(), float(spring_energy(config, start, targets)), 0.0
            for i in range(round(duration / ENV_STEP)):
                state = advance(config, state, i * ENV_STEP, ENV_STEP, HeldTargets(targets), check=False)
                drift = max(drift, abs(float(spring_energy(config, state, targets)) - energy0) / abs(energy0))
            rows.append({"model": model, "integrator": integrator, "step_s": ENV_STEP / n, "evals_per_env_step": 4 * n,
                         "energy_drift": drift})  # fmt: skip
            print(f"energy ({model}): {integrator} 1/{n / ENV_STEP:.0f} s: max relative drift {drift:.2g}", flush=True)
    return rows


def policy_rows(duration: float, settings=POLICY_SETTINGS):
    from rrrobot_gym.agents.ppo import load_ppo_agent

    from .policy_replay import MODEL, error_fields, replay, rollouts

    headings = (0.0, 90.0, 180.0, 270.0)
    _, start, starts, ends, dt, sim = rollouts(load_ppo_agent(MODEL), headings, round(duration / ENV_STEP))
    ref, _ = replay(sim, start, starts, ends, dt, reference=True)
    rows = []
    for integrator, n, halves in settings:
        config = replace(sim, integrator=integrator, timestep=dt / n, start_halves=halves,
                         backend="numba" if compiled.available() else "numpy")  # (the same states to the bit)
        with np.errstate(all="ignore"):
            path, _ = replay(config, start, starts, ends, dt)
        rows.append({"integrator": integrator, "step_s": dt / n, "start_halves": halves, "evals_per_env_step": 4 * (n + halves),
                     **error_fields(contact_error(path, ref), headings)})  # fmt: skip
        print(f"policy, {duration:g} s: {_label(integrator, n, halves, dt)}: worst {rows[-1]['contact_max_m'] * 1e3:.3g} mm",
              flush=True)  # fmt: skip
    return rows


ENVELOPE_SETTINGS = [("rk4", 15, 0), ("rk4", 30, 0), ("rk4", 60, 0), ("etdrk4b", 15, 0), ("etdrk4b", 6, 3)]
"""(integrator, steps a control step, ``start_halves``) of the envelope rows."""


def envelope_rows(seconds: float = 2.0, settings=ENVELOPE_SETTINGS):
    """The env's slip measure (``info["slip_velocity"]``, the missing impulse over a step per unit
    mass) on the shipped policy's first ``seconds`` along 0 deg, per ``settings`` (ENVELOPE_SETTINGS by default), the
    episode kept running past the model's limits: its largest value, and the steps past the
    policy's ``max_slip_velocity``."""
    import gymnasium

    from rrrobot_gym.agents.ppo import load_ppo_agent

    from .policy_replay import MODEL

    agent = load_ppo_agent(MODEL)
    rows = []
    for integrator, n, halves in settings:
        kwargs = {**agent.env_config, "integrator": integrator, "timestep": ENV_STEP / n, "frame_skip": n,
                  "start_halves": halves, "terminate_outside_model": False}  # fmt: skip
        env = gymnasium.make("RRRobot-v0", **kwargs)
        obs, _ = env.reset(seed=0, options={"target_direction": 0.0})
        slips = []
        for _ in range(round(seconds / ENV_STEP)):
            obs, _, _, _, info = env.step(agent.predict(obs, deterministic=True)[0])
            slips.append(float(info["slip_velocity"]))
        limit = env.unwrapped.config.max_slip_velocity
        rows.append({"integrator": integrator, "step_s": ENV_STEP / n, "start_halves": halves, "evals_per_env_step": 4 * (n + halves),
                     "max_slip_velocity_m_s": max(slips), "worst_env_step": int(np.argmax(slips)),
                     "steps_past_limit": sum(v > limit for v in slips), "limit_m_s": limit})  # fmt: skip
        print(f"envelope: {_label(integrator, n, halves)}: largest slip measure {max(slips):.4f} m/s, "
              f"{rows[-1]['steps_past_limit']} env steps past {limit} m/s", flush=True)  # fmt: skip
    return rows


def main(argv=None):
    report(__doc__.splitlines()[0], "benchmarks.exponential_step", argv)


def report(title: str, module: str, argv=None, gait_settings=GAIT_SETTINGS, batch_settings=BATCH_SETTINGS,
           numpy_other=("etdrk4b", 4), energy_settings=ENERGY_SETTINGS, env_settings=ENV_SETTINGS,
           policy_settings=POLICY_SETTINGS, envelope_settings=ENVELOPE_SETTINGS):
    """Parse the command line, run the parts with these settings (as the module constants), print and
    write the tables: the work of this module's main, shared with ``benchmarks.locked_rate``."""
    p = parser(title, markdown=True, workers=True)
    p.add_argument("--policy", action="store_true", help="also the shipped policy's replay (needs the train extra)")
    args = p.parse_args(argv)
    duration = 10.0 if args.quick else 50.0
    payload = {"machine": machine(), "duration_s": duration}
    payload["gaits"] = gaits = gait_rows(duration, args.workers, gait_settings)
    payload["batches"] = batches = batch_rows(batch_settings, numpy_other)
    payload["energy"] = energy = energy_rows(duration, energy_settings)
    payload["env"] = envs = env_rows(env_settings) if compiled.available() else []
    base, compiled_base = gaits[0]["cpu_s_per_run"], gaits[0]["compiled_cpu_s_per_run"]

    def compiled_cpu(r):
        if compiled_base is None:
            return ["-", "-"]
        return [fmt(r["compiled_cpu_s_per_run"]), f"{r['compiled_cpu_s_per_run'] / compiled_base:.2f}x"]

    command = f"python -m {module}{' --quick' if args.quick else ''}{' --policy' if args.policy else ''}"
    text = f"`{command}`, {duration:g} s\n\nSix gait cases, one robot (CPU time per run, mean of the six cases):\n\n" + markdown_table(
        ["integrator", "step", "first env step (evaluations)", "evaluations / env step", "worst max contact error (mm)",
         "CPU s / run, numpy", "vs RK4", "CPU s / run, compiled", "vs RK4"] + [f"{m} gait {g}" for m, g in CASES],
        [[r["integrator"], _step_text(r), r["first_env_step_evals"], r["evals_per_env_step"],
          fmt(r["contact_max_m"] * 1e3), fmt(r["cpu_s_per_run"]), f"{r['cpu_s_per_run'] / base:.2f}x", *compiled_cpu(r)]
         + [fmt(v * 1e3) for v in r["per_case_max_m"].values()] for r in gaits],
    )  # fmt: skip
    text += "\n\nOne env step of a batch (wall time: median of %d runs, median of %d alternating rounds):\n\n" % (REPEATS, ROUNDS) + markdown_table(
        ["N", "stepper", "evaluations / env step", "env steps / s", "vs RK4 numpy", "vs RK4 compiled"],
        [[r["num_robots"], r["stepper"], r["evals_per_env_step"], f"{r['env_steps_per_s']:,.0f}", f"{r['speed_vs_rk4_numpy']:.2f}x",
          "-" if r["speed_vs_rk4_compiled"] is None else f"{r['speed_vs_rk4_compiled']:.2f}x"] for r in batches],
    )  # fmt: skip
    text += "\n\nEnergy book with the servo working (kd = 0, no damping), max relative drift:\n\n" + markdown_table(
        ["model", "integrator", "step", "evaluations / env step", "energy drift"],
        [[r["model"], r["integrator"], f"1/{1 / r['step_s']:.0f} s", r["evals_per_env_step"], fmt(r["energy_drift"], 2)]
         for r in energy],
    )  # fmt: skip
    if envs:
        text += "\n\nThe env with its checks, compiled (env steps / s, median of %d alternating rounds):\n\n" % ROUNDS + markdown_table(
            ["integrator", "step", "evaluations / env step", "env", "env steps / s", "vs the default"],
            [[r["integrator"], _step_text(r), r["evals_per_env_step"], r["env"], f"{r['env_steps_per_s']:,.0f}",
              f"{r['vs_default']:.2f}x"] for r in envs],
        )  # fmt: skip
    if args.policy:
        payload["envelope"] = envelope = envelope_rows(settings=envelope_settings)
        text += "\n\nThe env's slip measure on the shipped policy's first 2 s along 0 deg (not terminated):\n\n" + markdown_table(
            ["integrator", "step", "evaluations / env step", "largest slip_velocity (m/s)", "at env step", "env steps past the limit"],
            [[r["integrator"], _step_text(r), r["evals_per_env_step"], f"{r['max_slip_velocity_m_s']:.4f}", r["worst_env_step"],
              f"{r['steps_past_limit']} (limit {r['limit_m_s']:g})"] for r in envelope],
        )  # fmt: skip
        payload["policy"] = policy = policy_rows(duration, policy_settings)
        text += f"\n\nThe shipped policy's ramps, {duration:g} s, four headings:\n\n" + markdown_table(
            ["integrator", "step", "evaluations / env step", "worst max contact error (mm)"],
            [[r["integrator"], _step_text(r), r["evals_per_env_step"], fmt(r["contact_max_m"] * 1e3)]
             for r in policy],
        )  # fmt: skip
    print(text)
    if args.markdown:
        with open(args.markdown, "w") as fh:
            fh.write(text + "\n")
    write_json(args.json, payload)


if __name__ == "__main__":
    main()
