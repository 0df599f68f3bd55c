"""Several seeds of one training configuration, summarised with robust statistics: ``train.py --seeds K``.

    python train.py --seeds 5 --bar 106.8                        # seeds 1 ... 5, here
    python train.py --seeds 5 --seed 10 --bar-from gaits.json    # seeds 10 ... 14; the bar from a gait search
    python train.py --seeds 5 --bar 106.8 --ray-address HOST:PORT   # each run a Ray task on a cluster

Runs K train.py runs, seeds ``--seed`` ... ``--seed`` + K - 1 with every other option as given, into
``runs/RRRobot-v0__<exp_name>__seeds<first>-<last>__<unix time>/``: each run's folder as train.py
writes it (with ``evaluations.npz``), its output in ``seed<S>.log``, and ``summary.json`` and
``summary.md``. Here the runs are subprocesses, each on ``--torch-threads 1`` unless that is given,
at most ``os.cpu_count()`` // that many at once (:func:`runs_at_once`): ``--torch-threads 2`` on two
cores runs them one by one, each as a lone ``python train.py`` runs. With ``--ray-address`` each run is a one-CPU Ray task
(:func:`rrrobot_gym.gait_search.ray_map`, with its one-line errors for a cluster that does not
answer or wants a token) that runs train.py in a temporary folder of its node and returns that
folder's files, written here. Files the runs read (``--resume``, ``--residual-on``) are given to
them by absolute path: on a cluster they must be there on every node.

The summary (``summary.json``, schema ``rrrobot_gym.seeds/1``; ``summary.md`` as tables; both
also in ``--summary-dir`` if given):

- ``algo``: the runs' ``--algo``;
- ``bar_mm_s`` and ``bar_source``: the worst heading's speed a run must reach (``--bar``, or
  ``--bar-from``: the best speed along its own direction from the paper's start among a gait
  search's re-scored gaits, ``robustness.paper_start_speed_mps``, which must have been searched
  under the training's servo and physics);
- ``runs``, one per seed: ``status`` ("ok"; "failed" with ``returncode`` and the log's last line in
  ``error``; "no evaluation" for a run shorter than ``--eval-freq``), ``run_dir``, ``log``,
  ``run_seconds``, ``ray_node_id`` (with ``--ray-address``: the node it ran on), and from
  ``evaluations.npz``: ``best_evaluation`` (the one that chose best_model.zip by ``--select-by``:
  ``timesteps``, ``wall_time_s``), its ``worst_heading_mm_s``, ``mean_heading_mm_s`` and
  ``heading_speeds_mm_s`` ({deg: mm/s}; the nominal robot from the paper's start, the 8 compass
  headings, over ``--episode-steps``), and ``time_to_bar_s`` and ``timesteps_to_bar``: the run's
  wall time (s from its start) and steps at its first evaluation whose worst heading reaches the
  bar (null if none does);
- ``worst_heading_iqm``: the interquartile mean of the ok runs' worst-heading speeds with its
  95 % stratified-bootstrap confidence interval (rliable, Agarwal et al. 2021; ``reps``
  replications, numpy RandomState ``random_seed``), null without such runs;
- ``reached_bar`` (how many seeds reach it), ``failed_runs``, ``wall_time_s`` (the whole command).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

SCHEMA = "rrrobot_gym.seeds/1"
IQM_RANDOM_SEED = 0
"""The bootstrap's numpy RandomState seed: the same runs give the same interval."""


def check_seeds_args(args, trained: dict) -> None:
    """Raise ValueError naming the problem with ``--seeds`` (or ``--sweep``) and its options (train.py's Args;
    ``trained``: the runs' env keywords as JSON, :func:`rrrobot_gym.training.env_config`)."""
    if args.seeds is not None and args.seeds < 1:
        raise ValueError(f"--seeds must be a positive integer, got {args.seeds}")
    if args.seeds is not None and args.seed + args.seeds > 2**32 - 100_000:
        raise ValueError(f"--seed {args.seed} + --seeds {args.seeds} passes the last seed, 2**32 - 100001")
    if (args.bar is None) == (args.bar_from is None):
        raise ValueError(f"--{'seeds' if args.seeds is not None else 'sweep'} needs a bar: give --bar MM_PER_S or "
                         "--bar-from GAIT_SEARCH.json (one of them)")
    if args.bar is not None and not math.isfinite(args.bar):
        raise ValueError(f"--bar must be a finite speed in mm/s, got {args.bar}")
    if args.bootstrap_reps < 1:
        raise ValueError(f"--bootstrap-reps must be a positive integer, got {args.bootstrap_reps}")
    if args.bar_from is not None:
        bar_from_gait_search(args.bar_from, args.model, trained)
    if args.ray_address is not None:  # (before any run: a head that does not answer or wants a token)
        from .gait_search import check_ray_address

        try:
            check_ray_address(args.ray_address)
        except ConnectionError as exc:
            raise ValueError("--ray-address" + str(exc).removeprefix("ray_address")) from None


