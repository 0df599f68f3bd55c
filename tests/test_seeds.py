"""train.py --seeds: K runs of one configuration and their summary (rrrobot_gym/seeds.py)."""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rrrobot_gym import seeds, training

ROOT = Path(__file__).resolve().parents[1]
SEARCHED = ROOT / "agents" / "searched"
TINY = ["--total-timesteps", "1536", "--num-envs", "4", "--n-steps", "32", "--batch-size", "64", "--n-epochs", "1",
        "--eval-freq", "512", "--checkpoint-freq", "100000", "--episode-steps", "40"]
REPS = ["--bootstrap-reps", "1000"]
PREFIX = "RRRobot-v0__ppo__"


def train_py(argv, timeout=600):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "train.py", *argv], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=timeout)


def only_folder(runs_dir: Path) -> Path:
    (folder,) = [p for p in runs_dir.iterdir() if p.is_dir()]
    return folder


def rliable_iqm(scores, reps):
    """rliable's IQM and 95 % interval of one score per run, computed here as the summary's docs say."""
    import warnings

    from rliable import library, metrics

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        points, intervals = library.get_interval_estimates(
            {"x": np.array(scores, dtype=float)[:, None]}, lambda x: np.array([metrics.aggregate_iqm(x)]), reps=reps,
            random_state=np.random.RandomState(seeds.IQM_RANDOM_SEED))
    return points["x"][0], intervals["x"][:, 0]


def speeds_as_evaluate_scores(run_dir: Path, headings_deg, episode_steps: int):
    """evaluate.py's speeds (mm/s) of run_dir's best model: nominal robot, paper's start, the run's episode length."""
    from rrrobot_gym.agents import load_ppo_agent
    from rrrobot_gym.evaluation import run_episodes, score

    agent = load_ppo_agent(run_dir / "best_model.zip")
    run = run_episodes({"ppo": agent}, "plane", headings_deg, duration=episode_steps * 0.05, randomize=None)["ppo"]
    return np.array([record["speed_mps"] * 1e3 for record in score(run, headings_deg)])


@pytest.fixture(scope="module")
def two_seeds(tmp_path_factory):
    """train.py --seeds 2 with a bar every evaluation reaches: the folder and its summary."""
    runs_dir = tmp_path_factory.mktemp("seeds")
    done = train_py(["--seeds", "2", "--seed", "7", "--bar", "-1000", *REPS, *TINY, "--runs-dir", str(runs_dir)])
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    folder = only_folder(runs_dir)
    return folder, json.loads((folder / "summary.json").read_text()), done.stdout


@pytest.mark.slow
def test_each_seed_is_its_own_run_and_the_summary_holds_its_evaluations(two_seeds):
    from rrrobot_gym.agents.ppo import load_sb3_model

    folder, summary, stdout = two_seeds
    assert summary["schema"] == seeds.SCHEMA and summary["seeds"] == 2 and summary["failed_runs"] == 0
    assert [run["seed"] for run in summary["runs"]] == [7, 8]
    assert {p.name for p in folder.iterdir() if p.is_file()} == {"summary.json", "summary.md", "seed7.log", "seed8.log"}
    evaluations = []
    for run in summary["runs"]:
        run_dir = folder / run["run_dir"]
        assert run["status"] == "ok" and run_dir.name.startswith(f"RRRobot-v0__ppo__{run['seed']}__")
        saved = json.loads((run_dir / "args.json").read_text())
        assert (saved["seed"], saved["torch_threads"], saved["progress_bar"], saved["seeds"]) == (run["seed"], 1, False, None)
        assert saved["total_timesteps"] == 1536 and saved["episode_steps"] == 40  # (the other options as given)
        data = dict(np.load(run_dir / "evaluations.npz"))
        evaluations.append(data)
        assert {"timesteps", "results", "ep_lengths", "wall_time_s", "heading_speeds_mm_s"} <= set(data)
        assert list(data["timesteps"]) == [512, 1024, 1536] and data["heading_speeds_mm_s"].shape == (3, 8)
        assert list(data["speed_headings_deg"]) == [0, 45, 90, 135, 180, 225, 270, 315]
        assert np.all(np.diff(data["wall_time_s"]) > 0) and data["wall_time_s"][0] > 0
        best = int(np.argmax(data["results"].min(axis=1)))  # (--select-by worst)
        assert load_sb3_model(run_dir / "best_model.zip").num_timesteps == data["timesteps"][best]
        speeds = data["heading_speeds_mm_s"][best]
        assert run["best_evaluation"] == {"index": best, "timesteps": int(data["timesteps"][best]),
                                          "wall_time_s": float(data["wall_time_s"][best])}
        assert run["worst_heading_mm_s"] == speeds.min() and run["mean_heading_mm_s"] == speeds.mean()
        assert list(run["heading_speeds_mm_s"].values()) == list(speeds)
        # a bar below every speed: reached at the first evaluation
        assert run["time_to_bar_s"] == data["wall_time_s"][0] and run["timesteps_to_bar"] == 512
        # the speeds are evaluate.py's for the best model over the evaluation episodes
        degrees = list(range(0, 360, 45))
        assert np.allclose(speeds_as_evaluate_scores(run_dir, degrees, 40), speeds, rtol=0, atol=1e-9)
    assert summary["reached_bar"] == 2
    # different seeds, different runs
    assert not np.array_equal(evaluations[0]["results"], evaluations[1]["results"])
    assert not np.array_equal(evaluations[0]["heading_speeds_mm_s"], evaluations[1]["heading_speeds_mm_s"])
    iqm, (low, high) = rliable_iqm([run["worst_heading_mm_s"] for run in summary["runs"]], 1000)
    assert summary["worst_heading_iqm"] == {"iqm_mm_s": iqm, "ci95_mm_s": [low, high], "runs": 2, "reps": 1000,
                                            "random_seed": seeds.IQM_RANDOM_SEED}
    assert low < high  # (two different runs)
    table = (folder / "summary.md").read_text()
    assert table in stdout and "Reached the bar: 2 of 2 seeds." in table
    assert f"| 7 | {summary['runs'][0]['worst_heading_mm_s']:.1f} |" in table


