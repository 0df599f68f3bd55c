"""RRRobot-v0, the single env: API conformance, the task's definitions, and its physics."""

import math
import os
import pathlib
import pickle
import subprocess
import sys
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.passive_env_checker import env_render_passive_checker

import rrrobot_gym
from rrrobot_gym import dynamics
from rrrobot_gym.analysis import travel_summary
from rrrobot_gym.control import table2_gait
from rrrobot_gym.envs import RRRobotEnv
from rrrobot_gym.envs.task import IDEAL_SERVO, RESET_INFO_KEYS, STEP_INFO_KEYS, leg_targets_to_action
from rrrobot_gym.simulation import SimConfig, initial_state, simulate

REPO_ROOT = pathlib.Path(__file__).resolve().parents[1]
IDEAL = IDEAL_SERVO._asdict()
"""The paper's servo, whose target jumps reach the ground, kick and slip the shell within a step."""

# Rates, leg angles and positions have no natural bound, so those Box bounds are infinite
# (as in the MuJoCo envs); Gymnasium's checker reports that as a style warning only.
INFINITE_BOUND_WARNINGS = (
    "observation space minimum value is -infinity",
    "observation space maximum value is infinity",
)


def upright_state(yaw=0.0, leg_angles=(0.5 * math.pi, 0.5 * math.pi)):
    state = initial_state(leg_angles=leg_angles)
    state[dynamics.QUAT] = (math.cos(0.5 * yaw), 0.0, 0.0, math.sin(0.5 * yaw))
    return state


def tilted_state(tilt, outward_rate, axis="x"):
    """At rest except for a rate pushing the tilt (about body x, or y) further out."""
    state = initial_state()
    angles = [tilt, 0.0, 0.0] if axis == "x" else [0.0, 0.0, tilt]
    state[dynamics.QUAT] = dynamics.quat_from_paper_angles(angles)
    state[dynamics.BODY_RATE] = (outward_rate, 0.0, 0.0) if axis == "x" else (0.0, outward_rate, 0.0)
    return state


def rollout(env, actions, seed):
    obs, info = env.reset(seed=seed)
    out = [(obs, info)]
    for action in actions:
        out.append(env.step(action))
    return out


@pytest.mark.slow
def test_gymnasium_check_env_with_default_arguments_passes_headless():
    """CI conditions: no display. check_env builds the env in every declared render mode
    ("human" too) and renders; the only notices are the infinite bounds and, once, why no
    window is shown."""
    code = (
        "import warnings, gymnasium, rrrobot_gym\n"
        "from gymnasium.utils.env_checker import check_env\n"
        "with warnings.catch_warnings(record=True) as caught:\n"
        "    warnings.simplefilter('always')\n"
        "    check_env(gymnasium.make('RRRobot-v0').unwrapped)\n"
        "for w in caught: print('WARNING', w.message)\n"
    )
    headless = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "MPLBACKEND")}
    result = subprocess.run([sys.executable, "-c", code], cwd=REPO_ROOT, env=headless, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    notices = [line for line in result.stdout.splitlines() if line.startswith("WARNING")]
    problems = [n for n in notices if not any(s in n for s in INFINITE_BOUND_WARNINGS)]
    assert len(problems) == 1 and "needs a display" in problems[0], notices


def test_make_registers_a_50_second_episode_with_20_fps():
    env = gymnasium.make("rrrobot_gym:RRRobot-v0")
    assert rrrobot_gym.ENV_ID == "RRRobot-v0"
    assert env.spec.max_episode_steps == 1000
    assert env.unwrapped.dt == pytest.approx(0.05)
    assert env.spec.max_episode_steps * env.unwrapped.dt == pytest.approx(50.0)
    assert env.metadata["render_fps"] == 20
    assert env.action_space == gymnasium.spaces.Box(-1, 1, (2,), np.float32)
    assert env.observation_space.shape == (15,) and env.observation_space.dtype == np.float32


def test_time_limit_truncates_after_exactly_1000_steps():
    env = gymnasium.make("RRRobot-v0")
    env.reset(seed=0)
    for step in range(1, 1001):
        _, _, terminated, truncated, _ = env.step(np.zeros(2, dtype=np.float32))
        assert not terminated
        assert truncated == (step == 1000)
    assert env.unwrapped.time == pytest.approx(50.0)


def test_same_seed_same_actions_give_identical_episodes_and_other_seeds_differ():
    actions = np.random.default_rng(3).uniform(-1, 1, (30, 2)).astype(np.float32)
    first = rollout(RRRobotEnv(), actions, seed=11)
    second = rollout(RRRobotEnv(), actions, seed=11)
    other = rollout(RRRobotEnv(), actions, seed=12)
    np.testing.assert_array_equal(first[0][0], second[0][0])
    for a, b in zip(first[1:], second[1:]):
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1:] == b[1:]
    assert not np.array_equal(first[0][0], other[0][0])
    assert first[0][1]["target_direction"] != other[0][1]["target_direction"]


