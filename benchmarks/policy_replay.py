"""Accuracy on an RL policy's path: the shipped policy's actions replayed at other steps.

    python -m benchmarks.policy_replay [--quick] [--json FILE] [--headings DEG ...]
        [--model ZIP] [--no-motor-limit | --refine-switches]

An RL policy's leg targets change every control step (a ramp over 0.05 s), unlike the smooth
Table II gaits. This rolls a PPO policy (default: the shipped plane one; needs the ``train``
extra) out in ``RRRobot-v0`` as it was trained, for 50 s (--quick: 10 s) along each heading, and
replays its ramps from the same starts with RK4 at several steps and with ``simulate_reference``
(DOP853, rtol = atol = 1e-10, control step by control step, since the ramps' rates jump there).
Reported: the contact error against the reference (maximum over the path), the distance
travelled, and whether the replay at the env's own step reproduces the env's states to the bit.
``--no-motor-limit`` replays the same ramps on a servo without the env's torque and rate limits.

Also measured: the amplification (m/rad) of a small error by the path itself, from the reference
solved again with each start's first leg angle PERTURBATION_RAD larger.

``--refine-switches`` (motor limits only): the replay substep by substep, a substep across which
a leg's motor changes branch (unsaturated, stall torque, torque-speed line) taken again in REFINE
substeps, a stand-in for splitting it at the switch (what locating the switches would buy).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import gymnasium as gym
import numpy as np

import rrrobot_gym  # noqa: F401  (registers RRRobot-v0)
from rrrobot_gym.control import RampTargets, motor_torque, pd_torque
from rrrobot_gym.simulation import SimConfig, _substeps, advance, simulate_reference

from ._common import contact_error, fmt, machine, markdown_table, parser, write_json

MODEL = Path(__file__).resolve().parent.parent / "agents" / "pretrained" / "best_model.zip"
STEPS_S = (1 / 300, 1 / 400, 1 / 600, 1 / 1200)
"""RK4 steps replayed; 1/300 s is the default."""
REFINE = 64
"""--refine-switches: a substep across a saturation switch is taken again in this many."""
PERTURBATION_RAD = 1e-7
"""The start change of the sensitivity run: small enough that the deviation stays linear in it,
large enough to stand above the reference's own error (1.4 um after 20 s on the pivot policy)."""


def settings():
    """(label, step) of each replay."""
    return [(f"1/{1 / h:.0f} s", h) for h in STEPS_S]


def rollout(agent, heading_deg: float, n_steps: int, seed: int = 0):
    """(states (n + 1, 13), ramp starts (n, 2), ramp ends (n, 2), control step, simulator config) of one episode."""
    # the whole path, even where it leaves the model, on the nominal robot (the replay's)
    kwargs = {**agent.env_config, "terminate_outside_model": False, "randomize": None}
    env = gym.make("RRRobot-v0", max_episode_steps=n_steps, **kwargs)
    obs, _ = env.reset(seed=seed, options={"target_direction": math.radians(heading_deg)})
    env_core = env.unwrapped
    if env_core.config.action_hold != "linear":
        raise ValueError(f"the replay ramps the targets; this policy's env holds them {env_core.config.action_hold!r}")
    states, starts, ends = [env_core.state.copy()], [], []
    for _ in range(n_steps):
        action, _ = agent.predict(obs, deterministic=True)
        starts.append(env_core.leg_targets.copy())
        obs, _, terminated, truncated, _ = env.step(action)
        ends.append(env_core.leg_targets.copy())
        states.append(env_core.state.copy())
        if terminated:
            raise RuntimeError(f"the episode along {heading_deg} deg ended early")
    dt = env_core.dt
    env.close()
    return np.array(states), np.array(starts), np.array(ends), dt, env_core.config.sim


def rollouts(agent, headings, n_steps: int):
    """The episodes of :func:`rollout` along each heading, as batches: (env states (N, n + 1, 13),
    starts' states (N, 13), ramp starts (N, n, 2), ramp ends (N, n, 2), control step, simulator config)."""
    episodes = [rollout(agent, heading, n_steps) for heading in headings]
    env_states, starts, ends = (np.array([e[k] for e in episodes]) for k in range(3))
    return env_states, env_states[:, 0].copy(), starts, ends, episodes[0][3], episodes[0][4]


def error_fields(err, headings) -> dict:
    """The JSON's summary of contact errors or deviations ``err`` (n + 1, N), m."""
    return {
        "contact_max_m": float(err.max()),
        "contact_end_m": float(err[-1].max()),
        "per_heading_max_m": {f"{h:g}": float(e) for h, e in zip(headings, err.max(axis=0))},
    }


