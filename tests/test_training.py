"""train.py, evaluate.py and agents/, run as a user would: in subprocesses, on tiny budgets."""

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
TINY = ["--num-envs", "8", "--n-steps", "64", "--batch-size", "256", "--n-epochs", "2", "--eval-freq", "1024",
        "--checkpoint-freq", "1024", "--episode-steps", "200", "--no-progress-bar"]


def run(args, timeout=300, **kwargs):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, *args], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=timeout, **kwargs)


def train_here(argv) -> Path:
    """rrrobot_gym.training.main (train.py's) in this process, its torch thread count put back: the run directory."""
    import torch

    from rrrobot_gym import training

    threads = torch.get_num_threads()
    try:
        return training.main([str(arg) for arg in argv])
    finally:
        torch.set_num_threads(threads)


def evaluate_here(argv, capsys) -> str:
    """rrrobot_gym.evaluation.main (evaluate.py's) in this process: what it printed."""
    from rrrobot_gym import evaluation

    capsys.readouterr()
    evaluation.main([str(arg) for arg in argv])
    return capsys.readouterr().out


def only_run(runs_dir: Path) -> Path:
    (run_dir,) = [p for p in runs_dir.iterdir() if p.is_dir()]
    return run_dir


@pytest.mark.slow
def test_train_then_evaluate_a_tiny_run(tmp_path):
    trained = run(["train.py", "--total-timesteps", "2000", "--runs-dir", str(tmp_path), "--seed", "3",
                   "--healthy-reward", "0.5", *TINY])
    assert trained.returncode == 0, trained.stderr
    # whole rollouts of 8 x 64: the run (and its progress bar) goes to 2048, and says so
    assert "training for 2,048 env steps" in trained.stdout
    run_dir = only_run(tmp_path)
    from rrrobot_gym.agents import load_ppo_agent
    from rrrobot_gym.envs import RRRobotEnv

    assert load_ppo_agent(run_dir / "final_model.zip").model.num_timesteps == 2048
    agent = load_ppo_agent(run_dir / "best_model.zip")
    # env_kwargs.json holds every env keyword: the agent rebuilds the training env's config
    assert set(json.loads((run_dir / "env_kwargs.json").read_text())) == set(RRRobotEnv().config.to_kwargs())
    # (train.py randomizes the robot by default: the training env's keyword too)
    assert RRRobotEnv(**agent.env_config).config == RRRobotEnv(healthy_reward=0.5, randomize="default").config
    assert "model" not in agent.env_kwargs and agent.env_kwargs["healthy_reward"] == 0.5
    assert run_dir.name.startswith("RRRobot-v0__ppo__3__")
    for name in ("best_model.zip", "vecnormalize.pkl", "final_model.zip", "final_vecnormalize.pkl",
                 "evaluations.npz", "args.json"):
        assert (run_dir / name).is_file(), name
    assert list((run_dir / "checkpoints").glob("ppo_*_steps.zip"))
    assert list(run_dir.glob("tb_*/events.out.tfevents.*"))
    # the log says "best" in one sense, --select-by's (the worst heading's return): once an evaluation that
    # improved on it, SB3's "New best mean reward!" (the mean's) never; its last line restates the best model
    evaluations = np.load(run_dir / "evaluations.npz")
    worst_returns = evaluations["results"].min(axis=1)
    best = int(np.argmax(worst_returns))
    speeds = evaluations["heading_speeds_mm_s"][best]
    lines = trained.stdout.strip().splitlines()
    assert lines[-1] == (f"best model: heading speeds {speeds.min():.1f} mm/s worst, {speeds.mean():.1f} mean, the "
                         f"evaluation at {evaluations['timesteps'][best]:,} steps of highest worst heading return; "
                         f"saved as {run_dir / 'best_model.zip'} (final model: {run_dir / 'final_model.zip'})")
    improved = sum(worst_returns[k] > worst_returns[:k].max(initial=-np.inf) for k in range(len(worst_returns)))
    assert [line for line in lines[:-1] if "best" in line.lower()] == [
        line for line in lines if line.startswith("evaluation at ") and line.endswith("the best yet: saved as best_model.zip")]
    assert sum(line.startswith("evaluation at ") for line in lines) == len(worst_returns) and improved >= 1
    assert sum("best yet" in line for line in lines) == improved

    out = tmp_path / "eval.json"
    evaluated = run(["evaluate.py", "--policy", str(run_dir / "best_model.zip"), "--models", "plane",
                     "--duration", "2", "--json", str(out)])
    assert evaluated.returncode == 0, evaluated.stderr
    assert f"| ppo ({run_dir / 'best_model.zip'}) |" in evaluated.stdout and "| gait1 |" in evaluated.stdout
    records = json.loads(out.read_text())["records"]
    agents = {r["agent"] for r in records}
    assert agents == {"ppo", "gait1", "gait1-swapped", "gait2", "gait2-swapped", "gait3", "gait3-swapped"}
    compass = sorted({r["heading_deg"] for r in records if r["compass"]})
    assert compass == [0, 45, 90, 135, 180, 225, 270, 315]
    for r in records:
        assert {"agent", "model", "heading_deg", "speed_mps"} <= set(r)
        assert math.isfinite(r["speed_mps"])


