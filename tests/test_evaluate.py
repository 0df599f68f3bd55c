"""evaluate.py (rrrobot_gym.evaluation): its effort figures come from the integrator's step record,
not from a rebuilt servo law; its tables, its refusals."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from rrrobot_gym.agents import gait_agent
from rrrobot_gym.evaluation import run_episodes, score
from rrrobot_gym import dynamics
from rrrobot_gym.control import RampTargets
from rrrobot_gym.envs.task import IDEAL_SERVO, SERVO
from rrrobot_gym.simulation import SimConfig, advance, initial_state

AGENTS = Path(__file__).resolve().parents[1] / "agents"
SHIPPED = {"default_policy": AGENTS / "pretrained" / "best_model.zip",
           "default_pivot_policy": AGENTS / "pretrained_pivot" / "best_model.zip"}
"""evaluate.py's defaults: the policies shipped in the repository's agents/."""


def test_effort_figures_are_the_torques_the_integrator_applied():
    """Gait 1 through evaluate.py for 1 s on the paper's ideal servo, against the same ramps
    replayed through `advance` by hand: the RMS and peak torque per step agree; the servo law
    without the ramp's rate (what evaluate.py used to rebuild) is several times larger."""
    duration = 1.0
    run = run_episodes({"gait1": gait_agent("gait1")}, "plane", [0.0], duration, **IDEAL_SERVO._asdict())["gait1"]
    config, dt = SimConfig(), 0.05
    state = initial_state()
    previous = state[dynamics.LEG_ANGLES].copy()
    rms, peak, rebuilt = [], [], []
    for k, target in enumerate(run["leg_targets"][:, 0]):  # rad, what the env ramped to
        state, record = advance(config, state, k * dt, dt, RampTargets(previous, target, k * dt, dt), record=True)
        rms.append(np.sqrt(np.mean(record.torque**2)))
        peak.append(np.abs(record.torque).max())
        previous = target
        legs = run["leg_angles"][k + 1, 0]
        np.testing.assert_allclose(state[dynamics.LEG_ANGLES], legs, rtol=0, atol=1e-12)
        rebuilt.append(np.sqrt(np.mean((2.0 * (target - legs) - 0.05 * state[dynamics.LEG_RATES]) ** 2)))
    np.testing.assert_allclose(run["torque_rms"][:, 0], rms, rtol=1e-9)
    np.testing.assert_allclose(run["torque_peak"][:, 0], peak, rtol=1e-9)
    record = score(run, [0.0], duration)[0]
    assert record["effort_rms_torque_nm"] == pytest.approx(np.sqrt(np.mean(np.square(rms))), rel=1e-9)
    assert record["peak_torque_nm"] == pytest.approx(max(peak), rel=1e-9)
    assert np.sqrt(np.mean(np.square(rebuilt[4:]))) > 2.0 * np.sqrt(np.mean(np.square(rms[4:])))


def test_a_policy_s_servo_holds_every_agent_scored_beside_it_on_its_model_only():
    """A pivot policy trained on the paper's ideal servo is compared with the gaits on that
    servo: Gait 2's torque peaks at about 1.6 N m on the pivot model, while on the plane, where
    no policy asked for another, the env's default servo (0.5 N m) holds it."""
    from rrrobot_gym.evaluation import evaluate

    ideal = gait_agent("gait1")
    ideal.env_kwargs = {**IDEAL_SERVO._asdict(), "healthy_reward": 2.0}
    records, _ = evaluate({"gait2": gait_agent("gait2")}, ["plane", "pivot"], duration=1.0,
                          per_model={"pivot": {"ppo": ideal}})  # fmt: skip
    peak = {(r["model"], r["agent"]): max(x["peak_torque_nm"] for x in records
                                          if (x["model"], x["agent"]) == (r["model"], r["agent"])) for r in records}
    assert {r["agent"] for r in records if r["model"] == "plane"} == {"gait2"}
    assert peak[("pivot", "gait2")] > 1.0 and peak[("plane", "gait2")] <= SERVO.torque_limit + 1e-9
    assert all(r["physics"] == (IDEAL_SERVO if r["model"] == "pivot" else SERVO)._asdict()
               for r in records)  # fmt: skip (healthy_reward changes the reward, not the motors: not imposed)


