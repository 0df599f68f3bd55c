"""Work against precision: CPU time against error for each shipped integrator and step.

    python -m benchmarks.work_precision [--quick] [--json FILE] [--plot FILE] [--markdown FILE] [--gains KP KD]

For both models and the three Table II gaits (50 s from the paper's start; --quick:
10 s and fewer settings), each setting is run at N = 1 in env steps of 0.05 s (the
integration step is 0.05 s / n) and compared with ``simulate_reference`` (DOP853,
rtol = atol = 1e-10) sampled at the same instants:

- contact error: distance between contact points, at the end and the maximum over the path;
- attitude error: the angle of R_ref^T R, maximum over the path;
- energy drift: a separate run with no damping and no leg torque (servo: the legs
  swing freely; kinematic: the legs are locked), started tilted and spinning, with
  the same integrator and step; the maximum of |E - E0| / E0 over the run.

Kinematic legs are a different model of the legs (they follow their path exactly,
see ``SimConfig.legs``): their error is taken against the kinematic reference, and
the table also gives their distance from the servo reference (the model difference).
The recommended setting per model and leg mode is the cheapest (fewest derivative
evaluations per env step) whose worst contact error over the path stays under 1 mm.

``--gains KP KD`` runs a servo of those gains instead of the paper's (servo legs only: kinematic
legs have no servo). Where it is stiff, RK4's fixed steps beyond its stability limit are refused
(printed) and RK4 also runs at ``timestep="auto"``.
"""

from __future__ import annotations

import math
import time

import numpy as np

from rrrobot_gym import dynamics
from rrrobot_gym.control import table2_gait
from rrrobot_gym.integrators import INTEGRATORS
from rrrobot_gym.params import PDGains, RobotParams
from rrrobot_gym.simulation import SimConfig, _kinematic_path, advance, initial_state

from ._common import (
    attitude_error,
    contact_error,
    fmt,
    machine,
    markdown_table,
    parser,
    reference,
    write_json,
)

ENV_STEP = 0.05
"""s, the control step of the environment; the integration step is ENV_STEP / n."""
EVALS_PER_STEP = {"rk4": 4}
BUDGET_M = 1e-3


def settings(quick: bool, gains=None):
    """(legs, integrator, n or "auto") to sweep (``gains``: a servo of its own, see the module docstring)."""
    if gains is not None:
        return [("servo", "rk4", n) for n in (15, 30, "auto")]
    servo, kinematic = ((10, 15, 20), (1, 3)) if quick else ((5, 6, 7, 8, 10, 12, 14, 15, 17, 20, 30), (1, 2, 3, 5))
    return [("servo", "rk4", n) for n in (*servo, "auto")] + [("kinematic", "rk4", n) for n in (*kinematic, "auto")]


def config_for(model: str, legs: str, integrator: str, n, gains=None) -> SimConfig:
    timestep = "auto" if n == "auto" else ENV_STEP / n
    # numpy for every row, so CPU times compare integrators, not backends (numba's errors are the same)
    return SimConfig(model=model, legs=legs, integrator=integrator, timestep=timestep, backend="numpy",
                     gains=gains or PDGains())  # fmt: skip


def run_steps(config: SimConfig, targets, state, n_env_steps: int):
    """States after each env step, shape (n_env_steps + 1, 13), and the CPU time it took."""
    out = np.empty((n_env_steps + 1, dynamics.STATE_SIZE))
    out[0] = state
    start = time.process_time()
    for i in range(n_env_steps):
        out[i + 1] = advance(config, out[i], i * ENV_STEP, ENV_STEP, targets, check=False)
    return out, time.process_time() - start


