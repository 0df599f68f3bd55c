"""The scripted turn-then-run baseline: it reads the yaw from the observation and turns the body."""

import math
from pathlib import Path

import numpy as np
import pytest

from agents.turn_then_run import TurnThenRunAgent, load_turn_then_run_agent, relative_yaw
from rrrobot_gym.envs import task
from rrrobot_gym.envs.vector import RRRobotVectorEnv

FILE = Path(__file__).resolve().parents[1] / "agents" / "searched" / "turn_then_run.json"
PIVOT_FILE = FILE.with_name("turn_then_run_pivot.json")


def _yaw(states):
    """Heading of the body x axis's horizontal part, from the quaternion (not the observation code)."""
    qw, qx, qy, qz = states[:, 2], states[:, 3], states[:, 4], states[:, 5]
    return np.arctan2(2.0 * (qx * qy + qw * qz), 1.0 - 2.0 * (qy * qy + qz * qz))


def test_relative_yaw_from_the_observation_is_the_body_yaw_minus_the_heading():
    rng = np.random.default_rng(5)
    states = task.start_states(np.zeros((200, 10)))
    quat = rng.standard_normal((200, 4))
    quat[:, 3] *= 3.0  # mostly yaw, with tilts up to the rim
    states[:, 2:6] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    keep = np.arccos(np.clip(1 - 2 * (states[:, 3] ** 2 + states[:, 4] ** 2), -1, 1)) < 1.2
    states, targets = states[keep], rng.uniform(-math.pi, math.pi, keep.sum())
    obs = task.observe(states, targets, task.make_task_config(), np.zeros(len(states)))
    error = (relative_yaw(obs) - (_yaw(states) - targets) + math.pi) % (2 * math.pi) - math.pi
    assert len(states) > 50 and np.abs(error).max() < 1e-5  # float32 observations


def _run(agent, headings_deg, seconds, halfway=False, **env_kwargs):
    """Start, end states, which episodes ended and the agent's state; with ``halfway`` also the
    states and agent state at half the time (one run instead of two)."""
    env = RRRobotVectorEnv(num_envs=len(headings_deg), max_episode_steps=None, reset_noise_scale=0.0, **env_kwargs)
    obs, _ = env.reset(seed=0, options={"target_direction": np.radians(headings_deg)})
    start, state, ended = env.states.copy(), None, np.zeros(len(headings_deg), dtype=bool)
    steps = int(round(seconds / env.dt))
    for k in range(steps):
        actions, state = agent.predict(obs, state=state, episode_start=np.full(len(headings_deg), k == 0))
        obs, _, terminated, _, _ = env.step(actions)
        ended |= terminated
        if halfway and k + 1 == steps // 2:
            middle = env.states.copy(), ended.copy(), state  # predict returns a new state each step
    return (start, env.states.copy(), ended, state) + (middle if halfway else ())


def test_it_turns_the_body_towards_the_heading_and_then_runs_along_it():
    """Along 0 deg from the paper's start the running gait (93 deg from the body's yaw) needs a
    quarter turn clockwise: after 12 s the yaw has turned about -90 deg and the robot travels
    along 0 deg; along 90 deg it runs at once, without turning."""
    agent = load_turn_then_run_agent(FILE)
    start, end, ended_end, _, after, ended, state = _run(agent, [0.0, 90.0], 24.0, halfway=True)
    assert not ended.any()
    assert state["mode"][1] == 2 and np.isnan(state["switched"][1])  # ran at once
    turned = np.degrees((_yaw(after) - _yaw(start) + math.pi) % (2 * math.pi) - math.pi)
    assert state["mode"][0] == 2 and abs(turned[0] + 90.0) < 30.0 and abs(turned[1]) < 30.0
    travel = end[0, 0:2] - start[0, 0:2]
    assert not ended_end[0] and travel[0] > 0.6 * 0.094 * 12.0  # most of the last 12 s at ~94 mm/s along +x


def test_on_the_pivot_it_turns_a_quarter_anticlockwise_and_then_runs_along_the_heading():
    """Pivot model, under evaluate.py's pivot motors (0.5 N m, 10 rad/s). The running gait
    (searched-pivot-own-1) travels at the body's yaw - 90 deg, so along 0 deg from the paper's
    start it needs a quarter turn anticlockwise (the turning gait's mirror): after 8 s the yaw
    has turned about +90 deg and it runs; from 8 to 16 s it travels along +x at well over half
    the gait's ~90 mm/s (the experiment: 89.7 mm/s over 50 s), and no episode ends."""
    agent = load_turn_then_run_agent(PIVOT_FILE)
    assert agent.model == "pivot" and agent.direction_offset == pytest.approx(-0.5 * math.pi)
    start, end, ended_end, _, after, ended, state = _run(
        agent, [0.0], 16.0, halfway=True, model="pivot", torque_limit=0.5, leg_rate_limit=10.0
    )
    assert not ended.any() and not ended_end.any()
    assert state["mode"][0] == 2 and 1.0 < state["switched"][0] < 5.0  # turned, blended, running
    turned = np.degrees((_yaw(after) - _yaw(start) + math.pi) % (2 * math.pi) - math.pi)
    assert abs(turned[0] - 90.0) < 30.0
    travel = end[0, 0:2] - after[0, 0:2]
    assert travel[0] > 0.6 * 0.09 * 8.0 and abs(travel[1]) < 0.5 * travel[0]


