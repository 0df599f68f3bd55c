"""train.py --algo: SB3's SAC and TD3 and sb3-contrib's TQC beside PPO, one at a time and side by side."""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rrrobot_gym import hyperparams as hp, seeds, training

ROOT = Path(__file__).resolve().parents[1]
OFF_POLICY = ("sac", "td3", "tqc")
TINY = ["--total-timesteps", "768", "--num-envs", "4", "--eval-freq", "256", "--checkpoint-freq", "100000",
        "--episode-steps", "40", "--no-progress-bar"]
OFF_POLICY_TINY = ["--learning-starts", "128", "--buffer-size", "2000", "--batch-size", "32", "--net-arch", "16,16"]


def train_here(argv) -> Path:
    """rrrobot_gym.training.main in this process, its torch thread count put back: the run directory."""
    import torch

    threads = torch.get_num_threads()
    try:
        return training.main([str(arg) for arg in argv])
    finally:
        torch.set_num_threads(threads)


def parse_error(argv, capsys) -> str:
    """train.py's one-line error for ``argv``."""
    with pytest.raises(SystemExit):
        training.parse_args(argv)
    return capsys.readouterr().err.strip().splitlines()[-1]


@pytest.mark.slow
@pytest.mark.parametrize("algo", OFF_POLICY)
def test_each_algorithm_writes_a_model_that_evaluate_py_scores(algo, tmp_path, capsys):
    from rrrobot_gym import evaluation
    from rrrobot_gym.agents import load_ppo_agent
    from rrrobot_gym.agents.mirror import MirroredAgent

    run_dir = train_here(["--algo", algo, "--runs-dir", tmp_path, *TINY, *OFF_POLICY_TINY, "--checkpoint-freq", "512"])
    assert run_dir.name.startswith(f"RRRobot-v0__{algo}__1__")
    assert json.loads((run_dir / "args.json").read_text())["algo"] == algo
    assert list((run_dir / "checkpoints").glob(f"{algo}_*_steps.zip"))
    # evaluations as PPO's: the heading speeds of each, the mirror, the training episodes' lengths
    with np.load(run_dir / "evaluations.npz") as data:
        assert list(data["timesteps"]) == [256, 512, 768] and data["heading_speeds_mm_s"].shape == (3, 8)
        assert np.all(data["train_episode_steps"][~np.isnan(data["train_episode_steps"])] <= 40)
        best = int(np.argmax(data["results"].min(axis=1)))  # (selection by the worst heading)
    agent = load_ppo_agent(run_dir / "best_model.zip")
    assert isinstance(agent, MirroredAgent)
    assert type(agent.model).__name__ == hp.ALGORITHMS[algo][1] and agent.model.num_timesteps == 256 * (best + 1)
    out = tmp_path / "scores.json"
    capsys.readouterr()
    evaluation.main(["--policy", str(run_dir / "best_model.zip"), "--models", "plane", "--duration", "2",
                     "--json", str(out)])
    assert f"| {algo} ({run_dir / 'best_model.zip'}" in capsys.readouterr().out  # (its row: its algorithm, its file)
    records = [r for r in json.loads(out.read_text())["records"] if r["agent"] == "ppo" and r["compass"]]
    assert len(records) == 8 and all(math.isfinite(r["speed_mps"]) for r in records)
    from rrrobot_gym.export import export_onnx

    with pytest.raises(ValueError, match=f"is a {algo} model .*: export-onnx writes PPO policies"):
        export_onnx(run_dir / "best_model.zip", tmp_path / "policy.onnx")


def test_each_algorithm_takes_its_own_defaults_and_a_given_option_wins():
    for algo in hp.ALGORITHMS:
        args = training.parse_args(["--algo", algo])
        for name, value in hp.ALGO_DEFAULTS[algo].items():
            assert getattr(args, name) == value, (algo, name)
        assert args.exp_name == algo and training.rounded_timesteps(args) >= args.total_timesteps
    assert hp.ALGO_DEFAULTS["sac"]["num_envs"] != training.parse_args([]).num_envs  # (else the above holds trivially)
    given = training.parse_args(["--algo", "sac", "--num-envs", "8", "--ent-coef", "0.05", "--use-sde",
                                 "--log-std-init", "-3"])
    assert (given.num_envs, given.ent_coef, given.use_sde, given.log_std_init) == (8, 0.05, True, -3.0)
    # the pivot's PPO defaults are PPO's: another algorithm on the pivot keeps its own
    pivot_sac = training.parse_args(["--algo", "sac", "--model", "pivot"])
    assert (pivot_sac.ent_coef, pivot_sac.total_timesteps) == tuple(hp.ALGO_DEFAULTS["sac"][k] for k in ("ent_coef", "total_timesteps"))


