"""Gait search (rrrobot_gym.gait_search, ``rrrobot gait-search``), its agents, evaluate.py --gaits,
Ray evaluation and the tuned PPO hyperparameters. Searches here are tiny: a few seconds each."""

from __future__ import annotations

import inspect
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rrrobot_gym import gait_search
from rrrobot_gym.envs.task import IDEAL_SERVO, LEG_TARGET_MAX, LEG_TARGET_MIN, action_to_leg_targets
from rrrobot_gym.envs.vector import RRRobotVectorEnv
from rrrobot_gym.gait_search import (
    PARAMETER_NAMES,
    PopulationRuns,
    SinusoidGait,
    evaluate_population,
    fitness_from_runs,
    load_gaits,
    repair,
    search,
)

pytest.importorskip("cma")
REPO = Path(__file__).resolve().parents[1]
GAIT1 = SinusoidGait(0.3, 0.3, 0.5 * math.pi, 0.5 * math.pi, 8.0, 0.5 * math.pi, name="gait1-as-sinusoid")
IDEAL = IDEAL_SERVO._asdict()
TINY = dict(duration=1.0, start_seeds=(0, 1), popsize=6, robustness_seeds=2, robustness_duration=1.0, progress=False)


@pytest.fixture(scope="module")
def tiny_result():
    return search(budget_evaluations=25, screen=0, start=GAIT1, seed=3, **TINY)


def test_search_improves_on_its_starting_gait(tiny_result):
    # screen=0: the start is scored alone first, then only CMA-ES generations follow.
    history = tiny_result.history
    assert history[0]["evaluations"] == 1
    start_fitness = history[0]["best_fitness"]
    assert tiny_result.gaits[0]["fitness"] > start_fitness + 1e-3, history
    assert tiny_result.used["evaluations"] == 25 and tiny_result.used["generations"] == 4
    # CMA-ES moves its population uphill, not just samples around the start.
    assert history[-1]["median_fitness"] > history[1]["median_fitness"], history


def test_sinusoid_matches_table2_gait():
    from rrrobot_gym.control import table2_gait

    times = np.linspace(0.0, 3.0, 61)
    np.testing.assert_allclose(GAIT1.angles(times), table2_gait(1).angles(times), atol=1e-15)
    for t in (0.0, 0.37, 2.1):
        np.testing.assert_allclose(GAIT1.leg_targets(t), table2_gait(1).leg_targets(t), atol=1e-12)


def test_repair_keeps_every_target_inside_the_action_range():
    rng = np.random.default_rng(0)
    raw = rng.uniform(-5, 5, size=(200, 6))
    params = repair(raw)
    times = np.linspace(0, 10, 400)[:, None]
    angles = gait_search.sinusoid_angles(params[None, :, :], times)
    assert angles.min() >= LEG_TARGET_MIN - 1e-12 and angles.max() <= LEG_TARGET_MAX + 1e-12
    lows = [gait_search.BOUNDS[n][0] for n in PARAMETER_NAMES]
    highs = [gait_search.BOUNDS[n][1] for n in PARAMETER_NAMES]
    assert np.all(params >= lows) and np.all(params <= highs)


def _runs(displacement, terminated, end_time, duration=10.0):
    displacement = np.asarray(displacement, dtype=float)
    shape = displacement.shape[:2]
    return PopulationRuns(displacement, np.asarray(end_time, float), np.asarray(terminated, bool),
                          np.zeros(shape), np.zeros(shape), duration)