def test_reward_is_the_sum_of_its_terms_and_the_terms_follow_their_definitions():
    env = RRRobotEnv(
        **IDEAL,  # (its wild kicks slip and lift the shell: every branch of the forward term)
        forward_reward_weight=1.5,
        ctrl_cost_weight=0.2,
        healthy_reward=0.3,
        terminate_outside_model=False,
        exclude_current_positions_from_observation=False,
    )
    obs, info = env.reset(seed=5)
    assert set(info) == set(RESET_INFO_KEYS)
    heading = np.array([math.cos(info["target_direction"]), math.sin(info["target_direction"])])
    rng = np.random.default_rng(0)
    branches = {"earned": 0, "slip only": 0, "lift-off only": 0}
    for step in range(40):
        # mostly gentle legs (travel the floor can give), every fourth step a wild kick
        action = rng.uniform(-1.5, 1.5, 2) if step % 4 == 3 else 0.5 + rng.uniform(-0.03, 0.03, 2)
        contact_before = np.array([info["x_position"], info["y_position"]])
        upright_before = np.array([info["x_upright"], info["y_upright"]])
        obs, reward, terminated, _, info = env.step(action)
        assert set(info) == set(STEP_INFO_KEYS)
        assert info["reward_survive"] == (0.0 if terminated else 0.3)
        contact = np.array([info["x_position"], info["y_position"]])
        upright = np.array([info["x_upright"], info["y_upright"]])
        assert reward == pytest.approx(info["reward_forward"] + info["reward_ctrl"] + info["reward_survive"], abs=1e-12)
        assert info["forward_velocity"] == pytest.approx((upright - upright_before) @ heading / env.dt, abs=1e-12)
        # travel while slipping or lifted off, or in the start-up grace (first 0.1 s), earns nothing;
        # terminate_outside_model=False only keeps such a step from ending the episode
        slipped = info["slip_velocity"] > env.config.max_slip_velocity
        lifted = info["liftoff_time"] > env.config.max_liftoff_time
        earned = not (slipped or lifted) and step * env.dt >= 0.1 - 1e-9
        expected_forward = 1.5 * 100.0 * info["forward_velocity"] if earned else 0.0
        if abs(info["forward_velocity"]) > 1e-4:  # a step whose forward term the rule decides
            if earned:
                branches["earned"] += 1
            elif slipped != lifted and step * env.dt >= 0.1:
                branches["slip only" if slipped else "lift-off only"] += 1
        # the model's envelope is measured, and reported, though it does not end the episode
        assert info["outside_model"] == (info["leg_clearance"] <= 0.0 or (step * env.dt >= 0.1 - 1e-9 and not earned))
        assert info["reward_forward"] == pytest.approx(expected_forward, rel=1e-12, abs=1e-15)  # cm/s
        assert info["reward_ctrl"] == pytest.approx(-0.2 * np.sum(np.clip(action, -1, 1) ** 2), rel=1e-12)
        assert (info["x_velocity"], info["y_velocity"]) == pytest.approx(tuple((contact - contact_before) / env.dt))
        np.testing.assert_allclose(obs[15:17], contact, rtol=1e-6)
        if terminated:  # the tilt limit (terminate_outside_model=False leaves only it and blow-ups)
            assert info["tilt"] >= dynamics.TILT_LIMIT
            break
    # every branch of the forward term was exercised on a step that moved
    assert branches["earned"] >= 5 and branches["slip only"] >= 1 and branches["lift-off only"] >= 1, branches


