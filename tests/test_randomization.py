"""Domain randomization (the env keyword ``randomize``): each drawn quantity acts as the env
with that value would, and nothing else changes."""

import dataclasses

import numpy as np
import pytest

from rrrobot_gym.envs import RRRobotEnv, RRRobotVectorEnv
from rrrobot_gym.envs import task
from rrrobot_gym.params import RobotParams

ACTIONS = np.random.default_rng(5).uniform(-0.6, 0.6, (12, 2))


def _states(env, actions, seed=3):
    obs, info = env.reset(seed=seed)
    states, observations, env.slips = [env.unwrapped.state.copy()], [obs], []
    for action in actions:
        obs, _, _, _, step_info = env.step(action)
        states.append(env.unwrapped.state.copy())
        observations.append(obs)
        env.slips.append(step_info["slip_velocity"])
    return np.array(states), np.array(observations), info


def test_an_action_delay_of_one_step_applies_the_previous_action():
    """Delayed by one step, the robot moves as an undelayed one given the actions one step late,
    the first step holding the start's legs (the state the reset left the servo in)."""
    delayed = RRRobotEnv(randomize={"action_delay": (1, 1)})
    plain = RRRobotEnv()
    states, _, info = _states(delayed, ACTIONS)
    assert info["randomized_action_delay"] == 1.0
    plain.reset(seed=3)
    hold = task.leg_targets_to_action(plain.state[6:8]).clip(-1.0, 1.0)
    expected, _, _ = _states(plain, np.vstack([hold, ACTIONS[:-1]]))
    np.testing.assert_array_equal(states, expected)
    assert not np.array_equal(states, _states(plain, ACTIONS)[0])


def test_observation_noise_perturbs_what_the_policy_sees_and_not_the_robot():
    noisy_env = RRRobotEnv(randomize={"observation_noise": (0.01, 0.01)})
    states, observations, _ = _states(noisy_env, ACTIONS)
    clean_states, clean, _ = _states(RRRobotEnv(), ACTIONS)
    np.testing.assert_array_equal(states, clean_states)  # (the physics does not see the noise)
    noise = (observations - clean)[:, task.noisy_observations(2)]
    assert 0.005 < noise[:, 6:].std() < 0.02  # rates and legs: sd 0.01
    np.testing.assert_array_equal(observations[:, 13:], clean[:, 13:])  # the commanded heading is the task's
    assert np.abs(observations[:, 0:6]).max() <= 1.0  # unit vectors stay in the observation space


@pytest.mark.parametrize("seed", [7, "sb3"])
def test_a_seeded_batch_repeats_its_observation_noise(seed):
    """Two batches seeded alike see the same noisy observations, through autoresets: an int seed,
    and SB3's seed(), which hands the batch a list (the batch's noise generator was left to the OS's
    entropy then, so no two training runs were alike)."""
    from rrrobot_gym.envs import RRRobotSB3VecEnv

    kwargs = dict(num_envs=4, randomize="default", max_episode_steps=5)
    actions = np.random.default_rng(1).uniform(-1, 1, (12, 4, 2)).astype(np.float32)
    runs = []
    for _ in range(2):
        if seed == "sb3":
            env = RRRobotSB3VecEnv(**kwargs)
            env.seed(7)
            observations = [env.reset()] + [env.step(action)[0] for action in actions]
        else:
            env = RRRobotVectorEnv(**kwargs)
            observations = [env.reset(seed=seed)[0]] + [env.step(action)[0] for action in actions]
        runs.append(np.array(observations))
    np.testing.assert_array_equal(runs[0], runs[1])
    ranges = {name: (r.low, r.high) for name, r in task.RANDOMIZATIONS["default"].items()}
    clean = RRRobotVectorEnv(**{**kwargs, "randomize": {**ranges, "observation_noise": (0.0, 0.0)}})
    assert not np.array_equal(runs[0][0], clean.reset(seed=7)[0])  # (the same robots and starts, but noisy)


@pytest.mark.parametrize("backend", ["numpy", "auto"])
def test_a_drawn_robot_moves_as_the_env_built_with_its_values(backend):
    """A randomized mass, leg length, gain and friction act as the same values given as keywords,
    in the single and in the vector env (whole episodes: the model's envelope does not end them)."""
    ranges = {"mass_tip": (1.08, 1.08), "leg_length": (0.93, 0.93), "kp": (1.1, 1.1), "friction_coefficient": (0.8, 0.8)}
    robot = dataclasses.replace(RobotParams(), mass_tip=0.057 * 1.08, leg_length=0.1 * 0.93)
    common = dict(backend=backend, terminate_outside_model=False)
    same = dict(robot=robot, kp=2.0 * 1.1, friction_coefficient=0.8, **common)
    drawn_env, given_env = RRRobotEnv(randomize=ranges, **common), RRRobotEnv(**same)
    drawn, _, info = _states(drawn_env, ACTIONS)
    assert info["randomized_mass_tip"] == 0.057 * 1.08 and info["randomized_friction_coefficient"] == 0.8
    given, _, _ = _states(given_env, ACTIONS)
    np.testing.assert_allclose(drawn, given, rtol=0, atol=1e-12)
    # the floor's grip too: the slip the step's record shows (some steps slip at friction 0.8)
    np.testing.assert_allclose(drawn_env.slips, given_env.slips, rtol=1e-9, atol=1e-12)
    assert max(given_env.slips) > 0.0
    nominal, _, _ = _states(RRRobotEnv(**common), ACTIONS)
    assert np.abs(drawn - nominal).max() > 1e-4
    vec = RRRobotVectorEnv(num_envs=3, randomize=ranges, **common)
    vec.reset(seed=[3, 4, 5])
    for action in ACTIONS:
        vec.step(np.tile(action, (3, 1)))
    np.testing.assert_allclose(vec.states[0], drawn[-1], rtol=0, atol=1e-12)