@pytest.fixture(scope="module")
def interrupted_run(tmp_path_factory):
    """A long run stopped by Ctrl-C once it has written a checkpoint (shared by the next three
    tests): in this process, the signal sent to its main thread as a terminal sends it."""
    import threading

    import torch

    from rrrobot_gym import training

    runs_dir = tmp_path_factory.mktemp("interrupted")
    threads = torch.get_num_threads()

    def press_ctrl_c():
        deadline = time.time() + 300
        while time.time() < deadline and not list(runs_dir.glob("*/checkpoints/*.zip")):
            time.sleep(0.2)
        signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)

    presser = threading.Thread(target=press_ctrl_c)
    presser.start()
    try:
        with pytest.raises(SystemExit) as exit_info:
            training.main(["--total-timesteps", "10000000", "--runs-dir", str(runs_dir), *TINY])
    finally:
        presser.join()
        torch.set_num_threads(threads)
    return exit_info.value.code, only_run(runs_dir)


@pytest.mark.slow
def test_ctrl_c_saves_the_model_before_exiting(interrupted_run, capsys):
    returncode, run_dir = interrupted_run
    assert returncode == 130
    assert (run_dir / "final_model.zip").is_file()
    from rrrobot_gym.agents.ppo import load_sb3_model

    checkpoint = sorted((run_dir / "checkpoints").glob("ppo_*_steps.zip"))[-1]
    # the model saved is the one training had reached: at or past its last checkpoint
    assert load_sb3_model(run_dir / "final_model.zip").num_timesteps >= int(checkpoint.stem.split("_")[1])


def _resume(interrupted_run, tmp_path, *flags):
    """train.py --resume from the interrupted run's last checkpoint for 512 more steps, here:
    (the checkpoint's steps, the resumed run's final model)."""
    from rrrobot_gym.agents.ppo import load_sb3_model

    *_, run_dir = interrupted_run
    checkpoint = sorted((run_dir / "checkpoints").glob("ppo_*_steps.zip"))[-1]
    resumed = train_here(["--total-timesteps", "512", "--runs-dir", tmp_path, "--resume", checkpoint, *TINY, *flags])
    return int(checkpoint.stem.split("_")[1]), load_sb3_model(resumed / "final_model.zip")


@pytest.mark.slow
def test_resume_continues_from_a_checkpoint(interrupted_run, tmp_path):
    steps, model = _resume(interrupted_run, tmp_path)
    assert model.num_timesteps == steps + 512  # continued counting from the checkpoint's steps


@pytest.mark.slow
def test_a_resumed_run_takes_the_ppo_settings_given_and_keeps_the_others(interrupted_run, tmp_path, capsys):
    _, model = _resume(interrupted_run, tmp_path, "--learning-rate", "0.0001", "--learning-rate-final", "none",
                       "--n-epochs", "3")  # fmt: skip
    out = capsys.readouterr().out
    assert "learning_rate 0.0001" in out and "n_epochs 3" in out
    assert (model.learning_rate, model.lr_schedule(1.0), model.lr_schedule(0.0), model.n_epochs) == (1e-4, 1e-4, 1e-4, 3)
    assert model.clip_range(1.0) == 0.2 and model.gae_lambda == 0.95  # not given: as trained