def test_a_gait_that_leaves_the_model_loses_to_one_that_stays():
    # Gait 0 goes far but leaves the model near the end on one start; gait 1 barely moves
    # (and backwards along the heading objective); gait 2 leaves early.
    runs = _runs(
        displacement=[[[3.0, 0.0], [2.9, 0.0]], [[-0.01, 0.0], [-0.012, 0.0]], [[0.05, 0.0], [0.05, 0.0]]],
        terminated=[[False, True], [False, False], [True, True]],
        end_time=[[10.0, 9.95], [10.0, 10.0], [0.5, 0.5]],
    )
    for objective, heading in (("own", None), ("heading", 0.0)):
        scores = fitness_from_runs(runs, objective, heading)
        assert scores.fitness[1] > scores.fitness[0] > scores.fitness[2], (objective, scores.fitness)
        assert list(scores.terminated_starts) == [1, 0, 2]
    own = fitness_from_runs(runs, "own")
    assert own.speed_mps[0] == pytest.approx(0.295) and own.direction_deg[1] == pytest.approx(180.0)


def test_json_round_trips_into_agents_whose_predict_reproduces_the_gaits(tiny_result, tmp_path):
    from rrrobot_gym.agents import load_gait_agents

    path = tmp_path / "gaits.json"
    tiny_result.write_json(path)
    data = json.loads(path.read_text())
    assert data["schema"] == gait_search.SCHEMA and len(data["gaits"]) == 3
    assert data["budget"] == {"evaluations": 25, "seconds": None} and data["seed"] == 3
    assert set(data["gaits"][0]["robustness"]) >= {"speeds_mps", "terminated", "paper_start_speed_mps"}
    assert data["ramp_s"] == gait_search.DEFAULT_RAMP_S  # the search's default: the agents must ramp alike
    # searched under the default servo, and saying so: its file replays alike whatever the defaults become
    assert data["env_kwargs"] == {"torque_limit": 0.5, "leg_rate_limit": 10.0, "leg_accel_limit": 60.0}
    agents = load_gait_agents(path)
    assert list(agents) == [g["name"] for g in data["gaits"]]
    for gait in data["gaits"]:
        agent = agents[gait["name"]]
        params = np.array([gait["parameters"][n] for n in PARAMETER_NAMES])
        state, obs = None, np.zeros((2, 15), dtype=np.float32)
        for k in range(30):
            actions, state = agent.predict(obs, state=state, episode_start=np.array([k == 0] * 2))
            expected = gait_search.sinusoid_angles(params, (k + 1) * 0.05, data["ramp_s"])
            np.testing.assert_allclose(action_to_leg_targets(actions.astype(float)), np.tile(expected, (2, 1)), atol=1e-6)


def test_evaluate_py_scores_a_searched_gait_like_the_search(tiny_result, tmp_path):
    """evaluate.py's loop, driving the loaded agent from the paper's start, measures the speed
    the search's paper-start re-score recorded: agent and search command the same targets."""
    from rrrobot_gym import evaluation

    path = tmp_path / "gaits.json"
    tiny_result.write_json(path)
    out = tmp_path / "records.json"
    records = evaluation.main(["--no-policy", "--gaits", str(path), "--duration", "1", "--models", "plane", "--json", str(out)])
    best = tiny_result.gaits[0]
    mine = [r for r in records if r["agent"] == best["name"]]
    assert len(mine) == 8 + 1 + 6 + 2  # 8 compass, its own, the other gaits' own directions
    agents = evaluation.load_gait_agents(path)
    runs = evaluation.run_episodes(agents, "plane", [best["direction_deg"]], duration=1.0)
    run = runs[best["name"]]
    # every heading runs the same open-loop gait from the paper's start: one effort, whatever the
    # heading scored, and the one the search's population run saw (its swing ramped in alike)
    effort = evaluate_population(np.array([agents[best["name"]].gait.as_array()]), duration=1.0, start_seeds=(0,),
                                 reset_noise_scale=0.0, ramp_s=tiny_result.settings["ramp_s"]).runs  # fmt: skip
    assert len({(r["peak_torque_nm"], r["peak_leg_rate_radps"]) for r in mine}) == 1
    assert mine[0]["peak_torque_nm"] == pytest.approx(effort.torque_peak.max(), rel=1e-12)
    assert mine[0]["peak_leg_rate_radps"] == pytest.approx(effort.leg_rate_peak.max(), rel=1e-12)
    travel = (run["xy"][-1, 0] - run["xy"][0, 0]) @ [math.cos(math.radians(best["direction_deg"])),
                                                       math.sin(math.radians(best["direction_deg"]))]
    assert travel / 1.0 == pytest.approx(best["robustness"]["paper_start_speed_mps"], abs=1e-12)
    assert json.loads(out.read_text())["records"]