@pytest.mark.parametrize("key, values", [("torque_limit", (0.5, 0.8)), ("torque_limit", (0.5, None)),
                                         ("leg_accel_limit", (60.0, None))])  # fmt: skip
def test_agents_trained_under_different_motors_are_not_scored_together(key, values):
    # (one of them with the env's default: the other's was imposed on both, silently)
    from rrrobot_gym.evaluation import evaluate

    a, b = gait_agent("gait1"), gait_agent("gait3")
    a.env_kwargs, b.env_kwargs = {key: values[0]}, {key: values[1]}
    with pytest.raises(ValueError, match=key):
        evaluate({"a": a, "b": b}, ["pivot"], duration=0.5)


def test_the_records_name_the_servo_a_policy_pinned_even_when_it_is_the_default():
    # (the tables then say which motors held every agent; other keywords at their defaults are left out)
    from rrrobot_gym.evaluation import evaluate

    pinned = gait_agent("gait1")
    pinned.env_kwargs = {"torque_limit": 0.5, "leg_rate_limit": 10.0, "leg_accel_limit": 60.0, "kp": 2.0}
    records, _ = evaluate({}, ["pivot"], duration=0.05, per_model={"pivot": {"ppo": pinned}})
    assert records and all(r["physics"] == {"torque_limit": 0.5, "leg_rate_limit": 10.0, "leg_accel_limit": 60.0}
                           for r in records)  # fmt: skip


@pytest.mark.slow
def test_a_second_policy_is_scored_by_name_on_its_own_model_as_the_policy_itself(capsys):
    """--also-policy NAME=FILE: the shipped pivot policy under a second name scores exactly what
    it scores as "ppo" (the default pivot policy), heading by heading; it gets no open-loop own
    direction (it is closed loop), and runs only on the pivot model it was trained on."""
    from rrrobot_gym.evaluation import COMPASS_DEG, main

    records = main(["--models", "plane", "pivot", "--duration", "0.5",
                    "--also-policy", "again=agents/pretrained_pivot/best_model.zip"], **SHIPPED)  # fmt: skip
    again = {r["heading_deg"]: r["speed_mps"] for r in records if r["agent"] == "again"}
    ppo = {r["heading_deg"]: r["speed_mps"] for r in records if r["agent"] == "ppo" and r["model"] == "pivot"}
    assert {r["model"] for r in records if r["agent"] == "again"} == {"pivot"}
    assert set(COMPASS_DEG) <= set(again) and again == ppo  # (and along the gaits' own directions, as every agent)
    assert not any("again" in r["own_direction_of"] for r in records)
    assert "| again (agents/pretrained_pivot/best_model.zip) |" in capsys.readouterr().out


def test_a_policy_is_scored_on_the_model_it_was_trained_on_in_rows_named_by_its_file(capsys):
    """--policy FILE (a plane policy) was scored on the pivot model too, in a row named only "ppo".
    Now its rows name the file and it runs on the plane only, saying so; --cross-model scores it on
    the pivot too, in rows that say where it was trained."""
    from rrrobot_gym.evaluation import main

    plane_policy = "agents/pretrained/best_model.zip"
    records = main(["--policy", plane_policy, "--duration", "0.1"])
    out, err = capsys.readouterr()
    policy_rows = [r for r in records if r["agent"] == "ppo"]
    assert {r["model"] for r in policy_rows} == {"plane"} and {r["model"] for r in records} == {"plane", "pivot"}
    assert all((r["policy_file"], r["trained_on"]) == (plane_policy, "plane") for r in policy_rows)
    assert not any("policy_file" in r for r in records if r["agent"] != "ppo")  # (gaits are no files' policies)
    assert f"| ppo ({plane_policy}) |" in out and "| ppo |" not in out
    assert f"--policy: {plane_policy} was trained on the plane model: not scored on pivot" in err
    records = main(["--policy", plane_policy, "--duration", "0.1", "--cross-model"])
    assert {r["model"] for r in records if r["agent"] == "ppo"} == {"plane", "pivot"}
    out, err = capsys.readouterr()
    pivot_table = out.split("### pivot")[1].split("### plane")[0]
    assert f"| ppo ({plane_policy}, trained on plane) |" in pivot_table and "not scored" not in err