def test_a_state_set_by_hand_is_the_one_the_next_steps_velocity_starts_from():
    """The env reuses the last step's upright contact point as the next step's start, but
    only for the state it made: a state a user puts in ``env.unwrapped.state`` is measured afresh."""
    env = RRRobotEnv(terminate_outside_model=False, target_direction=0.0)
    env.reset(seed=1)
    action = np.array([0.3, -0.2], dtype=np.float32)
    for _ in range(5):
        env.step(action)
    moved = env.state.copy()
    moved[0] += 0.5  # half a metre along the heading: no robot travels 10 m/s
    env.state = moved
    servo = env.leg_targets.copy(), env.leg_target_rates.copy()  # the servo's reference and its rate
    _, _, _, _, info = env.step(action)
    twin = RRRobotEnv(terminate_outside_model=False, target_direction=0.0)
    twin.reset(options={"state": moved})
    twin.time, (twin.leg_targets, twin.leg_target_rates) = 5 * env.dt, servo  # the first env's clock and servo
    _, _, _, _, expected = twin.step(action)
    assert abs(info["forward_velocity"]) < 0.5
    assert info["forward_velocity"] == expected["forward_velocity"]


def test_rocking_in_place_moves_the_contact_point_but_not_the_upright_contact_point():
    """A shell rocking on its bottom rolls its contact to and fro; rolled back upright, it is still."""
    env = RRRobotEnv(reset_noise_scale=0.0)
    _, info = env.reset(options={"state": tilted_state(0.2, 0.0)})
    assert info["y_upright"] == pytest.approx(info["y_position"] + 0.12 * 0.2, rel=1e-12)  # r * tilt
    contact, upright = [], []
    for _ in range(40):  # 2 s, about two rocking periods; legs held vertical
        _, _, _, _, info = env.step(leg_targets_to_action([0.5 * math.pi, 0.5 * math.pi]))
        contact.append((info["x_position"], info["y_position"]))
        upright.append((info["x_upright"], info["y_upright"]))
        assert abs(info["reward_forward"]) < 1e-6
    assert np.ptp(np.array(contact)[:, 1]) > 0.04  # m: the contact rolls over +-r * tilt
    assert np.ptp(np.array(upright), axis=0).max() < 1e-9


@pytest.mark.parametrize("shell_axes", [(0.12, 0.12, 0.09), (0.12, 0.12, 0.14)], ids=["oblate", "prolate"])
def test_an_ellipsoid_rocking_in_place_keeps_its_upright_contact_point(shell_axes):
    """The meridian's arc (a quadrature, not the sphere's r tilt) rolls the contact back upright:
    it stays put while the contact rolls to and fro."""
    env = RRRobotEnv(reset_noise_scale=0.0, shell_axes=shell_axes)
    env.reset(options={"state": tilted_state(0.2, 0.0)})
    contact, upright = [], []
    for _ in range(40):
        _, _, _, _, info = env.step(leg_targets_to_action([0.5 * math.pi, 0.5 * math.pi]))
        contact.append(info["y_position"])
        upright.append((info["x_upright"], info["y_upright"]))
    assert np.ptp(contact) > 0.03
    assert np.ptp(np.array(upright), axis=0).max() < 1e-9