def test_evaluate_py_gives_a_gait_that_leaves_the_model_its_direction_up_to_then(tmp_path):
    """A gait whose first episode terminates still gets an own direction (from its last position
    inside the model), instead of a NaN heading that the env rejects."""
    from rrrobot_gym import evaluation

    # From agents/searched/plane_own.json: from the paper's start, under the ideal servo it was
    # searched under, it leaves the model at 1.05 s.
    leaves = SinusoidGait(1.4798, 1.4974, 1.5664, 1.5771, 8.6063, -1.8792, name="leaves")
    from rrrobot_gym.agents import GaitAgent

    agents = {"leaves": GaitAgent(leaves, dt=0.05, name="leaves")}
    first = evaluation.run_episodes(agents, "plane", [0.0], duration=1.5, **IDEAL)["leaves"]
    assert first["terminated"][0], "the gait no longer leaves the model: pick another for this test"
    records, _ = evaluation.evaluate(agents, ["plane"], duration=1.5, physics=IDEAL)
    own = [r for r in records if "leaves" in r["own_direction_of"]]
    assert len(own) == 1 and math.isfinite(own[0]["heading_deg"]) and own[0]["terminated"]


def test_evaluate_py_scores_a_robot_that_left_the_model_by_its_last_position_inside_it():
    """After an episode ends, the robot's autoreset episode may end too (the open-loop gait runs
    on); that later end must not put the new episode's start back into the scored path."""
    from rrrobot_gym import evaluation
    from rrrobot_gym.agents import GaitAgent

    leaves = SinusoidGait(1.4798, 1.4974, 1.5664, 1.5771, 8.6063, -1.8792, name="leaves")
    run = evaluation.run_episodes({"leaves": GaitAgent(leaves, dt=0.05, name="leaves")}, "plane", [0.0], duration=3.0,
                                  **IDEAL)["leaves"]  # fmt: skip (the servo of the file it is from: it leaves at 1.05 s)
    path = run["xy"][:, 0]
    last = np.flatnonzero(np.all(np.isfinite(path), axis=1))
    assert np.all(np.diff(last) == 1), "the path must be finite up to the episode's end, NaN after"
    [record] = evaluation.score(run, [0.0], 3.0)
    scores = evaluate_population(np.array([leaves.as_array()]), duration=3.0, start_seeds=(0,), reset_noise_scale=0.0,
                                 **IDEAL)  # fmt: skip
    np.testing.assert_allclose(record["displacement_m"], scores.runs.displacement[0, 0], atol=1e-12)
    assert record["terminated"] and abs(record["displacement_m"][0]) > 0.01


@pytest.mark.slow
def test_evaluate_py_rejects_a_file_that_is_not_a_gait_search_result(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"gaits": []}))
    result = subprocess.run([sys.executable, str(REPO / "evaluate.py"), "--no-policy", "--gaits", str(bad), "--duration", "1"],
                            capture_output=True, text=True, cwd=REPO)
    assert result.returncode == 2 and "not a gait-search result" in result.stderr, result.stderr


def test_robustness_uses_start_seeds_the_search_did_not(tiny_result):
    robust = tiny_result.gaits[0]["robustness"]
    assert not set(robust["seeds"]) & set(tiny_result.settings["start_seeds"])
    assert len(robust["speeds_mps"]) == 2 and robust["duration_s"] == pytest.approx(1.0)


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "rrrobot_gym", "gait-search", *map(str, args)],
                          capture_output=True, text=True, cwd=REPO)


