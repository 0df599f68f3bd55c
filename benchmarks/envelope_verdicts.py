"""What the model checks' quadrature and the step change in the README's plane evaluation.

    python -m benchmarks.envelope_verdicts [--quick] [--json FILE]

Runs the README's evaluation command (``evaluate.py`` with the searched gaits and the
turn-then-run baseline, ``--models plane``, without plots or the accuracy check) once per
physics setting below, each through ``evaluate.main`` with ``--physics`` keywords, and compares
the 160 runs on the compass headings (20 agents x 8 headings; the runs along the gaits' own
directions are left out, since each setting re-measures those directions) with the setting
named as each one's baseline: which runs end differently (one ends early, the other runs the
50 s; ``--quick``: 10 s) with their speeds under both, and, among the others, the largest change
of speed along the heading.
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

from ._common import machine, markdown_table, parser, write_json

ROOT = Path(__file__).resolve().parent.parent
EVALUATION = ["--gaits", "agents/searched/plane_own.json", "--gaits", "agents/searched/plane_own_robust.json",
              "--gaits", "agents/searched/pivot_own_limited.json", "--gaits", "agents/searched/plane_heading180.json",
              "--turn-then-run", "agents/searched/turn_then_run.json",
              "--turn-then-run", "agents/searched/turn_then_run_pivot.json", "--models", "plane"]  # fmt: skip
"""The README's evaluation command's agents (its plane part)."""
LOCKED_200 = ("integrator=rk4_locked", "timestep=0.005", "frame_skip=10")
ETD_16 = ("integrator=etdrk4b", "timestep=0.016666666666666666", "frame_skip=3", "start_halves=1")
SETTINGS = {
    "default": (),
    "trapezoid": ("contact_quadrature=trapezoid",),
    "rk4_locked 1/200 s": LOCKED_200,
    "rk4_locked 1/200 s, trapezoid": LOCKED_200 + ("contact_quadrature=trapezoid",),
    "etdrk4b 1/60 s, start_halves=1, trapezoid": ETD_16 + ("contact_quadrature=trapezoid",),
}
"""name: the ``--physics`` keywords of each setting."""
COMPARISONS = [
    ("trapezoid", "default"),
    ("rk4_locked 1/200 s", "default"),
    ("rk4_locked 1/200 s, trapezoid", "trapezoid"),
    ("etdrk4b 1/60 s, start_halves=1, trapezoid", "trapezoid"),
]
"""(setting, its baseline)."""


def compass_runs(physics, duration: float) -> dict:
    """{(agent, heading_deg): (ended early, speed m/s)} of the compass runs of one evaluation."""
    from rrrobot_gym import evaluation

    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "records.json"
        args = [*EVALUATION, "--duration", str(duration), "--json", str(out)]
        for keyword in physics:
            args += ["--physics", keyword]
        evaluation.main(args, default_policy=ROOT / "agents" / "pretrained" / "best_model.zip",
                        default_pivot_policy=ROOT / "agents" / "pretrained_pivot" / "best_model.zip")
        records = json.loads(out.read_text())
    records = records["records"] if isinstance(records, dict) else records
    return {(r["agent"], round(r["heading_deg"])): (bool(r["terminated"]), r["speed_mps"])
            for r in records if r["model"] == "plane" and r["compass"]}  # fmt: skip


def compare(runs: dict, baseline: dict) -> dict:
    changed = sorted(key for key in runs if runs[key][0] != baseline[key][0])
    same = [key for key in runs if runs[key][0] == baseline[key][0]]
    worst = max(same, key=lambda key: abs(runs[key][1] - baseline[key][1]))
    return {
        "runs": len(runs),
        "ended_early": sum(ended for ended, _ in runs.values()),
        "baseline_ended_early": sum(ended for ended, _ in baseline.values()),
        "verdicts_changed": len(changed),
        "now_ended": [f"{agent} {heading} deg" for agent, heading in changed if runs[agent, heading][0]],
        "now_running": [f"{agent} {heading} deg" for agent, heading in changed if not runs[agent, heading][0]],
        "changed_speeds_mm_s": {f"{agent} {heading} deg": [baseline[agent, heading][1] * 1e3, runs[agent, heading][1] * 1e3]
                                for agent, heading in changed},  # fmt: skip
        "max_speed_change_mm_s": abs(runs[worst][1] - baseline[worst][1]) * 1e3,
        "at": f"{worst[0]} {worst[1]} deg",
    }


def main(argv=None):
    p = parser(__doc__.splitlines()[0])
    args = p.parse_args(argv)
    duration = 10.0 if args.quick else 50.0
    runs = {name: compass_runs(physics, duration) for name, physics in SETTINGS.items()}
    rows = []
    for name, base in COMPARISONS:
        rows.append({"setting": name, "physics": list(SETTINGS[name]), "baseline": base, **compare(runs[name], runs[base])})
    for r in rows:
        print(f"{r['setting']} against {r['baseline']}: {r['verdicts_changed']} of {r['runs']} verdicts changed "
              f"(now ended: {', '.join(r['now_ended']) or '-'}; now running: {', '.join(r['now_running']) or '-'}); "
              f"largest speed change otherwise {r['max_speed_change_mm_s']:.3f} mm/s ({r['at']})", flush=True)  # fmt: skip
        if r["now_running"]:
            print("  speeds (mm/s, baseline -> setting) of the runs that now run: " + ", ".join(
                f"{run} {r['changed_speeds_mm_s'][run][0]:.2f} -> {r['changed_speeds_mm_s'][run][1]:.2f}" for run in r["now_running"]))
    print(markdown_table(
        ["setting", "against", "runs ended early (baseline)", "verdicts changed", "largest speed change otherwise (mm/s)"],
        [[r["setting"], r["baseline"], f"{r['ended_early']} ({r['baseline_ended_early']})", r["verdicts_changed"],
          f"{r['max_speed_change_mm_s']:.3f}"] for r in rows],
    ))  # fmt: skip
    write_json(args.json, {"machine": machine(), "duration_s": duration, "evaluation": EVALUATION, "rows": rows})


if __name__ == "__main__":
    main()
