"""Where in a control step the evaluations go: graded ETDRK4-B steps on a policy's path (issue 10).

    python -m benchmarks.graded_schedule [--quick] [--json FILE] [--markdown FILE] [--workers W] [--drift | --inject] [--schedule W:W:...]

A probe of the "at most 16 derivative evaluations an env step" aim on the path where the shipped
steps miss it: the shipped policy's leg-target ramps (``benchmarks.policy_replay``; needs the
``train`` extra), where every control step's new ramp kicks the servo. ETDRK4-B in the locked
rate, as the shipped ``integrator="etdrk4b"`` steps (``benchmarks.exp_rosenbrock``'s full-matrix
version with ``locked=True``, which ``tests/test_integrators.py`` holds to the shipped step), takes
each control step in steps whose lengths are in the ratio of a schedule's weights, shortest first.
The shipped options give some of them: ``timestep=1/60, start_halves=1`` is 1:1:2:2 (16
evaluations), ``1/60`` with ``start_halves=2`` is 1:1:1:1:2 and ``1/80`` with ``start_halves=1``
1:1:2:2:2 (20), ``1/120`` with ``start_halves=2`` 1:1:1:1:2:2:2:2 (32). The others need a schedule
the shipped steppers do not take.

Two questions, each answered by rows side by side:

- is the matrix A the limit? The shipped schedule with A the exact Jacobian (forward differences,
  12 more evaluations a step, counted) beside the servo's part of it;
- is it where the steps fall? Schedules of four to six steps, and of seven and eight (what 1 mm
  costs here: 28 and 32 evaluations).

Each row is run on the policy's ramps along 0, 90, 180 and 270 deg for 50 s (--quick: 10 s),
control step by control step, against ``simulate_reference`` solved so, and, for the servo's A,
on the six Table II cases for 50 s (every env step in the same schedule, from the paper's start),
against the reference paths. Reported: the worst contact error over each path. CPU time means
nothing here (the phi-functions come from scipy's expm): only evaluations and errors count.

``--drift`` asks what the policy's error is made of instead: along DRIFT_HEADINGS, with the
shipped schedule and the closest one of four steps, the whole state against the reference's,
every DRIFT_EVERY_S: the contact error and the body's rotation error (the rotation vector of
q_ref^-1 q, in the body's frame; z is the shell's axis, about which the robot turns its heading).

``--inject`` asks which of the step's errors make that: the reference is run again, step by step
of a schedule, and at the end of each of its steps the error that the probe's step makes from the
same state (the injected run's own state at that step's start) is added, but only in some rows of
the state and for some of the steps. The rows are taken in the locked rate's variables (those the
step integrates), so the legs' errors can be told from the body's. All rows of all steps give the
schedule's own run, to rounding (each step then ends where the probe's step ends). Each group of
rows alone says what its errors cost (the errors are small, so the groups' runs about add up to
the whole), and the locked rate's errors from one step alone say where in the control step that
cost is made.
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from rrrobot_gym import dynamics
from rrrobot_gym.control import RampTargets, table2_gait
from rrrobot_gym.simulation import SimConfig, simulate_reference

from ._common import contact_error, fmt, machine, markdown_table, parser, reference, write_json
from .exp_rosenbrock import CASES, ENV_STEP, POLICY_HEADINGS, Problem, Setting, env_step, policy_episode, policy_rows, run_case

SHIPPED = (1, 1, 2, 2)
"""``timestep=1/60, start_halves=1``: the shipped options' 16 evaluations an env step."""
SHIPPED_32 = (1, 1, 1, 1, 2, 2, 2, 2)
"""``timestep=1/120, start_halves=2``: 32 evaluations an env step."""
SCHEDULES = [
    ("servo", SHIPPED),
    ("full", SHIPPED),
    ("servo", (1, 2, 3, 4)),
    ("servo", (1, 2, 4, 5)),
    ("servo", (1, 1, 1, 1, 2)),
    ("servo", (1, 1, 2, 2, 2)),
    ("servo", (1, 2, 3, 4, 5)),
    ("servo", (1, 1, 1, 1, 4, 4)),
    ("servo", (1, 1, 2, 2, 2, 2, 2)),
    ("servo", SHIPPED_32),
]
"""(A, weights): the steps of a control step in the ratio of the weights. The last two ask what
1 mm costs on the policy's path with this method: the shortest step at the kick and 1/120 s after it."""
DRIFT_HEADINGS = (0.0, 90.0)
DRIFT_SCHEDULES = (SHIPPED, (1, 2, 4, 5))
DRIFT_EVERY_S = 10.0
ALL_ROWS = tuple(range(dynamics.STATE_SIZE))
ROW_GROUPS = {
    "contact and attitude (x, y, q)": (0, 1, 2, 3, 4, 5),
    "legs (angles and rates)": (6, 7, 11, 12),
    "locked rate": (8, 9, 10),
}
"""--inject: the rows whose errors are added, in the locked rate's variables (rows 8-10 Lambda)."""