def described(row) -> str:
    """A row's errors as printed: the worst, then each heading's (mm)."""
    per_heading = ", ".join(f"{h} deg {v * 1e3:.3g}" for h, v in row["per_heading_max_m"].items())
    return f"max contact error {row['contact_max_m'] * 1e3:.3g} mm ({per_heading})"


def sensitivity(config: SimConfig, start, starts, ends, dt: float, ref, headings):
    """The reference's contact deviation (n + 1, N) when each start's first leg angle is
    PERTURBATION_RAD larger, and its summary for the JSON."""
    perturbed = start.copy()
    perturbed[:, 6] += PERTURBATION_RAD
    path, _ = replay(config, perturbed, starts, ends, dt, reference=True)
    dev = contact_error(path, ref)
    n = dev.shape[0] - 1
    return dev, {
        "perturbation_rad": PERTURBATION_RAD,
        "contact_max_m": float(dev.max()),
        "amplification_m_per_rad": float(dev.max() / PERTURBATION_RAD),
        "per_heading_max_m": {f"{h:g}": float(e) for h, e in zip(headings, dev.max(axis=0))},
        # the worst heading's deviation every 5 s (a control step is dt)
        "max_m_every_5_s": [float(dev[: i + 1].max()) for i in range(0, n + 1, round(5.0 / dt))],
    }


def motor_branches(config: SimConfig, state, targets, t: float):
    """Per leg of one robot (state (13,)), which branch of control.motor_torque gives its torque at
    time t: 0 unsaturated; 1 or 2 cut to the stall torque from above or below; 3 or 4 cut to the
    torque-speed line (the leg turning the way it pushes). The derivative is smooth within a branch."""
    angles, rates = (float(state[6]), float(state[7])), (float(state[11]), float(state[12]))
    wanted = pd_torque(config.gains, angles, rates, targets.leg_targets(t))
    out = []
    for tau, rate in zip(wanted, rates):
        given = motor_torque(tau, rate, config.torque_limit, config.leg_rate_limit)
        if given == tau:
            out.append(0)
        else:
            on_line = config.leg_rate_limit is not None and (rate > 0.0 if given < tau else rate < 0.0)
            out.append((3 if on_line else 1) if given < tau else (4 if on_line else 2))
    return tuple(out)


def replay_refined(config: SimConfig, start, starts, ends, dt: float, refine: int):
    """Contact points (n + 1, N, 2) of the episodes replayed substep by substep, each with
    ``advance`` (one call a substep, a robot at a time), a substep across which a motor changes
    branch (:func:`motor_branches`) taken again in ``refine`` substeps; and how many were."""
    n_sub, h = _substeps(dt, config.step)  # advance's own substeps
    fine = replace(config, timestep=h / refine)
    out = np.empty((starts.shape[1] + 1, start.shape[0], 2))
    refined = 0
    for j, state in enumerate(start):
        out[0, j] = state[:2]
        for i in range(starts.shape[1]):
            targets = RampTargets(starts[j, i], ends[j, i], 0.0, dt)
            for s in range(n_sub):
                t = s * h
                new = advance(config, state, t, h, targets, check=False)
                if refine > 1 and motor_branches(config, state, targets, t) != motor_branches(config, new, targets, t + h):
                    new = advance(fine, state, t, h, targets, check=False)
                    refined += 1
                state = new
            out[i + 1, j] = state[:2]
    return out, refined


def replay(config: SimConfig, start, starts, ends, dt: float, reference: bool = False, whole: bool = False):
    """Contact points (n + 1, N, 2) of the batch of episodes replayed control step by control step,
    each from t = 0 as the envs step (``whole``: the whole states, (n + 1, N, 13)), and the last states."""
    kept = slice(None) if whole else slice(0, 2)
    state = start.copy()
    out = [state[:, kept].copy()]
    for i in range(starts.shape[1]):
        targets = RampTargets(starts[:, i], ends[:, i], 0.0, dt)
        if reference:
            state = simulate_reference(config, targets, dt, state=state, sample_dt=dt).states[-1]
        else:
            state = advance(config, state, 0.0, dt, targets, check=False)  # as the envs call it
        out.append(state[:, kept].copy())
    return np.array(out), state