def _results(summary):
    return [{key: run[key] for key in ("seed", "returncode", "run_seconds", "log")} for run in summary["runs"]]


@pytest.mark.slow
def test_a_bar_never_reached_is_null_and_one_reached_later_is_its_first_evaluation(two_seeds):
    folder, summary, _ = two_seeds
    args = training.parse_args(["--seeds", "2", "--seed", "7", "--bar", "1", *REPS])
    never = seeds.summarize(folder, _results(summary), 1e6, "--bar", args, PREFIX, 1.0)
    assert never["reached_bar"] == 0
    assert all(run["time_to_bar_s"] is None and run["timesteps_to_bar"] is None for run in never["runs"])
    assert "| - | - |" in seeds.markdown(never) and "Reached the bar: 0 of 2 seeds." in seeds.markdown(never)
    run_dir = folder / summary["runs"][0]["run_dir"]
    data = np.load(run_dir / "evaluations.npz")
    worst = data["heading_speeds_mm_s"].min(axis=1)
    later = seeds.summarize(folder, _results(summary), worst.max(), "--bar", args, PREFIX, 1.0)["runs"][0]
    first = int(np.flatnonzero(worst >= worst.max())[0])
    assert later["time_to_bar_s"] == data["wall_time_s"][first] and later["timesteps_to_bar"] == data["timesteps"][first]


@pytest.mark.slow
def test_a_failed_run_is_reported_and_left_out_of_the_iqm(two_seeds):
    folder, summary, _ = two_seeds
    (folder / "seed9.log").write_text("starting\nValueError: something broke\n")
    try:
        args = training.parse_args(["--seeds", "3", "--seed", "7", "--bar", "-1000", *REPS])
        results = _results(summary) + [{"seed": 9, "returncode": 1, "run_seconds": 2.0, "log": "seed9.log"}]
        out = seeds.summarize(folder, results, -1000.0, "--bar", args, PREFIX, 1.0)
    finally:
        (folder / "seed9.log").unlink()
    failed = out["runs"][2]
    assert (failed["seed"], failed["status"], failed["returncode"]) == (9, "failed", 1)
    assert failed["error"] == "ValueError: something broke" and "worst_heading_mm_s" not in failed
    assert out["failed_runs"] == 1 and out["reached_bar"] == 2 and out["worst_heading_iqm"]["runs"] == 2
    assert "| 9 | - | - |" in seeds.markdown(out) and "1 failed" in seeds.markdown(out)


def test_each_run_gets_the_options_given_but_those_of_seeds(monkeypatch):
    monkeypatch.chdir(ROOT)
    argv = ["--seeds", "3", "--bar", "5", "--seed", "4", "--direction-deg", "45", "--learning-rate-final", "none",
            "--env", "contact_quadrature=trapezoid", "--no-mirror", "--torch-threads", "2", "--runs-dir", "x",
            "--residual-on", "agents/searched/turn_then_run.json"]
    args = training.parse_args(argv)
    child = training.seed_argv(argv, 5)
    assert not {"--seeds", "--bar", "--runs-dir"} & set(child)
    again = training.parse_args(child)
    expected = {**vars(args), "seed": 5, "progress_bar": False, "seeds": None, "bar": None, "runs_dir": "runs",
                "residual_on": str(Path("agents/searched/turn_then_run.json").resolve())}  # (the same file anywhere)
    assert vars(again) == expected
    # one torch thread each, unless given
    assert training.parse_args(training.seed_argv(["--seeds", "3", "--bar", "5"], 4)).torch_threads == 1