def test_tipping_over_towards_the_heading_earns_no_forward_reward():
    """Rolling onto the rim carries the contact ~r pi/2 = 0.19 m but is no locomotion."""
    env = RRRobotEnv(reset_noise_scale=0.0, target_direction=-0.5 * math.pi)
    _, start = env.reset(options={"state": tilted_state(0.1, 8.0)})  # rolls towards -Y
    total = 0.0
    for _ in range(20):
        _, _, terminated, _, info = env.step(leg_targets_to_action([0.5 * math.pi, 0.5 * math.pi]))
        total += info["reward_forward"]
        if terminated:
            break
    assert terminated and info["tilt"] >= dynamics.TILT_LIMIT
    assert start["y_position"] - info["y_position"] > 0.15
    assert abs(total) < 1e-3  # the raw contact point would have paid ~350


def test_out_of_range_actions_are_clipped_to_the_box():
    clipped = rollout(RRRobotEnv(), [np.array([1.0, -1.0])] * 5, seed=2)
    beyond = rollout(RRRobotEnv(), [np.array([7.0, -3.0])] * 5, seed=2)
    for a, b in zip(clipped[1:], beyond[1:]):
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1:] == b[1:]


@pytest.mark.parametrize(
    "action, message",
    [
        (np.zeros(3), "shape"),
        (np.zeros((1, 2)), "shape"),
        (np.array([0.0, np.nan]), "NaN"),
        (np.array([np.inf, 0.0]), "inf"),
    ],
)
def test_bad_actions_raise_value_error_naming_the_problem(action, message):
    env = RRRobotEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        env.step(action)


@pytest.mark.parametrize(
    "kwargs, error, name",
    [
        ({"frame_skp": 15}, TypeError, "frame_skp"),
        ({"frame_skip": -1}, ValueError, "frame_skip"),
        ({"frame_skip": 0}, ValueError, "frame_skip"),
        ({"frame_skip": 1.5}, TypeError, "frame_skip"),
        ({"timestep": 0.0}, ValueError, "timestep"),
        ({"model": "moon"}, ValueError, "model"),
        ({"integrator": "euler"}, ValueError, "integrator"),
        ({"kp": -2.0}, ValueError, "kp"),
        ({"damping": 0.1}, ValueError, "damping"),
        ({"robot": {"radius": 0.1}}, TypeError, "robot"),
        ({"ctrl_cost_weight": -0.1}, ValueError, "ctrl_cost_weight"),
        ({"reset_noise_scale": float("nan")}, ValueError, "reset_noise_scale"),
        ({"target_direction": "north"}, TypeError, "target_direction"),
        ({"exclude_current_positions_from_observation": "yes"}, TypeError, "exclude_current_positions"),
        ({"render_mode": "video"}, ValueError, "render_mode"),
        ({"width": 10}, ValueError, "width"),
        ({"legs": "wheels"}, ValueError, "legs"),
        ({"timestep": "fast"}, ValueError, "timestep"),
        ({"torque_limit": 0.0}, ValueError, "torque_limit"),
        ({"torque_limit": None, "leg_rate_limit": 5.0}, ValueError, "leg_rate_limit"),  # needs a torque_limit
        ({"legs": "kinematic", "torque_limit": 0.1}, ValueError, "torque_limit"),
        ({"legs": "kinematic"}, ValueError, "torque_limit=None and leg_rate_limit=None"),  # the default servo's limits
        ({"leg_accel_limit": 0.0}, ValueError, "leg_accel_limit"),
        ({"leg_accel_limit": -60.0}, ValueError, "leg_accel_limit"),
        ({"leg_accel_limit": float("nan")}, ValueError, "leg_accel_limit"),
        ({"leg_accel_limit": "fast"}, TypeError, "leg_accel_limit"),
    ],
)
@pytest.mark.filterwarnings("ignore:.*render_mode='video'")
def test_bad_keywords_raise_at_construction_naming_the_keyword(kwargs, error, name):
    with pytest.raises(error, match=name):
        gymnasium.make("RRRobot-v0", **kwargs)