def test_the_learning_rate_falls_linearly_to_the_final_one_and_a_resume_takes_it(capsys):
    from rrrobot_gym import training

    args = training.parse_args(["--learning-rate", "2e-4", "--learning-rate-final", "5e-5"])
    rate = training.learning_rate(args)
    assert (rate(1.0), rate(0.5), rate(0.0)) == pytest.approx((2e-4, 1.25e-4, 5e-5))
    default = training.learning_rate(training.parse_args([]))  # by default, 5e-4 falling to 0
    assert (default(1.0), default(0.0)) == (5e-4, 0.0)
    assert training.learning_rate(training.parse_args(["--learning-rate-final", "none"])) == 5e-4  # constant
    shipped = str(ROOT / "agents" / "pretrained" / "best_model.zip")
    argv = ["--resume", shipped, "--learning-rate-final", "0", "--mirror"]
    resumed = training.resume_overrides(training.parse_args(argv), argv)["learning_rate"]
    assert (resumed(1.0), resumed(0.0)) == (5e-4, 0.0)
    with pytest.raises(SystemExit):
        training.parse_args(["--learning-rate-final", "-1e-4"])
    assert "--learning-rate-final" in capsys.readouterr().err


def test_a_resumed_run_refuses_settings_its_model_fixed(capsys):
    from rrrobot_gym import training

    shipped = str(ROOT / "agents" / "pretrained" / "best_model.zip")
    with pytest.raises(SystemExit):
        training.parse_args(["--resume", shipped, "--net-arch", "64,64", "--gamma", "0.98", "--activation", "tanh"])
    assert "--activation, --gamma, --net-arch" in capsys.readouterr().err
    argv = ["--resume", shipped, "--learning-rate", "3e-4", "--learning-rate-final", "none"]
    assert training.resume_overrides(training.parse_args(argv), argv) == {"learning_rate": 3e-4}  # given, though the default


@pytest.mark.parametrize("heading", [[], ["--direction-deg", "30"]], ids=["any-heading", "specialist"])
def test_the_evaluation_env_scores_the_same_reward_as_the_training_env(heading):
    """best_model.zip is chosen on the evaluation's reward: it must be the reward that is logged."""
    import dataclasses

    from rrrobot_gym import hyperparams as hp, training

    args = training.parse_args(["--healthy-reward", "0.7", "--clock-frequency", "8", "--episode-steps", "123",
                             "--torque-limit", "0.5", "--leg-rate-limit", "10", "--randomize", "none", *heading,
                             "--env", "contact_quadrature=trapezoid", "--env", "max-slip-velocity=0.03"])  # fmt: skip
    train_env = training.make_env(args, 2, seed=0).venv.vector_env
    evaluation = training.make_eval_env(args, seed=1).venv.vector_env
    # the same keywords but the start noise (evaluations start from the paper's start) and the training margin from
    # the slip tolerance (evaluations keep the robot's), the same episode
    assert evaluation.config == dataclasses.replace(train_env.config, reset_noise_scale=0.0, max_slip_velocity=0.03)
    # (by default training draws a robot an episode, and evaluations run the nominal one)
    randomized = training.parse_args(heading)
    assert training.make_env(randomized, 2, seed=0).venv.vector_env.config.randomize == "default"
    assert training.make_eval_env(randomized, seed=1).venv.vector_env.config.randomize is None
    assert evaluation.max_episode_steps == train_env.max_episode_steps == 123
    assert (train_env.config.torque_limit, train_env.config.leg_rate_limit) == (0.5, 10.0)
    assert train_env.config.contact_quadrature == "trapezoid"
    assert train_env.config.max_slip_velocity == pytest.approx(0.03 - hp.SLIP_MARGIN)
    saved = training.env_config(args)  # (env_kwargs.json: evaluate.py reads it) the robot's, not the training margin
    assert (saved["contact_quadrature"], saved["max_slip_velocity"]) == ("trapezoid", 0.03)
    if heading:
        assert train_env.config.target_direction == pytest.approx(math.radians(30.0))
    train_env.reset(seed=0)
    start = {"state": train_env.states[0].copy(), "target_direction": 0.4}
    rewards = []
    for env in (train_env, evaluation):
        env.reset(seed=0, options=start)
        actions = np.tile([0.3, -0.2], (env.num_envs, 1))
        rewards.append([env.step(actions)[1][0] for _ in range(5)])
    assert rewards[0] == rewards[1]
    assert rewards[0][-1] != 0.0


def test_total_timesteps_are_rounded_up_to_whole_rollouts():
    from rrrobot_gym import training

    assert training.rounded_timesteps(training.parse_args(["--total-timesteps", "5000"])) == 8_192  # 2 x 16 x 256
    assert training.rounded_timesteps(training.parse_args(["--total-timesteps", "4096"])) == 4_096