def inject_variants(steps: int) -> list[tuple[str, tuple, tuple]]:
    """(label, rows, steps) of --inject's runs for a schedule of ``steps`` steps: all rows from all
    steps, each of ROW_GROUPS from all steps, then the locked rate from each step alone."""
    every = tuple(range(steps))
    return ([("all rows", ALL_ROWS, every)] + [(name, rows, every) for name, rows in ROW_GROUPS.items()]
            + [(f"locked rate, step {i + 1} only", ROW_GROUPS["locked rate"], (i,)) for i in every])  # fmt: skip


def injected_run(job) -> np.ndarray:
    """States (n + 1, V, 13), V = len(variants), of the reference replay of one episode's ramps
    (each control step from t = 0), solved step by step of a schedule in the ratio of ``weights``.
    A variant is (label, rows, steps, 0-based): at the end of each of its steps, its rows are set,
    in the locked rate's variables, to where one probe ETDRK4-B step from the same state ends."""
    config, start, starts, ends, dt, weights, variants = job
    edges = np.concatenate([[0], np.cumsum(weights)]) * dt / sum(weights)
    masks = np.zeros((len(variants), len(weights), dynamics.STATE_SIZE))
    for v, (_, rows, steps) in enumerate(variants):
        masks[np.ix_([v], steps, rows)] = 1.0
    one_step = Setting("etdrk4b", "servo", (1,), locked=True)
    state = np.repeat(np.asarray(start, dtype=float)[None], len(variants), axis=0)
    out = [state.copy()]
    for ramp_start, ramp_end in zip(starts, ends):
        problem = Problem(config, RampTargets(ramp_start, ramp_end, 0.0, dt), locked=True)
        batch_start, batch_end = (np.repeat([ramp], len(variants), axis=0) for ramp in (ramp_start, ramp_end))
        for i, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
            # the reference over [a, b]: the same ramp, its clock started at a
            batch = RampTargets(batch_start, batch_end, -a, dt)
            exact = simulate_reference(config, batch, b - a, state=state, sample_dt=b - a).states[-1]
            for v in np.flatnonzero(masks[:, i].any(axis=1)):
                step = problem.to_locked(env_step(problem, np.append(state[v], a), one_step, b - a), 1.0)
                end = problem.to_locked(np.append(exact[v], b), 1.0)
                end[:-1] += masks[v, i] * (step - end)[:-1]
                end[dynamics.QUAT] /= np.linalg.norm(end[dynamics.QUAT])
                exact[v] = problem.to_locked(end, -1.0)[:-1]
            state = exact
        out.append(state.copy())
    return np.array(out)


def _schedule_runs(workers: int, seconds: float, schedules):
    """What --drift and --inject share: the shipped policy's ramps along DRIFT_HEADINGS for
    ``seconds`` ((simulator config, starts' states, ramp starts, ramp ends, control step)), the
    reference's whole states (n + 1, N, 13), the (weights, heading index) of each of ``schedules``
    along each heading, and those runs' whole states (the probe's ETDRK4-B in the locked rate)."""
    from rrrobot_gym.agents.ppo import load_ppo_agent

    from .policy_replay import MODEL, replay, rollouts

    _, start, starts, ends, dt, sim = rollouts(load_ppo_agent(MODEL), DRIFT_HEADINGS, round(seconds / ENV_STEP))
    refs, _ = replay(sim, start, starts, ends, dt, reference=True, whole=True)
    cases = [(weights, j) for weights in schedules for j in range(len(start))]
    jobs = [(Setting("etdrk4b", "servo", w, locked=True), sim, start[j], starts[j], ends[j], dt) for w, j in cases]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        paths = [states for states, _ in pool.map(policy_episode, jobs)]
    return (sim, start, starts, ends, dt), refs, cases, paths