@pytest.mark.slow
def test_cli_search_writes_its_json_with_the_command(tmp_path):
    out = tmp_path / "g.json"
    result = _cli("--model", "plane", "--objective", "heading", "--heading-deg", "90", "--evaluations", "4",
                  "--popsize", "2", "--screen", "2", "--duration", "0.5", "--robustness-seeds", "0",
                  "--env", "max_slip_velocity=0.05", "--no-progress", "--out", out)
    assert result.returncode == 0, result.stderr
    data = json.loads(out.read_text())
    assert data["objective"] == "heading" and data["heading_deg"] == 90.0
    assert data["env_kwargs"] == {"torque_limit": 0.5, "leg_rate_limit": 10.0, "leg_accel_limit": 60.0, "max_slip_velocity": 0.05}
    assert data["command"].startswith("rrrobot gait-search --model plane")
    assert "gait search" not in result.stderr  # --no-progress
    assert [g["name"] for g in data["gaits"]] == ["searched-plane-heading90-1", "searched-plane-heading90-2",
                                                  "searched-plane-heading90-3"]
    named = tmp_path / "named.json"
    result = _cli("--model", "plane", "--evaluations", "4", "--popsize", "2", "--screen", "2", "--duration", "0.5",
                  "--robustness-seeds", "0", "--keep", "2", "--name", "plane-50s", "--no-progress", "--out", named)
    assert result.returncode == 0, result.stderr
    assert [g.name for g in load_gaits(named)] == ["plane-50s-1", "plane-50s-2"]


@pytest.mark.parametrize(
    "args, problem",
    [
        (["--objective", "heading"], "--heading-deg"),
        (["--heading-deg", "90"], "--objective heading"),
        (["--env", "bogus=1"], "bogus"),
        (["--env", "model=pivot"], "--model"),
        (["--evaluations", "0"], "positive integer"),
        (["--popsize", "1"], "popsize"),
        (["--out", "gaits.txt"], ".json"),
        (["--name", "two words"], "--name"),
    ],
)
@pytest.mark.slow
def test_cli_bad_argument_is_one_clear_error(tmp_path, args, problem):
    if "--out" not in args:
        args = args + ["--out", tmp_path / "g.json"]
    result = _cli("--model", "plane", "--evaluations", "2", "--no-progress", *args)
    assert result.returncode == 2
    errors = [line for line in result.stderr.splitlines() if "error:" in line]
    assert len(errors) == 1 and problem in errors[0], result.stderr
    assert "Traceback" not in result.stderr


def test_search_rejects_bad_input():
    with pytest.raises(ValueError, match="budget"):
        search(progress=False)
    with pytest.raises(ValueError, match="heading_deg"):
        search(objective="heading", budget_evaluations=2, progress=False)
    with pytest.raises(ValueError, match="objective"):
        evaluate_population(np.array([GAIT1.as_array()]), objective="fast")
    with pytest.raises(ValueError, match="shape"):
        evaluate_population(np.zeros((2, 5)))
    with pytest.raises(TypeError, match="bogus"):
        search(budget_evaluations=2, progress=False, bogus=1)


def test_motor_limits_pass_through_to_the_env():
    """torque_limit reaches the env through **env_kwargs: no step applies more torque."""
    if "torque_limit" not in inspect.signature(RRRobotVectorEnv).parameters:
        pytest.skip("RRRobotVectorEnv has no torque_limit keyword yet (added on another branch)")
    scores = evaluate_population(np.array([GAIT1.as_array()]), duration=1.0, torque_limit=0.05, leg_rate_limit=20.0)
    assert scores.runs.torque_peak.max() <= 0.05 + 1e-12


