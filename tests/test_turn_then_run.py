"""The scripted turn-then-run baseline: it reads the yaw from the observation and turns the body."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from rrrobot_gym.agents.turn_then_run import TurnThenRunAgent, load_turn_then_run_agent, relative_yaw
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


def _run(agent, headings_deg, seconds, halfway=False, yaws=None, **env_kwargs):
    """Start, end states, which episodes ended and the agent's state; with ``halfway`` also the
    states and agent state at half the time (one run instead of two); the body's yaw after each
    step appended to a list ``yaws``."""
    env = RRRobotVectorEnv(num_envs=len(headings_deg), max_episode_steps=None, reset_noise_scale=0.0, **env_kwargs)
    obs, _ = env.reset(seed=0, options={"target_direction": np.radians(headings_deg)})
    start, state, ended = env.states.copy(), None, np.zeros(len(headings_deg), dtype=bool)
    steps = int(round(seconds / env.dt))
    for k in range(steps):
        actions, state = agent.predict(obs, state=state, episode_start=np.full(len(headings_deg), k == 0))
        obs, _, terminated, _, _ = env.step(actions)
        ended |= terminated
        if yaws is not None:
            yaws.append(_yaw(env.states))
        if halfway and k + 1 == steps // 2:
            middle = env.states.copy(), ended.copy(), state  # predict returns a new state each step
    return (start, env.states.copy(), ended, state) + (middle if halfway else ())


def test_it_turns_the_body_towards_the_heading_and_then_runs_along_it():
    """Along 0 deg from the paper's start the running gait (at the body's yaw - 90 deg) needs a
    quarter turn anticlockwise: it turns, runs, and over the last 12 s travels along 0 deg with the
    yaw turned about +90 deg; along 90 deg (the gait's mirror travels at the yaw + 90 deg) it runs
    at once, without turning. Both at most of the gait's ~82 mm/s (its search's speed)."""
    agent = load_turn_then_run_agent(FILE)
    yaws = []
    start, end, ended_end, _, after, ended, state = _run(agent, [0.0, 90.0], 24.0, halfway=True, yaws=yaws,
                                                         **agent.search_env_kwargs)  # (its servo: the default one)
    assert not ended_end.any()
    assert state["mode"][1] == 2 and np.isnan(state["switched"][1])  # ran at once
    assert state["mode"][0] == 2 and 0.0 < state["switched"][0] < 12.0  # turned, then ran
    # (the yaw swings up to +-30 deg within each 0.85 s period of the running gait: its means over 2 s and 6 s)
    turned = np.degrees((np.array(yaws) - _yaw(start) + math.pi) % (2 * math.pi) - math.pi)
    second = int(round(1.0 / agent.dt))
    assert turned[4 * second : 6 * second, 0].mean() > 45.0, turned[::second]  # (turning, the right way)
    last = turned[-6 * second :].mean(axis=0)
    assert abs(last[0] - 90.0) < 20.0 and abs(last[1]) < 20.0, last
    travel = end[:, 0:2] - after[:, 0:2]  # the last 12 s: along +x, and along +y
    assert travel[0, 0] > 0.6 * 0.082 * 12.0 and abs(travel[0, 1]) < 0.5 * travel[0, 0], travel
    assert travel[1, 1] > 0.6 * 0.082 * 12.0 and abs(travel[1, 0]) < 0.5 * travel[1, 1], travel


def test_on_the_pivot_it_turns_a_quarter_anticlockwise_and_then_runs_along_the_heading():
    """Pivot model, under its file's servo (the default: 0.5 N m, 10 rad/s, 60 rad/s^2 profile).
    The running gait (pivot_own.json's searched-pivot-own-1) travels at the body's yaw - 91 deg,
    so along 0 deg from the paper's start it needs a quarter turn anticlockwise (the turning
    gait's mirror). It switches to running within 5 s, short of the full turn, and the heading
    correction brings the yaw on: from 16 to 32 s its mean has turned about +90 deg and the robot
    travels along +x at well over half the gait's ~85 mm/s (its search's speed; ~85 mm/s here),
    and no episode ends. (From 8 to 16 s it still travels ~40 deg off the heading.)"""
    agent = load_turn_then_run_agent(PIVOT_FILE)
    assert agent.model == "pivot" and agent.direction_offset == pytest.approx(math.radians(-91.0))
    assert agent.search_env_kwargs == {"torque_limit": 0.5, "leg_rate_limit": 10.0, "leg_accel_limit": 60.0}
    yaws = []
    start, end, ended_end, _, after, ended, state = _run(agent, [0.0], 32.0, halfway=True, yaws=yaws, model="pivot",
                                                         **agent.search_env_kwargs)  # fmt: skip
    assert not ended.any() and not ended_end.any()
    assert state["mode"][0] == 2 and 1.0 < state["switched"][0] < 5.0  # turned, blended, running
    # (the yaw swings by ~20 deg (its standard deviation) about its mean: the means over 8 s and 16 s)
    turned = np.degrees((np.array(yaws)[:, 0] - _yaw(start)[0] + math.pi) % (2 * math.pi) - math.pi)
    second = int(round(1.0 / agent.dt))
    assert turned[: 8 * second].mean() > 20.0 and abs(turned[16 * second :].mean() - 90.0) < 20.0, turned[::second]
    travel = end[0, 0:2] - after[0, 0:2]
    assert travel[0] > 0.6 * 0.085 * 16.0 and abs(travel[1]) < 0.5 * travel[0], travel


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
    from rrrobot_gym import evaluation

    records = evaluation.main(["--no-policy", "--duration", "0.5", "--turn-then-run", str(FILE)])
    table = capsys.readouterr().out
    row = next(line for line in table.splitlines() if line.startswith("| turn-then-run |"))
    assert row.split("|")[-2].strip() == ""  # no "own direction": scored along the compass headings
    assert {r["model"] for r in records if r["agent"] == "turn-then-run"} == {"plane"}  # searched there only
    assert {r["model"] for r in records} == {"plane", "pivot"}


def test_evaluate_scores_each_baseline_file_on_the_model_its_json_names(capsys, tmp_path):
    from rrrobot_gym import evaluation

    assert load_turn_then_run_agent(FILE).model == "plane" and load_turn_then_run_agent(PIVOT_FILE).model == "pivot"
    records = evaluation.main(["--no-policy", "--duration", "0.5", "--turn-then-run", str(PIVOT_FILE), "--turn-then-run", str(FILE)])
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
        again = {f: [r["displacement_m"] for r in evaluation.score(evaluation.run_episodes(
            {"b": load_turn_then_run_agent(f)}, model, evaluation.COMPASS_DEG, 0.5)["b"], evaluation.COMPASS_DEG, 0.5)]
            for f in (mine, other)}  # fmt: skip
        assert np.allclose(scored, again[mine], rtol=0, atol=1e-9) and not np.allclose(scored, again[other], rtol=0, atol=1e-4)
    with pytest.raises(SystemExit):  # one file twice: an error naming it
        evaluation.main(["--no-policy", "--duration", "0.5", "--turn-then-run", str(FILE), "--turn-then-run", str(FILE)])
    assert f"--turn-then-run {FILE}: given twice" in capsys.readouterr().err
    # A second file for one model is scored beside the first, named by its file.
    copy = tmp_path / "ttr_copy.json"
    (tmp_path / "plane_own.json").write_text(FILE.with_name("plane_own.json").read_text())
    spec = json.loads(FILE.read_text())
    copy.write_text(json.dumps({**spec, "turn_gait": [0.5 * spec["turn_gait"][0]] + spec["turn_gait"][1:]}))
    records = evaluation.main(["--no-policy", "--models", "plane", "--duration", "0.5", "--turn-then-run", str(FILE),
                             "--turn-then-run", str(copy)])  # fmt: skip
    capsys.readouterr()
    first, second = ([r["displacement_m"] for r in records if r["agent"] == name and r["compass"]]
                     for name in ("turn-then-run", "ttr_copy/turn-then-run"))  # fmt: skip
    by_hand = {f: [r["displacement_m"] for r in evaluation.score(evaluation.run_episodes(
        {"b": load_turn_then_run_agent(f)}, "plane", evaluation.COMPASS_DEG, 0.5)["b"], evaluation.COMPASS_DEG, 0.5)]
        for f in (FILE, copy)}  # fmt: skip
    assert not np.allclose(by_hand[FILE], by_hand[copy], rtol=0, atol=1e-5)
    assert np.allclose(first, by_hand[FILE], rtol=0, atol=1e-9) and np.allclose(second, by_hand[copy], rtol=0, atol=1e-9)
    bad = tmp_path / "ttr.json"  # beside a copy of its running gait's file
    gaits = PIVOT_FILE.with_name(json.loads(PIVOT_FILE.read_text())["run_gait_file"])
    (tmp_path / gaits.name).write_text(gaits.read_text())
    bad.write_text(PIVOT_FILE.read_text().replace('"model": "pivot"', '"model": "moon"'))
    with pytest.raises(SystemExit):
        evaluation.main(["--no-policy", "--turn-then-run", str(bad)])
    assert f"turn-then-run file {bad}: \"model\" must be" in capsys.readouterr().err


def _variant(path, tmp_path, name, **changes):
    """The agent of a copy of ``path`` (beside a copy of its running gait's file) with keys
    changed (None: removed)."""
    spec = json.loads(Path(path).read_text())
    (tmp_path / spec["run_gait_file"]).write_text(Path(path).with_name(spec["run_gait_file"]).read_text())
    for key, value in changes.items():
        spec.pop(key, None) if value is None else spec.__setitem__(key, value)
    (tmp_path / name).write_text(json.dumps(spec))
    return load_turn_then_run_agent(tmp_path / name)


STEER_KEYS = ("steer_gain", "steer_integral", "steer_limit", "steer_param", "steer_after_s", "run_at_once_below_deg")


def _heading_of_travel(agents, headings_deg, seconds, last, **env_kwargs):
    """Direction of travel (deg) over the last ``last`` s minus the heading, one robot per agent
    along its heading (``headings_deg``) in one env, and which episodes ended."""
    n = len(agents)
    env = RRRobotVectorEnv(num_envs=n, max_episode_steps=None, reset_noise_scale=0.0, **env_kwargs)
    obs, _ = env.reset(seed=0, options={"target_direction": np.radians(headings_deg)})
    states, ended = [None] * n, np.zeros(n, dtype=bool)
    steps, tail = int(round(seconds / env.dt)), int(round(last / env.dt))
    for k in range(steps):
        actions = np.empty((n, 2), dtype=np.float32)
        for i, agent in enumerate(agents):
            actions[i : i + 1], states[i] = agent.predict(obs[i : i + 1], state=states[i], episode_start=np.array([k == 0]))
        obs, _, terminated, _, _ = env.step(actions)
        ended |= terminated
        if k + 1 == steps - tail:
            before = env.states[:, 0:2].copy()
    travel = env.states[:, 0:2] - before
    off = np.degrees(np.arctan2(travel[:, 1], travel[:, 0])) - np.asarray(headings_deg)
    return (off + 180.0) % 360.0 - 180.0, ended


@pytest.mark.slow
def test_the_heading_correction_holds_the_pivot_on_its_heading(tmp_path):
    """Pivot, 90 deg (the running gait's mirror, no turn needed) and 270 deg (the gait itself),
    30 s, with the running gait of pivot_own_limited.json (at the yaw - 90 deg) under its servo
    (0.5 N m, 10 rad/s, no motion profile): the open-loop gait's yaw drifts about 0.84 deg/s, so
    over the last 10 s the uncorrected agent travels well off the heading (~28 deg); the
    correction tuned for that gait (gain 0.01, integral 0.01 /s, limit 0.0075 rad) holds it within
    a few degrees, and the same correction with its sign flipped (positive feedback) does not.
    (The shipped pivot file's own gait, pivot_own.json's under the default servo, stops making way
    along 90 and 270 deg from the paper's start after ~16 s: no heading to hold there.)"""
    gait_file = PIVOT_FILE.with_name("pivot_own_limited.json")
    (tmp_path / gait_file.name).write_text(gait_file.read_text())
    spec = {"steer_gain": 0.01, "steer_integral": 0.01, "steer_limit": 0.0075}
    # (the maneuver and gait the correction was tuned with: the lead, the 3.66 s blend into the gait)
    maneuver = {"turn_gait": [1.3858, 1.0593, 2.4530, 1.2129, 10.5903, -0.8368], "lead_s": 2.6035, "ramp_s": 3.6624,
                "run_gait": "searched-pivot-own-1"}
    corrected = _variant(PIVOT_FILE, tmp_path, "limited.json", run_gait_file=gait_file.name, direction_offset_deg=-90.0,
                         **maneuver,
                         env_kwargs=json.loads(gait_file.read_text())["env_kwargs"], **spec)  # fmt: skip
    assert corrected.steering and corrected.search_env_kwargs["leg_accel_limit"] is None
    plain = TurnThenRunAgent(corrected.turn_gait, corrected.run_gait, dt=corrected.dt, lead=corrected.lead,
                             ramp=corrected.ramp, direction_offset=corrected.direction_offset, window=corrected.window)
    flipped = TurnThenRunAgent(corrected.turn_gait, corrected.run_gait, dt=corrected.dt, lead=corrected.lead,
                               ramp=corrected.ramp, direction_offset=corrected.direction_offset, window=corrected.window,
                               steer_gain=-spec["steer_gain"], steer_integral=-spec["steer_integral"],
                               steer_limit=spec["steer_limit"])  # fmt: skip
    off, ended = _heading_of_travel([plain, corrected, flipped, plain, corrected], [90.0] * 3 + [270.0] * 2, 30.0, 10.0,
                                    model="pivot", **corrected.search_env_kwargs)  # fmt: skip
    assert not ended.any()
    assert abs(off[1]) < 5.0 and abs(off[4]) < 5.0, off
    assert abs(off[0]) > 12.0 and abs(off[2]) > 12.0 and abs(off[3]) > 12.0, off


def test_without_the_steering_keys_the_agent_is_the_uncorrected_one(tmp_path):
    """The steering keys are optional: absent, the agent acts exactly as before they existed (and
    a zero gain is the same agent)."""
    for path in (FILE, PIVOT_FILE):
        plain = _variant(path, tmp_path, "plain.json", **{key: None for key in STEER_KEYS})
        zero = _variant(path, tmp_path, "zero.json", steer_gain=0.0, steer_integral=0.0, steer_limit=0.1,
                        steer_after_s=3.0, run_at_once_below_deg=None)
        assert not plain.steering and not zero.steering and plain.run_at_once_below == 0.0
        rng = np.random.default_rng(1)
        states = task.start_states(rng.uniform(-0.05, 0.05, (4, 10)))
        obs = task.observe(states, np.radians([0.0, 90.0, 180.0, 300.0]), task.make_task_config(), np.zeros(4))
        a, sa = plain.predict(obs)
        b, sb = zero.predict(obs)
        for _ in range(40):
            a, sa = plain.predict(obs, state=sa)
            b, sb = zero.predict(obs, state=sb)
            assert np.array_equal(a, b)


def test_bad_steering_values_are_named(tmp_path):
    bad = {
        "steer_gain": ("a lot", "steer_gain must be a finite number"),
        "steer_integral": (float("nan"), "steer_integral must be a finite number"),
        "steer_limit": (-0.1, "steer_limit must be a number in"),
        "steer_param": ("phase", "steer_param must be"),
        "steer_after_s": (-1.0, "steer_after_s must be a number in"),
        "run_at_once_below_deg": (200.0, "run_at_once_below_deg must be a number in"),
    }
    for key, (value, message) in bad.items():
        with pytest.raises(ValueError, match=f"turn-then-run file .*: {message}"):
            _variant(PIVOT_FILE, tmp_path, "bad.json", **{key: value})
    for limit in ([0.1, 0.2], [-0.1, 0.2, 0.3], [-0.6, 0.1], "0.1", [0.1, float("inf")]):
        with pytest.raises(ValueError, match="steer_limit must be"):
            TurnThenRunAgent(np.zeros(6), np.zeros(6), dt=0.05, lead=0.5, ramp=1.0, steer_gain=0.1, steer_limit=limit)
    agent = TurnThenRunAgent(np.zeros(6), np.zeros(6), dt=0.05, lead=0.5, ramp=1.0, steer_gain=0.1, steer_limit=[-0.1, 0.05])
    assert agent.steer_limit == (-0.1, 0.05)


def test_the_steering_change_is_the_documented_one_for_the_gait_and_its_mirror():
    """Started 4 deg off a running direction (run at once below 10 deg), once ramped in the change
    d is clip(sense * gain * e) with e the yaw's error from the target, applied as o1 + d, o2 - d
    (or a1 (1 + d), a2 (1 - d)) in the running gait's own frame, i.e. with the legs exchanged
    for its mirror; the leg targets are the changed gait's."""
    from rrrobot_gym.agents.turn_then_run import per_leg_angles, per_leg_gait

    run = np.array([1.2, 1.0, 1.5, 1.6, 8.0, 1.0])
    states = task.start_states(np.zeros((2, 10)))
    # The body's yaw (0) 4 deg anticlockwise of the target yaw: the gait (travel = yaw + 90) along
    # 86 deg, its mirror (travel = yaw - 90) along -94 deg.
    obs = task.observe(states, np.radians([86.0, -94.0]), task.make_task_config(), np.zeros(2))
    error = math.radians(4.0)
    for param in ("offset", "amplitude"):
        agent = TurnThenRunAgent(np.zeros(6), run, dt=0.05, lead=0.5, ramp=1.0, steer_gain=0.3, steer_limit=[-0.01, 0.02],
                                 steer_param=param, run_at_once_below=10.0)  # fmt: skip
        actions, state = agent.predict(obs)
        assert state["steer"].tolist() == [0.0, 0.0]  # ramped in from 0 at steer_after (0 s) over ramp (1 s)
        for _ in range(20):
            actions, state = agent.predict(obs, state=state)
        assert list(state["mode"]) == [2, 2] and list(state["run_sense"]) == [1.0, -1.0]
        # the agent's target: the yaw + the (4 deg) turn; the yaw 4 deg anticlockwise of it
        assert np.allclose(relative_yaw(obs) - state["target"], error, atol=1e-5)
        d = np.clip(np.array([1.0, -1.0]) * 0.3 * error, -0.01, 0.02)  # own: 0.0209 -> 0.02; mirror: -0.0209 -> -0.01
        assert np.allclose(state["steer"], d, atol=1e-6)
        for i, mirror in enumerate((False, True)):
            changed = run.copy()
            if param == "offset":
                changed[2:4] += [d[i], -d[i]]
            else:
                changed[0:2] *= [1.0 + d[i], 1.0 - d[i]]
            g = per_leg_gait(changed, mirror)[None]
            expected = np.clip(task.leg_targets_to_action(per_leg_angles(g, g[:, 4] * 0.05 * 21)), -1, 1)
            assert np.allclose(actions[i], expected[0], atol=1e-5)


def test_a_start_that_runs_at_once_keeps_the_running_gaits_own_ramp():
    """The shipped agent's running gait starts with a 2 s swing ramp from rest. A start that needs
    no turn (270 deg from the paper's start: the gait travels at the yaw - 90 deg) runs it at once
    with that ramp, acting as the gait's own agent until the heading correction sets in at 5 s,
    and stays in the model (under the file's servo); a start that turns first blends into the gait
    and is untouched by its ramp."""
    from rrrobot_gym.agents.searched import load_gait_agents

    spec = json.loads(FILE.read_text())
    agent = load_turn_then_run_agent(FILE)
    gait_agent = load_gait_agents(FILE.with_name(spec["run_gait_file"]))[spec["run_gait"]]
    assert agent.run_ramp == gait_agent.gait.ramp_s == 2.0 and agent.steer_after == 5.0
    unramped = load_turn_then_run_agent(FILE)
    unramped.run_ramp = 0.0

    env = RRRobotVectorEnv(num_envs=2, max_episode_steps=None, reset_noise_scale=0.0, **agent.search_env_kwargs)
    obs, _ = env.reset(seed=0, options={"target_direction": np.radians([270.0, 0.0])})
    state = gait_state = plain_state = None
    for k in range(160):  # 8 s: the turning start runs from ~5.4 s, over 2 s of the gait's ramp
        first = np.full(2, k == 0)
        actions, state = agent.predict(obs, state=state, episode_start=first)
        gait_actions, gait_state = gait_agent.predict(obs, state=gait_state, episode_start=first)
        plain, plain_state = unramped.predict(obs, state=plain_state, episode_start=first)
        if k < 100:  # 5 s: the correction's weight is 0 up to there
            assert np.allclose(actions[0], gait_actions[0], atol=1e-6)
        assert np.array_equal(actions[1], plain[1])  # the turning start
        if k < 30:
            assert not np.allclose(actions[0], plain[0], atol=1e-3)  # the ramp is on
        obs, _, terminated, _, _ = env.step(actions)
        assert not terminated.any()
    assert list(state["at_once"]) == [True, False] and np.isnan(state["switched"][0]) and 0.0 < state["switched"][1] < 6.0


@pytest.mark.parametrize("key, value, named", [("lead_s", float("nan"), "lead"), ("lead_s", -1e9, "lead"),
                                               ("direction_offset_deg", float("nan"), "direction_offset")])
def test_a_turn_then_run_file_with_a_nan_or_negative_lead_is_refused(tmp_path, key, value, named):
    """A NaN lead never switched to running (scored as a gait that turns for 50 s); a NaN offset
    gave NaN actions, refused by the env without naming the file."""
    spec = json.loads(FILE.read_text())
    spec[key] = value
    bad = tmp_path / FILE.name
    bad.write_text(json.dumps(spec))  # (NaN as JSON's NaN, which Python's json reads)
    for gaits in FILE.parent.glob(spec["run_gait_file"]):
        (tmp_path / gaits.name).write_text(gaits.read_text())
    with pytest.raises(ValueError, match=f"turn-then-run file {bad}: {named} must be"):
        load_turn_then_run_agent(bad)


TUNED_FILES = sorted(p for p in FILE.parent.glob("turn_then_run*.json") if "steer_tune" in json.loads(p.read_text()))


@pytest.mark.parametrize("path", TUNED_FILES, ids=lambda p: p.name)
def test_each_shipped_file_scores_again_what_its_steering_tune_recorded(path):
    """`rrrobot turn-then-run-steer` recorded the setting it kept first among its rows, with the
    speed from the paper's start along the 8 compass headings (its first 8 episodes). evaluate.py's
    loop must give them again: the file, the agent and the physics the same as when it was made."""
    from rrrobot_gym.evaluation import COMPASS_DEG, run_episodes, score

    spec = json.loads(path.read_text())
    row = spec["steer_tune"]["rows"][0]  # (tune_steering writes its rows best first: the kept one)
    agent = load_turn_then_run_agent(path)
    run = run_episodes({"ttr": agent}, agent.model, COMPASS_DEG, spec["steer_tune"]["duration_s"], 0)["ttr"]
    speeds = [record["speed_mps"] for record in score(run, COMPASS_DEG)]
    np.testing.assert_allclose(speeds, row["speeds_mps"][: len(COMPASS_DEG)], rtol=0, atol=1e-6)