@pytest.mark.parametrize("algo", list(hp.ALGORITHMS))
def test_the_model_is_built_with_the_declared_settings(algo):
    from stable_baselines3.common.vec_env import VecNormalize

    from rrrobot_gym.envs import RRRobotSB3VecEnv

    args = training.parse_args(["--algo", algo, "--num-envs", "2", "--buffer-size", "1000"] if algo != "ppo" else
                               ["--num-envs", "2"])
    model = hp.algorithm_class(algo)("MlpPolicy", VecNormalize(RRRobotSB3VecEnv(num_envs=2)),
                                     **training.algorithm_kwargs(args))
    defaults = hp.defaults(algo)
    assert (model.gamma, model.lr_schedule(1.0)) == (defaults["gamma"], defaults["learning_rate"])
    assert model.batch_size == args.batch_size == defaults["batch_size"]
    hidden = [int(n) for n in defaults["net_arch"].split(",")]
    actor = model.policy.mlp_extractor.policy_net if algo == "ppo" else model.actor
    layers = [m for m in actor.modules() if not list(m.children()) and type(m).__name__ not in ("Flatten", "Identity")]
    assert [m.out_features for m in layers if type(m).__name__ == "Linear"][:len(hidden)] == hidden
    assert type(layers[1]).__name__ == hp.ACTIVATIONS[defaults["activation"]]
    if algo != "ppo":
        assert (model.learning_starts, model.tau, model.train_freq.frequency, model.gradient_steps) == (
            defaults["learning_starts"], defaults["tau"], defaults["train_freq"], defaults["gradient_steps"])
        assert model.replay_buffer.buffer_size == 1000 // 2  # (given; per env)
    if algo in ("sac", "tqc"):
        assert model.ent_coef == defaults["ent_coef"] and model.use_sde == defaults["use_sde"]
    if algo == "td3":
        assert np.allclose(np.std([model.action_noise() for _ in range(4000)], axis=0), defaults["action_noise"], rtol=0.1)


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--algo", "a2c"], "--algo must be one of ppo, sac, td3, tqc"),
        (["--algo", "sac", "--n-epochs", "3"], "--n-epochs is not a setting of --algo sac"),
        (["--learning-starts", "100"], "--learning-starts is not a setting of --algo ppo"),
        (["--algo", "td3", "--use-sde"], "--use-sde is not a setting of --algo td3"),
        (["--ent-coef", "auto"], "--ent-coef must be a number >= 0, got 'auto'"),
        (["--algo", "sac", "--ent-coef", "auto_x"], "--ent-coef must be a number >= 0 or auto"),
        (["--algo", "sac", "--log-std-init", "-3"], "give --use-sde too"),
        (["--algo", "sac", "--gradient-steps", "0"], "--gradient-steps must be a positive integer or -1"),
        (["--algo", "sac", "--tau", "1.5"], "--tau must be in (0, 1]"),
        (["--algo", "td3", "--action-noise", "-0.1"], "--action-noise must be a number >= 0"),
        (["--algo", "sac", "--resume", str(ROOT / "agents" / "pretrained" / "best_model.zip")],
         "--resume continues PPO runs only"),
        (["--algo", "td3", "--sweep", "2", "--bar", "70", "--max-minutes", "1"], "--sweep tunes PPO's settings"),
        (["--algo", "ppo,sac"], "several algorithms run side by side with --seeds"),
        (["--algo", "ppo,sac", "--seeds", "2", "--bar", "70"], "needs --max-minutes"),
        (["--algo", "ppo,ppo", "--seeds", "2", "--bar", "70", "--max-minutes", "1"], "names an algorithm twice"),
        (["--algo", "ppo,sac", "--seeds", "2", "--bar", "70", "--max-minutes", "1", "--n-epochs", "3"],
         "--n-epochs is not a setting of --algo sac"),
        (["--algo", "ppo,sac", "--seeds", "2", "--max-minutes", "1"], "needs a bar"),
    ],
)
def test_a_bad_algorithm_option_is_one_line_naming_it(argv, words, capsys):
    assert words in parse_error(argv, capsys)