def short_episode(steps=20, **kwargs):
    """Positions and infos of ``steps`` steps of Table II's Gait 1, from the same seeded start."""
    env = gymnasium.make("RRRobot-v0", **kwargs)
    env.reset(seed=3)
    gait, rows = table2_gait(1), []
    for k in range(steps):
        _, _, terminated, _, info = env.step(leg_targets_to_action(gait.angles((k + 1) * env.unwrapped.dt)))
        assert not terminated and not info["numerical_failure"], (kwargs, k, info)
        rows.append(info)
    return np.array([(i["x_position"], i["y_position"]) for i in rows]), rows


@pytest.mark.parametrize("kwargs", [{"legs": "kinematic", "torque_limit": None, "leg_rate_limit": None},  # (no motor)
                                    {"timestep": "auto"}, {"timestep": 1 / 600, "frame_skip": 30}])
def test_simulator_keywords_run_an_episode_that_differs_from_the_default(kwargs):
    default, _ = short_episode()
    other, _ = short_episode(**kwargs)
    difference = np.max(np.abs(other - default))
    assert 1e-9 < difference < 1e-2  # m: another simulation of the same motion, not another motion


def test_torque_limit_caps_the_leg_torque_the_step_reports():
    _, free = short_episode()
    assert max(info["torque_peak"] for info in free) > 0.1  # N m: the gait's start needs more
    for motor in ({"torque_limit": 0.05}, {"torque_limit": 0.05, "leg_rate_limit": 20.0}):
        _, limited = short_episode(**motor)
        assert max(info["torque_peak"] for info in limited) <= 0.05 + 1e-12


def test_a_stiff_servo_refused_at_the_default_step_runs_as_the_error_suggests():
    """SimConfig's message recommends timestep='auto' or legs='kinematic', the latter without the
    default servo's motor limits: all are env keywords."""
    stiff = {"kp": 200.0, "kd": 5.0}
    with pytest.raises(ValueError, match="timestep='auto', or legs='kinematic' with torque_limit=None and leg_rate_limit=None"):
        gymnasium.make("RRRobot-v0", **stiff)
    for fix in ({"timestep": "auto"}, {"legs": "kinematic", "torque_limit": None, "leg_rate_limit": None}):
        env = gymnasium.make("RRRobot-v0", **stiff, **fix)
        env.reset(seed=0)
        assert env.step(np.zeros(2, dtype=np.float32))[-1]["numerical_failure"] is False
        vector = gymnasium.make_vec("RRRobot-v0", num_envs=2, **stiff, **fix)
        vector.reset(seed=0)
        assert not vector.step(np.zeros((2, 2), dtype=np.float32))[-1]["numerical_failure"].any()
    assert gymnasium.make("RRRobot-v0", timestep="auto").unwrapped.config.sim.timestep == "auto"


def test_bad_reset_options_raise():
    env = RRRobotEnv()
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(options={"tilt": 1.0})
    with pytest.raises(ValueError, match="shape"):
        env.reset(options={"state": np.zeros(12)})
    with pytest.raises(ValueError, match="tilt"):
        env.reset(options={"state": tilted_state(1.6, 0.0)})


def test_upright_observation_gives_world_up_and_the_heading_relative_to_the_body_yaw():
    yaw, target = 0.7, 2.0
    env = RRRobotEnv(exclude_current_positions_from_observation=False)
    obs, _ = env.reset(seed=0, options={"state": upright_state(yaw), "target_direction": target})
    np.testing.assert_allclose(obs[0:3], [0, 0, 1], atol=1e-7)
    np.testing.assert_allclose(obs[3:6], [math.cos(target - yaw), math.sin(target - yaw), 0], atol=1e-7)
    np.testing.assert_allclose(obs[6:9], 0.0)
    np.testing.assert_allclose(obs[9:11], 0.5 * math.pi, rtol=1e-7)
    np.testing.assert_allclose(obs[11:13], 0.0)
    np.testing.assert_allclose(obs[13:15], [math.cos(target), math.sin(target)], atol=1e-7)
    np.testing.assert_allclose(obs[15:17], 0.0)
    assert RRRobotEnv().reset(seed=0)[0].shape == (15,)


