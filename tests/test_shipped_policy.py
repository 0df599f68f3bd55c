"""The pretrained policies shipped in agents/ load and walk, right after install, and only as they
were trained to run."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "agents" / "pretrained" / "best_model.zip"
SHIPPED_PIVOT = ROOT / "agents" / "pretrained_pivot" / "best_model.zip"
FOLDERS = ("pretrained", "pretrained_pivot", "pretrained_residual")
RECORDED = ROOT / "tests" / "data" / "shipped_policy_actions.npz"
"""Each shipped agent of FOLDERS along 12 headings (the compass; 1, 359, 100 and 260 deg), its first
40 steps from the paper's start with start noise (seed 0), as load_ppo_agent ran them before the
zips named a policy class PPO.load refuses: ``<folder>/observations`` (40, 12, 15) and
``<folder>/actions`` (40, 12, 2), and ``headings_deg``."""


@pytest.mark.parametrize("folder", FOLDERS)
def test_sb3_s_own_load_of_a_shipped_policy_is_refused_in_one_line_naming_the_loader(folder):
    """PPO.load and the VecNormalize statistics ran the mirrored networks unmirrored towards -Y (next
    test) and the residual network without its base agent; each zip now names a class that refuses."""
    from stable_baselines3 import PPO

    with pytest.raises(RuntimeError, match=r"load it with rrrobot_gym\.agents\.load_ppo_agent\(path\)") as refused:
        PPO.load(ROOT / "agents" / folder / "best_model.zip", device="cpu")
    assert "\n" not in str(refused.value)


@pytest.mark.parametrize("folder", ["pretrained", "pretrained_pivot"])
def test_the_mirrored_network_alone_acts_as_its_agent_only_on_headings_towards_plus_y(folder):
    """What the refusal guards against, as a user measured it: the network with its VecNormalize
    statistics (the usual SB3 way) acts as the agent where sin(heading) >= 0 and otherwise on every
    heading towards -Y (by more than 0.3 here; up to 1.5)."""
    import pickle

    from rrrobot_gym.agents.ppo import load_sb3_model

    recorded = np.load(RECORDED)
    observations, actions = recorded[f"{folder}/observations"], recorded[f"{folder}/actions"]
    with open(ROOT / "agents" / folder / "vecnormalize.pkl", "rb") as handle:
        stats = pickle.load(handle)
    normalised = np.clip((observations - stats.obs_rms.mean) / np.sqrt(stats.obs_rms.var + stats.epsilon),
                         -stats.clip_obs, stats.clip_obs).astype(np.float32)  # fmt: skip
    network = load_sb3_model(ROOT / "agents" / folder / "best_model.zip")
    usual = network.predict(normalised.reshape(-1, observations.shape[-1]), deterministic=True)[0].reshape(actions.shape)
    plus_y = np.sin(np.radians(recorded["headings_deg"])) >= 0
    np.testing.assert_allclose(usual[:, plus_y], actions[:, plus_y], rtol=0, atol=1e-5)
    assert np.abs(usual[:, ~plus_y] - actions[:, ~plus_y]).max(axis=(0, 2)).min() > 0.3


@pytest.mark.parametrize("folder", FOLDERS)
def test_each_shipped_policy_acts_as_recorded_before_its_zip_refused_ppo_load(folder):
    """The zips were rewritten in the policy class they name only (the network's and the optimizer's
    bytes as they were): load_ppo_agent's actions on the recorded observations are the recorded ones on
    every heading, to 1e-5 (float32 network arithmetic may round otherwise on another CPU; they were
    equal to the bit where recorded), the residual agent's base carried through the steps."""
    from rrrobot_gym.agents import load_ppo_agent
    from rrrobot_gym.agents.mirror import MirroredPolicy
    from rrrobot_gym.agents.ppo import saved_policy_class
    from rrrobot_gym.agents.residual import ResidualPolicy

    path = ROOT / "agents" / folder / "best_model.zip"
    assert saved_policy_class(path) is (ResidualPolicy if folder == "pretrained_residual" else MirroredPolicy)
    recorded = np.load(RECORDED)
    agent = load_ppo_agent(path)
    state, starting = None, np.ones(len(recorded["headings_deg"]), dtype=bool)
    for observations, expected in zip(recorded[f"{folder}/observations"], recorded[f"{folder}/actions"]):
        actions, state = agent.predict(observations, state=state, episode_start=starting)
        starting = np.zeros_like(starting)
        np.testing.assert_allclose(actions, expected, rtol=0, atol=1e-5)


def test_a_zip_that_names_the_mirror_needs_its_mirror_file_even_without_args_json(tmp_path):
    import shutil

    from rrrobot_gym.agents import load_ppo_agent

    run = tmp_path / "run"
    shutil.copytree(ROOT / "agents" / "pretrained", run)
    (run / "mirror.json").unlink()
    (run / "args.json").unlink()
    with pytest.raises(FileNotFoundError, match="mirror.json is missing \\(the zip names MirroredPolicy as its policy"):
        load_ppo_agent(run / "best_model.zip")
    with pytest.raises(ValueError, match="README.md is not a Stable-Baselines3 model zip"):
        load_ppo_agent(ROOT / "README.md")


