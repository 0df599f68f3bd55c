"""Algorithms side by side on one task and one wall-clock budget: ``train.py --algo A,B,... --seeds K``.

    python train.py --algo ppo,sac,td3,tqc --seeds 3 --max-minutes 20 --bar 77.57 \\
        --summary-dir docs/training/algorithms

Runs K seeds of each algorithm as ``--seeds`` runs them (:mod:`rrrobot_gym.seeds`): train.py runs
with every other option as given and each algorithm's own defaults
(:data:`rrrobot_gym.hyperparams.ALGO_DEFAULTS`), so each trains the same env, is evaluated the same
way and keeps its best model by the same rule, and each ends after ``--max-minutes`` (required:
the budget they share) or its ``--total-timesteps``. Each run takes its algorithm's
``--torch-threads`` unless that is given (PPO's default two, the off-policy ones' one), as a lone
``python train.py --algo A`` would. The runs go in the order seed by seed and, within a seed,
algorithm by algorithm, as many at once as the cores hold for the largest ``--torch-threads`` among
them (:func:`rrrobot_gym.seeds.runs_at_once`): by default one by one on two cores, each alone on
the machine; ``--torch-threads 1`` runs two at once there. With ``--ray-address`` each is a Ray task.

Writes ``runs/RRRobot-v0__<exp_name>__algorithms__seeds<first>-<last>__<unix time>/``: each run's
folder (``RRRobot-v0__<algo>__<seed>__<time>``), its output in ``<algo>_seed<S>.log``, and
``summary.json``, ``summary.md`` and ``learning_curves.png`` (also into ``--summary-dir``).

``summary.json`` (schema ``rrrobot_gym.algorithms/1``): ``bar_mm_s``, ``bar_source``,
``budget_minutes``, ``seeds``, ``first_seed``, ``select_by``, ``command``, ``wall_time_s`` and
``algorithms``, one entry an algorithm, in ``--algo``'s order:

- ``settings``: its train.py settings (``rrrobot_gym.hyperparams.SETTINGS``, ``num_envs``,
  ``total_timesteps``, ``torch_threads``, ``eval_freq``), from its first run's ``args.json``;
- ``runs``: one a seed, :func:`rrrobot_gym.seeds.seed_record`'s (the best model's worst and mean
  heading speed, its evaluation, the time to the bar) plus ``curve``: at each evaluation
  ``wall_time_s``, ``timesteps``, ``worst_heading_mm_s`` and ``train_episode_s`` (the mean
  length of the last 100 training episodes, s: short ones mean the robots leave the model);
- ``worst_heading_mm_s``: ``worst`` (the worst seed's) and ``mean`` (over the seeds) of the ok
  runs' worst-heading speeds; ``mean_heading_mm_s``: the mean of their mean-heading speeds;
  ``worst_heading_iqm``: their interquartile mean with its 95 % bootstrap interval
  (:func:`rrrobot_gym.seeds.iqm_interval`, rliable); ``reached_bar``, ``failed_runs``.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

from . import hyperparams as hp
from .envs.task import kwargs_from_json, make_task_config
from .seeds import bar_of, iqm_interval, run_rows, seed_record, write_summary

SCHEMA = "rrrobot_gym.algorithms/1"
FIGURE = "learning_curves.png"
SHOWN_SETTINGS = ("num_envs", "total_timesteps", "torch_threads", "eval_freq")
"""train.py options recorded with each algorithm's settings, besides its own (hyperparams.SETTINGS)."""


