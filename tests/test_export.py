"""``rrrobot export-onnx``: the ONNX network gives the shipped policies' actions on observations of
their own rollouts, the mirror branch included; a policy that is not one network is refused."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
ort = pytest.importorskip("onnxruntime")
pytest.importorskip("onnx")

import gymnasium  # noqa: E402

import rrrobot_gym  # noqa: E402,F401  (registers RRRobot-v0)
from rrrobot_gym.agents import load_ppo_agent  # noqa: E402
from rrrobot_gym.agents.mirror import sin_index  # noqa: E402
from rrrobot_gym.cli import main  # noqa: E402
from rrrobot_gym.envs.task import make_task_config  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ["pretrained", "pretrained_pivot", "family_legs4"]  # (the last: a four-leg robot)
HEADINGS_DEG = (0, 45, 90, 135, 180, -135, -90, -45)
"""From the paper's start: the +Y side, the -Y side (mirrored) and both axis headings (not)."""


def _recorded_observations(agent, steps=12):
    """The observations of ``agent``'s own rollouts in its training env along every heading."""
    env = gymnasium.make("RRRobot-v0", **{**agent.env_config, "target_direction": None})
    observations = []
    for seed, heading in enumerate(HEADINGS_DEG):
        observation, _ = env.reset(seed=seed, options={"target_direction": np.radians(heading)})
        for _ in range(steps):
            observations.append(observation)
            action, _ = agent.predict(observation, deterministic=True)
            observation, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
    env.close()
    return np.array(observations)


@pytest.mark.parametrize("shipped", SHIPPED)
def test_the_onnx_network_gives_the_policy_s_actions(shipped, tmp_path, capsys):
    model = ROOT / "agents" / shipped / "best_model.zip"
    out = tmp_path / "policy.onnx"
    assert main(["export-onnx", str(model), "--out", str(out)]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    agent = load_ppo_agent(model)
    observations = _recorded_observations(agent)
    sines = observations[:, sin_index(make_task_config(**agent.env_config))]
    assert (sines < -0.5).sum() >= 20 and (sines > 0.5).sum() >= 20  # both sides of the mirror seen
    # and observations far outside the training statistics, so the normalisation's clip acts
    observations = np.concatenate([observations, 1e3 * observations[::8]])

    session = ort.InferenceSession(str(out), providers=["CPUExecutionProvider"])
    assert [i.name for i in session.get_inputs()] == ["observation"]
    onnx_actions = session.run(["action"], {"observation": observations.astype(np.float32)})[0]
    expected, _ = agent.predict(observations, deterministic=True)
    legs = make_task_config(**agent.env_config).num_robot_legs  # (one action a leg)
    assert onnx_actions.shape == (len(observations), legs) and onnx_actions.dtype == np.float32
    np.testing.assert_allclose(onnx_actions, expected, rtol=0, atol=1e-5)
    assert np.abs(expected).max() > 0.1  # (the actions are not trivially equal)
    # one row at a time (the batch axis is dynamic) gives the same
    single = session.run(["action"], {"observation": observations[:1].astype(np.float32)})[0]
    np.testing.assert_allclose(single, expected[:1], rtol=0, atol=1e-5)


def test_a_residual_policy_is_refused(tmp_path, capsys):
    model = ROOT / "agents" / "pretrained_residual" / "best_model.zip"
    assert main(["export-onnx", str(model), "--out", str(tmp_path / "policy.onnx")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rrrobot: error: ") and "residual" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "policy.onnx").exists()


def test_a_policy_without_its_statistics_is_refused(tmp_path, capsys):
    for name in ("best_model.zip", "env_kwargs.json", "args.json", "mirror.json"):
        shutil.copy(ROOT / "agents" / "pretrained_pivot" / name, tmp_path / name)
    out = tmp_path / "policy.onnx"
    assert main(["export-onnx", str(tmp_path / "best_model.zip"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rrrobot: error: ") and "vecnormalize.pkl is missing" in err
    assert len(err.strip().splitlines()) == 1 and not out.exists()
    assert main(["export-onnx", str(tmp_path / "none.zip"), "--out", str(out)]) == 2
    assert "no PPO model at" in capsys.readouterr().err