def inject_rows(workers: int, seconds: float, schedules=DRIFT_SCHEDULES) -> list[dict]:
    """--inject's rows: along DRIFT_HEADINGS, each of ``schedules``, each of its variants, and the
    schedule's own run: contact error at the end and its maximum, and the body z rotation at the end."""
    (sim, start, starts, ends, dt), refs, cases, owns = _schedule_runs(workers, seconds, schedules)
    jobs = [(sim, start[j], starts[j], ends[j], dt, w, inject_variants(len(w))) for w, j in cases]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        injected = list(pool.map(injected_run, jobs))
    rows = []
    for (weights, j), own, runs, (*_, variants) in zip(cases, owns, injected, jobs):
        ref = refs[:, j]
        labelled = [("the schedule's own run", own)] + [(label, runs[:, v]) for v, (label, _, _) in enumerate(variants)]
        for label, path in labelled:
            contact = contact_error(path, ref)
            rows.append({"weights": weights, "heading_deg": DRIFT_HEADINGS[j], "injected": label,
                         "contact_end_m": float(contact[-1]), "contact_max_m": float(contact.max()),
                         "body_z_rotation_end_rad": float(body_rotation_error(path[-1], ref[-1])[2])})  # fmt: skip
            r = rows[-1]
            print(f"{':'.join(map(str, weights))} along {r['heading_deg']:g} deg, {label}: contact {r['contact_end_m'] * 1e3:.3g} mm "
                  f"(max {r['contact_max_m'] * 1e3:.3g}), body z {r['body_z_rotation_end_rad'] * 1e3:.3g} mrad", flush=True)  # fmt: skip
    return rows


def body_rotation_error(states, ref) -> np.ndarray:
    """(..., 3) rad: the rotation vector of q_ref^-1 q, in the body's frame (to second order in the angle)."""
    conjugate = ref[..., dynamics.QUAT] * np.array([1.0, -1.0, -1.0, -1.0])
    relative = dynamics.quat_multiply(conjugate, states[..., dynamics.QUAT])
    return 2.0 * np.sign(relative[..., :1]) * relative[..., 1:]


def drift_rows(workers: int, seconds: float, schedules=DRIFT_SCHEDULES) -> list[dict]:
    """Contact error and body rotation error every DRIFT_EVERY_S along DRIFT_HEADINGS."""
    (*_, dt), refs, cases, paths = _schedule_runs(workers, seconds, schedules)
    every = round(DRIFT_EVERY_S / dt)
    rows = []
    for (weights, j), path in zip(cases, paths):
        heading = DRIFT_HEADINGS[j]
        ref = refs[:, j]
        samples = np.arange(every, len(ref), every)
        contact = contact_error(path[samples], ref[samples])
        rotation = body_rotation_error(path[samples], ref[samples])
        rows.append({"weights": weights, "heading_deg": heading, "times_s": (samples * dt).tolist(),
                     "contact_m": contact.tolist(), "body_rotation_rad": rotation.tolist(),
                     "distance_m": float(np.hypot(*(ref[-1, :2] - ref[0, :2])))})  # fmt: skip
        print(f"{':'.join(map(str, weights))} along {heading:g} deg: "
              + ", ".join(f"{t:g} s {c * 1e3:.3g} mm, z {r[2] * 1e3:.3g} mrad" for t, c, r in zip(rows[-1]["times_s"], contact, rotation)),
              flush=True)  # fmt: skip
    return rows


def _ratio(text: str) -> tuple[int, ...]:
    """A schedule's weights from "1:2:4:5": positive whole numbers."""
    try:
        weights = tuple(int(w) for w in text.split(":"))
    except ValueError:
        weights = ()
    if not weights or min(weights) < 1:
        raise argparse.ArgumentTypeError(f"a schedule is positive whole numbers joined by ':', e.g. 1:2:4:5, got {text!r}")
    return weights


def _write_mode(args, flag: str, table: str, rows: list[dict], seconds: float):
    """Print a mode's table and write it as Markdown and its rows as JSON, if asked."""
    print(table)
    if args.markdown:
        with open(args.markdown, "w") as fh:
            schedules = "".join(f" --schedule {':'.join(map(str, w))}" for w in args.schedule or ())
            fh.write(f"`python -m benchmarks.graded_schedule {flag}{schedules}{' --quick' if args.quick else ''}`\n\n{table}\n")
    write_json(args.json, {"machine": machine(), "duration_s": seconds, "rows": rows})