def test_a_model_takes_its_own_defaults_where_none_are_given():
    from rrrobot_gym import hyperparams as hp, training

    plane, pivot = training.parse_args([]), training.parse_args(["--model", "pivot"])
    assert hp.MODEL_DEFAULTS["pivot"]  # (else the checks below hold trivially)
    for name, value in hp.MODEL_DEFAULTS["pivot"].items():
        assert getattr(pivot, name) == value
        assert getattr(plane, name) != value  # the plane keeps the table's defaults
    # the shipped pivot policy was trained with them (its args.json predates --activation: tanh, then the only one)
    shipped = json.loads((ROOT / "agents" / "pretrained_pivot" / "args.json").read_text())
    for name, value in hp.MODEL_DEFAULTS["pivot"].items():
        assert shipped.get(name, "tanh" if name == "activation" else None) == value, name
    # an option given on the command line wins over the model's default
    given = training.parse_args(["--model", "pivot", "--n-steps", "16", "--activation", "relu"])
    assert (given.n_steps, given.activation, given.ent_coef) == (16, "relu", 0.0)
    # and a resumed run takes the resumed model's settings where none are given, whatever the model's defaults
    argv = ["--model", "pivot", "--resume", str(ROOT / "agents" / "pretrained_pivot" / "best_model.zip")]
    assert training.resume_overrides(training.parse_args(argv), argv) == {}


@pytest.mark.parametrize("argv, named", [
    (["--torque-limit", "-1"], "--torque-limit"),
    (["--torque-limit", "nan"], "--torque-limit"),
    (["--torque-limit", "none", "--leg-rate-limit", "10"], "--torque-limit"),
    (["--leg-accel-limit", "-60"], "--leg-accel-limit"),
    (["--randomize", "sometimes"], "randomize"),
    (["--clock-frequency", "0"], "--clock-frequency"),
    (["--slip-margin", "-0.001"], "--slip-margin"),
    (["--slip-margin", "nan"], "--slip-margin"),
    (["--slip-margin", "0.02"], "--slip-margin must be >= 0 and under the env's max_slip_velocity (0.02"),
    (["--sweep", "2", "--bar", "50"], "--sweep needs --max-minutes"),
    (["--sweep", "2", "--max-minutes", "1"], "--sweep needs a bar"),
    (["--sweep", "2", "--seeds", "2", "--bar", "50", "--max-minutes", "1"], "cannot be combined"),
    (["--sweep", "0", "--bar", "50", "--max-minutes", "1"], "--sweep must be a positive integer"),
    (["--max-minutes", "-1"], "--max-minutes must be a positive number"),
    (["--stop-at-speed", "nan"], "--stop-at-speed must be a finite speed"),
])
def test_bad_motor_clock_and_sweep_arguments_are_named(argv, named, capsys):
    from rrrobot_gym import training

    with pytest.raises(SystemExit):
        training.parse_args(argv)
    assert named in capsys.readouterr().err


def test_bad_arguments_are_named(tmp_path, capsys):
    from rrrobot_gym import evaluation, training

    for main, argv, named in ((training.main, ["--model", "moon", "--runs-dir", str(tmp_path)], "--model"),
                              (evaluation.main, ["--policy", str(tmp_path / "missing.zip")], "no model file")):  # fmt: skip
        with pytest.raises(SystemExit) as exit_info:
            main(argv)
        assert exit_info.value.code == 2 and named in capsys.readouterr().err


def test_gait_agents_move_like_the_simulator_core():
    """Through the env (targets ramped over each step) a gait moves as the core's continuous gait
    (Gaits 1 and 3, run side by side in one batched env)."""
    from rrrobot_gym.agents import gait_agent
    from rrrobot_gym.evaluation import run_episodes
    from rrrobot_gym.analysis import travel_summary
    from rrrobot_gym.control import table2_gait
    from rrrobot_gym.simulation import SimConfig, simulate

    duration = 20.0
    runs = run_episodes({f"gait{n}": gait_agent(f"gait{n}") for n in (1, 3)}, "plane", [0.0], duration)
    for number in (1, 3):
        env_run = runs[f"gait{number}"]
        core = simulate(SimConfig(), table2_gait(number), duration, sample_dt=0.05)
        period = table2_gait(number).period
        ours = travel_summary(env_run["times"], env_run["xy"][:, 0, 0], env_run["xy"][:, 0, 1], period)
        theirs = travel_summary(core.times, core.x, core.y, period)
        assert ours["path_length_m"] == pytest.approx(theirs["path_length_m"], rel=0.1), number
        assert abs(ours["turning_deg"] - theirs["turning_deg"]) < 20.0, number
        if number == 1:
            assert abs(ours["direction_deg"] - theirs["direction_deg"]) < 3.0