@pytest.mark.parametrize("argv, named", [
    (["--policy", "agents/pretrained_pivot/best_model.zip", "--models", "plane"],
     "--policy: agents/pretrained_pivot/best_model.zip was trained on the pivot model, which --models leaves out"),
    (["--policy", "agents/pretrained/best_model.zip", "--pivot-policy", "agents/pretrained/best_model.zip"],
     "--pivot-policy: agents/pretrained/best_model.zip was trained on the plane model, not the pivot: give --cross-model"),
    (["--policy", "agents/pretrained_pivot/best_model.zip", "--pivot-policy", "agents/pretrained_pivot/best_model.zip"],
     "was trained on the pivot model, where --pivot-policy is scored: give one of them"),
    (["--pivot-policy", "agents/pretrained_pivot/best_model.zip", "--models", "plane", "--policy",
      "agents/pretrained/best_model.zip"], "--pivot-policy: --models leaves out the pivot model"),
    (["--no-policy", "--models", "plane", "--also-policy", "again=agents/pretrained_pivot/best_model.zip"],
     "--also-policy again=agents/pretrained_pivot/best_model.zip: agents/pretrained_pivot/best_model.zip was trained "
     "on the pivot model, which --models leaves out"),
])
def test_a_policy_asked_for_on_a_model_it_was_not_trained_on_is_refused_before_the_runs(argv, named, capsys):
    from rrrobot_gym.evaluation import main

    with pytest.raises(SystemExit):
        main([*argv, "--duration", "0.5"])
    out, err = capsys.readouterr()
    assert named in err and "| gait1 |" not in out


@pytest.mark.parametrize("spec, named", [
    ("again", "NAME=FILE"),
    ("gait1=agents/pretrained_pivot/best_model.zip", "already taken"),
    ("ppo=agents/pretrained_pivot/best_model.zip", "already taken"),
    ("again=missing.zip", "no model file"),
])
def test_bad_second_policies_are_named(spec, named, capsys):
    from rrrobot_gym.evaluation import main

    with pytest.raises(SystemExit):
        main(["--no-policy", "--duration", "0.5", "--also-policy", spec])
    assert named in capsys.readouterr().err


def test_two_searches_of_one_model_are_scored_side_by_side_named_by_file(tmp_path):
    # Both files name their gaits searched-plane-own-1..3; the second set is told apart by its file.
    import shutil
    from pathlib import Path

    from rrrobot_gym.evaluation import main

    REPO = Path(__file__).resolve().parents[1]
    first, second = tmp_path / "first.json", tmp_path / "second.json"
    shutil.copy(REPO / "agents" / "searched" / "plane_own.json", first)
    search = json.loads(first.read_text())
    for gait in search["gaits"]:  # the second search's gaits: the same with a third of the swing
        for leg in ("amplitude_1", "amplitude_2"):
            gait["parameters"][leg] /= 3.0
    second.write_text(json.dumps(search))
    # (5 s: both files' gaits ramp their swing in over their first 2 s)
    records = main(["--no-policy", "--models", "plane", "--duration", "5", "--gaits", str(first), "--gaits", str(second)])
    names = {r["agent"] for r in records}
    assert {"searched-plane-own-1", "second/searched-plane-own-1"} <= names
    # each gait along its own direction (the shipped ones travel at ~270 deg from the paper's start)
    own = {r["agent"]: r["speed_mps"] for r in records if r["agent"] in r["own_direction_of"]}
    # the two are different gaits: the small swing is the slower, on every one of the three
    for i in (1, 2, 3):
        assert abs(own[f"searched-plane-own-{i}"]) > 2 * abs(own[f"second/searched-plane-own-{i}"])


def test_physics_holds_gaits_to_motor_limits_without_a_policy():
    # Gait 2's servo peaks above 1 N m unlimited (test above); --physics limits it on every model asked.
    from rrrobot_gym.evaluation import main

    records = main(["--no-policy", "--models", "plane", "pivot", "--duration", "1", "--physics", "torque_limit=0.3",
                    "--physics", "leg_rate_limit=8"])  # fmt: skip
    assert records and all(r["physics"] == {"torque_limit": 0.3, "leg_rate_limit": 8, "leg_accel_limit": 60.0}
                           for r in records)  # fmt: skip
    assert max(r["peak_torque_nm"] for r in records if r["agent"] == "gait2") <= 0.3 + 1e-9


