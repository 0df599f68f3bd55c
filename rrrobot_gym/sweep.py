"""A hyperparameter sweep for the wall time to a bar: ``train.py --sweep TRIALS``.

    python train.py --sweep 16 --bar 77.57 --max-minutes 10
    python train.py --sweep 64 --bar 77.57 --max-minutes 10 --ray-address HOST:PORT

optuna's TPE sampler chooses each trial's PPO settings from :data:`SPACE`, the first trial
those given (train.py's defaults, when they are inside the space); a trial is one train.py
run with every other option as given (seed ``--seed``), which ends at its first evaluation whose
worst heading reaches the bar (``--stop-at-speed``) or after ``--max-minutes``. Its score, to
minimise, is :func:`score`: the seconds to the bar, or for a run that misses it ``--max-minutes``
in seconds times (2 - its best worst heading / the bar), so between one and two budgets.
Here trials run as ``--seeds``' runs do (on one torch thread each unless ``--torch-threads`` is
given, as many at once as the cores hold: :func:`rrrobot_gym.seeds.runs_at_once`); with
``--ray-address`` each is a Ray task, its files gathered here, as ``--seeds``' runs
(:mod:`rrrobot_gym.seeds`).

Writes ``runs/RRRobot-v0__<exp_name>__sweep__<unix time>/``: each trial's run folder and log
(``trial<N>.log``), and ``summary.json`` (schema ``rrrobot_gym.sweep/1``: the bar, the budget, the
space, every trial's settings, status, ``time_to_bar_s``, ``timesteps_to_bar``, best
``worst_heading_mm_s`` and ``score``, sorted by score, and the best trial's train.py options) and
``summary.md``.
"""

from __future__ import annotations

import json
import math
import sys
import threading
import time
from pathlib import Path

SCHEMA = "rrrobot_gym.sweep/1"
SPACE = {
    "learning_rate": ("log-uniform", (1e-4, 2e-3)),
    "num_envs": ("choice", (128, 256, 512, 1024)),
    "n_steps": ("choice", (16, 32, 64)),
    "batch_size": ("choice", (2048, 4096, 8192, 16384)),
    "n_epochs": ("integer", (2, 8)),
    "ent_coef": ("choice", (0.0, 1e-4, 1e-3, 1e-2)),
    "log_std_init": ("choice", (-2.0, -1.5, -1.0, -0.5)),
}
"""The swept train.py options: {option: (kind, range or choices)}; a batch size above a rollout
(num_envs x n_steps) is taken as the whole rollout."""


def suggest(trial) -> dict:
    """One trial's settings from :data:`SPACE` (optuna's ``trial``)."""
    settings = {}
    for name, (kind, values) in SPACE.items():
        if kind == "log-uniform":
            settings[name] = trial.suggest_float(name, *values, log=True)
        elif kind == "integer":
            settings[name] = trial.suggest_int(name, *values)
        else:
            settings[name] = trial.suggest_categorical(name, values)
    settings["batch_size"] = min(settings["batch_size"], settings["num_envs"] * settings["n_steps"])
    return settings


def score(record: dict, bar: float, budget_s: float) -> float:
    """A trial's score (s, lower is better) from its summary record (:func:`rrrobot_gym.seeds.seed_record`):
    its time to the bar, else the budget times (2 - its best worst heading / bar), clipped to
    [1, 2] budgets; a run that failed or never evaluated scores three budgets."""
    if record.get("time_to_bar_s") is not None:
        return float(record["time_to_bar_s"])
    if record["status"] != "ok":
        return 3.0 * budget_s
    return budget_s * (2.0 - min(1.0, max(0.0, record["worst_heading_mm_s"] / bar)))