def test_turning_the_whole_scene_about_the_vertical_leaves_the_body_observations_and_rewards_unchanged():
    """The dynamics do not know about world yaw, and neither should entries 0:13 of the
    observation nor the reward: Gait 1 from a rocking start, commanded along -1.2 rad, then
    the same with start and heading turned by 1.1 rad, agree to rounding on every step."""
    gait = table2_gait(1)
    start = initial_state(leg_angles=(1.3, 1.9))
    start[dynamics.QUAT] = dynamics.quat_from_paper_angles([0.1, 0.0, -0.05])
    start[dynamics.BODY_RATE] = (0.2, -0.1, 0.3)
    turned = start.copy()
    turn = 1.1
    yaw_turn = [math.cos(0.5 * turn), 0.0, 0.0, math.sin(0.5 * turn)]
    turned[dynamics.QUAT] = dynamics.quat_multiply(yaw_turn, start[dynamics.QUAT])

    env_a, env_b = RRRobotEnv(), RRRobotEnv()
    obs_a, _ = env_a.reset(options={"state": start, "target_direction": -1.2})
    obs_b, _ = env_b.reset(options={"state": turned, "target_direction": -1.2 + turn})
    np.testing.assert_allclose(obs_a[:13], obs_b[:13], atol=1e-6)
    earning = 0
    for k in range(60):
        action = leg_targets_to_action(gait.angles((k + 1) * env_a.dt))
        obs_a, reward_a, terminated_a, _, info_a = env_a.step(action)
        obs_b, reward_b, terminated_b, _, info_b = env_b.step(action)
        assert not terminated_a and not terminated_b
        np.testing.assert_allclose(obs_a[:13], obs_b[:13], atol=1e-6)
        assert reward_a == pytest.approx(reward_b, abs=1e-9)
        assert info_a["reward_forward"] == pytest.approx(info_b["reward_forward"], abs=1e-9)
        earning += info_a["reward_forward"] != 0.0
    assert earning >= 55  # the forward term, not only the control cost, was compared


def gait_through_env(model, number, duration, target_direction):
    """Play Table II gait ``number`` through the env: each step holds the gait's angles at the step's end.

    Returns the gait, the step times, the contact points (steps + 1, 2), the total reward
    and the last info.
    """
    gait = table2_gait(number)
    env = RRRobotEnv(model=model, reset_noise_scale=0.0, target_direction=target_direction)
    env.reset(seed=0)
    steps = round(duration / env.dt)
    xy, total_reward = [(0.0, 0.0)], 0.0
    for k in range(steps):
        action = leg_targets_to_action(gait.angles((k + 1) * env.dt))
        _, reward, terminated, _, info = env.step(action)
        assert not terminated
        xy.append((info["x_position"], info["y_position"]))
        total_reward += reward
    times = env.dt * np.arange(steps + 1)
    return gait, times, np.array(xy), total_reward, info


@pytest.mark.parametrize(
    "model, number, direction_tolerance_deg",
    [("plane", 1, 3.0), ("pivot", 1, 3.0), ("plane", 3, 8.0)],
)
def test_scripted_table2_gait_moves_through_the_env_as_in_the_simulator_core(model, number, direction_tolerance_deg):
    """Held targets (rate 0, one per 0.05 s step) are not the continuous gait, so not identical.

    Measured over 20 s: the env's displacement is 3-5 % shorter than the core's, the
    direction within 1 degree (Gait 1) and 4 degrees (Gait 3), the turning within 7 degrees.
    """
    duration = 20.0
    gait, times, xy, _, _ = gait_through_env(model, number, duration, target_direction=-0.5 * math.pi)
    core = simulate(SimConfig(model=model), gait, duration, sample_dt=0.05)
    ours = travel_summary(times, xy[:, 0], xy[:, 1], gait.period)
    reference = travel_summary(core.times, core.x, core.y, gait.period)
    assert ours["displacement_m"] == pytest.approx(reference["displacement_m"], rel=0.10)
    direction_error = (ours["direction_deg"] - reference["direction_deg"] + 180.0) % 360.0 - 180.0
    assert abs(direction_error) < direction_tolerance_deg
    assert ours["turning_deg"] == pytest.approx(reference["turning_deg"], abs=15.0)


