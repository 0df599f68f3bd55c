"""Time to target: the worst heading's speed against wall time for train.py's earlier defaults and today's.

    python -m benchmarks.time_to_target [--minutes 15] [--bar 77.57] [--seed 1] [--figure FILE] [--json FILE]
    python -m benchmarks.time_to_target --plot LABEL=RUN_DIR [LABEL=RUN_DIR ...] [--figure FILE]

Runs ``python train.py`` twice at once, side by side on their own cores (one torch thread each,
the same seed and evaluation every 250,000 steps): with the PPO settings train.py had before its
defaults were tuned for wall time (:data:`EARLIER`: 64 robots, 256-step rollouts, 10 epochs, tanh,
the learning rate falling over 20 M steps) and with its defaults, each ended after ``--minutes`` of
wall time. Both train the default task (the servo, randomized robots); the evaluations run the
nominal robot on the compass headings. Reports each run's wall time (from its start, imports
included) to the first evaluation whose worst heading reaches ``--bar`` (default: the best
searched gait's own-direction speed under the servo, docs/evaluation) and draws both curves.
``--plot`` draws runs already made (``evaluations.npz`` in each folder or its run folders) instead.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from ._common import machine, markdown_table, parser, write_json

HERE = Path(__file__).resolve().parents[1]
BAR_MM_S = 77.57
"""mm/s: the best searched gait's speed along its own direction from the paper's start under the
default servo (agents/searched, docs/evaluation)."""
EARLIER = {"num_envs": 64, "n_steps": 256, "n_epochs": 10, "batch_size": 4096, "learning_rate": 3e-4, "ent_coef": 0.0,
           "log_std_init": -2.0, "total_timesteps": 20_000_000, "net_arch": "128,128", "activation": "tanh",
           "slip_margin": 0.0, "eval_freq": 250_000}
"""train.py's PPO settings before they were tuned for wall time."""


def curve(run_dir: Path) -> dict:
    """{"wall_time_s", "timesteps", "worst_mm_s"} of the run in ``run_dir`` (or its one run folder)."""
    found = sorted(Path(run_dir).glob("**/evaluations.npz"))
    if len(found) != 1:
        raise SystemExit(f"{run_dir}: expected one evaluations.npz below it, found {len(found)}")
    with np.load(found[0]) as data:
        return {"wall_time_s": data["wall_time_s"].tolist(), "timesteps": data["timesteps"].tolist(),
                "worst_mm_s": data["heading_speeds_mm_s"].min(axis=1).tolist()}


def time_to_bar(c: dict, bar: float):
    """(s, steps) at the first evaluation reaching ``bar``, or (None, None)."""
    reached = np.flatnonzero(np.asarray(c["worst_mm_s"]) >= bar)
    return (c["wall_time_s"][reached[0]], c["timesteps"][reached[0]]) if len(reached) else (None, None)


def train_side_by_side(minutes: float, seed: int, runs_dir: str) -> dict:
    """{label: run folder} of the earlier and today's defaults, run at once for ``minutes``."""
    common = ["--seed", str(seed), "--max-minutes", str(minutes), "--torch-threads", "1", "--no-progress-bar",
              "--eval-freq", str(EARLIER["eval_freq"]), "--runs-dir"]
    earlier = [f"--{k.replace('_', '-')}={v}" for k, v in EARLIER.items() if k != "eval_freq"]
    commands = {"earlier defaults": [*earlier, "--exp-name", "earlier"], "defaults": ["--exp-name", "defaults"]}
    runs = {}
    for label, flags in commands.items():
        folder = Path(runs_dir) / label.replace(" ", "_")
        runs[label] = (folder, subprocess.Popen([sys.executable, "train.py", *flags, *common, str(folder)], cwd=HERE,
                                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True))
    for label, (folder, process) in runs.items():
        if process.wait() != 0:
            raise SystemExit(f"{label}: train.py failed: {process.stderr.read()[-2000:]}")
    return {label: folder for label, (folder, _) in runs.items()}


def figure(curves: dict, bar: float, path: str):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    colours = {}  # (one colour for the seeds of a setting: the label before ", seed")
    for label, c in curves.items():
        setting = label.split(", seed")[0]
        first = setting not in colours
        colour = colours.setdefault(setting, f"C{len(colours)}")
        ax.plot(np.asarray(c["wall_time_s"]) / 60, c["worst_mm_s"], marker=".", ms=3, lw=1, color=colour,
                label=setting if first else None)
    ax.axhline(bar, color="k", ls="--", lw=1, label=f"bar {bar:g} mm/s")
    ax.set(xlabel="wall time (min)", ylabel="worst heading speed (mm/s)", ylim=(0, None),
           title="PPO on RRRobot-v0 (servo, randomized robots): time to target")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")


def main(argv=None):
    p = parser(__doc__.split("\n\n")[0])
    p.add_argument("--minutes", type=float, default=15.0, help="wall-time budget of each run")
    p.add_argument("--bar", type=float, default=BAR_MM_S, help="mm/s the worst heading must reach")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--figure", metavar="FILE", help="write the curves as a PNG")
    p.add_argument("--plot", nargs="+", metavar="LABEL=RUN_DIR", help="draw these runs instead of training")
    args = p.parse_args(argv)
    if args.plot:
        if any("=" not in item for item in args.plot):
            p.error("--plot takes LABEL=RUN_DIR items")
        curves = {label: curve(Path(folder)) for label, folder in (item.split("=", 1) for item in args.plot)}
    else:
        with tempfile.TemporaryDirectory() as runs_dir:
            minutes = 2.0 if args.quick else args.minutes
            curves = {label: curve(folder) for label, folder in train_side_by_side(minutes, args.seed, runs_dir).items()}
    rows = []
    for label, c in curves.items():
        seconds, steps = time_to_bar(c, args.bar)
        rows.append([label, "-" if seconds is None else f"{seconds / 60:.1f}", "-" if steps is None else f"{steps:,}",
                     f"{max(c['worst_mm_s']):.1f}", f"{c['wall_time_s'][-1] / 60:.1f}"])
    table = markdown_table(["run", "minutes to bar", "steps to bar", "best worst heading (mm/s)",
                            "last evaluation (min)"], rows)
    print(table)
    if args.figure:
        figure(curves, args.bar, args.figure)
    write_json(args.json, {"machine": machine(), "bar_mm_s": args.bar, "curves": curves, "table": table})


if __name__ == "__main__":
    main()
