"""The family's members through the env, the vector env, the mirror and the gait search: sizes follow
the leg count, episodes run without NaN, batches step as single envs do, and bad keywords are refused
naming the keyword."""

from __future__ import annotations

import json
import math

import gymnasium
import numpy as np
import pytest

import rrrobot_gym  # noqa: F401  (registers RRRobot-v0)
from rrrobot_gym import evaluation, gait_search
from rrrobot_gym.agents.mirror import has_mirror
from rrrobot_gym.envs.task import TERMINATIONS, make_task_config
from rrrobot_gym.envs.vector import RRRobotVectorEnv
from rrrobot_gym.gait_search import SinusoidGait

OBLATE = (0.12, 0.12, 0.09)


def _episode(steps, seed=0, **kwargs):
    """Random actions (seeded) for up to ``steps`` steps: the observations, rewards and end."""
    env = gymnasium.make("RRRobot-v0", **kwargs)
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    observations, rewards, info = [obs], [], {}
    for _ in range(steps):
        action = rng.uniform(-1.0, 1.0, env.action_space.shape).astype(np.float32)
        obs, reward, terminated, truncated, info = env.step(action)
        observations.append(obs)
        rewards.append(reward)
        if terminated or truncated:
            break
    env.close()
    return env, np.array(observations), np.array(rewards), info


STEP = {1: "auto"}
"""One leg swings the body about more than two do: its servo's fastest pole (2,000 1/s on the plane
against 380) puts the default 1/300 s beyond rk4's stability limit (1/728 s), which the env refuses
naming timestep="auto"; every other count runs at the default step."""


@pytest.mark.parametrize("legs", [1, 3, 4, 6])
def test_the_action_and_observation_follow_the_leg_count(legs):
    env = gymnasium.make("RRRobot-v0", num_legs=legs, timestep=STEP.get(legs, 1 / 300), backend="numpy")
    assert env.action_space.shape == (legs,)
    assert env.observation_space.shape == (11 + 2 * legs,)  # (the contact position excluded, as by default)
    obs, _ = env.reset(seed=0)
    obs, _, _, _, _ = env.step(env.action_space.sample())
    assert obs.shape == (11 + 2 * legs,) and np.all(np.isfinite(obs))
    env.close()


def test_one_leg_at_the_default_step_is_refused_naming_the_step_that_runs():
    with pytest.raises(ValueError, match="beyond the stability limit.*timestep='auto'"):
        gymnasium.make("RRRobot-v0", num_legs=1)


@pytest.mark.parametrize("kwargs", [{"num_legs": 3, "backend": "numpy"}, {"shell_axes": OBLATE},
                                    {"num_legs": 4, "shell_axes": OBLATE}, {"shell_axes": (0.12, 0.12, 0.168)}])
def test_a_member_runs_a_random_episode_to_its_end_without_nan(kwargs):
    env, observations, rewards, info = _episode(2000, **kwargs)
    assert np.all(np.isfinite(observations)) and np.all(np.isfinite(rewards))
    assert len(rewards) >= 5  # (random actions end a plane episode in about 2 s)
    assert info["termination"] in TERMINATIONS and info["termination"] != "numerical_failure"


@pytest.mark.parametrize("kwargs, name", [
    ({"num_legs": 0}, "num_legs"), ({"num_legs": 7}, "num_legs"), ({"num_legs": 2.5}, "num_legs"),
    ({"num_legs": True}, "num_legs"), ({"shell_axes": (0.12, 0.12)}, "shell_axes"),
    ({"shell_axes": (0.12, -0.12, 0.1)}, "shell_axes"), ({"shell_axes": (0.12, 0.12, math.nan)}, "shell_axes"),
    ({"shell_axes": "round"}, "shell_axes"),
])  # fmt: skip
def test_a_bad_leg_count_or_shell_is_refused_in_one_line_naming_the_keyword(kwargs, name):
    with pytest.raises((TypeError, ValueError), match=name) as error:
        gymnasium.make("RRRobot-v0", **kwargs)
    assert "\n" not in str(error.value)


