"""A residual policy on the turn-then-run baseline (rrrobot_gym/agents/residual.py, train.py --residual-on)."""

import json
import math

import numpy as np
import pytest

from rrrobot_gym.agents.residual import FEATURES, ResidualAgent, base_features, combine, make_residual_vec_env
from rrrobot_gym.agents.turn_then_run import load_turn_then_run_agent
from rrrobot_gym.envs.sb3 import RRRobotSB3VecEnv
from rrrobot_gym.envs.task import action_to_leg_targets
from rrrobot_gym.envs.vector import RRRobotVectorEnv
from tests.test_training import ROOT, TINY, evaluate_here, train_here

BASE = ROOT / "agents" / "searched" / "turn_then_run.json"
HEADINGS = np.radians([0.0, 90.0, 135.0, 200.0])
BASE_SERVO = json.loads(BASE.read_text())["env_kwargs"]
"""The servo the base was searched under (the default one), under which it stays in the model."""
IDEAL_BASE = ROOT / "agents" / "searched" / "turn_then_run_robust.json"
"""A base searched under the paper's ideal servo (its ``env_kwargs``)."""


def _wrapped(scale=0.05, episode_steps=30, base=BASE):
    servo = json.loads(base.read_text())["env_kwargs"]
    venv = RRRobotSB3VecEnv(num_envs=len(HEADINGS), max_episode_steps=episode_steps, reset_noise_scale=0.0, **servo)
    venv.set_options({"target_direction": HEADINGS})
    venv.seed(0)  # the next episodes' headings are drawn: as the plain envs below draw them
    return make_residual_vec_env(venv, load_turn_then_run_agent(base), scale)


def test_a_zero_residual_runs_the_base_agent_exactly_across_an_episode_end():
    """With the policy adding nothing, the wrapped env is the base agent in the plain env, step for
    step; the policy sees the env's observation followed by the base's features, also in the last
    observation of a truncated episode (PPO bootstraps its value from it)."""
    wrapped = _wrapped(episode_steps=30)
    base = load_turn_then_run_agent(BASE)
    plain = RRRobotVectorEnv(num_envs=len(HEADINGS), max_episode_steps=30, reset_noise_scale=0.0, **BASE_SERVO)
    obs = wrapped.reset()
    raw, _ = plain.reset(seed=list(range(len(HEADINGS))), options={"target_direction": HEADINGS})
    state, start = None, np.ones(len(HEADINGS), dtype=bool)
    size = raw.shape[1]
    assert obs.shape == (len(HEADINGS), size + len(FEATURES)) == (len(HEADINGS), wrapped.observation_space.shape[0])
    for step in range(40):
        actions, state = base.predict(raw, state, start)
        np.testing.assert_array_equal(obs[:, :size], raw)
        np.testing.assert_array_equal(obs[:, size:], base_features(state, actions))
        obs, rewards, dones, infos = wrapped.step(np.zeros((len(HEADINGS), 2), dtype=np.float32))
        raw, plain_rewards, terminated, truncated, _ = plain.step(actions)
        start = terminated | truncated
        np.testing.assert_array_equal(rewards, plain_rewards.astype(np.float32))
        np.testing.assert_array_equal(dones, start)
        if step == 29:
            assert dones.all() and not terminated.any()
            for info in infos:
                assert info["terminal_observation"].shape == (size + len(FEATURES),)
                assert info["TimeLimit.truncated"]
        else:
            assert not dones.any()
    # the second episode restarted the base agent: it turns again from the start
    assert (state["steps"] == 10).all()


def test_the_policy_moves_the_leg_targets_by_at_most_the_scale():
    # (on the ideal servo the reference ends each step on the action's target; the default servo's
    # motion profile would hold it short of a far target)
    wrapped = _wrapped(scale=0.05, base=IDEAL_BASE)
    assert wrapped.venv.vector_env.config.leg_accel_limit is None
    wrapped.reset()
    before = wrapped.base_actions.copy()
    wrapped.step(np.tile([5.0, -0.5], (len(HEADINGS), 1)).astype(np.float32))  # clipped to 1, then 0.05 x
    sent = np.clip(before + [0.05, -0.025], -1, 1)
    np.testing.assert_allclose(wrapped.venv.vector_env.leg_targets, action_to_leg_targets(sent), atol=1e-6)
    np.testing.assert_array_equal(combine([[0.99, -0.99]], [[1.0, -1.0]], 0.05), [[1.0, -1.0]])