@pytest.mark.slow  # (episodes of the shipped policies)
def test_the_shipped_policy_acts_on_observations_normalised_with_its_saved_statistics():
    """SB3's predict clips actions to the box, so an action range check cannot fail; what can
    go wrong is the normalisation: the agent must feed the policy VecNormalize's statistics."""
    import pickle

    import gymnasium

    from rrrobot_gym.agents import load_ppo_agent
    from rrrobot_gym.agents.mirror import MirroredAgent

    agent = load_ppo_agent(SHIPPED)
    if isinstance(agent, MirroredAgent):  # (trained mirrored: the network and its statistics inside)
        agent = agent.policy
    with open(SHIPPED.with_name("vecnormalize.pkl"), "rb") as handle:
        stats = pickle.load(handle)
    env = gymnasium.make("RRRobot-v0", **agent.env_kwargs)
    observations = np.array([env.reset(seed=seed)[0] for seed in range(4)])
    expected = np.clip(
        (observations - stats.obs_rms.mean) / np.sqrt(stats.obs_rms.var + stats.epsilon), -stats.clip_obs, stats.clip_obs
    ).astype(np.float32)
    actions, _ = agent.predict(observations)
    np.testing.assert_allclose(actions, agent.model.predict(expected, deterministic=True)[0], atol=1e-6)
    raw, _ = agent.model.predict(observations, deterministic=True)
    assert np.max(np.abs(actions - raw)) > 0.05  # the statistics matter: raw observations act otherwise


@pytest.mark.slow  # (episodes of the shipped policies)
def test_the_shipped_policy_travels_along_the_commanded_heading():
    from rrrobot_gym.agents import load_ppo_agent
    from rrrobot_gym.evaluation import run_episodes, score

    headings = [90.0, 270.0]
    run = run_episodes({"ppo": load_ppo_agent(SHIPPED)}, "plane", headings, duration=10.0)["ppo"]
    records = score(run, headings, 10.0)
    for record in records:
        assert not record["terminated"]
        # the paper's gait 1 makes about 9 mm/s along its axis; the policy beats it there
        assert record["speed_mps"] > 0.009, record


@pytest.mark.slow  # (episodes of the shipped policies)
def test_the_shipped_pivot_policy_moves_along_its_headings_inside_its_motor_limits():
    """Trained on the pivot model with a 0.5 N m stall torque and a 10 rad/s no-load speed: it
    runs under them (the applied torque never exceeds 0.5 N m) and, 15 s from the paper's start,
    already makes more than twice Gait 1's 10.8 mm/s along its own axis (the issue's pivot target)
    on two opposite diagonals (it makes ~98 mm/s there)."""
    from rrrobot_gym.agents import load_ppo_agent
    from rrrobot_gym.evaluation import run_episodes, score

    agent = load_ppo_agent(SHIPPED_PIVOT)
    assert (agent.env_config["model"], agent.env_kwargs["torque_limit"], agent.env_kwargs["leg_rate_limit"]) == (
        "pivot", 0.5, 10.0)
    headings = [45.0, 225.0]
    run = run_episodes({"ppo": agent}, "pivot", headings, duration=15.0)["ppo"]
    for record in score(run, headings, 15.0):
        assert not record["terminated"]
        assert record["peak_torque_nm"] <= 0.5 + 1e-9, record
        assert record["speed_mps"] > 2 * 0.0108, record


@pytest.mark.slow  # (episodes of the shipped policies)
def test_evaluate_uses_the_shipped_policies_by_default(tmp_path):
    out = tmp_path / "eval.json"
    result = subprocess.run(
        [sys.executable, "evaluate.py", "--duration", "2", "--json", str(out)],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    assert result.returncode == 0, result.stderr
    records = json.loads(out.read_text())["records"]
    agents = {r["agent"] for r in records}
    assert "ppo" in agents and "gait1" in agents
    # each model's ppo rows name its file: the plane's and the pivot's shipped policies, each on its own model
    assert {(r["model"], r["policy_file"], r["trained_on"]) for r in records if r["agent"] == "ppo"} == {
        ("plane", "agents/pretrained/best_model.zip", "plane"), ("pivot", "agents/pretrained_pivot/best_model.zip", "pivot")}
    # each model's ppo is its shipped policy: every agent there runs under the servo it was trained with
    for model, policy in (("plane", SHIPPED), ("pivot", SHIPPED_PIVOT)):
        trained = json.loads((policy.parent / "env_kwargs.json").read_text())
        servo = {key: trained[key] for key in ("torque_limit", "leg_rate_limit", "leg_accel_limit")}
        assert all(r["physics"] == servo for r in records if r["model"] == model)
