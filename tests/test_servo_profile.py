"""The default servo's motion profile (rrrobot_gym.envs.task.step_targets): the reference the leg
servo follows moves towards each action's target with a bounded rate and acceleration."""

import gymnasium
import numpy as np
import pytest

import rrrobot_gym  # noqa: F401  (registers RRRobot-v0)
from rrrobot_gym import dynamics
from rrrobot_gym.control import HeldTargets, RampTargets
from rrrobot_gym.envs import RRRobotEnv, RRRobotVectorEnv, task
from rrrobot_gym.simulation import advance

DEFAULT = task.make_task_config()
RATE, ACCEL, DT = 10.0, 60.0, 0.05
"""rad/s, rad/s^2, s: the default servo's limits and control step, as the env's docstring gives them."""


def test_the_defaults_are_the_servo_the_profile_is_checked_against():
    assert (DEFAULT.leg_rate_limit, DEFAULT.leg_accel_limit, DEFAULT.dt) == pytest.approx((RATE, ACCEL, DT), rel=1e-12)
    assert DEFAULT.torque_limit == 0.5 and DEFAULT.action_hold == "linear"


def _random_actions(rng, steps, robots):
    """Actions in [-1, 1]: per robot, targets held for a random number of steps (some for one
    step, some for many) and jumping anywhere, the last quarter of the robots drawing anew every step."""
    actions = np.empty((steps, robots, 2))
    for i in range(robots):
        for leg in range(2):
            k = 0
            while k < steps:
                hold = 1 if i >= 3 * robots // 4 else int(rng.geometric(0.15))
                actions[k:k + hold, i, leg] = rng.uniform(-1.0, 1.0)
                k += hold
    return actions


@pytest.mark.parametrize("hold", ["linear", "zero_order"])
def test_over_random_actions_the_reference_keeps_to_the_rate_and_acceleration_limits(hold):
    config = task.make_task_config(action_hold=hold)
    rng = np.random.default_rng(7)
    robots, steps = 64, 300
    actions = _random_actions(rng, steps, robots)
    reference = task.action_to_leg_targets(rng.uniform(-1.0, 1.0, (robots, 2)))
    rates = np.zeros((robots, 2))
    fastest, hardest = 0.0, 0.0
    for k in range(steps):
        held, end, new_rates = task.step_targets(actions[k], reference, rates, config, t=k * DT)
        assert np.all(np.abs(new_rates) <= RATE * (1.0 + 1e-12))
        assert np.all(np.abs(new_rates - rates) <= ACCEL * DT * (1.0 + 1e-12))
        np.testing.assert_allclose(end, reference + new_rates * DT, rtol=0, atol=1e-12)  # the rate is the step's
        # what the integrator follows: from the last reference to the new one, or the new one held
        start_angles, start_rates, _ = held.leg_targets(k * DT)
        end_angles, _, _ = held.leg_targets((k + 1) * DT)
        if hold == "linear":
            assert isinstance(held, RampTargets)
            np.testing.assert_allclose(np.transpose(start_angles), reference, rtol=0, atol=1e-12)
            np.testing.assert_allclose(np.transpose(start_rates), new_rates, rtol=1e-12, atol=1e-12)
        else:
            assert isinstance(held, HeldTargets)
            np.testing.assert_array_equal(np.transpose(start_angles), end)
        np.testing.assert_allclose(np.transpose(end_angles), end, rtol=0, atol=1e-12)
        fastest = max(fastest, np.abs(new_rates).max())
        hardest = max(hardest, np.abs(new_rates - rates).max())
        reference, rates = end, new_rates
    # both limits were met, not merely respected from afar
    assert fastest == pytest.approx(RATE, rel=1e-12) and hardest == pytest.approx(ACCEL * DT, rel=1e-12)


def test_a_constant_target_is_reached_and_held_without_overshoot():
    """From rest, a constant target: the reference reaches it within two control steps of the
    fastest a rate- and acceleration-limited motion can (a trapezoidal speed profile, continuous
    in time), passes it by no more than one step's change of rate times the step, a dt^2, and
    then holds it exactly, at rate 0."""
    rng = np.random.default_rng(3)
    robots = 2000
    actions = rng.uniform(-1.0, 1.0, (robots, 2))
    actions[:4] = [[1.0, -1.0], [-1.0, 1.0], [0.001, 0.0], [0.2, 0.3]]  # the longest moves, and short ones
    goal = task.action_to_leg_targets(actions)
    start = task.action_to_leg_targets(rng.uniform(-1.0, 1.0, (robots, 2)))
    start[:4] = task.action_to_leg_targets([[-1.0, 1.0], [1.0, -1.0], [0.0, 0.0], [0.2, 0.0]])
    towards = np.sign(goal - start)
    reference, rates = start.copy(), np.zeros((robots, 2))
    overshoot, reached = np.zeros((robots, 2)), np.full((robots, 2), -1)
    for k in range(40):  # 2 s: the longest move (3 pi / 2) takes 0.64 s
        _, reference, rates = task.step_targets(actions, reference, rates, DEFAULT)
        overshoot = np.maximum(overshoot, (reference - goal) * towards)
        at_goal = reference == goal
        assert np.all(at_goal[reached >= 0]) and np.all(rates[reached >= 0] == 0.0)  # held once reached
        reached[at_goal & (reached < 0)] = k + 1
    assert np.all(reached > 0)
    distance = np.abs(goal - start)
    cruising = distance > RATE**2 / ACCEL
    fastest = np.where(cruising, distance / RATE + RATE / ACCEL, 2.0 * np.sqrt(distance / ACCEL))  # s
    assert np.all(reached * DT <= fastest + 2 * DT + 1e-9), (reached * DT - fastest).max()
    assert overshoot.max() <= ACCEL * DT**2 + 1e-12