def test_gait1_earns_its_travel_along_minus_y_as_reward():
    """Gait 1 goes along -Y: commanded that way it is rewarded, the opposite way penalised, equally.

    The forward terms add up to the net travel of the upright contact point (x 100 / dt)
    after the start-up grace.
    """
    _, _, xy, along, last = gait_through_env("plane", 1, 10.0, target_direction=-0.5 * math.pi)
    _, _, _, against, _ = gait_through_env("plane", 1, 10.0, target_direction=0.5 * math.pi)
    ctrl = along + against  # the forward terms cancel; what is left is twice the (equal) control cost
    assert along > 0 > against
    # (less the first 0.1 s, which earns nothing: 0.14 % of this travel)
    assert along - 0.5 * ctrl == pytest.approx(-100.0 * last["y_upright"] / 0.05, rel=5e-3)
    # The upright and the raw contact point end within a few millimetres: the net travel is the same.
    assert last["y_upright"] == pytest.approx(xy[-1, 1], abs=5e-3)
    assert along / 200 == pytest.approx(0.9, abs=0.1)  # ~0.9 cm/s: ~0.9 reward a step


def test_reaching_the_tilt_limit_terminates_cleanly():
    env = gymnasium.make("RRRobot-v0", reset_noise_scale=0.0)
    # Pitch about body y: the legs sit on that axis, so the rim, not a leg, meets the ground.
    env.reset(seed=0, options={"state": tilted_state(1.45, 4.0, axis="y")})
    for _ in range(20):
        obs, reward, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
        if terminated:
            break
    assert terminated and not truncated
    assert info["tilt"] >= dynamics.TILT_LIMIT
    assert not info["outside_model"]
    assert not info["numerical_failure"]
    assert np.all(np.isfinite(obs)) and math.isfinite(reward)


def test_a_numerical_blow_up_ends_the_episode_with_a_flag_and_the_last_finite_observation():
    env = gymnasium.make("RRRobot-v0", reset_noise_scale=0.0)
    exploding = initial_state()
    exploding[dynamics.BODY_RATE] = (1e30, 0.0, 0.0)  # finite, but the first step overflows
    obs0, _ = env.reset(seed=0, options={"state": exploding})
    obs, reward, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
    assert terminated and not truncated
    assert info["numerical_failure"] is True
    np.testing.assert_array_equal(obs, obs0)
    assert reward == 0.0 and info["reward_forward"] == 0.0 and info["reward_ctrl"] == 0.0


def test_rgb_array_frames_are_uint8_images_that_change_as_the_robot_moves():
    env = gymnasium.make("RRRobot-v0", render_mode="rgb_array")
    env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env_render_passive_checker(env.unwrapped)
    first = env.render()
    assert first.shape == (400, 800, 3) and first.dtype == np.uint8
    for _ in range(10):
        env.step(np.array([1.0, -1.0], dtype=np.float32))
    assert np.any(env.render() != first)
    small = gymnasium.make("RRRobot-v0", render_mode="rgb_array", width=320, height=160)
    small.reset(seed=0)
    assert small.render().shape == (160, 320, 3)
    env.close()
    env.close()


def test_human_rendering_without_a_display_warns_once_why_and_runs_on():
    matplotlib = pytest.importorskip("matplotlib")
    previous = matplotlib.get_backend()
    matplotlib.use("Agg")
    try:
        env = RRRobotEnv(render_mode="human")
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            env.reset(seed=0)  # human mode renders on reset and step
            for _ in range(3):
                env.step(np.zeros(2, dtype=np.float32))
            assert env.render() is None
        messages = [str(w.message) for w in caught]
        assert len(messages) == 1 and "needs a display" in messages[0] and "rgb_array" in messages[0], messages
    finally:
        matplotlib.use(previous)