class _Recorder:
    """A stand-in policy: records what it is shown and adds a fixed residual."""

    def __init__(self, residual):
        self.seen, self.residual = [], np.asarray(residual, dtype=np.float32)
        self.env_config, self.env_kwargs = {}, {}

    def predict(self, observation, deterministic=True):
        self.seen.append(np.array(observation))
        return np.tile(self.residual, (len(observation), 1)), None


def test_the_agent_shows_its_policy_what_training_showed_it():
    """ResidualAgent (evaluation) and the training wrapper build the same extended observation and
    send the same actions, with a residual that changes the run."""
    residual = np.array([0.7, -0.3], dtype=np.float32)  # what SB3 sends
    wrapped = _wrapped(scale=0.05)
    agent = ResidualAgent(_Recorder(residual), load_turn_then_run_agent(BASE), 0.05)
    plain = RRRobotVectorEnv(num_envs=len(HEADINGS), max_episode_steps=30, reset_noise_scale=0.0, **BASE_SERVO)
    obs = wrapped.reset()
    raw, _ = plain.reset(seed=list(range(len(HEADINGS))), options={"target_direction": HEADINGS})
    state, start = None, np.ones(len(HEADINGS), dtype=bool)
    for _ in range(12):
        actions, state = agent.predict(raw, state, start)
        start[:] = False
        np.testing.assert_array_equal(agent.policy.seen[-1], obs)
        np.testing.assert_array_equal(actions, combine(wrapped.base_actions, np.tile(residual, (4, 1)), 0.05))
        obs, *_ = wrapped.step(np.tile(residual, (len(HEADINGS), 1)).astype(np.float32))
        raw, *_ = plain.step(actions)
    base_only = _wrapped(scale=0.05)
    base_only.reset()
    for _ in range(12):
        moved, *_ = base_only.step(np.zeros((len(HEADINGS), 2), dtype=np.float32))
    assert np.abs(moved[:, 9:11] - obs[:, 9:11]).max() > 1e-3  # the residual changed the legs' motion


@pytest.mark.parametrize("scale", [0.0, -0.1, 3.0, math.nan, True])
def test_a_bad_scale_is_named(scale):
    venv = RRRobotSB3VecEnv(num_envs=1)
    with pytest.raises(ValueError, match="residual scale"):
        make_residual_vec_env(venv, load_turn_then_run_agent(BASE), scale)


@pytest.mark.parametrize("argv, named", [
    (["--residual-scale", "0"], "--residual-scale"),
    (["--residual-on", "missing.json"], "--residual-on"),
    (["--residual-on", str(ROOT / "agents" / "searched" / "turn_then_run_pivot.json")], "pivot model"),
])
def test_bad_residual_arguments_are_named(argv, named, capsys):
    from rrrobot_gym import training

    with pytest.raises(SystemExit):
        training.parse_args(argv)
    assert named in capsys.readouterr().err


SHIPPED_RESIDUAL = ROOT / "agents" / "pretrained_residual" / "best_model.zip"
SHIPPED_PLAIN = ROOT / "agents" / "pretrained" / "best_model.zip"


@pytest.mark.parametrize("argv, named", [
    (["--resume", str(SHIPPED_RESIDUAL)], "is a residual policy"),  # (not "--residual-on": the usage line has it)
    (["--resume", str(SHIPPED_RESIDUAL), "--residual-on", str(BASE), "--residual-scale", "0.1"], "scale 0.05"),
    (["--resume", str(SHIPPED_PLAIN), "--residual-on", str(BASE)], "not a residual policy"),
])
def test_a_resumed_run_must_match_the_residual_it_was_trained_as(argv, named, capsys):
    from rrrobot_gym import training

    with pytest.raises(SystemExit):
        training.parse_args(argv)
    assert named in capsys.readouterr().err


def test_a_residual_run_resumes_as_one():
    from rrrobot_gym import training

    args = training.parse_args(["--resume", str(SHIPPED_RESIDUAL), "--residual-on", str(BASE), "--residual-scale", "0.05"])
    assert args.residual_scale == 0.05 and args.resume == str(SHIPPED_RESIDUAL)