def test_bad_turn_then_run_input_is_named(tmp_path):
    with pytest.raises(ValueError, match="turn_gait must be 6 finite numbers"):
        TurnThenRunAgent([1.0, 2.0], np.zeros(6), dt=0.05, lead=0.5, ramp=1.0)
    with pytest.raises(ValueError, match="ramp must be a positive"):
        TurnThenRunAgent(np.zeros(6), np.zeros(6), dt=0.05, lead=0.5, ramp=0.0)
    agent = load_turn_then_run_agent(FILE)
    obs = np.zeros((3, 15), dtype=np.float32)
    obs[:, 2], obs[:, 3] = 1.0, 1.0
    _, state = agent.predict(obs)
    with pytest.raises(ValueError, match="state must be this agent's state for 2 envs"):
        agent.predict(obs[:2], state=state)
    bad = tmp_path / "ttr.json"
    bad.write_text('{"turn_gait": [0, 0, 1, 1, 8, 0]}')
    with pytest.raises(ValueError, match="KeyError"):
        load_turn_then_run_agent(bad)


def test_evaluate_scores_the_baseline_on_the_plane_only_with_no_own_direction(capsys):
    import evaluate

    records = evaluate.main(["--no-policy", "--duration", "0.5", "--turn-then-run", str(FILE)])
    table = capsys.readouterr().out
    row = next(line for line in table.splitlines() if line.startswith("| turn-then-run |"))
    assert row.split("|")[-2].strip() == ""  # no "own direction": scored along the compass headings
    assert {r["model"] for r in records if r["agent"] == "turn-then-run"} == {"plane"}  # searched there only
    assert {r["model"] for r in records} == {"plane", "pivot"}


def test_evaluate_scores_each_baseline_file_on_the_model_its_json_names(capsys, tmp_path):
    import evaluate

    assert load_turn_then_run_agent(FILE).model == "plane" and load_turn_then_run_agent(PIVOT_FILE).model == "pivot"
    records = evaluate.main(["--no-policy", "--duration", "0.5", "--turn-then-run", str(PIVOT_FILE), "--turn-then-run", str(FILE)])
    table = capsys.readouterr().out
    rows = [line for line in table.splitlines() if line.startswith("| turn-then-run |") and line.count("|") == 11]
    assert len(rows) == 2 and all(row.split("|")[-2].strip() == "" for row in rows)  # both speed tables: no own direction
    ours = [r for r in records if r["agent"] == "turn-then-run"]
    assert {r["model"] for r in ours} == {"plane", "pivot"} and not any("turn-then-run" in r["own_direction_of"] for r in ours)
    ours = [r for r in ours if r["compass"]]  # (it also runs along the gaits' own directions, as every agent does)
    assert sorted(r["model"] for r in ours) == ["pivot"] * 8 + ["plane"] * 8
    # Each model's scores are its own file's agent's (the same runs again by hand), not the other file's.
    for model, mine, other in (("plane", FILE, PIVOT_FILE), ("pivot", PIVOT_FILE, FILE)):
        scored = [r["displacement_m"] for r in ours if r["model"] == model]
        again = {f: [r["displacement_m"] for r in evaluate.score(evaluate.run_episodes(
            {"b": load_turn_then_run_agent(f)}, model, evaluate.COMPASS_DEG, 0.5)["b"], evaluate.COMPASS_DEG, 0.5)]
            for f in (mine, other)}  # fmt: skip
        assert np.allclose(scored, again[mine], rtol=0, atol=1e-9) and not np.allclose(scored, again[other], rtol=0, atol=1e-4)
    with pytest.raises(SystemExit):  # two files for one model: an error naming the second file
        evaluate.main(["--no-policy", "--duration", "0.5", "--turn-then-run", str(FILE), "--turn-then-run", str(FILE)])
    assert f"--turn-then-run {FILE}: a second baseline for the plane model" in capsys.readouterr().err
    bad = tmp_path / "ttr.json"  # beside a copy of its running gait's file
    (tmp_path / "pivot_own_limited.json").write_text(PIVOT_FILE.with_name("pivot_own_limited.json").read_text())
    bad.write_text(PIVOT_FILE.read_text().replace('"model": "pivot"', '"model": "moon"'))
    with pytest.raises(SystemExit):
        evaluate.main(["--no-policy", "--turn-then-run", str(bad)])
    assert f"turn-then-run file {bad}: \"model\" must be" in capsys.readouterr().err