@pytest.mark.slow
def test_ray_evaluation_equals_local_evaluation():
    ray = pytest.importorskip("ray")
    population = repair(np.random.default_rng(1).uniform(
        [gait_search.BOUNDS[n][0] for n in PARAMETER_NAMES], [gait_search.BOUNDS[n][1] for n in PARAMETER_NAMES], size=(5, 6)))
    population[0] = GAIT1.as_array()
    settings = dict(duration=1.0, start_seeds=(0, 1), objective="own")
    local = evaluate_population(population, **settings)
    ray.init(num_cpus=1, include_dashboard=False, runtime_env=gait_search.ray_runtime_env(), log_to_driver=False)
    try:
        remote = evaluate_population(population, ray_address="local", ray_chunks=3, **settings)
    finally:
        ray.shutdown()
    for key in ("displacement", "end_time", "terminated", "torque_peak", "leg_rate_peak"):
        np.testing.assert_allclose(getattr(remote.runs, key), getattr(local.runs, key), rtol=0, atol=1e-12, err_msg=key)
    np.testing.assert_allclose(remote.fitness, local.fitness, rtol=0, atol=1e-12)


@pytest.mark.parametrize("address", ["127.0.0.1:1", "ray://127.0.0.1:1"])
def test_a_ray_address_where_nothing_answers_is_named(address):
    # (ray.init retried it for minutes without a word; port 1 refuses at once)
    pytest.importorskip("ray")
    with pytest.raises(ConnectionError, match=f"ray_address '{address}': nothing answers at 127.0.0.1:1"):
        evaluate_population(np.array([GAIT1.as_array()]), duration=0.1, ray_address=address)


@pytest.mark.slow
def test_tuned_ppo_hyperparameters_cap_the_minibatch_at_one_rollout_and_learn(tmp_path):
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from rrrobot_gym.envs import RRRobotSB3VecEnv
    from rrrobot_gym.hyperparams import ppo_hyperparams, vecnormalize_kwargs

    with pytest.raises(ValueError, match="num_envs"):
        ppo_hyperparams(0)
    assert ppo_hyperparams(learning_rate_final=None)["learning_rate"] == 5e-4  # an override: a constant rate
    with pytest.raises(ValueError, match="activation must be one of tanh, relu, got 'softplus'"):
        ppo_hyperparams(activation="softplus")

    def activations(model):  # (the networks' layers other than the linear ones)
        return [type(m).__name__ for m in model.policy.mlp_extractor.modules()
                if not list(m.children()) and type(m).__name__ != "Linear"]

    tanh = PPO("MlpPolicy", VecNormalize(RRRobotSB3VecEnv(num_envs=2)), **ppo_hyperparams(2, activation="tanh"))
    assert activations(tanh) == ["Tanh"] * 4  # two hidden layers in each of the policy and value networks

    venv = VecNormalize(RRRobotSB3VecEnv(num_envs=2, max_episode_steps=100), **vecnormalize_kwargs())
    model = PPO("MlpPolicy", venv, seed=0, **ppo_hyperparams(num_envs=2))
    assert model.batch_size == 32 and model.n_steps == 16  # one minibatch a rollout at 2 envs
    assert activations(model) == ["ReLU"] * 4  # the default
    before = [p.detach().clone() for p in model.policy.parameters()]
    model.learn(64)  # two rollouts of 16 steps x 2 envs, each then 5 epochs (the last one's at rate 0)
    assert model.num_timesteps == 64
    assert any(not np.allclose(b.numpy(), a.detach().numpy()) for b, a in zip(before, model.policy.parameters()))
    venv.close()


def _report(terminated=(False, False), paper=False):
    return {"terminated": list(terminated), "paper_start_terminated": paper}