def run_algorithms(args, rows, env_id: str, trained: dict) -> Path:
    """train.py --algo A,B,... --seeds K (``args``: its Args; ``rows``: (algo, seed, the run's train.py
    command line), :func:`rrrobot_gym.training.seed_argv`'s, in the order they run; run folders named
    ``env_id``__algo__...; ``trained``: the env keywords as JSON): the runs, then the summary (module
    docstring). The folder."""
    start = time.monotonic()
    algos = args.algo.split(",")
    bar, source = bar_of(args, trained)
    seeds = range(args.seed, args.seed + args.seeds)
    folder = Path(args.runs_dir) / f"{env_id}__{args.exp_name}__algorithms__seeds{seeds[0]}-{seeds[-1]}__{int(time.time())}"
    folder.mkdir(parents=True, exist_ok=False)
    print(f"{', '.join(algos)}: seeds {seeds[0]} ... {seeds[-1]} of each, {args.max_minutes:g} minutes a run, into "
          f"{folder}", flush=True)
    results = run_rows(args, [(seed, argv, f"{algo}_seed{seed}.log") for algo, seed, argv in rows], folder,
                       labels=[f"{algo} " for algo, *_ in rows])
    by_algo = {algo: [result for result, row in zip(results, rows) if row[0] == algo] for algo in algos}
    summary = summarize(folder, by_algo, bar, source, args, env_id)
    summary.update(command=" ".join([sys.executable, *sys.argv]), wall_time_s=round(time.monotonic() - start, 3))
    table = markdown(summary)
    write_summary(summary, table, [folder, args.summary_dir])
    for out in filter(None, [folder, args.summary_dir]):
        figure(summary, Path(out) / FIGURE)
    print(table, flush=True)
    return folder


def curve(folder: Path, run_dir: str | None) -> dict | None:
    """A run's evaluations (``evaluations.npz`` in ``folder/run_dir``) as lists, or None without them."""
    npz = None if run_dir is None else folder / run_dir / "evaluations.npz"
    if npz is None or not npz.is_file():
        return None
    with np.load(npz) as data:
        episodes = data["train_episode_steps"] if "train_episode_steps" in data else np.full(len(data["timesteps"]), np.nan)
        dt = make_task_config(**kwargs_from_json(json.loads((folder / run_dir / "env_kwargs.json").read_text()))).dt
        return {"wall_time_s": data["wall_time_s"].tolist(), "timesteps": data["timesteps"].tolist(),
                "worst_heading_mm_s": data["heading_speeds_mm_s"].min(axis=1).tolist(),
                "train_episode_s": [None if np.isnan(steps) else float(steps) * dt for steps in episodes]}


def settings(folder: Path, runs: list, algo: str) -> dict:
    """``algo``'s train.py settings, from its first run's ``args.json`` ({} if none wrote one)."""
    for run in runs:
        if run.get("run_dir") and (folder / run["run_dir"] / "args.json").is_file():
            saved = json.loads((folder / run["run_dir"] / "args.json").read_text())
            return {name: saved[name] for name in (*SHOWN_SETTINGS, *hp.SETTINGS[algo]) if name in saved}
    return {}


def summarize(folder: Path, by_algo: dict, bar: float, source: str, args, env_id: str) -> dict:
    """summary.json's contents (module docstring) for the runs' :func:`rrrobot_gym.seeds.run_one`
    results, ``by_algo`` ({algo: results})."""
    algorithms = {}
    for algo, results in by_algo.items():
        runs = [seed_record(folder, result, bar, args.select_by, f"{env_id}__{algo}__")
                for result in sorted(results, key=lambda r: r["seed"])]
        for run in runs:
            run["curve"] = curve(folder, run["run_dir"])
        ok = [run for run in runs if run["status"] == "ok"]
        worst = [run["worst_heading_mm_s"] for run in ok]
        algorithms[algo] = {
            "settings": settings(folder, runs, algo), "runs": runs,
            "worst_heading_mm_s": {"worst": min(worst), "mean": float(np.mean(worst))} if ok else None,
            "mean_heading_mm_s": float(np.mean([run["mean_heading_mm_s"] for run in ok])) if ok else None,
            "worst_heading_iqm": iqm_interval(worst, args.bootstrap_reps) if ok else None,
            "reached_bar": sum(run.get("time_to_bar_s") is not None for run in runs),
            "failed_runs": sum(run["status"] == "failed" for run in runs),
        }
    return {"schema": SCHEMA, "bar_mm_s": bar, "bar_source": source, "budget_minutes": args.max_minutes,
            "seeds": args.seeds, "first_seed": args.seed, "select_by": args.select_by, "algorithms": algorithms}