@pytest.mark.slow
def test_a_residual_run_loads_as_its_policy_on_its_base_and_evaluates(tmp_path, capsys):
    """train.py --residual-on writes residual.json and copies of the base's files; load_ppo_agent
    rebuilds the residual agent from the run directory alone; evaluate.py scores it."""
    run_dir = train_here(["--total-timesteps", "512", "--runs-dir", tmp_path / "runs", "--residual-on", BASE,
                          "--residual-scale", "0.1", *TINY])  # fmt: skip
    spec = json.loads((run_dir / "residual.json").read_text())
    assert spec["scale"] == 0.1 and (run_dir / spec["base"]).is_file()
    assert (run_dir / "residual_base" / "plane_own.json").is_file()
    from rrrobot_gym.agents import load_ppo_agent

    agent = load_ppo_agent(run_dir / "best_model.zip")
    assert isinstance(agent, ResidualAgent) and agent.scale == 0.1
    from stable_baselines3 import PPO

    with pytest.raises(RuntimeError, match="residual on a scripted base agent.*load it with rrrobot_gym.agents.load_ppo_agent"):
        PPO.load(run_dir / "best_model.zip", device="cpu")  # (it would give the residual alone)
    assert agent.policy.model.observation_space.shape == (15 + len(FEATURES),)
    env = RRRobotVectorEnv(num_envs=len(HEADINGS), reset_noise_scale=0.0, **agent.env_kwargs)
    obs, _ = env.reset(options={"target_direction": HEADINGS})
    actions, _ = agent.predict(obs, None, np.ones(len(HEADINGS), dtype=bool))
    base_actions, _ = load_turn_then_run_agent(BASE).predict(obs, None, np.ones(len(HEADINGS), dtype=bool))
    assert 0.0 < np.abs(actions - base_actions).max() <= 0.1 + 1e-6  # the residual acts, within its scale
    evaluated = evaluate_here(["--policy", run_dir / "best_model.zip", "--models", "plane", "--duration", "1"], capsys)
    assert f"| ppo ({run_dir / 'best_model.zip'}) |" in evaluated


def test_the_shipped_residual_policy_loads_from_its_directory_alone():
    from rrrobot_gym.agents import load_ppo_agent

    agent = load_ppo_agent(ROOT / "agents" / "pretrained_residual" / "best_model.zip")
    assert isinstance(agent, ResidualAgent) and agent.scale == 0.05 and agent.base.model == "plane"


def test_a_residual_run_s_checkpoint_loads_and_resumes_as_a_residual_policy(tmp_path, capsys):
    """A checkpoint lives in RUN/checkpoints/, one directory below the run's residual.json: it
    loads on its base as the run's models do, and resuming it asks for the residual's flags."""
    import shutil

    from rrrobot_gym import training
    from rrrobot_gym.agents import load_ppo_agent

    shipped = SHIPPED_RESIDUAL.parent
    run_dir = tmp_path / "run"
    shutil.copytree(shipped / "residual_base", run_dir / "residual_base")
    shutil.copy(shipped / "residual.json", run_dir / "residual.json")
    shutil.copy(shipped / "env_kwargs.json", run_dir / "env_kwargs.json")
    (run_dir / "checkpoints").mkdir()
    checkpoint = run_dir / "checkpoints" / "ppo_1000_steps.zip"
    shutil.copy(SHIPPED_RESIDUAL, checkpoint)
    shutil.copy(shipped / "vecnormalize.pkl", run_dir / "checkpoints" / "ppo_vecnormalize_1000_steps.pkl")
    agent = load_ppo_agent(checkpoint)
    assert isinstance(agent, ResidualAgent) and agent.scale == 0.05 and agent.base.model == "plane"
    with pytest.raises(SystemExit):
        training.parse_args(["--resume", str(checkpoint)])
    assert "is a residual policy" in capsys.readouterr().err


def test_a_residual_resume_is_checked_against_this_runs_observation_too(capsys):
    """The residual's own observation (the env's and its base's features) against this run's env:
    with a clock the resume passed parse_args and failed in SB3's assertion."""
    from rrrobot_gym import training

    with pytest.raises(SystemExit):
        training.parse_args(["--resume", str(SHIPPED_RESIDUAL), "--residual-on", str(BASE), "--residual-scale", "0.05",
                          "--clock-frequency", "8"])  # fmt: skip
    assert "the model observes 21 numbers, this run's env 23" in capsys.readouterr().err


def test_a_residual_agent_names_an_observation_it_cannot_take():
    from rrrobot_gym.agents import load_ppo_agent

    agent = load_ppo_agent(SHIPPED_RESIDUAL)
    with pytest.raises(ValueError, match=r"shape \(15,\) or \(n, 15\) for this policy, got \(17,\)"):
        agent.predict(np.zeros(17))  # (named the extended (1, 23) and the policy's 21 before)
