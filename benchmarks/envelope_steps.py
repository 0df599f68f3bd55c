"""How the model envelope's verdict depends on the integration step, for the shipped baselines.

    python -m benchmarks.envelope_steps [--quick] [--json FILE] [--headings 90 ...]
        [--substeps 13 15 20 30 60 120] [--quadrature rectangle trapezoid] [--integrator rk4]
        [--gaits FILE ...]

The env ends an episode on the plane when a step's slip velocity (the impulse the floor could
not give, per unit mass: ``rrrobot_gym.validity.step_measures``) exceeds ``max_slip_velocity``
(0.02 m/s), or a spell without contact outlasts ``max_liftoff_time``. Both are sums over the
step record's samples, one at the start of each integration substep, so by the env's default
``contact_quadrature="rectangle"`` (each sample standing for its substep) they depend on the
step; ``"trapezoid"`` (a line between samples) is the opt-in that converges. The searched
gaits were chosen by searches run at the default step (1/300 s), and the strongest sit close
to that threshold. This runs each shipped plane baseline below (AGENTS)
along each heading for 50 s (--quick: 10 s) at ``frame_skip`` n and ``timestep`` 0.05 s / n,
the same 0.05 s control step, and reports the largest slip velocity and lift-off spell of any
step after ``STARTUP_GRACE``, and when the episode ended if it did, under each ``--quadrature``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rrrobot_gym.agents import load_gait_agents
from rrrobot_gym.agents.turn_then_run import load_turn_then_run_agent
from rrrobot_gym.evaluation import run_episodes
from rrrobot_gym.envs.task import STARTUP_GRACE, make_task_config
from rrrobot_gym.validity import QUADRATURES

from ._common import machine, markdown_table, parser, write_json

SEARCHED = Path(__file__).resolve().parent.parent / "agents" / "searched"
AGENTS = (
    ("plane_own.json", "searched-plane-own-1"),
    ("plane_own.json", "searched-plane-own-2"),
    ("plane_own_robust.json", "searched-plane-own-1"),
    ("plane_own_robust.json", "searched-plane-own-2"),
    ("turn_then_run.json", "turn-then-run"),
    ("../pretrained/best_model.zip", "ppo"),
)
"""(file of agents/searched, agent): the plane baselines that docs/evaluation scores, and the
shipped PPO policy, whose every action kicks the servo."""


def load(file: str, name: str):
    if name == "ppo":
        from rrrobot_gym.agents import load_ppo_agent

        return load_ppo_agent(SEARCHED / file)
    if name == "turn-then-run":
        return load_turn_then_run_agent(SEARCHED / file)
    return load_gait_agents(SEARCHED / file)[name]


def run(agents: dict, substeps: int, headings_deg, duration: float, quadrature: str = "rectangle",
        integrator: str = "rk4") -> dict:
    """Each agent's episodes along each heading at ``substeps`` a control step, in one batched env
    (evaluate.run_episodes): the largest slip velocity (m/s) and lift-off spell (s) of the steps
    after STARTUP_GRACE, and when each episode ended (s, or None), the env's measures integrated
    by ``quadrature`` (its ``contact_quadrature``), the physics stepped by ``integrator``."""
    runs = run_episodes(agents, "plane", headings_deg, duration, info_keys=("slip_velocity", "liftoff_time"),
                        timestep=0.05 / substeps, frame_skip=substeps, contact_quadrature=quadrature,
                        integrator=integrator)  # fmt: skip
    first = math.ceil(STARTUP_GRACE / 0.05 - 1e-9)  # the first step that starts after the grace
    out = {}
    for name, episode in runs.items():
        # a step after an episode's end is NaN: it counts as nothing
        slip, liftoff = (np.where(np.isnan(episode[key]), 0.0, episode[key])[first:].max(axis=0)
                         for key in ("slip_velocity", "liftoff_time"))  # fmt: skip
        # an ended episode's path holds its last position at the end of the step that ended it, then NaN
        last = np.isfinite(episode["xy"][:, :, 0]).sum(axis=0) - 1
        ended = [float(episode["times"][i]) if gone else None for i, gone in zip(last, episode["terminated"])]
        out[name] = {"slip_velocity_max_mps": slip.tolist(), "liftoff_time_max_s": liftoff.tolist(), "ended_at_s": ended}
    return out


def main(argv=None):
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--headings", nargs="+", type=float, default=[90.0], metavar="DEG")
    p.add_argument("--substeps", nargs="+", type=int, default=[13, 15, 20, 30, 60, 120])
    p.add_argument("--quadrature", nargs="+", default=["rectangle"], choices=QUADRATURES,
                   help="the env's contact_quadrature (each is run)")
    p.add_argument("--integrator", default="rk4", help="the env's integrator (default rk4; e.g. rk4_locked)")
    p.add_argument("--gaits", nargs="+", default=[], metavar="FILE", help="also every gait of these gait-search files")
    args = p.parse_args(argv)
    for substeps in args.substeps:  # (the env's own checks: RK4's stability limit is 1/138 s on the plane)
        try:
            make_task_config(integrator=args.integrator, timestep=0.05 / substeps, frame_skip=substeps)
        except (TypeError, ValueError) as exc:
            p.error(f"--substeps {substeps} with --integrator {args.integrator}: {exc}")
    duration = 10.0 if args.quick else 50.0
    listed = [(file, name, load(file, name)) for file, name in AGENTS]
    for path in args.gaits:  # (a search's file: every gait in it, after the shipped baselines)
        listed += [(path, name, agent) for name, agent in load_gait_agents(Path(path)).items()]
    agents = {f"{file}: {name}": agent for file, name, agent in listed}
    rows = []
    cases = [(quadrature, substeps) for quadrature in args.quadrature for substeps in args.substeps]
    results = {case: run(agents, case[1], args.headings, duration, case[0], args.integrator) for case in cases}
    for file, name, _ in listed:
        for quadrature, substeps in cases:
            result = results[quadrature, substeps][f"{file}: {name}"]
            rows.append({"file": file, "agent": name, "quadrature": quadrature, "substeps": substeps,
                         "step_s": 0.05 / substeps, **result})  # fmt: skip
            ends = ", ".join("ran" if t is None else f"ended at {t:.2f} s" for t in result["ended_at_s"])
            print(f"{file} {name}, {quadrature}, 1/{20 * substeps} s: slip up to {max(result['slip_velocity_max_mps']) * 1e3:.2f} mm/s, "
                  f"lift-off spells up to {max(result['liftoff_time_max_s']) * 1e3:.2f} ms; {ends}", flush=True)  # fmt: skip
    print(
        markdown_table(
            ["agent", "quadrature", "step", "largest slip velocity (mm/s)", "longest lift-off (ms)", "ended"],
            [[f"{r['file']}: {r['agent']}", r["quadrature"], f"1/{20 * r['substeps']} s", f"{max(r['slip_velocity_max_mps']) * 1e3:.2f}",
              f"{max(r['liftoff_time_max_s']) * 1e3:.2f}",
              ", ".join("-" if t is None else f"{t:.2f} s" for t in r["ended_at_s"])] for r in rows],
        )  # fmt: skip
    )
    write_json(args.json, {"machine": machine(), "duration_s": duration, "headings_deg": args.headings,
                           "quadratures": args.quadrature, "integrator": args.integrator, "rows": rows})  # fmt: skip


if __name__ == "__main__":
    main()
