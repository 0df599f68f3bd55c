"""evaluate.py --randomize (rrrobot_gym.evaluation.evaluate_randomized): every agent meets the same
drawn robots, the figures are those of the robots run, and robots drawn from ranges that vary
nothing are the nominal robot to the bit. The nominal tables stay nominal."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from rrrobot_gym.agents import gait_agent
from rrrobot_gym.agents.turn_then_run import load_turn_then_run_agent
from rrrobot_gym.envs import RRRobotEnv
from rrrobot_gym.envs.task import RANDOMIZATIONS, RANDOMIZED
from rrrobot_gym.evaluation import (COMPASS_DEG, evaluate, evaluate_randomized, main, randomized_targets, robot_seeds,
                                    run_episodes)  # fmt: skip

TURN_THEN_RUN = Path(__file__).resolve().parents[1] / "agents" / "searched" / "turn_then_run.json"
"""A closed-loop agent (it steers by the observation, so observation noise reaches it)."""
NOTHING_VARIES = {name: (1.0, 1.0) if r.scale else (0.0, 0.0) for name, r in RANDOMIZATIONS["default"].items()}
NOTHING_VARIES["friction_coefficient"] = (1.0, 1.0)  # (drawn as itself, not as a scale of the env's 1.0)


def test_every_agent_meets_the_same_robots_and_the_same_noise_on_a_heading():
    """Robot j of a heading has the same draws (the reset info's) for every agent, and the robots
    differ; a closed-loop agent entered twice scores the same on every robot to the bit, which a
    different noise stream on the same robots does not."""
    agents = {"gait1": gait_agent("gait1"), "ttr": load_turn_then_run_agent(TURN_THEN_RUN),
              "ttr-again": load_turn_then_run_agent(TURN_THEN_RUN)}  # fmt: skip
    (section,), runs = evaluate_randomized(agents, ["plane"], 2, duration=2.0)
    draws = {name: runs[(name, "plane")]["compass"]["draws"] for name in agents}
    assert set(draws["gait1"]) == set(RANDOMIZED)
    for name in agents:
        for key in RANDOMIZED:
            np.testing.assert_array_equal(draws[name][key], draws["gait1"][key])
    assert len(np.unique(draws["gait1"]["mass_tip"])) == 2 * len(COMPASS_DEG)  # 16 robots, all different
    assert np.all(draws["gait1"]["observation_noise"] > 0)
    for k, robots in enumerate(section["robots"]):  # the JSON's robots are the ones run
        assert robots["draws"]["mass_tip"] == draws["ttr"]["mass_tip"][2 * k: 2 * k + 2].tolist()
    speeds = {name: [s for x in section["agents"][name]["headings"] for s in x["speeds_mps"]] for name in agents}
    assert speeds["ttr"] == speeds["ttr-again"]
    other_noise = run_episodes({"ttr": agents["ttr"]}, "plane", [float(h) for h in COMPASS_DEG for _ in range(2)], 2.0,
                               seed=1, randomize="default", robot_seeds=[s for k in range(8) for s in robot_seeds(0, k, 2)])
    np.testing.assert_array_equal(other_noise["ttr"]["draws"]["mass_tip"], draws["ttr"]["mass_tip"])
    assert not np.array_equal(other_noise["ttr"]["xy"][-1], runs[("ttr", "plane")]["compass"]["xy"][-1])


def test_the_json_s_figures_are_numpy_s_of_the_robots_it_records_and_a_robot_is_the_one_run(tmp_path):
    """Median, P10 and share ended per heading and overall are numpy's of the per-robot speeds in
    the JSON; replaying one recorded robot in the single env (reset with its seed) draws the same
    robot and moves it as far."""
    out = tmp_path / "r.json"
    main(["--no-policy", "--models", "plane", "--duration", "2", "--randomize", "2", "--json", str(out)])
    (section,) = json.loads(out.read_text())["randomized"]
    assert section["robots_per_heading"] == 2 and section["targets"] is None  # (no policy)
    for name, summary in section["agents"].items():
        for x in summary["headings"] + [summary["own_direction"]]:
            assert x["median_mps"] == np.median(x["speeds_mps"]) and x["p10_mps"] == np.percentile(x["speeds_mps"], 10)
            assert x["share_ended"] == np.mean(x["ended"])
        worst = min(summary["headings"], key=lambda x: x["p10_mps"])
        assert (summary["worst_heading_deg"], summary["worst_p10_mps"]) == (worst["heading_deg"], worst["p10_mps"])
        assert summary["share_ended"] == np.mean([e for x in summary["headings"] for e in x["ended"]])
    k, j = 2, 1  # robot 1 of 90 deg, gait 2 (it moves along it)
    robot = section["robots"][k]
    env = RRRobotEnv(reset_noise_scale=0.0, randomize="default")
    obs, info = env.reset(seed=robot["seeds"][j], options={"target_direction": math.radians(robot["heading_deg"])})
    assert {key: info["randomized_" + key] for key in RANDOMIZED} == {key: robot["draws"][key][j] for key in RANDOMIZED}
    agent, state, start = gait_agent("gait2"), None, np.array([info["x_position"], info["y_position"]])
    for _ in range(40):  # 2 s
        action, state = agent.predict(obs[None], state=state)
        obs, _, terminated, _, info = env.step(action[0])
        if terminated:
            break
    speed = (info["y_position"] - start[1]) / 2.0
    recorded = section["agents"]["gait2"]["headings"][k]["speeds_mps"][j]
    assert abs(speed) > 1e-3 and speed == pytest.approx(recorded, rel=1e-9, abs=1e-12)


def test_robots_drawn_from_ranges_that_vary_nothing_are_the_nominal_robot_to_the_bit():
    """Every quantity drawn (masses, gains, limits, friction, noise 0, delay 0), through the
    per-robot physics: each robot's speed is the nominal run's, to the bit, on every heading and
    along a gait's own direction, for an open-loop and a closed-loop agent."""
    agents = {"gait3": gait_agent("gait3"), "ttr": load_turn_then_run_agent(TURN_THEN_RUN)}
    records, _ = evaluate(agents, ["plane"], duration=2.0)
    nominal = {(r["agent"], r["heading_deg"]): r["speed_mps"] for r in records}
    own = {"plane": {g: r["heading_deg"] for r in records for g in r["own_direction_of"]}}
    (section,), runs = evaluate_randomized(agents, ["plane"], 2, duration=2.0, ranges=NOTHING_VARIES, own=own)
    assert set(runs[("ttr", "plane")]["compass"]["draws"]) == set(RANDOMIZED)
    for name, summary in section["agents"].items():
        for x in summary["headings"] + ([summary["own_direction"]] if name == "gait3" else []):
            assert x["speeds_mps"] == [nominal[(name, x["heading_deg"])]] * 2
    assert any(abs(v) > 1e-3 for v in nominal.values())


def test_a_policy_trained_randomized_is_scored_on_the_nominal_robot():
    randomized = gait_agent("gait1")
    randomized.env_kwargs = {"randomize": "default"}  # (as train.py's env_kwargs.json)
    runs = run_episodes({"a": randomized, "b": gait_agent("gait1")}, "plane", [0.0, 90.0], 1.0)
    assert runs["a"]["draws"] == {} and np.array_equal(runs["a"]["xy"], runs["b"]["xy"])
    records, _ = evaluate({"gait1": randomized}, ["plane"], duration=1.0)
    plain, _ = evaluate({"gait1": gait_agent("gait1")}, ["plane"], duration=1.0)
    assert [r["speed_mps"] for r in records] == [r["speed_mps"] for r in plain]


def test_ppo_s_randomized_targets_follow_the_numbers():
    """0.8 x the nominal worst heading, every searched gait's P10 (the better of its best compass
    heading and its own direction), at most 5 % ended; Table II gaits are not searched."""
    def summary(p10s, own=None, ended=0.0):
        out = {"headings": [{"heading_deg": float(h), "p10_mps": p} for h, p in zip(COMPASS_DEG, p10s)],
               "share_ended": ended}
        worst = min(out["headings"], key=lambda x: x["p10_mps"])
        out.update(worst_heading_deg=worst["heading_deg"], worst_p10_mps=worst["p10_mps"], worst_median_mps=0.0)
        return out | ({"own_direction": {"p10_mps": own}} if own is not None else {})

    records = [{"model": "plane", "agent": "ppo", "compass": True, "speed_mps": 0.125 + 0.01 * k} for k in range(8)]
    section = {"model": "plane", "robots_per_heading": 16, "ranges": "default", "searched_gaits": ["s"],
               "agents": {"ppo": summary([0.1] * 8, ended=0.05), "s": summary([0.07] * 8, own=0.099),
                          "gait1": summary([0.2] * 8)}}  # fmt: skip
    target = randomized_targets(section, records)
    assert target["all_hold"] and target["qualifies"] and target["searched_gait_p10_mps"] == {"s": 0.099}  # (0.8 x 0.125 is 0.1 in binary too)
    section["agents"]["s"] = summary([0.07] * 8, own=0.101)
    assert randomized_targets(section, records)["p10_at_least_every_searched_gait"] is False
    section["agents"]["ppo"] = summary([0.0999] + [0.2] * 7, ended=0.0626)
    target = randomized_targets(section, records)
    assert not target["p10_at_least_0.8_nominal_worst"] and not target["share_ended_at_most_5pct"]
    section.update(robots_per_heading=15, searched_gaits=[])
    target = randomized_targets(section, records)
    assert not target["qualifies"] and target["p10_at_least_every_searched_gait"] is None and target["all_hold"] is None