def test_rank_robust_first_puts_gaits_that_never_left_the_model_first_in_search_order():
    gaits = [
        {"search_rank": 1, "terminated_starts": 0, "robustness": _report((False, True))},  # a new start ended it
        {"search_rank": 2, "terminated_starts": 1, "robustness": _report()},  # a search start ended it
        {"search_rank": 3, "terminated_starts": 0, "robustness": _report()},
        {"search_rank": 4, "terminated_starts": 0, "robustness": _report(paper=True)},  # the paper's start ended it
        {"search_rank": 5, "terminated_starts": 0, "robustness": _report()},
    ]
    ranked = gait_search.rank_robust_first(gaits)
    assert [g["search_rank"] for g in ranked] == [3, 5, 1, 2, 4]
    assert [g["robust"] for g in ranked] == [True, True, False, False, False]


def test_search_writes_the_fittest_robust_gait_first(monkeypatch):
    # The fittest gait of a tiny search is made to leave the model on one new start: the search must
    # then put the next robust gait first, and keep the fittest, marked, behind the robust ones
    # (keep = the pool: every re-scored gait is written).
    real = gait_search.robustness
    pools = []

    def one_new_start_ends_the_fittest(parameters, **kwargs):
        reports = real(parameters, **kwargs)
        pools.append(len(parameters))
        reports[0]["terminated"][1] = True
        return reports

    monkeypatch.setattr(gait_search, "robustness", one_new_start_ends_the_fittest)
    result = search(budget_evaluations=13, screen=0, start=GAIT1, seed=3, keep=8, robust_pool=4, **TINY)
    assert pools == [8] and result.settings["robust_pool"] == 8
    gaits = result.gaits
    assert len(gaits) == 8 and [g["name"] for g in gaits] == [f"searched-plane-own-{i}" for i in range(1, 9)]
    ranks = [g["search_rank"] for g in gaits]
    robust = [g for g in gaits if g["robust"]]
    assert gaits[0]["robust"] and gaits[0]["search_rank"] > 1
    assert ranks.index(1) == len(robust) and not gaits[ranks.index(1)]["robust"]
    assert [g["search_rank"] for g in robust] == sorted(g["search_rank"] for g in robust)
    assert gaits[0]["fitness"] <= gaits[ranks.index(1)]["fitness"]


def test_without_a_re_score_the_order_is_the_search_fitness():
    result = search(budget_evaluations=7, screen=0, start=GAIT1, seed=3, keep=4,
                    **{**TINY, "robustness_seeds": 0})  # fmt: skip
    assert [g["search_rank"] for g in result.gaits] == [1, 2, 3, 4]
    assert all(g["robust"] is None and "robustness" not in g for g in result.gaits)
    assert result.settings["robust_pool"] is None
    fitness = [g["fitness"] for g in result.gaits]
    assert fitness == sorted(fitness, reverse=True)


RAMPED = SinusoidGait(1.2, 0.9, 1.6, 1.5, 8.4, -1.7, ramp_s=2.0)


def test_a_ramped_gait_starts_at_rest_and_its_rates_are_the_derivatives_of_its_angles():
    (a0, rate0, _) = RAMPED.leg_targets(0.0)
    assert a0 == (1.6, 1.5) and rate0 == (0.0, 0.0)  # the swing grows from nothing, at rest
    h = 1e-6
    for t in (0.13, 0.9, 1.41, 1.999):
        angles, rates, accels = (np.array(v) for v in RAMPED.leg_targets(t))
        np.testing.assert_allclose(angles, RAMPED.angles([t])[0], atol=1e-15)
        before, after = (np.array(RAMPED.leg_targets(t + d)[0]) for d in (-h, h))
        np.testing.assert_allclose((after - before) / (2 * h), rates, atol=1e-6)
        before, after = (np.array(RAMPED.leg_targets(t + d)[1]) for d in (-h, h))
        np.testing.assert_allclose((after - before) / (2 * h), accels, atol=1e-4)
    plain = SinusoidGait(1.2, 0.9, 1.6, 1.5, 8.4, -1.7)
    for t in (2.0, 2.3, 7.0):  # after the ramp: the plain sinusoid, to the bit
        assert RAMPED.leg_targets(t) == plain.leg_targets(t)
        assert np.array_equal(RAMPED.angles([t]), plain.angles([t]))
    # angle and rate are continuous where the ramp ends
    end, just_before = np.array(RAMPED.leg_targets(2.0)[:2]), np.array(RAMPED.leg_targets(2.0 - 1e-9)[:2])
    np.testing.assert_allclose(end, just_before, atol=1e-7)