@pytest.fixture(scope="module")
def side_by_side(tmp_path_factory):
    """train.py --algo ppo,td3 --seeds 2 on tiny budgets, its summary also in --summary-dir."""
    runs_dir = tmp_path_factory.mktemp("algorithms")
    summary_dir = runs_dir / "docs" / "algorithms"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run(
        [sys.executable, "train.py", "--algo", "ppo,td3", "--seeds", "2", "--bar", "-1000", "--max-minutes", "5",
         "--bootstrap-reps", "1000", *TINY, "--runs-dir", str(runs_dir), "--summary-dir",
         str(summary_dir)], cwd=ROOT, env=env, capture_output=True, text=True, timeout=900)  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    (folder,) = [p for p in runs_dir.iterdir() if p.is_dir() and p.name != "docs"]
    return folder, summary_dir, json.loads((folder / "summary.json").read_text()), done.stdout


@pytest.mark.slow
def test_the_side_by_side_summary_holds_every_seed_s_worst_heading(side_by_side):
    folder, summary_dir, summary, stdout = side_by_side
    assert folder.name.startswith("RRRobot-v0__ppo-td3__algorithms__seeds1-2__")
    assert summary["schema"] == "rrrobot_gym.algorithms/1" and list(summary["algorithms"]) == ["ppo", "td3"]
    assert summary["budget_minutes"] == 5 and summary["bar_mm_s"] == -1000
    for algo, entry in summary["algorithms"].items():
        assert [run["seed"] for run in entry["runs"]] == [1, 2] and entry["failed_runs"] == 0
        worst = []
        for run in entry["runs"]:
            run_dir = folder / run["run_dir"]
            assert run_dir.name.startswith(f"RRRobot-v0__{algo}__{run['seed']}__") and run["log"] == f"{algo}_seed{run['seed']}.log"
            saved = json.loads((run_dir / "args.json").read_text())
            assert (saved["algo"], saved["seed"], saved["max_minutes"]) == (algo, run["seed"], 5)
            assert saved["torch_threads"] == training.algorithm_default(algo, "torch_threads")  # (its own, not given)
            with np.load(run_dir / "evaluations.npz") as data:
                speeds = data["heading_speeds_mm_s"]
                best = int(np.argmax(data["results"].min(axis=1)))
                assert run["worst_heading_mm_s"] == speeds[best].min() and run["mean_heading_mm_s"] == speeds[best].mean()
                assert run["curve"]["worst_heading_mm_s"] == speeds.min(axis=1).tolist()
                assert run["curve"]["wall_time_s"] == data["wall_time_s"].tolist()
            worst.append(run["worst_heading_mm_s"])
        assert entry["worst_heading_mm_s"] == {"worst": min(worst), "mean": np.mean(worst)}
        assert entry["worst_heading_iqm"] == seeds.iqm_interval(worst, 1000)
        assert entry["settings"]["num_envs"] == 4 and set(hp.SETTINGS[algo]) <= set(entry["settings"])
    for out in (folder, summary_dir):
        assert json.loads((out / "summary.json").read_text()) == summary
        assert (out / "learning_curves.png").stat().st_size > 10_000
    table = (summary_dir / "summary.md").read_text()
    assert table in stdout
    td3 = summary["algorithms"]["td3"]["runs"][1]
    assert f"| td3 | 2 | {td3['worst_heading_mm_s']:.1f} | {td3['mean_heading_mm_s']:.1f} |" in table
    # the runs went seed by seed, one at a time (PPO's two torch threads on this machine's cores, or fewer)
    order = [line.split(":")[0] for line in stdout.splitlines() if line.endswith(" s") and " seed " in line]
    assert order == ["ppo seed 1", "td3 seed 1", "ppo seed 2", "td3 seed 2"] or (os.cpu_count() or 1) > 3
