"""``rrrobot turn-then-run-search`` and ``turn-then-run-steer`` (rrrobot_gym.turn_then_run_search),
and the one-line Ray errors of the search commands. Searches here are tiny: seconds each."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from rrrobot_gym import cli, gait_search
from rrrobot_gym import turn_then_run_search as ttr
from rrrobot_gym.agents.turn_then_run import load_turn_then_run_agent

pytest.importorskip("cma")
REPO = Path(__file__).resolve().parents[1]
SEARCHED = REPO / "agents" / "searched"


def _one_line_error(capsys, argv, problem):
    try:
        status, parsed = cli.main(argv), True
    except SystemExit as exc:  # (argparse's own errors: its usage lines, then the error)
        status, parsed = exc.code, False
    assert status == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 or not parsed, lines
    assert lines[-1].startswith("rrrobot") and "error:" in lines[-1] and problem in lines[-1], lines
    return lines[-1]


@pytest.fixture(scope="module")
def tiny_agent_file(tmp_path_factory):
    """A search of 40 candidates for searched-plane-own-1 of plane_own.json (the wall-clock budget
    far beyond it: the same search on any machine), scored on heading 0 deg over 10 s, its screen
    warm-started from the shipped maneuver (too small a budget to find one from nothing)."""
    out = tmp_path_factory.mktemp("ttr") / "agent.json"
    argv = ["turn-then-run-search", "--model", "plane", "--run-gaits", str(SEARCHED / "plane_own.json"), "--budget", "600",
            "--evaluations", "40", "--duration", "10", "--headings", "0", "--starts", "1", "--popsize", "4", "--no-progress",
            "--warm-start", str(SEARCHED / "turn_then_run.json"), "--out", str(out)]  # fmt: skip
    assert cli.main(argv) == 0
    return out


def test_a_tiny_search_writes_an_agent_that_turns_to_the_heading_and_travels_along_it(tiny_agent_file):
    spec = json.loads(tiny_agent_file.read_text())
    assert spec["made_by"][0].startswith("rrrobot turn-then-run-search --model plane")
    # the running gait travels at the body's yaw - 90 deg (measured, to the whole degree)
    assert spec["direction_offset_deg"] == -90.0 and abs(spec["search"]["direction"]["direction_offset_deg"] + 90.0) < 1.0
    # the running gait's file was searched under the default servo: the search ran, and its file says so
    assert spec["env_kwargs"] == {"torque_limit": 0.5, "leg_rate_limit": 10, "leg_accel_limit": 60}
    agent = load_turn_then_run_agent(tiny_agent_file)
    speed, ended, _, runs = ttr.run_agents([agent], [0.0], [None], 20.0, model="plane", env_kwargs=spec["env_kwargs"],
                                           reset_noise_scale=0.0, record=True)  # fmt: skip
    assert not ended.any()
    # from the paper's start (yaw 0) the body turns a quarter turn anticlockwise, to point the gait along +X ...
    yaw = np.degrees(runs["yaw"][:, 0])
    second = int(round(1.0 / runs["dt"]))
    assert yaw[3 * second] > 30.0, yaw[::second]  # (turning, the right way)
    # (the body's yaw swings within each period of the running gait: its mean over the last 5 s)
    assert abs(yaw[-5 * second:].mean() - 90.0) < 10.0, yaw[::second]
    # ... and travels along it: most of the gait's ~70 mm/s once the turn is done
    assert speed[0, 0] > 0.035, speed
    last = runs["upright"][-1, 0] - runs["upright"][-int(round(5.0 / runs["dt"])), 0]
    assert abs(math.degrees(math.atan2(last[1], last[0]))) < 20.0, last


def test_the_search_record_matches_what_the_agent_file_runs(tiny_agent_file):
    spec = json.loads(tiny_agent_file.read_text())
    found = spec["search"]["maneuver"]
    # the recorded fitness is the written maneuver's, re-scored the same way
    settings = dict(model="plane", env_kwargs=spec["env_kwargs"], seeds=[None], headings_deg=[0.0], duration=10.0, dt=spec["dt"],
                    run_gait=gait_search.load_gaits(SEARCHED / "plane_own.json")[0].as_array(), run_ramp=0.0,
                    direction_offset_deg=spec["direction_offset_deg"], run_at_once_below_deg=10.0,
                    reset_noise_scale=0.01)  # fmt: skip
    again = ttr.score_maneuvers(np.array([spec["turn_gait"] + [spec["lead_s"], spec["ramp_s"]]]), settings)
    assert again[0, 0] == pytest.approx(found["fitness"], abs=1e-12)
    assert found["evaluations"] >= 5  # (the warm start, its longer blends and the screen)
    # the two steps used the budget of candidates, half each, and it (not the clock) ended them
    search = spec["search"]
    assert search["budget_evaluations"] == 40 and search["seconds"] < search["budget_seconds"]
    assert search["turning_gait"]["evaluations"] == 20 and found["evaluations"] == 20


@pytest.mark.parametrize("args, problem", [
    (["--budget", "0"], "--budget: must be a positive number of seconds"),
    (["--budget", "-60"], "--budget: must be a positive number of seconds"),
    (["--budget", "nan"], "--budget: must be finite"),
    (["--evaluations", "0"], "--evaluations: must be a positive integer"),
    (["--model", "moon"], "--model: invalid choice: 'moon'"),
    (["--popsize", "2"], "popsize must be an integer >= 4"),
    (["--turning-share", "1"], "turning_share must be a fraction in (0, 1)"),
    (["--headings", "1e9"], "headings_deg must be one or more finite headings"),
    (["--run-gaits", str(SEARCHED / "turn_then_run.json")], "is not a gait-search result"),
    (["--model", "pivot"], "was searched on the plane model, not pivot"),
    (["--env", "torque_limit=-1"], "torque_limit"),
    (["--out", "agent.txt"], "--out must name a .json file"),
])  # fmt: skip
def test_bad_input_is_one_clear_error(capsys, tmp_path, args, problem):
    base = {"--model": "plane", "--run-gaits": str(SEARCHED / "plane_own.json"), "--budget": "1",
            "--out": str(tmp_path / "agent.json")}  # fmt: skip
    base.update(dict(zip(args[::2], args[1::2])))
    argv = ["turn-then-run-search", "--no-progress"] + [x for kv in base.items() for x in kv]
    _one_line_error(capsys, argv, problem)
    assert not (tmp_path / "agent.json").exists()


def test_the_steering_tune_keeps_the_combination_whose_runs_end_least(tmp_path, capsys):
    # (a file made under the paper's ideal servo, run under it: the default servo's motion profile
    # keeps even a full-scale correction from ending a run)
    out = tmp_path / "steered.json"
    argv = ["turn-then-run-steer", "--agent", str(SEARCHED / "turn_then_run_robust.json"), "--gain", "1", "--limit",
            "0.5", "--after", "0", "--duration", "5", "--starts", "1", "--no-progress", "--out", str(out)]  # fmt: skip
    assert cli.main(argv) == 0
    spec = json.loads(out.read_text())
    rows = spec["steer_tune"]["rows"]
    assert len(rows) == 2 and {json.dumps(r["combo"]) for r in rows} == {"{}", json.dumps(
        {"steer_gain": 1.0, "steer_limit": 0.5, "steer_after_s": 0.0})}
    # a full-scale correction from the first step ends runs that the uncorrected agent does not end
    uncorrected = next(r for r in rows if r["combo"] == {})
    steered = next(r for r in rows if r["combo"])
    assert steered["ended"] > uncorrected["ended"] == 0, rows
    assert rows[0] is not steered and rows[0]["combo"] == {}
    assert not any(key in spec for key in ttr.STEER_KEYS)  # (the file's own correction is left out too)
    assert spec["env_kwargs"] == {"torque_limit": None, "leg_rate_limit": None, "leg_accel_limit": None}  # the file's
    load_turn_then_run_agent(out)
    assert "turn-then-run-steer" in spec["made_by"][-1]
    _one_line_error(capsys, argv[:3] + ["--out", str(out)], "give the values to try")


# ---------------------------------------------------------------- Ray


@pytest.mark.parametrize("command", [
    ["gait-search", "--model", "plane", "--evaluations", "2", "--popsize", "2"],
    ["turn-then-run-search", "--model", "plane", "--run-gaits", str(SEARCHED / "plane_own.json"), "--budget", "1"],
])  # fmt: skip
def test_a_ray_address_where_nothing_answers_is_one_line_before_any_work(capsys, tmp_path, command):
    pytest.importorskip("ray")
    out = tmp_path / "out.json"
    err = _one_line_error(capsys, command + ["--ray-address", "127.0.0.1:1", "--no-progress", "--out", str(out)],
                          "ray_address '127.0.0.1:1': nothing answers at 127.0.0.1:1")  # fmt: skip
    assert "ray start --head" in err and not out.exists()