def energy_drift(model: str, legs: str, integrator: str, step: float, duration: float) -> float:
    """max |E - E0| / E0 over a run with no damping and no torque, with this integrator and step.

    Servo legs: the legs swing freely (leg torque 0). Kinematic legs: the legs are
    locked (rate and acceleration 0). Either way nothing feeds or drains energy. The
    robot starts tilted by 0.3 rad, spinning, legs moving (servo).
    """
    robot = RobotParams(damping=0.0)
    free = dynamics.derivative_function(robot, model, kinematic=legs != "servo")
    state = initial_state(leg_angles=(1.2, 2.0))
    tilt = 0.3
    state[dynamics.QUAT] = (math.cos(tilt / 2), math.sin(tilt / 2) * 0.8, math.sin(tilt / 2) * 0.6, 0.0)
    state[dynamics.BODY_RATE] = (0.3, -0.2, 1.0)
    if legs == "servo":
        state[dynamics.LEG_RATES] = (1.0, -2.0)

        def f(t, c):
            return free(c, (0.0, 0.0))  # (servo legs: no torque)

    else:

        def f(t, c):
            return free(c, (0.0, 0.0))  # (kinematic legs: no acceleration)

    stepper = INTEGRATORS[integrator].step
    steps_per_env = round(ENV_STEP / step)
    y = state.tolist()
    energies = [float(dynamics.total_energy(state, robot, model))]
    for i in range(round(duration / ENV_STEP)):
        y = stepper(f, f, i * ENV_STEP, y, ENV_STEP / steps_per_env, steps_per_env)
        energies.append(float(dynamics.total_energy(np.array(y), robot, model)))
    energies = np.array(energies)
    return float(np.max(np.abs(energies - energies[0])) / abs(energies[0]))


def main(argv=None):
    p = parser(__doc__.splitlines()[0], markdown=True)
    p.add_argument("--plot", metavar="FILE", help="write the log-log plot (PNG)")
    p.add_argument("--gains", nargs=2, type=float, metavar=("KP", "KD"), help="a servo of these PD gains (servo legs only)")
    args = p.parse_args(argv)
    gains = None if args.gains is None else PDGains(kp=args.gains[0], kd=args.gains[1])
    duration = 10.0 if args.quick else 50.0
    n_env = round(duration / ENV_STEP)
    models, gaits = ("plane", "pivot"), (1, 2, 3)

    refs = {}
    for model in models:
        for legs in ("servo",) if gains is not None else ("servo", "kinematic"):
            # (the reference is DOP853's own; "auto" only keeps SimConfig from refusing a stiff servo's default step)
            cfg = SimConfig(model=model, legs=legs, gains=gains or PDGains(), timestep="auto")
            for g in gaits:
                refs[model, legs, g] = reference(cfg, table2_gait(g), duration, ENV_STEP)

    rows = []
    for model in models:
        for legs, integ, n in settings(args.quick, gains):
            try:
                cfg = config_for(model, legs, integ, n, gains=gains)
            except ValueError as exc:  # SimConfig refuses steps beyond the servo's stability limit
                print(f"{model:5s} {legs:9s} {integ} n={n}: refused: {exc}".split(": the run")[0], flush=True)
                continue
            steps_per_env = math.ceil(ENV_STEP / cfg.step - 1e-9)
            per_gait = {}
            cpu = 0.0
            for g in gaits:
                targets = _kinematic_path(cfg, table2_gait(g), initial_state())
                states, seconds = run_steps(cfg, targets, initial_state(), n_env)
                cpu += seconds
                err = contact_error(states, refs[model, legs, g])
                rec = {
                    "contact_end_m": float(err[-1]),
                    "contact_max_m": float(err.max()),
                    "attitude_max_rad": float(attitude_error(states, refs[model, legs, g]).max()),
                    "cpu_s": seconds,
                }
                if legs == "kinematic":
                    rec["vs_servo_end_m"] = float(contact_error(states, refs[model, "servo", g])[-1])
                per_gait[g] = rec
            rows.append(
                {
                    "model": model,
                    "legs": legs,
                    "integrator": integ,
                    "n": n,
                    "step_s": ENV_STEP / steps_per_env,
                    "evals_per_env_step": steps_per_env * EVALS_PER_STEP[integ],
                    "cpu_s_per_run": cpu / len(gaits),
                    "contact_end_m": max(r["contact_end_m"] for r in per_gait.values()),
                    "contact_max_m": max(r["contact_max_m"] for r in per_gait.values()),
                    "attitude_max_rad": max(r["attitude_max_rad"] for r in per_gait.values()),
                    "vs_servo_end_m": max((r.get("vs_servo_end_m", 0.0) for r in per_gait.values()), default=0.0),
                    "energy_drift": energy_drift(model, legs, integ, ENV_STEP / steps_per_env, duration),
                    "per_gait": per_gait,
                }
            )
            r = rows[-1]
            print(
                f"{model:5s} {legs:9s} {integ} h=1/{1 / r['step_s']:.0f} evals/env-step={r['evals_per_env_step']:3d} "
                f"cpu={r['cpu_s_per_run']:.2f}s contact end={r['contact_end_m'] * 1e3:.3g} mm "
                f"max={r['contact_max_m'] * 1e3:.3g} mm attitude={r['attitude_max_rad']:.2g} rad "
                f"energy={r['energy_drift']:.2g}",
                flush=True,
            )

    best = {}
    for r in rows:
        key = (r["model"], r["legs"])
        if r["contact_max_m"] < BUDGET_M and math.isfinite(r["contact_max_m"]):
            if key not in best or (r["evals_per_env_step"], r["cpu_s_per_run"]) < (
                best[key]["evals_per_env_step"],
                best[key]["cpu_s_per_run"],
            ):
                best[key] = r

    header = ["model", "legs", "integrator", "step", "evals / 0.05 s", "CPU s / run", "contact at end (mm)",
              "contact max (mm)", "attitude max (rad)", "energy drift", "kinematic vs servo (mm)"]  # fmt: skip
    table_rows = []
    for r in rows:
        step = f"1/{1 / r['step_s']:.0f} s" + (" (auto)" if r["n"] == "auto" else "")
        mark = " **" if best.get((r["model"], r["legs"])) is r else ""
        table_rows.append(
            [r["model"], r["legs"], r["integrator"] + mark, step, r["evals_per_env_step"], fmt(r["cpu_s_per_run"]),
             fmt(r["contact_end_m"] * 1e3), fmt(r["contact_max_m"] * 1e3), fmt(r["attitude_max_rad"], 2),
             fmt(r["energy_drift"], 2), fmt(r["vs_servo_end_m"] * 1e3) if r["legs"] == "kinematic" else ""]
        )  # fmt: skip
    table = markdown_table(header, table_rows)
    summary = [
        f"cheapest under 1 mm ({duration:g} s, worst over gaits 1-3): {m} {legs}: {r['integrator']} "
        f"step 1/{1 / r['step_s']:.0f} s ({r['evals_per_env_step']} evaluations per 0.05 s env step, "
        f"max contact error {r['contact_max_m'] * 1e3:.3g} mm)"
        for (m, legs), r in sorted(best.items())
    ]
    servo = "" if gains is None else f", servo kp = {gains.kp:g}, kd = {gains.kd:g}"
    text = f"Work-precision, {duration:g} s, N = 1{servo} (`**` = cheapest under 1 mm)\n\n{table}\n\n" + "\n".join(
        "- " + s for s in summary
    )
    print()
    print(text)
    if args.markdown:
        with open(args.markdown, "w") as fh:
            fh.write(text + "\n")
    if args.plot:
        plot(rows, args.plot, duration)
    write_json(args.json, {"machine": machine(), "duration_s": duration, "gains": None if gains is None else list(args.gains),
                           "rows": rows, "recommended": summary})  # fmt: skip