def _number(value, form="{:.1f}"):
    return "-" if value is None else form.format(value)


def markdown(summary: dict) -> str:
    """summary.md: the algorithms' table, each run's, and each algorithm's settings."""
    lines = [f"### Algorithms side by side: {summary['seeds']} seeds each from {summary['first_seed']}, "
             f"{summary['budget_minutes']:g} minutes of wall time a run; speeds of each run's best model (mm/s, "
             f"chosen by the {summary['select_by']} heading), bar {summary['bar_mm_s']:.2f} mm/s "
             f"({summary['bar_source']})\n",
             "| algorithm | worst heading, worst seed | worst heading, mean of seeds | worst heading, IQM (95 % CI) "
             "| mean heading, mean of seeds | reached the bar | failed |",
             "|---|---|---|---|---|---|---|"]
    for algo, entry in summary["algorithms"].items():
        worst, iqm = entry["worst_heading_mm_s"] or {}, entry["worst_heading_iqm"]
        interval = "-" if iqm is None else f"{iqm['iqm_mm_s']:.1f} ({iqm['ci95_mm_s'][0]:.1f} to {iqm['ci95_mm_s'][1]:.1f})"
        lines.append(f"| {algo} | {_number(worst.get('worst'))} | {_number(worst.get('mean'))} | {interval} "
                     f"| {_number(entry['mean_heading_mm_s'])} | {entry['reached_bar']} of {len(entry['runs'])} "
                     f"| {entry['failed_runs']} |")
    lines += ["", "| algorithm | seed | worst heading | mean heading | best at (steps) | best at (min) | time to bar "
                  "(min) | env steps in all | last training episodes (s) | status |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for algo, entry in summary["algorithms"].items():
        for run in entry["runs"]:
            best, c = run.get("best_evaluation") or {}, run.get("curve") or {}
            bar_s = run.get("time_to_bar_s")
            status = run["status"] + (f" (exit {run['returncode']}: {run['error']})" if run["status"] == "failed" else "")
            lines.append(f"| {algo} | {run['seed']} | {_number(run.get('worst_heading_mm_s'))} "
                         f"| {_number(run.get('mean_heading_mm_s'))} | {_number(best.get('timesteps'), '{:,}')} "
                         f"| {_number(None if not best else best['wall_time_s'] / 60)} "
                         f"| {_number(None if bar_s is None else bar_s / 60)} "
                         f"| {_number(c['timesteps'][-1] if c else None, '{:,}')} "
                         f"| {_number(c['train_episode_s'][-1] if c else None)} | {status} |")
    lines.append("")
    for algo, entry in summary["algorithms"].items():
        lines.append(f"- {algo}: " + ", ".join(f"{name} {value}" for name, value in entry["settings"].items()))
    lines.append("\nIQM: the interquartile mean of the seeds' worst-heading speeds, 95 % stratified-bootstrap "
                 "interval (rliable). Learning curves: learning_curves.png.")
    return "\n".join(lines) + "\n"


def figure(summary: dict, path: Path) -> None:
    """learning_curves.png: every run's curve, one colour an algorithm (:func:`rrrobot_gym.plotting.plot_learning_curves`)."""
    from .plotting import plot_learning_curves

    curves = {algo: [run["curve"] for run in entry["runs"] if run.get("curve")]
              for algo, entry in summary["algorithms"].items()}
    curves = {algo: runs for algo, runs in curves.items() if runs}
    if curves:
        plot_learning_curves(path, curves, summary["bar_mm_s"],
                             f"RRRobot-v0, {summary['budget_minutes']:g} min a run: worst heading of each evaluation")