def test_physics_takes_the_integration_schedule_and_the_gaits_speeds_barely_move():
    # 13 substeps of the same 0.05 s control step. The same physics integrated otherwise:
    # every gait's speed must agree with the default's to well under a mm/s, and not to the bit.
    from rrrobot_gym.evaluation import main

    graded = {"timestep": 0.05 / 13, "frame_skip": 13}
    plain = main(["--no-policy", "--models", "plane", "--duration", "2"])
    records = main(["--no-policy", "--models", "plane", "--duration", "2"] + [a for k, v in graded.items() for a in ("--physics", f"{k}={v!r}")])
    assert records and all(r["physics"] == {**SERVO._asdict(), **graded} for r in records)
    default = {(r["agent"], r["heading_deg"]): r["speed_mps"] for r in plain if r["compass"]}
    moved = [abs(r["speed_mps"] - default[(r["agent"], r["heading_deg"])]) for r in records if r["compass"]]
    assert len(moved) == len(default) == 6 * 8 and 0.0 < max(moved) < 1e-4


def test_physics_that_contradicts_a_policy_or_is_not_physics_is_named():
    from rrrobot_gym.evaluation import evaluate, parse_physics

    limited = gait_agent("gait1")
    limited.env_kwargs = {"torque_limit": 0.5}
    with pytest.raises(ValueError, match="torque_limit=0.3.*pivot.*torque_limit=0.5"):
        evaluate({}, ["pivot"], duration=0.5, per_model={"pivot": {"ppo": limited}}, physics={"torque_limit": 0.3})
    records, _ = evaluate({}, ["pivot"], duration=0.5, per_model={"pivot": {"ppo": limited}},
                          physics={"torque_limit": 0.5, "leg_rate_limit": 9.0})  # fmt: skip
    assert all(r["physics"] == {"torque_limit": 0.5, "leg_rate_limit": 9.0, "leg_accel_limit": 60.0} for r in records)
    for spec, named in (("healthy_reward=2", "KEY one of"), ("torque_limit", "KEY=VALUE"), ("torque_limit=-1", "torque_limit"),
                        ("integrator=euler", "integrator"), ("robot=1", "KEY one of")):
        with pytest.raises(ValueError, match=named):
            parse_physics([spec])


def test_speeds_are_over_the_whole_control_steps_simulated():
    """0.07 s ran one 0.05 s step and divided its travel by 0.07 (29 % slow); 0.02 s ran none
    and failed indexing the empty path. A run is whole control steps, the nearest to the time
    asked, and its speeds are over the time it simulated."""
    agents = {"gait1": gait_agent("gait1")}
    with pytest.raises(ValueError, match="under half of the env's 0.05 s control step"):
        run_episodes(agents, "plane", [0.0], 0.02)
    run = run_episodes(agents, "plane", [0.0], 0.07)["gait1"]
    assert run["times"][-1] == pytest.approx(0.05)
    travel = run["xy"][-1, 0] - run["xy"][0, 0]
    assert score(run, [0.0])[0]["speed_mps"] == pytest.approx(travel[0] / 0.05, rel=1e-12)
    with pytest.raises(ValueError, match="simulated"):  # a duration that is not the run's
        score(run, [0.0], 0.07)


@pytest.mark.parametrize("flag, where, named", [
    ("--json", "missing/r.json", "no directory"),
    ("--markdown", "", "a directory"),
    ("--plots", "file.txt", "is a file, not a directory"),
])
def test_evaluate_output_paths_are_checked_before_the_runs(tmp_path, flag, where, named, capsys):
    from rrrobot_gym.evaluation import main

    (tmp_path / "file.txt").write_text("")
    with pytest.raises(SystemExit):
        main(["--no-policy", "--models", "plane", "--duration", "0.5", flag, str(tmp_path / where)])
    err = capsys.readouterr()
    assert named in err.err and "| gait1 |" not in err.out  # refused, and nothing was run


def test_a_model_named_twice_is_refused_before_the_runs(capsys):
    from rrrobot_gym.evaluation import main

    with pytest.raises(SystemExit):  # (it was evaluated and reported twice)
        main(["--no-policy", "--models", "plane", "plane", "--duration", "0.5"])
    err = capsys.readouterr()
    assert "names a model twice" in err.err and "| gait1 |" not in err.out