@pytest.mark.slow
def test_plain_stepping_imports_no_rendering_or_training_libraries():
    code = (
        "import sys, numpy as np, gymnasium, rrrobot_gym\n"
        "env = gymnasium.make('RRRobot-v0'); env.reset(seed=0)\n"
        "for _ in range(3): env.step(np.zeros(2, dtype=np.float32))\n"
        "loaded = [m for m in ('PIL', 'matplotlib', 'stable_baselines3', 'torch') if m in sys.modules]\n"
        "assert not loaded, loaded\n"
        "assert env.unwrapped._path is None\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=REPO_ROOT)


def test_env_pickles_and_rebuilds_with_its_arguments():
    env = RRRobotEnv(model="pivot", ctrl_cost_weight=0.3, target_direction=1.0)
    clone = pickle.loads(pickle.dumps(env))
    assert clone.config == env.config
    actions = [np.array([0.5, -0.2])] * 5
    for a, b in zip(rollout(env, actions, seed=4)[1:], rollout(clone, actions, seed=4)[1:]):
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1:] == b[1:]


def test_a_leg_reaching_the_ground_ends_the_episode_outside_the_model():
    """Leg-ground contact is not modelled: a leg tip at the floor ends the episode (with a flag)."""
    start = tilted_state(1.2, 0.0)  # rolled 69 degrees onto leg 1's side
    start[dynamics.LEG_ANGLES] = (0.0, 0.5 * math.pi)
    from rrrobot_gym.envs import task

    down = task.leg_targets_to_action([-0.25 * math.pi, 0.5 * math.pi]).astype(np.float32)
    for terminate in (True, False):  # (the ideal servo swings the leg down within the step)
        env = gymnasium.make("RRRobot-v0", reset_noise_scale=0.0, terminate_outside_model=terminate, **IDEAL)
        env.reset(seed=0, options={"state": start})
        obs, reward, terminated, truncated, info = env.step(down)
        assert info["leg_clearance"] <= 0.0 and info["outside_model"]
        assert info["tilt"] < dynamics.TILT_LIMIT and not info["numerical_failure"]
        assert terminated is terminate


@pytest.mark.slow
def test_table2_gaits_stay_inside_the_model_for_a_whole_episode():
    from rrrobot_gym.agents import gait_agent

    for name in ("gait1", "gait2", "gait3"):
        env = gymnasium.make("RRRobot-v0", reset_noise_scale=0.0)
        obs, _ = env.reset(seed=0)
        agent, state = gait_agent(name, dt=env.unwrapped.dt), None
        clearance, friction, normal = [], [], []
        for step in range(1000):
            action, state = agent.predict(obs, state=state, episode_start=np.array([step == 0]))
            obs, _, terminated, truncated, info = env.step(action)
            clearance.append(info["leg_clearance"])
            friction.append(info["friction_ratio"])
            normal.append(info["normal_force"])
            assert not terminated, (name, step)
        assert truncated
        # after the start-up (the legs leave vertical abruptly at t = 0) they need less than
        # a friction coefficient of 1, and the ground always pushes
        assert min(clearance) > 0.01 and max(friction[2:]) < 1.0 and min(normal) > 0.0


def test_a_kick_that_would_slip_the_shell_earns_no_forward_reward_and_ends_the_episode():
    env = RRRobotEnv(reset_noise_scale=0.0, target_direction=0.0, **IDEAL)  # (the ideal servo's full-range kick)
    env.reset(seed=0)
    for _ in range(3):  # past the 0.1 s start-up grace, legs still
        _, _, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
        assert not terminated and info["slip_velocity"] < 1e-6
    _, reward, terminated, _, info = env.step(np.array([1.0, -1.0], dtype=np.float32))
    assert info["slip_velocity"] > env.config.max_slip_velocity
    assert info["outside_model"] and terminated
    assert info["reward_forward"] == 0.0