@pytest.mark.parametrize("servo", [task.IDEAL_SERVO._asdict(), {"leg_accel_limit": None}], ids=["ideal", "motors only"])
@pytest.mark.parametrize("hold", ["linear", "zero_order"])
def test_without_an_acceleration_limit_the_reference_goes_straight_to_the_action_s_target(servo, hold):
    """leg_accel_limit=None, with or without motor limits: the step ends on the action's target,
    and the env integrates exactly the step it did before the profile existed: from the last
    step's target, ramped or held, to this one's."""
    config = task.make_task_config(action_hold=hold, **servo)
    rng = np.random.default_rng(11)
    previous = task.action_to_leg_targets(rng.uniform(-1.0, 1.0, (50, 2)))
    actions = rng.uniform(-1.0, 1.0, (50, 2))
    _, end, rates = task.step_targets(actions, previous, rng.normal(0.0, 5.0, (50, 2)), config)
    np.testing.assert_array_equal(end, task.action_to_leg_targets(actions))
    np.testing.assert_array_equal(rates, (task.action_to_leg_targets(actions) - previous) / config.dt)

    env = RRRobotEnv(terminate_outside_model=False, action_hold=hold, **servo)
    env.reset(seed=4)
    for action in rng.uniform(-0.4, 0.4, (12, 2)).astype(np.float32):
        before, previous = env.state.copy(), env.leg_targets.copy()
        target = task.action_to_leg_targets(action)
        old = RampTargets(previous, target, 0.0, config.dt) if hold == "linear" else HeldTargets(target)
        after, _ = advance(config.sim, before, 0.0, config.dt, old, check=False, record=True)  # (as the env calls it)
        _, _, terminated, _, info = env.step(action)
        assert not info["numerical_failure"] and not terminated
        np.testing.assert_array_equal(env.state, after)
        np.testing.assert_array_equal(env.leg_targets, target)


def test_single_and_vector_envs_step_alike_to_the_bit_under_the_profile():
    """Random actions, where the profile's limits bind at almost every step: each sub-env's state,
    reference and rate are the single env's with the same seed, bit for bit."""
    n, kwargs = 4, {"terminate_outside_model": False}
    vector = RRRobotVectorEnv(num_envs=n, **kwargs)
    vector.reset(seed=9)
    singles = [RRRobotEnv(**kwargs) for _ in range(n)]
    for i, single in enumerate(singles):
        single.reset(seed=9 + i)
    actions = np.random.default_rng(2).uniform(-1.0, 1.0, (30, n, 2)).astype(np.float32)
    bound = 0
    for k, action in enumerate(actions):
        _, _, terminated, _, _ = vector.step(action)
        for i, single in enumerate(singles):
            _, _, ended, _, _ = single.step(action[i])
            assert ended == terminated[i]
            if ended:  # (the tilt limit: the vector env has restarted it)
                continue
            np.testing.assert_array_equal(single.state, vector.states[i])
            np.testing.assert_array_equal(single.leg_targets, vector.leg_targets[i])
            np.testing.assert_array_equal(single.leg_target_rates, vector.leg_target_rates[i])
        bound += int(np.sum(vector.leg_targets != task.action_to_leg_targets(action)))
        if terminated.any():
            break
    assert k >= 15 and bound > 0.9 * 2 * n * (k + 1)  # the reference lagged the actions' targets


def _random_episode_seconds(model):
    """A new user's first loop, env.action_space.sample() on the registered env of ``model``: how
    long each of 40 seeded episodes lasts (s), each checked to end physically (the tilt limit,
    leaving the model, or the 50 s truncation), none in a numerical failure."""
    env = gymnasium.make("RRRobot-v0", model=model)
    assert env.unwrapped.config.model == model and env.unwrapped.config.leg_accel_limit == ACCEL
    seconds = []
    for seed in range(40):
        env.reset(seed=seed)
        env.action_space.seed(seed)
        steps, terminated, truncated = 0, False, False
        while not (terminated or truncated):
            _, _, terminated, truncated, info = env.step(env.action_space.sample())
            steps += 1
        assert not info["numerical_failure"], seed
        assert truncated or info["outside_model"] or info["tilt"] >= dynamics.TILT_LIMIT, (seed, info)
        seconds.append(steps * env.unwrapped.dt)
    return seconds


def test_random_actions_on_the_default_env_last_a_second_in_median_and_end_physically():
    """The plane (the registered default): over seeds 0-39 the median lasts at least 1 s (2.28 s)."""
    seconds = _random_episode_seconds("plane")
    assert np.median(seconds) >= 1.0, sorted(seconds)


def test_random_actions_on_the_pivot_model_last_about_20_s_in_median_and_end_physically():
    """The README's pivot figure: over seeds 0-39 the median episode lasts about 20 s (19.7 s;
    5 of the 40 reach the 50 s truncation)."""
    seconds = _random_episode_seconds("pivot")
    assert 15.0 <= np.median(seconds) <= 25.0, sorted(seconds)