def test_gait_agent_commands_the_gait_at_the_end_of_each_step_and_restarts_with_each_episode():
    from rrrobot_gym.agents import gait_agent
    from rrrobot_gym.control import table2_gait
    from rrrobot_gym.envs.task import action_to_leg_targets

    agent = gait_agent("gait3-swapped", dt=0.05)
    obs = np.zeros((2, 15), dtype=np.float32)
    state = None
    for k in range(5):
        actions, state = agent.predict(obs, state=state, episode_start=np.array([k == 0, k in (0, 3)]))
    expected = table2_gait(3, swapped=True).angles([5 * 0.05, 2 * 0.05])
    np.testing.assert_allclose(action_to_leg_targets(actions), expected, atol=1e-6)
    with pytest.raises(ValueError, match="unknown gait agent"):
        gait_agent("gait4")


@pytest.mark.parametrize("kwargs", [{"frame_skip": 30}, {"action_hold": "zero_order"}])
def test_a_gait_agent_made_for_an_env_plays_the_gait_at_that_env_s_control_step(kwargs):
    """With another frame_skip the control step is another dt: the agent must count in it."""
    import gymnasium

    from rrrobot_gym.agents import gait_agent
    from rrrobot_gym.control import table2_gait
    from rrrobot_gym.envs.task import action_to_leg_targets

    env = gymnasium.make("RRRobot-v0", **kwargs)
    agent = gait_agent("gait1", env=env)
    obs, _ = env.reset(seed=0)
    state, sampled = None, []
    for k in range(4):
        action, state = agent.predict(obs, state=state, episode_start=np.array([k == 0]))
        sampled.append(action_to_leg_targets(action))
        obs, *_ = env.step(action)
    fraction = 0.5 if kwargs.get("action_hold") == "zero_order" else 1.0  # a held target lags half a step
    times = (np.arange(4) + fraction) * env.unwrapped.dt
    np.testing.assert_allclose(sampled, table2_gait(1).angles(times), atol=1e-6)
    vector = gymnasium.make_vec("RRRobot-v0", num_envs=2, **kwargs)
    assert gait_agent("gait1", env=vector).dt == env.unwrapped.dt


def test_a_checkpoint_loads_with_its_run_s_env_keywords(tmp_path):
    """Checkpoints sit in RUN/checkpoints/ and the run's env_kwargs.json one directory up: a
    checkpoint of a pivot run under motor limits loads with those keywords, not the defaults
    (limits here made other than the env's defaults, which the shipped run may have trained under)."""
    import shutil

    from rrrobot_gym.agents import load_ppo_agent

    shipped = ROOT / "agents" / "pretrained_pivot"
    (tmp_path / "checkpoints").mkdir()
    run_kwargs = {**json.loads((shipped / "env_kwargs.json").read_text()), "torque_limit": 0.4, "leg_rate_limit": 8.0}
    (tmp_path / "env_kwargs.json").write_text(json.dumps(run_kwargs))
    checkpoint = tmp_path / "checkpoints" / "ppo_1000_steps.zip"
    shutil.copy(shipped / "best_model.zip", checkpoint)
    shutil.copy(shipped / "vecnormalize.pkl", tmp_path / "checkpoints" / "ppo_vecnormalize_1000_steps.pkl")
    shutil.copy(shipped / "mirror.json", tmp_path / "mirror.json")  # (the shipped run is mirrored: its zip says so)
    agent = load_ppo_agent(checkpoint)
    assert agent.env_config["model"] == "pivot"
    assert agent.env_kwargs["torque_limit"] == 0.4 and agent.env_kwargs["leg_rate_limit"] == 8.0


@pytest.mark.parametrize(
    "spec, words",
    [("model=pivot", "set model with --model"), ("contact_quadrature=simpson", "unknown contact_quadrature 'simpson'"),
     ("nosuch=1", "unknown keyword argument"), ("timestep=0.02", "stability limit"),
     ("frame_skip=2 frame_skip=3", "frame_skip given twice"), ("contact_quadrature", "expected KEY=VALUE")],
)
def test_env_keywords_given_by_env_are_checked_by_the_env_and_name_the_problem(spec, words, capsys):
    from rrrobot_gym import training

    with pytest.raises(SystemExit):
        training.parse_args([arg for one in spec.split() for arg in ("--env", one)])
    assert words in capsys.readouterr().err