def main(argv=None):
    p = parser(__doc__.splitlines()[0], markdown=True, workers=True)
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--drift", action="store_true", help="instead of the tables: the heading and contact errors along two headings every 10 s")
    mode.add_argument("--inject", action="store_true", help="instead of the tables: the reference with the probe's step errors of chosen rows and steps added (which errors make the miss at 16)")
    p.add_argument("--schedule", action="append", type=_ratio, metavar="W:W:...",
                   help="with --drift or --inject: a control step's steps in this ratio, e.g. 1:1:1:1:2:2:2:2 "
                   "(repeat for more; default 1:1:2:2, the shipped 16, and 1:2:4:5)")  # fmt: skip
    args = p.parse_args(argv)
    if args.schedule and not (args.drift or args.inject):
        p.error("--schedule applies to --drift and --inject (the tables run their own SCHEDULES)")
    seconds = 10.0 if args.quick else 50.0
    if args.inject:
        rows = inject_rows(args.workers, seconds, args.schedule or DRIFT_SCHEDULES)
        table = markdown_table(
            ["steps of a control step (ratio)", "heading (deg)", "errors added to the reference", f"contact error at {seconds:g} s (mm)",
             "max (mm)", f"body z rotation at {seconds:g} s (mrad)"],
            [[":".join(map(str, r["weights"])), f"{r['heading_deg']:g}", r["injected"], fmt(r["contact_end_m"] * 1e3),
              fmt(r["contact_max_m"] * 1e3), fmt(r["body_z_rotation_end_rad"] * 1e3)] for r in rows],
        )  # fmt: skip
        return _write_mode(args, "--inject", table, rows, seconds)
    if args.drift:
        rows = drift_rows(args.workers, seconds, args.schedule or DRIFT_SCHEDULES)
        table = markdown_table(
            ["steps of a control step (ratio)", "heading (deg)", "start to end (m)"]
            + [f"{t:g} s: contact (mm) / body z rotation (mrad)" for t in rows[0]["times_s"]],
            [[":".join(map(str, r["weights"])), f"{r['heading_deg']:g}", f"{r['distance_m']:.2f}"]
             + [f"{fmt(c * 1e3)} / {fmt(z[2] * 1e3)}" for c, z in zip(r["contact_m"], r["body_rotation_rad"])] for r in rows],
        )  # fmt: skip
        return _write_mode(args, "--drift", table, rows, seconds)
    settings = [Setting("etdrk4b", jacobian, weights, "coarse", locked=True) for jacobian, weights in SCHEDULES]
    gait_settings = [s for s in settings if s.jacobian == "servo"]
    for model, gait in CASES:  # fill the reference cache before the workers read it
        reference(SimConfig(model=model), table2_gait(gait), seconds, ENV_STEP)
    jobs = [(setting, case, seconds) for setting in gait_settings for case in CASES]
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        gaits = dict(zip([(s, c) for s, c, _ in jobs], pool.map(run_case, jobs)))
    rk4, *policy = policy_rows(args.workers, settings, seconds)  # the first row is RK4 at the default step
    rows = []
    for setting, replayed in zip(settings, policy):
        row = {"jacobian": setting.jacobian, "weights": setting.weights,
               "evals_per_env_step": replayed["evals_per_env_step"], "policy_contact_max_m": replayed["contact_max_m"],
               "policy_per_heading_max_m": replayed["per_heading_max_m"]}  # fmt: skip
        if setting in gait_settings:
            per_case = {f"{m}_gait{g}": gaits[setting, (m, g)][0] for m, g in CASES}
            row["gaits_contact_max_m"], row["gaits_per_case_max_m"] = max(per_case.values()), per_case
        rows.append(row)
        gait_text = f", gaits {row['gaits_contact_max_m'] * 1e3:.3g} mm" if "gaits_contact_max_m" in row else ""
        print(f"A={row['jacobian']} {':'.join(map(str, row['weights']))} ({row['evals_per_env_step']} evaluations): "
              f"policy {row['policy_contact_max_m'] * 1e3:.3g} mm{gait_text}", flush=True)  # fmt: skip
    table = markdown_table(
        ["A", "steps of a control step (ratio)", "evaluations / env step", f"policy, worst max contact error, {seconds:g} s (mm)"]
        + [f"{h:g} deg" for h in POLICY_HEADINGS] + [f"six gaits, worst, {seconds:g} s (mm)"],
        [[r["jacobian"], ":".join(map(str, r["weights"])), r["evals_per_env_step"], fmt(r["policy_contact_max_m"] * 1e3)]
         + [fmt(v * 1e3) for v in r["policy_per_heading_max_m"].values()]
         + [fmt(r["gaits_contact_max_m"] * 1e3) if "gaits_contact_max_m" in r else "-"] for r in rows],
    )  # fmt: skip
    print(table)
    rk4_text = f"RK4 at the default step (the envs' own, {rk4['evals_per_env_step']} evaluations): policy {rk4['contact_max_m'] * 1e3:.3g} mm"
    print(rk4_text)
    if args.markdown:
        with open(args.markdown, "w") as fh:
            fh.write(f"`python -m benchmarks.graded_schedule{' --quick' if args.quick else ''}`\n\n{table}\n\n{rk4_text}\n")
    write_json(args.json, {"machine": machine(), "duration_s": seconds, "headings_deg": POLICY_HEADINGS,
                           "rows": rows, "rk4_default_policy": rk4})  # fmt: skip


if __name__ == "__main__":
    main()