def test_a_gait_agent_names_a_bad_sampling_point_or_step_count():
    from rrrobot_gym.agents.gaits import GaitAgent
    from rrrobot_gym.control import table2_gait

    with pytest.raises(ValueError, match="sample_fraction must be finite"):  # (NaN gave NaN actions)
        GaitAgent(table2_gait(1), dt=0.05, sample_fraction=float("nan"))
    with pytest.raises(ValueError, match=r"sample_fraction must be in \[0, 1\]"):
        GaitAgent(table2_gait(1), dt=0.05, sample_fraction=1.5)
    with pytest.raises(TypeError, match="dt must be a real number"):  # (numpy's isfinite TypeError)
        GaitAgent(table2_gait(1), dt=None)
    agent = gait_agent("gait1")
    with pytest.raises(ValueError, match="whole step counts >= 0"):  # (NaN became -9.2e18 steps)
        agent.predict(np.zeros((1, 15), dtype=np.float32), state=[np.nan])
    action, state = agent.predict(np.zeros((2, 15), dtype=np.float32), state=[3, 4])
    np.testing.assert_array_equal(state, [4, 5])


def test_a_physics_keyword_given_twice_is_refused():
    from rrrobot_gym.evaluation import parse_physics

    with pytest.raises(ValueError, match="torque_limit is given twice"):  # (the last one won, silently)
        parse_physics(["torque_limit=0.5", "torque_limit=0.6"])


def test_a_physics_number_json_does_not_read_is_still_a_number():
    # (".5" was a string, and real_number, which no longer takes strings of digits, refused it)
    from rrrobot_gym.evaluation import parse_physics

    assert parse_physics(["torque_limit=.3", "timestep=1/600", "frame_skip=30"]) == {
        "torque_limit": 0.3, "timestep": 1 / 600, "frame_skip": 30}
    assert parse_physics(["action_hold=zero_order"]) == {"action_hold": "zero_order"}
    with pytest.raises(ValueError, match="must be finite"):
        parse_physics(["torque_limit=inf"])


def test_the_tables_and_plots_name_the_duration_scored_and_explain_an_ended_episode(tmp_path, monkeypatch):
    """--duration 1.5: the tables and the gaits' plot say 1.5 s, not the default 50 s; a gait that
    leaves the model (from plane_own.json: at 1.05 s from the paper's start, on the ideal servo)
    is marked (T), and the table says what (T) means."""
    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure

    from rrrobot_gym.evaluation import TERMINATED_NOTE, main

    titles = []
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: titles.extend(ax.get_title() for ax in fig.axes))
    gaits = tmp_path / "leaves.json"
    data = json.loads((AGENTS / "searched" / "plane_own.json").read_text())
    first = data["gaits"][0]
    leaves = dict(zip(first["parameters"], [1.4798, 1.4974, 1.5664, 1.5771, 8.6063, -1.8792]))
    data["gaits"] = [dict(first, name="leaves", parameters=leaves)]
    data["ramp_s"] = 0.0  # (its swing at once, as searched then)
    gaits.write_text(json.dumps(data))
    table = tmp_path / "table.md"
    main(["--no-policy", "--models", "plane", "--duration", "1.5", "--gaits", str(gaits), "--markdown", str(table),
          "--plots", str(tmp_path / "plots")] + [a for key in IDEAL_SERVO._fields for a in ("--physics", f"{key}=none")])
    text = table.read_text()
    assert "mean speed along the commanded heading (mm/s), 1.5 s from rest" in text and "50 s" not in text
    assert "Table II gaits, 1.5 s (plane)" in titles and not any("50 s" in t for t in titles)
    assert "| leaves |" in text and "(T)" in text.split("| leaves |")[1].split("\n")[0]
    assert TERMINATED_NOTE in text


def shipped_run_without(tmp_path, folder, missing):
    """A copy of a shipped policy's run folder without the file ``missing``."""
    run = tmp_path / folder
    shutil.copytree(AGENTS / folder, run)
    (run / missing).unlink()
    return run / "best_model.zip"