def run_sweep(args, argv: list, child_argv, env_id: str, trained: dict) -> Path:
    """train.py --sweep (``args``: its Args; ``argv``: its command line; ``child_argv(argv, seed,
    settings)``: a trial's train.py command line (:func:`rrrobot_gym.training.seed_argv`); run
    folders are named ``env_id``__exp_name__...; ``trained``: the env keywords as JSON)."""
    import optuna

    from .seeds import bar_of, run_one, run_remote, runs_at_once, seed_record, torch_threads

    start = time.monotonic()
    bar, source = bar_of(args, trained)
    budget_s = 60.0 * args.max_minutes
    folder = Path(args.runs_dir) / f"{env_id}__{args.exp_name}__sweep__{int(time.time())}"
    folder.mkdir(parents=True, exist_ok=False)
    print(f"sweep of {args.sweep} trials into {folder}: bar {bar:.2f} mm/s, {args.max_minutes:g} min each", flush=True)
    records, lock = [], threading.Lock()

    def objective(trial):
        settings = suggest(trial)
        name = f"{args.exp_name}_t{trial.number}"
        trial_argv = child_argv(argv, args.seed, {**settings, "exp_name": name, "stop_at_speed": bar})
        log = f"trial{trial.number}.log"
        if args.ray_address is None:
            result = run_one(args.seed, trial_argv, folder, log)
        else:
            result = run_remote([(args.seed, trial_argv, log)], args.ray_address, folder)[0]
        record = seed_record(folder, result, bar, args.select_by, f"{env_id}__{name}__")
        record = {"trial": trial.number, "settings": settings, **record, "score": score(record, bar, budget_s)}
        with lock:
            records.append(record)
        reached = record.get("time_to_bar_s")
        print(f"trial {trial.number}: {'bar at %.0f s' % reached if reached is not None else 'no bar'}, worst heading "
              f"{record.get('worst_heading_mm_s', math.nan):.1f} mm/s, score {record['score']:.0f}: "
              + ", ".join(f"{k} {v:g}" for k, v in settings.items()), flush=True)
        return record["score"]

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(direction="minimize", sampler=optuna.samplers.TPESampler(seed=args.seed))
    given = {name: getattr(args, name) for name in SPACE}
    if all(values[0] <= given[name] <= values[1] if kind != "choice" else given[name] in values
           for name, (kind, values) in SPACE.items()):
        study.enqueue_trial(given)  # trial 0: the settings given (train.py's defaults): does any trial beat them?
    workers = args.sweep if args.ray_address is not None else runs_at_once(torch_threads(child_argv(argv, args.seed)),
                                                                            args.sweep)
    study.optimize(objective, n_trials=args.sweep, n_jobs=workers)
    records.sort(key=lambda r: (r["score"], r["trial"]))
    summary = {"schema": SCHEMA, "trials": len(records), "seed": args.seed, "bar_mm_s": bar, "bar_source": source,
               "max_minutes": args.max_minutes, "space": {k: [kind, list(v)] for k, (kind, v) in SPACE.items()},
               "records": records, "best_options": _options(records[0]["settings"]) if records else None,
               "reached_bar": sum(r.get("time_to_bar_s") is not None for r in records),
               "wall_time_s": round(time.monotonic() - start, 3), "command": " ".join([sys.executable, *sys.argv])}
    (folder / "summary.json").write_text(json.dumps(summary, indent=1, allow_nan=False) + "\n")
    (folder / "summary.md").write_text(markdown(summary))
    print(markdown(summary), flush=True)
    return folder


def _options(settings: dict) -> str:
    return " ".join(f"--{name.replace('_', '-')} {value:g}" for name, value in settings.items())


def markdown(summary: dict) -> str:
    """summary.md: the trials by score."""
    names = list(SPACE)
    lines = [f"### {summary['trials']} trials, bar {summary['bar_mm_s']:.2f} mm/s ({summary['bar_source']}), "
             f"{summary['max_minutes']:g} min each, seed {summary['seed']}\n",
             "| trial | " + " | ".join(names) + " | time to bar (s) | steps to bar | worst heading (mm/s) | score |",
             "|---" * (len(names) + 5) + "|"]
    for r in summary["records"]:
        reached, settings = r.get("time_to_bar_s"), r["settings"]
        lines.append(f"| {r['trial']} | " + " | ".join(f"{settings[n]:.3g}" if isinstance(settings[n], float)
                                                      else str(settings[n]) for n in names)
                     + f" | {'-' if reached is None else f'{reached:.0f}'} | "
                     + ("-" if r.get("timesteps_to_bar") is None else f"{r['timesteps_to_bar']:,}")
                     + f" | {r.get('worst_heading_mm_s', math.nan):.1f} | {r['score']:.0f} |")
    lines.append(f"\nReached the bar: {summary['reached_bar']} of {summary['trials']} trials.")
    if summary["best_options"]:
        lines.append(f"Best: `python train.py {summary['best_options']}`.")
    return "\n".join(lines) + "\n"
