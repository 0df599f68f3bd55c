"""train.py --sweep (rrrobot_gym/sweep.py), and the two ways a run ends early that its trials use:
--stop-at-speed and --max-minutes."""

import json
import zipfile

import numpy as np
import pytest

from rrrobot_gym import sweep

from test_seeds import TINY, only_folder, train_py


GIVEN = {"learning_rate": 3e-4, "num_envs": 128, "n_steps": 16, "batch_size": 2048, "n_epochs": 2, "ent_coef": 0.0,
         "log_std_init": -2.0}
"""Settings inside the sweep's space: its first trial runs them."""


@pytest.fixture(scope="module")
def two_trials(tmp_path_factory):
    """train.py --sweep 2 with a bar every first evaluation reaches: its folder and summary."""
    runs = tmp_path_factory.mktemp("sweep")
    given = [part for name, value in GIVEN.items() for part in (f"--{name.replace('_', '-')}", str(value))]
    done = train_py(["--sweep", "2", "--bar", "-1000", "--max-minutes", "5", *TINY, *given, "--runs-dir", str(runs)])
    assert done.returncode == 0, done.stderr[-3000:]
    folder = only_folder(runs)
    return folder, json.loads((folder / "summary.json").read_text())


@pytest.mark.slow
def test_each_trial_runs_its_settings_and_stops_at_the_bar(two_trials):
    folder, summary = two_trials
    assert summary["schema"] == sweep.SCHEMA and summary["trials"] == 2 and summary["reached_bar"] == 2
    scores = [r["score"] for r in summary["records"]]
    assert scores == sorted(scores)
    for record in summary["records"]:
        settings = record["settings"]
        for name, (kind, values) in sweep.SPACE.items():
            if kind == "choice" and name != "batch_size":
                assert settings[name] in values
            elif kind != "choice":
                assert values[0] <= settings[name] <= values[1]
        assert settings["batch_size"] <= settings["num_envs"] * settings["n_steps"]
        run_dir = folder / record["run_dir"]
        args = json.loads((run_dir / "args.json").read_text())
        for name, value in settings.items():
            assert args[name] == pytest.approx(value, rel=1e-12), name
        assert args["seed"] == summary["seed"] and args["stop_at_speed"] == summary["bar_mm_s"]
        with np.load(run_dir / "evaluations.npz") as data:  # stopped at its first evaluation, which reached the bar
            assert len(data["timesteps"]) == 1
            assert record["time_to_bar_s"] == data["wall_time_s"][0] == record["score"]
        assert (run_dir / "final_model.zip").is_file() and (folder / record["log"]).is_file()
    assert "| trial |" in (folder / "summary.md").read_text()
    (first,) = [r for r in summary["records"] if r["trial"] == 0]
    assert first["settings"] == GIVEN  # the settings given are the first trial's
    (second,) = [r for r in summary["records"] if r["trial"] == 1]
    assert second["settings"] != GIVEN


def test_a_missed_bar_scores_between_one_and_two_budgets_by_how_near_it_came():
    budget = 600.0
    assert sweep.score({"status": "ok", "time_to_bar_s": 123.0}, 80.0, budget) == 123.0
    missed = [sweep.score({"status": "ok", "time_to_bar_s": None, "worst_heading_mm_s": w}, 80.0, budget)
              for w in (-5.0, 0.0, 40.0, 79.0)]
    assert missed == [2 * budget, 2 * budget, 1.5 * budget, pytest.approx(budget * (1 + 1 / 80))]
    assert sweep.score({"status": "failed"}, 80.0, budget) == 3 * budget


@pytest.mark.slow
def test_max_minutes_ends_training_early_and_saves(tmp_path):
    done = train_py(["--total-timesteps", "50000000", "--max-minutes", "0.05", "--num-envs", "4", "--n-steps", "32",
                     "--batch-size", "64", "--n-epochs", "1", "--eval-freq", "1000000", "--no-progress-bar",
                     "--runs-dir", str(tmp_path)])
    assert done.returncode == 0, done.stderr[-3000:]
    assert "--max-minutes reached" in done.stdout
    run_dir = only_folder(tmp_path)
    with zipfile.ZipFile(run_dir / "final_model.zip") as archive:
        trained = json.loads(archive.read("data"))["num_timesteps"]
    assert 0 < trained < 50_000_000