def plot(rows, path: str, duration: float):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    for ax, model in zip(axes, ("plane", "pivot")):
        for legs, integ, style in (("servo", "rk4", "o-"), ("kinematic", "rk4", "^--")):
            sel = [r for r in rows if (r["model"], r["legs"], r["integrator"]) == (model, legs, integ) and r["n"] != "auto"]
            sel = [r for r in sel if math.isfinite(r["contact_max_m"]) and r["contact_max_m"] < 10.0]
            if not sel:
                continue
            sel.sort(key=lambda r: r["cpu_s_per_run"])
            ax.loglog([r["cpu_s_per_run"] for r in sel], [r["contact_max_m"] * 1e3 for r in sel], style,
                      label=f"{integ}, {legs} legs")  # fmt: skip
        for r in rows:
            if r["model"] == model and r["n"] == "auto" and math.isfinite(r["contact_max_m"]):
                ax.loglog(r["cpu_s_per_run"], r["contact_max_m"] * 1e3, "k*", ms=12)
        ax.axhline(1.0, color="grey", lw=0.8, ls=":")
        ax.set_title(f"{model} model, worst of gaits 1-3, {duration:g} s")
        ax.set_xlabel("CPU time per run (s, N = 1)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("max contact-position error (mm)")
    axes[0].legend(fontsize=8, title="star: timestep='auto'", title_fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