def bar_from_gait_search(path, model: str, trained: dict) -> tuple:
    """(mm/s, description): the best speed along its own direction from the paper's start among the
    re-scored gaits of gait-search file ``path``, searched on ``model`` under the physics of the
    env keywords ``trained`` (as JSON)."""
    from .evaluation import PHYSICS_KEYWORDS

    try:
        data = json.loads(Path(path).read_text())
        searched_on, searched, gaits = data["model"], data.get("env_kwargs") or {}, list(data["gaits"])
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise ValueError(f"--bar-from {path}: not a readable gait-search JSON ({exc})") from None
    if data.get("objective") != "own":
        raise ValueError(f"--bar-from {path}: a search with objective 'own' (each gait's best direction), not "
                         f"{data.get('objective')!r}")
    if searched_on != model:
        raise ValueError(f"--bar-from {path}: its gaits were searched on the {searched_on} model, not {model}")
    differ = [key for key in sorted(set(PHYSICS_KEYWORDS) | {"leg_accel_limit"})
              if key in searched and key in trained and searched[key] != trained[key]]
    if differ:
        raise ValueError(f"--bar-from {path}: its gaits were searched under "
                         f"{', '.join(f'{k}={searched[k]!r}' for k in differ)}, the runs train under "
                         f"{', '.join(f'{k}={trained[k]!r}' for k in differ)}: give a search of the same robot, or --bar")
    speeds = {gait["name"]: gait["robustness"]["paper_start_speed_mps"] * 1e3 for gait in gaits
              if isinstance(gait.get("robustness"), dict) and not gait["robustness"].get("paper_start_terminated")}
    if not speeds:
        raise ValueError(f"--bar-from {path}: no gait re-scored from the paper's start (robustness) stays in the model")
    name = max(speeds, key=speeds.get)
    return speeds[name], f"{path}: {name}, along its own direction from the paper's start"