@pytest.mark.parametrize("folder, missing", [
    ("pretrained_pivot", "vecnormalize.pkl"),
    ("pretrained_pivot", "env_kwargs.json"),
    ("pretrained_pivot", "mirror.json"),  # (its args.json says mirror: true)
    ("pretrained_residual", "residual.json"),  # (its args.json names residual_on)
])
def test_a_policy_missing_a_file_its_training_wrote_is_refused_naming_it(tmp_path, capsys, folder, missing):
    from rrrobot_gym.agents import load_ppo_agent
    from rrrobot_gym.evaluation import main

    model = shipped_run_without(tmp_path, folder, missing)
    with pytest.raises(FileNotFoundError, match=f"{missing} is missing"):
        load_ppo_agent(model)
    with pytest.raises(SystemExit):
        main(["--models", "pivot", "--duration", "0.5", "--policy", str(model)])
    assert f"--policy: {model}: {model.parent / missing} is missing" in capsys.readouterr().err


@pytest.mark.parametrize("flag", ["--policy", "--pivot-policy"])
def test_no_policy_with_a_policy_is_refused(flag, capsys):
    from rrrobot_gym.evaluation import main

    with pytest.raises(SystemExit):
        main(["--no-policy", flag, str(SHIPPED["default_policy"]), "--duration", "0.5"])
    assert f"--no-policy scores only the gaits: leave out {flag}" in capsys.readouterr().err


def test_without_a_default_policy_the_library_asks_for_one(capsys):
    from rrrobot_gym.evaluation import main

    with pytest.raises(SystemExit):
        main(["--duration", "0.5"])
    assert "--policy: give a PPO model zip" in capsys.readouterr().err


def test_every_option_has_help():
    from rrrobot_gym.evaluation import build_parser

    undocumented = [action.option_strings for action in build_parser()._actions if not action.help]
    assert not undocumented


def test_check_accuracy_reports_the_shipped_policy_of_each_model_at_its_own_step(tmp_path, capsys):
    """evaluate.py --check-accuracy, models by default both: the shipped plane and pivot policies each
    run again at a 10x finer step (1/3000 s, the same 0.05 s control step), from the paper's start and
    from --accuracy-starts starts a heading drawn with the env's reset noise, the same at both steps;
    each table headed by the largest change of a mean and the 0.1 % verdict; the JSON keeps both."""
    pytest.importorskip("stable_baselines3")
    from rrrobot_gym.evaluation import main

    out = tmp_path / "r.json"
    main(["--duration", "0.5", "--check-accuracy", "--accuracy-starts", "3", "--json", str(out)], **SHIPPED)
    text = capsys.readouterr().out
    for model in ("plane", "pivot"):
        assert f"at its step, 1/300 s, and at a 10x finer one, 1/3000 s ({model}): means over 3 starts a heading" in text
    checked = json.loads(out.read_text())["accuracy_check"]
    assert set(checked) == {"plane", "pivot"}
    for records in checked.values():
        assert [r["heading_deg"] for r in records] == [float(h) for h in range(0, 360, 45)]
        for r in records:
            assert r["step_s"] == pytest.approx(1 / 300) and r["fine_step_s"] == pytest.approx(1 / 3000)
            assert r["relative_change"] == pytest.approx(r["speed_mps"] / r["fine_step_speed_mps"] - 1.0)
            assert r["starts_used"] == 3 and r["speed_range_mps"][0] < r["speed_range_mps"][1]  # (starts that differ)
            assert r["mean_relative_change"] == pytest.approx(r["mean_speed_mps"] / r["fine_step_mean_speed_mps"] - 1.0)


def test_check_accuracy_takes_a_whole_number_of_starts(capsys):
    from rrrobot_gym.evaluation import main

    with pytest.raises(SystemExit):
        main(["--no-policy", "--models", "plane", "--duration", "0.5", "--check-accuracy", "--accuracy-starts", "0"])
    err = capsys.readouterr()
    assert "--accuracy-starts must be a number of starts >= 1" in err.err and "| gait1 |" not in err.out


def test_check_accuracy_refines_an_agent_s_own_step():
    """An agent trained at another step (1/200 s, 10 substeps a control step) is checked against
    1/2000 s, not the default's 1/3000 s."""
    from rrrobot_gym.evaluation import accuracy_check, accuracy_markdown

    agent = gait_agent("gait1")
    agent.env_kwargs = {"timestep": 1 / 200, "frame_skip": 10}
    checked = accuracy_check(agent, "plane", 0.5)
    assert checked[0]["step_s"] == pytest.approx(1 / 200) and checked[0]["fine_step_s"] == pytest.approx(1 / 2000)
    assert "at its step, 1/200 s, and at a 10x finer one, 1/2000 s (plane)" in accuracy_markdown("plane", checked)