@pytest.mark.parametrize("cores, argv, at_once", [
    (2, [], 2), (2, ["--torch-threads", "2"], 1), (4, ["--torch-threads", "2"], 2), (1, [], 1),
    (2, ["--torch-threads", "3"], 1), (8, [], 3)])  # (never more than the runs)
def test_runs_at_once_share_the_cores_by_each_runs_torch_threads(monkeypatch, cores, argv, at_once):
    monkeypatch.setattr(seeds.os, "cpu_count", lambda: cores)
    threads = seeds.torch_threads(training.seed_argv(["--seeds", "3", "--bar", "5", *argv], 1))
    assert seeds.runs_at_once(threads, 3) == at_once


@pytest.mark.parametrize("argv, problem", [
    (["--bar", "100"], "--bar is an option of --seeds"),
    (["--ray-address", "local"], "--ray-address is an option of --seeds"),
    (["--seeds", "2"], "--seeds needs a bar"),
    (["--seeds", "2", "--bar", "1", "--bar-from", str(SEARCHED / "plane_own.json")], "--seeds needs a bar"),
    (["--seeds", "0", "--bar", "1"], "--seeds must be a positive integer"),
    (["--seeds", "2", "--bar", "nan"], "--bar must be a finite speed"),
    (["--seeds", "2", "--bar", "1", "--bootstrap-reps", "0"], "--bootstrap-reps must be a positive integer"),
    (["--seeds", "2", "--bar-from", str(SEARCHED / "plane_own.json"), "--torque-limit", "none", "--leg-rate-limit",
      "none", "--leg-accel-limit", "none"],
     "searched under leg_accel_limit=60, leg_rate_limit=10, torque_limit=0.5, the runs train under "
     "leg_accel_limit=None, leg_rate_limit=None, torque_limit=None"),
    (["--seeds", "2", "--bar-from", str(SEARCHED / "plane_heading180.json")], "a search with objective 'own'"),
    (["--seeds", "2", "--bar-from", str(SEARCHED / "plane_own.json"), "--model", "pivot"], "on the plane model"),
    (["--seeds", "2", "--bar-from", "no/such.json"], "not a readable gait-search JSON"),
    (["--seeds", "2", "--bar", "1", "--ray-address", "127.0.0.1:1"],
     "--ray-address '127.0.0.1:1': nothing answers at 127.0.0.1:1"),
])
def test_bad_seeds_options_are_named_before_any_run(argv, problem, capsys):
    with pytest.raises(SystemExit) as exit_info:
        training.parse_args(argv)
    assert exit_info.value.code == 2
    assert problem in capsys.readouterr().err.strip().splitlines()[-1]


def test_the_bar_from_a_gait_search_is_its_best_gait_from_the_paper_start():
    path = SEARCHED / "plane_own.json"
    args = training.parse_args([])
    gaits = json.loads(path.read_text())["gaits"]
    best = max(g["robustness"]["paper_start_speed_mps"] for g in gaits if not g["robustness"]["paper_start_terminated"])
    bar, source = seeds.bar_from_gait_search(path, "plane", training.env_config(args))
    assert bar == best * 1e3 and math.isfinite(bar) and str(path) in source


@pytest.mark.slow
def test_on_ray_each_run_is_a_task_whose_files_come_back(tmp_path):
    pytest.importorskip("ray")
    done = train_py(["--seeds", "1", "--bar", "-1000", *REPS, *TINY, "--no-mirror", "--ray-address", "local",
                     "--runs-dir", str(tmp_path)])
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    folder = only_folder(tmp_path)
    (run,) = json.loads((folder / "summary.json").read_text())["runs"]
    assert run["status"] == "ok" and (folder / "seed1.log").is_file()
    run_dir = folder / run["run_dir"]
    for name in ("best_model.zip", "vecnormalize.pkl", "final_model.zip", "evaluations.npz", "args.json"):
        assert (run_dir / name).is_file(), name
    data = np.load(run_dir / "evaluations.npz")
    assert list(data["speed_headings_deg"]) == list(range(0, 360, 45))  # (not mirrored: all 8 run)
    speeds = data["heading_speeds_mm_s"][run["best_evaluation"]["index"]]
    assert run["worst_heading_mm_s"] == speeds.min()
    assert np.allclose(speeds_as_evaluate_scores(run_dir, list(range(0, 360, 45)), 40), speeds, rtol=0, atol=1e-9)