def test_a_batch_of_three_leg_robots_steps_as_single_envs_do():
    """The vector env's rows are the single env's steps, bit for bit, for a member too."""
    kwargs = dict(num_legs=3, shell_axes=OBLATE, backend="numpy")
    venv = RRRobotVectorEnv(num_envs=3, **kwargs)
    obs, _ = venv.reset(seed=[4, 5, 6])
    singles = [gymnasium.make("RRRobot-v0", **kwargs) for _ in range(3)]
    single_obs = [env.reset(seed=seed)[0] for env, seed in zip(singles, (4, 5, 6))]
    assert np.array_equal(obs, np.array(single_obs))
    rng = np.random.default_rng(1)
    for _ in range(20):
        actions = rng.uniform(-0.5, 0.5, (3, 3)).astype(np.float32)
        obs, rewards, terminated, _, _ = venv.step(actions)
        for i, env in enumerate(singles):
            o, r, t, _, _ = env.step(actions[i])
            assert np.array_equal(obs[i], o) and rewards[i] == r and terminated[i] == t
    venv.close()


@pytest.mark.parametrize("legs, mirrored", [(1, False), (2, True), (3, False), (4, True), (5, False), (6, True)])
def test_the_heading_mirror_is_used_only_where_the_legs_have_the_symmetry(legs, mirrored):
    """Reflecting y -> -y maps the default rim placement onto itself (a leg
    at -90 deg has one at +90 deg) for 2, 4 and 6 legs; for 1, 3 and 5 it does not, and training learns every heading."""
    assert has_mirror(make_task_config(num_legs=legs, timestep=STEP.get(legs, 1 / 300))) is mirrored


def test_an_l_leg_sinusoid_is_each_legs_own_sinusoid():
    amplitudes, offsets, w, phases = (0.4, 0.5, 0.6, 0.7), (1.0, 1.2, 1.4, 1.6), 7.0, (0.0, 0.5, 1.5, -2.0)
    gait = SinusoidGait(*amplitudes, *offsets, w, *phases[1:])
    assert gait.num_legs == 4 and gait.phase_4 == -2.0
    times = np.linspace(0.0, 2.0, 9)
    expected = np.stack([o + a * np.sin(w * times + b) for a, o, b in zip(amplitudes, offsets, phases)], axis=-1)
    np.testing.assert_allclose(gait.angles(times), expected, rtol=0, atol=1e-15)
    angles, rates, _ = gait.leg_targets(0.7)
    np.testing.assert_allclose(angles, [o + a * math.sin(w * 0.7 + b)
                                                         for a, o, b in zip(amplitudes, offsets, phases)], atol=1e-15)
    np.testing.assert_allclose(rates, [a * w * math.cos(w * 0.7 + b) for a, b in zip(amplitudes, phases)], atol=1e-14)
    assert SinusoidGait.from_dict(gait.parameters()) == gait


def test_a_search_on_a_four_leg_robot_writes_its_leg_count_and_names_and_evaluate_scores_it(tmp_path):
    # (four legs: the leg count whose compiled stepper the suite builds anyway, for the shipped policy)
    result = gait_search.search(budget_evaluations=12, popsize=4, screen=4, duration=1.0, robustness_seeds=1,
                                robustness_duration=1.0, robust_pool=2, keep=2, progress=False, num_legs=4,
                                backend="numpy")  # fmt: skip
    data = result.to_json()
    assert data["num_legs"] == 4 and data["parameter_names"] == list(gait_search.parameter_names(4))
    assert set(data["bounds"]) == set(data["parameter_names"])
    path = tmp_path / "gaits.json"
    result.write_json(path)
    gaits = gait_search.load_gaits(path)
    assert [g.num_legs for g in gaits] == [4, 4]
    # evaluate.py runs the file's gaits on their robot, leaving out the two-leg Table II gaits
    report = tmp_path / "report.json"
    records = evaluation.main(["--no-policy", "--gaits", str(path), "--models", "plane", "--duration", "1",
                               "--json", str(report)])  # fmt: skip
    assert json.loads(report.read_text())["records"] == json.loads(json.dumps(records))
    scored = {r["agent"] for r in records}
    assert scored == {g.name for g in gaits}
    with pytest.raises(ValueError, match="3 legs, so a gait has 9 parameters"):
        gait_search.evaluate_population(np.zeros((1, 6)), duration=1.0, num_legs=3, backend="numpy")