@pytest.mark.parametrize(
    "flags, named",
    [
        (["--gamma", "2"], "--gamma must be in [0, 1]"),  # (trained and saved without a word)
        (["--gae-lambda", "nan"], "--gae-lambda must be in [0, 1]"),  # (torch's "invalid values" after a rollout)
        (["--clip-range", "-1"], "--clip-range must be a positive number"),
        (["--ent-coef", "nan"], "--ent-coef"),
        (["--log-std-init", "1000"], "--log-std-init must be in"),
        (["--net-arch", "64,x"], "--net-arch"),
        (["--net-arch=-4,4"], "--net-arch"),
        (["--net-arch", "\u00b2"], "--net-arch"),  # (a digit to str.isdigit, not to int())
        (["--activation", "sigmoid"], "--activation must be one of tanh, relu, got 'sigmoid'"),
        (["--batch-size", "1"], "--batch-size must be at least 2"),  # (SB3's assertion)
        (["--seed", "-1"], "--seed"),
        (["--resume", str(ROOT / "README.md")], "not a Stable-Baselines3 model zip"),
    ],
)
def test_ppo_settings_that_cannot_train_are_refused_before_any_work(flags, named, capsys):
    from rrrobot_gym import training

    with pytest.raises(SystemExit) as exit_info:
        training.parse_args(flags)
    assert exit_info.value.code == 2
    assert named in capsys.readouterr().err


def test_a_runs_dir_that_is_a_file_is_refused(tmp_path, capsys):
    from rrrobot_gym import training

    taken = tmp_path / "runs"
    taken.write_text("")
    with pytest.raises(SystemExit):
        training.parse_args(["--runs-dir", str(taken)])
    assert "is a file, not a directory" in capsys.readouterr().err


def test_a_resume_is_checked_against_its_statistics_and_this_runs_observation(tmp_path, capsys):
    """Both failed once the envs were made: the statistics with exit status 1, the observation in
    SB3's assertion 'spaces must have the same shape'."""
    import shutil

    from rrrobot_gym import training

    shipped = ROOT / "agents" / "pretrained" / "best_model.zip"
    for flags, named in (
        (["--clock-frequency", "8"], "the model observes 15 numbers, this run's env 17"),
        (["--env", "exclude_current_positions_from_observation=false"], "the model observes 15 numbers, this run's env 17"),
    ):
        with pytest.raises(SystemExit) as exit_info:
            training.parse_args(["--resume", str(shipped), *flags])
        assert exit_info.value.code == 2 and named in capsys.readouterr().err
    alone = tmp_path / "best_model.zip"
    shutil.copy(shipped, alone)
    (tmp_path / "mirror.json").write_text((shipped.parent / "mirror.json").read_text())
    with pytest.raises(SystemExit) as exit_info:
        training.parse_args(["--resume", str(alone)])
    assert exit_info.value.code == 2 and "needs the normalisation statistics" in capsys.readouterr().err


@pytest.mark.slow
def test_ppo_updates_on_the_torch_threads_asked_and_rollouts_on_one(tmp_path, monkeypatch):
    # (the env steps between updates, so its core is free for torch's matrix products then; the
    # rollouts' 64-row forward passes and the model's construction stay on one thread)
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.policies import ActorCriticPolicy

    from rrrobot_gym import training

    seen = {"update": set(), "rollout": set()}
    update, forward = PPO.train, ActorCriticPolicy.forward

    def recorded_update(self, *args, **kwargs):
        seen["update"].add(torch.get_num_threads())
        return update(self, *args, **kwargs)

    def recorded_forward(self, *args, **kwargs):
        seen["rollout"].add(torch.get_num_threads())
        return forward(self, *args, **kwargs)

    monkeypatch.setattr(PPO, "train", recorded_update)
    monkeypatch.setattr(ActorCriticPolicy, "forward", recorded_forward)
    threads = torch.get_num_threads()
    try:
        training.main(["--total-timesteps", "1024", "--runs-dir", str(tmp_path), "--torch-threads", "2", *TINY])
    finally:
        torch.set_num_threads(threads)
    assert seen == {"update": {2}, "rollout": {1}}
    assert training.parse_args([]).torch_threads == 2