def main(argv=None):
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--headings", nargs="+", type=float, default=[0.0, 90.0, 180.0, 270.0], metavar="DEG")
    p.add_argument("--model", default=str(MODEL), metavar="ZIP", help="the PPO policy (default: the shipped one)")
    p.add_argument(
        "--no-motor-limit", action="store_true",
        help="replay the same ramps on a servo without the env's torque and rate limits (their kinks are "
        "where fixed steps lose their order)",
    )  # fmt: skip
    p.add_argument(
        "--refine-switches", action="store_true",
        help=f"also replay substep by substep, taking a substep across a motor's saturation switch again in {REFINE} "
        "(what locating the switches would buy; needs the motor limits)",
    )  # fmt: skip
    args = p.parse_args(argv)
    if args.refine_switches and args.no_motor_limit:
        p.error("--refine-switches refines the motor limits' switches; --no-motor-limit drops them")
    from rrrobot_gym.agents.ppo import load_ppo_agent

    agent = load_ppo_agent(args.model)
    duration = 10.0 if args.quick else 50.0
    env_states, start, starts, ends, dt, sim = rollouts(agent, args.headings, round(duration / 0.05))
    if args.no_motor_limit:
        sim = replace(sim, torque_limit=None, leg_rate_limit=None)
    if args.refine_switches and sim.torque_limit is None:
        raise SystemExit(f"--refine-switches: this policy's env has no motor limits ({sim!r})")
    print(f"{len(args.headings)} episodes of {duration:g} s, control step {dt:g} s, {sim!r}", flush=True)

    ref, _ = replay(sim, start, starts, ends, dt, reference=True)
    lengths = np.hypot(*(ref[-1] - ref[0]).T)  # m, start to end
    _, sens = sensitivity(sim, start, starts, ends, dt, ref, args.headings)
    print(
        f"reference from starts with the first leg angle {PERTURBATION_RAD:g} rad larger: contact moves "
        f"{sens['contact_max_m'] * 1e3:.3g} mm at most ({sens['amplification_m_per_rad']:.3g} m/rad; by 5 s "
        + ", ".join(f"{v * 1e3:.2g}" for v in sens["max_m_every_5_s"][1:]) + " mm)",
        flush=True,
    )
    rows, refined_rows = [], []
    for label, step in settings():
        config = replace(sim, timestep=step)  # the env's own (a torque limit included)
        path, _ = replay(config, start, starts, ends, dt)
        err = contact_error(path, ref)  # (n + 1, N)
        row = {
            "integrator": "rk4",
            "setting": label,
            "step_s": step,
            "evals_per_env_step": 4 * round(dt / step),
            **error_fields(err, args.headings),
        }
        if config == sim and not args.no_motor_limit:
            row["reproduces_env"] = bool(np.array_equal(path, env_states[:, :, :2].transpose(1, 0, 2)))
        rows.append(row)
        extra = f", reproduces the env's states to the bit: {row['reproduces_env']}" if "reproduces_env" in row else ""
        print(f"rk4 {label} ({row['evals_per_env_step']} evaluations an env step): {described(row)}{extra}", flush=True)
    if args.refine_switches:
        for label, step in settings():
            config = replace(sim, timestep=step)
            for refine in (1, REFINE):
                path, refined = replay_refined(config, start, starts, ends, dt, refine)
                err = contact_error(path, ref)
                row = {
                    "integrator": "rk4, substep by substep" + (f", switches' substeps in {refine}" if refine > 1 else ""),
                    "setting": label,
                    "step_s": step,
                    "refine": refine,
                    "substeps_refined": refined,
                    **error_fields(err, args.headings),
                }
                refined_rows.append(row)
                print(f"{row['integrator']} {label} ({refined} substeps refined): {described(row)}", flush=True)
    print("distance travelled (reference, start to end): " + ", ".join(f"{h:g} deg {length:.2f} m" for h, length in zip(args.headings, lengths)))
    print(
        markdown_table(
            ["RK4 step", "evaluations / env step", "max contact error (mm)"] + [f"{h:g} deg" for h in args.headings],
            [[r["setting"], r["evals_per_env_step"], fmt(r["contact_max_m"] * 1e3)]
             + [fmt(v * 1e3) for v in r["per_heading_max_m"].values()] for r in rows],
        )  # fmt: skip
    )
    write_json(
        args.json,
        {
            "machine": machine(),
            "duration_s": duration,
            "model": args.model,
            "config": repr(sim),
            "no_motor_limit": args.no_motor_limit,
            "headings_deg": args.headings,
            "distance_m": {f"{h:g}": float(length) for h, length in zip(args.headings, lengths)},
            "sensitivity": sens,
            **({"refined_switch_rows": refined_rows} if args.refine_switches else {}),
            "rows": rows,
        },
    )


if __name__ == "__main__":
    main()