def test_a_ramped_gait_is_simulated_on_numpy_and_its_legs_follow_the_growing_swing():
    from rrrobot_gym.simulation import SimConfig, simulate

    assert RAMPED.compiled_targets() is None  # the compiled stepper has no ramp
    with pytest.raises(TypeError, match="numba"):
        simulate(SimConfig(backend="numba"), RAMPED, 0.1)
    run = simulate(SimConfig(), RAMPED, 3.0)
    legs = run.states[:, 6:8]
    early, late = run.times < 0.5, run.times > 2.2
    # the servo follows the targets: a small swing in the first half second, the full one after the ramp
    swing_early = legs[early].max(axis=0) - legs[early].min(axis=0)
    swing_late = legs[late].max(axis=0) - legs[late].min(axis=0)
    assert np.all(swing_early < 0.2 * swing_late) and np.all(swing_late > 1.5 * np.array([1.2, 0.9]))
    assert RAMPED.replace(ramp_s=0.0).compiled_targets() is not None


def test_gait_files_carry_their_ramp_and_old_files_mean_none(tmp_path):
    data = {"schema": gait_search.SCHEMA, "gaits": [{"name": "g", "parameters": RAMPED.parameters()}]}
    path = tmp_path / "g.json"
    path.write_text(json.dumps(data))
    assert gait_search.load_gaits(path)[0].ramp_s == 0.0
    path.write_text(json.dumps({**data, "ramp_s": 2.0}))
    assert gait_search.load_gaits(path)[0] == RAMPED.__class__(**RAMPED.parameters(), ramp_s=2.0, name="g")
    for bad in (-1.0, "x", None):
        path.write_text(json.dumps({**data, "ramp_s": bad}))
        with pytest.raises(ValueError, match="ramp_s"):
            gait_search.load_gaits(path)


@pytest.mark.parametrize("bad", [-0.5, float("nan"), "2"])
def test_a_bad_ramp_is_named(bad):
    with pytest.raises((TypeError, ValueError), match="ramp_s"):
        SinusoidGait(1.0, 1.0, 1.5, 1.5, 8.0, 1.0, ramp_s=bad)
    with pytest.raises((TypeError, ValueError), match="ramp_s"):
        search(budget_evaluations=2, ramp_s=bad, **TINY)


def test_the_robustness_pool_skips_near_copies_of_fitter_gaits():
    units = np.array([[0.5] * 6, [0.51] * 6, [0.5] * 5 + [0.53], [0.2] * 6, [0.21] * 6])
    order = [0, 1, 2, 3, 4]  # fittest first
    assert gait_search.distinct_fittest(units, order, 5, spacing=0.02) == [0, 2, 3]
    assert gait_search.distinct_fittest(units, order, 2, spacing=0.02) == [0, 2]
    assert gait_search.distinct_fittest(units, order, 5, spacing=0.0) == [0, 1, 2, 3, 4]
    assert gait_search.distinct_fittest(units, [4, 3, 2, 1, 0], 5, spacing=0.02) == [4, 2, 1]