def run_one(seed: int, argv: list, runs_dir, log: str | None = None) -> dict:
    """Run train.py's ``argv`` into ``runs_dir`` in a subprocess, its output in ``log`` there
    (default ``seed<S>.log``). The subprocess runs in ``runs_dir``: ``python -m`` puts its working
    directory first on the path, and a Ray worker's (where ``ray start`` ran) may hold another
    copy of this package."""
    package_root = str(Path(__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([package_root, *filter(None, [os.environ.get("PYTHONPATH")])])}
    runs_dir = Path(runs_dir).resolve()
    log = log or f"seed{seed}.log"
    start = time.monotonic()
    with (runs_dir / log).open("w") as out:
        returncode = subprocess.run([sys.executable, "-m", "rrrobot_gym.training", *argv, "--runs-dir", str(runs_dir)],
                                    stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env,
                                    cwd=runs_dir).returncode
    return {"seed": seed, "returncode": returncode, "run_seconds": round(time.monotonic() - start, 3), "log": log}


def _reported(result: dict, label: str = "") -> dict:
    ended = "done" if result["returncode"] == 0 else f"failed (exit {result['returncode']})"
    print(f"{label}seed {result['seed']}: {ended} after {result['run_seconds']:.0f} s", flush=True)
    return result


def run_rows(args, rows, folder: Path, labels=None) -> list:
    """:func:`run_one` of each row ((seed, argv) or (seed, argv, log)) into ``folder``: here, as many
    at once as the cores hold for the rows' largest ``--torch-threads`` (:func:`runs_at_once`),
    in the rows' order; or each a Ray task with ``args.ray_address``. Reports each as it ends
    (``labels``: a text before each row's line). The results, in the rows' order."""
    labels = labels or [""] * len(rows)
    if args.ray_address is None:
        threads = max(torch_threads(row[1]) for row in rows)
        with ThreadPoolExecutor(max_workers=runs_at_once(threads, len(rows))) as pool:
            return list(pool.map(lambda row, label: _reported(run_one(row[0], row[1], folder, *row[2:]), label),
                                 rows, labels))
    return [_reported(result, label) for result, label in zip(run_remote(rows, args.ray_address, folder), labels)]


def _run_remote(rows, settings) -> list:
    """A Ray task's runs (``rows``: (seed, argv)), each in a temporary folder: :func:`run_one`'s
    results with ``files``, that folder's {relative path: bytes}, and ``ray_node_id``, where it ran."""
    import ray

    results = []
    for row in rows:
        with tempfile.TemporaryDirectory() as folder:
            result = run_one(row[0], row[1], folder, *row[2:])
            result["files"] = {str(p.relative_to(folder)): p.read_bytes() for p in Path(folder).rglob("*") if p.is_file()}
        results.append({**result, "ray_node_id": ray.get_runtime_context().get_node_id()})
    return results


def run_remote(rows, address: str, folder: Path) -> list:
    """:func:`run_one` of each row ((seed, argv) or (seed, argv, log)) as a Ray task on the cluster
    at ``address``, its files written into ``folder``: the results."""
    from .gait_search import ray_map

    results = [result for chunk in ray_map(_run_remote, rows, {}, address, len(rows)) for result in chunk]
    for result in results:
        for name, data in result.pop("files").items():
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            (folder / name).write_bytes(data)
    return results


def torch_threads(argv) -> int:
    """The ``--torch-threads`` of a run's train.py command line (:func:`rrrobot_gym.training.seed_argv`
    always gives it)."""
    return int(argv[argv.index("--torch-threads") + 1])


def runs_at_once(threads: int, count: int) -> int:
    """How many of ``count`` runs run at once here: as many as the cores hold, each run taking
    ``threads`` (its ``--torch-threads``, train.py's update threads; the env and the rollouts take
    one of them), at least one."""
    return max(1, min(count, (os.cpu_count() or 1) // threads))


def bar_of(args, trained: dict) -> tuple:
    """(mm/s, its source): ``--bar``, or ``--bar-from``'s (:func:`bar_from_gait_search`)."""
    if args.bar is not None:
        return args.bar, "--bar"
    return bar_from_gait_search(args.bar_from, args.model, trained)


def run_seeds(args, rows, prefix: str, trained: dict) -> Path:
    """train.py --seeds (``args``: its Args): the runs ``rows`` ((seed, train.py's argv), their run
    folders named ``prefix`` + seed + ...) of the env keywords ``trained`` (as JSON), then
    summary.json and summary.md in their folder (module docstring)."""
    start = time.monotonic()
    bar, source = bar_of(args, trained)
    first, last = rows[0][0], rows[-1][0]
    folder = Path(args.runs_dir) / f"{prefix}seeds{first}-{last}__{int(time.time())}"
    folder.mkdir(parents=True, exist_ok=False)
    print(f"seeds {first} ... {last} into {folder}", flush=True)
    results = run_rows(args, rows, folder)
    summary = summarize(folder, results, bar, source, args, prefix, round(time.monotonic() - start, 3))
    summary["command"] = " ".join([sys.executable, *sys.argv])
    write_summary(summary, markdown(summary), [folder, args.summary_dir])
    print(markdown(summary), flush=True)
    return folder


def write_summary(summary: dict, table: str, folders) -> None:
    """``summary`` as summary.json and ``table`` as summary.md in each of ``folders`` (None: left
    out), made if missing."""
    for out in filter(None, folders):
        Path(out).mkdir(parents=True, exist_ok=True)
        (Path(out) / "summary.json").write_text(json.dumps(summary, indent=1, allow_nan=False) + "\n")
        (Path(out) / "summary.md").write_text(table)


def selection_score(returns, select_by: str) -> float:
    """An evaluation's score for train.py's --select-by (its headings' ``returns``): the worst or
    the mean. The best evaluation, whose model is best_model.zip, is the first highest."""
    returns = np.asarray(returns, dtype=float)
    return float(returns.min() if select_by == "worst" else returns.mean())


def seed_record(folder: Path, result: dict, bar: float, select_by: str, prefix: str) -> dict:
    """One run's entry of the summary (module docstring) from its :func:`run_one` ``result``."""
    found = sorted(p.name for p in folder.iterdir() if p.is_dir() and p.name.startswith(f"{prefix}{result['seed']}__"))
    record = {"seed": result["seed"], "status": "ok", "returncode": result["returncode"],
              "run_dir": found[-1] if found else None, "log": result["log"],
              "run_seconds": result["run_seconds"], **{k: v for k, v in result.items() if k == "ray_node_id"}}
    if result["returncode"] != 0:
        lines = (folder / record["log"]).read_text(errors="replace").strip().splitlines()
        return {**record, "status": "failed", "error": lines[-1] if lines else ""}
    npz = folder / found[-1] / "evaluations.npz" if found else None
    if npz is None or not npz.is_file():
        return {**record, "status": "no evaluation"}
    with np.load(npz) as data:
        speeds, degrees = data["heading_speeds_mm_s"], data["speed_headings_deg"]
        timesteps, wall, results = data["timesteps"], data["wall_time_s"], data["results"]
    best = int(np.argmax([selection_score(returns, select_by) for returns in results]))
    reached = np.flatnonzero(speeds.min(axis=1) >= bar)
    return {
        **record,
        "best_evaluation": {"index": best, "timesteps": int(timesteps[best]), "wall_time_s": float(wall[best])},
        "worst_heading_mm_s": float(speeds[best].min()),
        "mean_heading_mm_s": float(speeds[best].mean()),
        "heading_speeds_mm_s": {f"{d:g}": float(v) for d, v in zip(degrees, speeds[best])},
        "time_to_bar_s": float(wall[reached[0]]) if len(reached) else None,
        "timesteps_to_bar": int(timesteps[reached[0]]) if len(reached) else None,
    }


def iqm_interval(scores, reps: int, random_seed: int = IQM_RANDOM_SEED) -> dict:
    """rliable's interquartile mean of ``scores`` (one per run) with its 95 % stratified-bootstrap
    confidence interval (``reps`` replications)."""
    import warnings

    from rliable import library, metrics

    matrix = np.asarray(scores, dtype=float).reshape(-1, 1)  # (runs x tasks): one task
    with warnings.catch_warnings():  # (arch's notice that random_state will become a Generator)
        warnings.simplefilter("ignore", FutureWarning)
        points, intervals = library.get_interval_estimates(
            {"runs": matrix}, lambda x: np.array([metrics.aggregate_iqm(x)]), reps=reps,
            confidence_interval_size=0.95, random_state=np.random.RandomState(random_seed))
    return {"iqm_mm_s": float(points["runs"][0]), "ci95_mm_s": [float(v) for v in intervals["runs"][:, 0]],
            "runs": len(matrix), "reps": reps, "random_seed": random_seed}


def summarize(folder: Path, results, bar: float, source: str, args, prefix: str, seconds: float) -> dict:
    """summary.json's contents (module docstring) for the runs' :func:`run_one` ``results``."""
    runs = [seed_record(folder, result, bar, args.select_by, prefix) for result in sorted(results, key=lambda r: r["seed"])]
    worst = [run["worst_heading_mm_s"] for run in runs if run["status"] == "ok"]
    return {
        "schema": SCHEMA, "algo": args.algo, "seeds": len(runs), "first_seed": args.seed, "bar_mm_s": bar,
        "bar_source": source, "select_by": args.select_by, "runs": runs,
        "worst_heading_iqm": iqm_interval(worst, args.bootstrap_reps) if worst else None,
        "reached_bar": sum(run.get("time_to_bar_s") is not None for run in runs),
        "failed_runs": sum(run["status"] == "failed" for run in runs), "wall_time_s": seconds,
    }


def markdown(summary: dict) -> str:
    """summary.md: the runs' table and the aggregates."""
    def number(value, form="{:.1f}"):
        return "-" if value is None else form.format(value)

    lines = [f"### {summary['seeds']} seeds from {summary['first_seed']}: worst and mean heading speed of each best "
             f"model (mm/s), bar {summary['bar_mm_s']:.2f} mm/s ({summary['bar_source']})\n",
             "| seed | worst heading | mean heading | best at (steps) | time to bar (s) | steps to bar | run (s) | status |",
             "|---|---|---|---|---|---|---|---|"]
    for run in summary["runs"]:
        best = run.get("best_evaluation") or {}
        status = run["status"] + (f" (exit {run['returncode']}: {run['error']})" if run["status"] == "failed" else "")
        lines.append(f"| {run['seed']} | {number(run.get('worst_heading_mm_s'))} | {number(run.get('mean_heading_mm_s'))} "
                     f"| {number(best.get('timesteps'), '{:,}')} | {number(run.get('time_to_bar_s'), '{:.0f}')} "
                     f"| {number(run.get('timesteps_to_bar'), '{:,}')} | {run['run_seconds']:.0f} | {status} |")
    iqm = summary["worst_heading_iqm"]
    lines.append("")
    if iqm is None:
        lines.append("No run finished with an evaluation: no IQM.")
    else:
        low, high = iqm["ci95_mm_s"]
        lines.append(f"Worst-heading speed, interquartile mean over {iqm['runs']} runs: {iqm['iqm_mm_s']:.1f} mm/s, "
                     f"95 % CI {low:.1f} to {high:.1f} (rliable, stratified bootstrap, {iqm['reps']:,} replications).")
    lines.append(f"Reached the bar: {summary['reached_bar']} of {summary['seeds']} seeds"
                 + (f"; {summary['failed_runs']} failed." if summary["failed_runs"] else "."))
    return "\n".join(lines) + "\n"