def test_a_search_re_scores_distinct_gaits_and_names_their_places(monkeypatch):
    real = gait_search.robustness
    pools = []

    def keep_pool(parameters, **kwargs):
        pools.append(np.array(parameters))
        return real(parameters, **kwargs)

    monkeypatch.setattr(gait_search, "robustness", keep_pool)
    # a spacing wide enough that a tiny search's gaits crowd within it: the pool must thin them out
    monkeypatch.setattr(gait_search, "POOL_SPACING", 0.3)
    result = search(budget_evaluations=25, screen=0, start=GAIT1, seed=3, keep=6, robust_pool=6, **TINY)
    lows, highs = gait_search._lows_highs()
    units = (pools[0] - lows) / (highs - lows)
    gaps = [np.abs(units[i] - units[j]).max() for i in range(len(units)) for j in range(i)]
    assert 2 <= len(units) <= 6 and min(gaps) >= 0.3
    ranks = [g["search_rank"] for g in result.gaits]
    assert len(ranks) == len(units) and 1 in ranks and len(set(ranks)) == len(ranks) and max(ranks) <= 25


def test_the_scoring_helpers_name_a_nan_heading_direction_or_parameter():
    """Each returned NaN fitness or speeds, or NaN gaits, without a word (search() checked its own)."""
    runs = evaluate_population(np.array([GAIT1.as_array()]), duration=0.1).runs
    with pytest.raises(ValueError, match="finite heading_deg"):
        fitness_from_runs(runs, "heading", float("nan"))
    with pytest.raises(ValueError, match="finite heading_deg"):
        gait_search.robustness(np.array([GAIT1.as_array()]), objective="heading", heading_deg=float("nan"), seeds=1,
                               duration=0.1)  # fmt: skip
    with pytest.raises(ValueError, match="directions_deg must be finite"):
        gait_search.robustness(np.array([GAIT1.as_array()]), directions_deg=[float("nan")], seeds=1, duration=0.1)
    with pytest.raises(ValueError, match="seeds must be a positive whole number"):
        gait_search.robustness(np.array([GAIT1.as_array()]), directions_deg=[0.0], seeds=0, duration=0.1)
    with pytest.raises(ValueError, match="ramp_s"):
        gait_search.ramp_factor(1.0, float("nan"))
    with pytest.raises(ValueError, match="gait parameters must be finite"):
        repair([float("nan")] * 6)


def test_a_bad_robustness_duration_is_refused_before_the_search(tmp_path):
    for bad in (-1.0, float("nan"), "50"):  # (named "duration", after the whole budget)
        with pytest.raises(ValueError, match="robustness_duration must be a positive number"):
            search(budget_evaluations=2, progress=False, robustness_duration=bad)


def test_a_duration_under_half_a_control_step_is_refused_and_the_time_scored_is_recorded():
    # (under half a step scored one 0.05 s step, and the file recorded the duration asked)
    for label, kwargs in (("duration", {"duration": 0.01}), ("robustness_duration", {"robustness_duration": 0.02})):
        with pytest.raises(ValueError, match=f"{label} 0.0[12] s is under half of the env's 0.05 s control step"):
            search(budget_evaluations=2, progress=False, **kwargs)
    with pytest.raises(ValueError, match="under half"):
        evaluate_population(np.array([GAIT1.as_array()]), duration=0.01)
    result = search(budget_evaluations=2, popsize=2, screen=0, start=GAIT1, duration=0.07, robustness_seeds=0,
                    progress=False)  # fmt: skip
    assert result.settings["duration_s"] == pytest.approx(0.05)  # one step, the nearest


def test_a_gait_file_naming_two_gaits_alike_is_refused(tmp_path):
    """load_gait_agents kept one of three gaits named "dup", silently."""
    data = json.loads((REPO / "agents" / "searched" / "plane_own.json").read_text())
    for gait in data["gaits"]:
        gait["name"] = "dup"
    path = tmp_path / "dup.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match="two or more gaits the name 'dup'"):
        gait_search.load_gaits(path)


def test_cli_out_that_is_a_directory_is_refused_before_the_search(tmp_path):
    (tmp_path / "taken.json").mkdir()
    result = _cli("--model", "plane", "--evaluations", "2", "--no-progress", "--out", tmp_path / "taken.json")
    assert result.returncode == 2 and "it is a directory" in result.stderr, result.stderr
