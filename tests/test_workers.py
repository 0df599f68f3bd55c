"""advance(workers=...): a batch split over numba's threads gives exactly the one-thread result;
and small batches on numpy, robot by robot."""

import numpy as np
import pytest

from rrrobot_gym import compiled, dynamics
from rrrobot_gym.control import RampTargets, table2_gait
from rrrobot_gym.simulation import SimConfig, advance, initial_state


def _states(n, seed=0):
    rng = np.random.default_rng(seed)
    states = initial_state(n)
    quat = np.column_stack([np.ones(n), 0.2 * rng.standard_normal((n, 3))])
    states[:, dynamics.QUAT] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    states[:, dynamics.LEG_ANGLES] = rng.uniform(0.0, 3.0, (n, 2))
    states[:, dynamics.BODY_RATE] = rng.standard_normal((n, 3))
    states[:, dynamics.LEG_RATES] = rng.standard_normal((n, 2))
    return states


needs_numba = pytest.mark.skipif(not compiled.available(), reason="numba is not installed")


@needs_numba
def test_workers_give_bit_identical_states_and_records_under_motor_limits():
    # (the default scene over lane blocks, padded blocks and single robots: test_compiled's threads test)
    config, workers = SimConfig(model="pivot", torque_limit=0.5, leg_rate_limit=10.0, timestep="auto"), 3
    states = _states(37)
    ramp = RampTargets(states[:, dynamics.LEG_ANGLES], np.random.default_rng(1).uniform(0, 3, (37, 2)), 0.0, 0.05)
    one, one_record = advance(config, states, 0.0, 0.05, ramp, record=True)
    many, many_record = advance(config, states, 0.0, 0.05, ramp, record=True, workers=workers)
    assert np.array_equal(one, many)
    for field in ("times", "torque", "force", "normal", "leg_clearance", "leg_rates"):
        assert np.array_equal(getattr(one_record, field), getattr(many_record, field)), field
    # a target shared by all robots (a scripted gait) is split too
    assert np.array_equal(
        advance(config, states, 0.3, 0.05, table2_gait(3)),
        advance(config, states, 0.3, 0.05, table2_gait(3), workers=workers),
    )


@needs_numba
def test_more_workers_than_robots_and_bad_counts():
    states = _states(2)
    assert np.array_equal(advance(SimConfig(), states, 0.0, 0.05, table2_gait(1), workers=8),
                          advance(SimConfig(), states, 0.0, 0.05, table2_gait(1)))  # fmt: skip
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="workers"):
            advance(SimConfig(), states, 0.0, 0.05, table2_gait(1), workers=bad)


def test_workers_on_the_numpy_path_are_refused_by_name():
    import gymnasium

    import rrrobot_gym  # noqa: F401

    for config in (SimConfig(backend="numpy"), SimConfig(legs="kinematic")):
        with pytest.raises(ValueError, match="numba's threads, and this scene runs on numpy"):
            advance(config, _states(30), 0.0, 0.05, table2_gait(1), workers=2)
    with pytest.raises(ValueError, match="workers=2 shares the robots among numba's threads.*backend 'numpy'"):
        gymnasium.make_vec("RRRobot-v0", num_envs=4, workers=2, backend="numpy")


@needs_numba
def test_make_vec_with_workers_steps_exactly_as_with_one():
    import gymnasium

    import rrrobot_gym  # noqa: F401

    from rrrobot_gym.envs.task import IDEAL_SERVO

    # the ideal servo: its bang-bang kicks end episodes within the 30 steps (the default's mostly last longer)
    envs = [gymnasium.make_vec("RRRobot-v0", num_envs=9, workers=workers, **IDEAL_SERVO._asdict()) for workers in (1, 2)]
    observations = [env.reset(seed=3)[0] for env in envs]
    rng = np.random.default_rng(0)
    for _ in range(30):  # bang-bang actions: some robots leave the model and are reset in the step
        action = rng.choice([-1.0, 1.0], size=(9, 2)).astype(np.float32)
        results = [env.step(action) for env in envs]
        for item in range(4):
            assert np.array_equal(results[0][item], results[1][item])
        assert np.array_equal(results[0][4]["torque_rms"], results[1][4]["torque_rms"])
    assert np.any(results[0][2]) or np.any(envs[0].unwrapped.episode_steps < 30)  # resets happened
    with pytest.raises(ValueError, match="workers"):
        gymnasium.make_vec("RRRobot-v0", num_envs=2, workers=0)


@pytest.mark.parametrize(
    "config",
    [SimConfig(torque_limit=0.3, leg_rate_limit=8.0, backend="numpy"), SimConfig(model="pivot", backend="numpy"),
     SimConfig(legs="kinematic", timestep="auto")],
    ids=["servo-limited", "pivot", "kinematic-auto"],
)  # fmt: skip
def test_a_small_batch_run_robot_by_robot_matches_the_array_path_and_one_robot(config, monkeypatch):
    """Batches up to ROW_BY_ROW_MAX robots run robot by robot on floats: the same motion and
    record as numpy's batched path (to rounding) and exactly what each robot does alone."""
    from rrrobot_gym import simulation

    n = simulation.ROW_BY_ROW_MAX
    states = _states(n, seed=4)
    ends = np.random.default_rng(2).uniform(0, 3, (n, 2))
    ramp = RampTargets(states[:, dynamics.LEG_ANGLES], ends, 0.0, 0.05)
    rows, rows_record = advance(config, states, 0.0, 0.05, ramp, record=True)
    if config.timestep != "auto":  # (auto chooses one step for the whole batch: alone, a robot may get another)
        alone = advance(config, states[3], 0.0, 0.05, RampTargets(states[3, dynamics.LEG_ANGLES], ends[3], 0.0, 0.05),
                        record=True)  # fmt: skip
        assert np.array_equal(rows[3], alone[0]) and np.array_equal(rows_record.force[:, 3], alone[1].force)
    monkeypatch.setattr(simulation, "ROW_BY_ROW_MAX", 0)
    arrays, arrays_record = advance(config, states, 0.0, 0.05, ramp, record=True)
    np.testing.assert_allclose(rows, arrays, rtol=1e-12, atol=1e-12)
    assert np.abs(rows - states).max() > 1e-3  # they moved
    for field in ("torque", "force", "normal", "leg_clearance", "leg_rates"):
        np.testing.assert_allclose(getattr(rows_record, field), getattr(arrays_record, field), rtol=1e-10, atol=1e-10,
                                   err_msg=field)  # fmt: skip


def test_a_robot_blowing_up_in_a_small_batch_is_a_named_numerical_failure():
    from rrrobot_gym.simulation import NumericalFailure

    states = _states(3)
    states[1, dynamics.BODY_RATE] = 1e200  # overflows on floats
    with pytest.raises(NumericalFailure, match="non-finite state"):
        advance(SimConfig(), states, 0.0, 0.05, table2_gait(1))


def test_each_target_source_gives_a_small_batch_the_targets_each_robot_has_alone():
    """Robot by robot, a batch's held targets (their ``robot(i)``) and a source without
    ``robot`` (indexed at every evaluation) drive each robot exactly as it is driven alone."""
    from rrrobot_gym.control import HeldTargets

    class Indexed:  # a user's source of per-robot targets, without robot(i)
        def __init__(self, angles):
            self.angles = angles

        def leg_targets(self, t):
            return (self.angles[:, 0], self.angles[:, 1]), (0.0, 0.0), (0.0, 0.0)

    n = 5
    states = _states(n, seed=7)
    ends = np.random.default_rng(3).uniform(0, 3, (n, 2))
    for batch_targets in (HeldTargets(ends), Indexed(ends)):
        batch = advance(SimConfig(), states, 0.0, 0.05, batch_targets)
        for i in range(n):
            alone = advance(SimConfig(), states[i], 0.0, 0.05, HeldTargets(ends[i]))
            assert np.array_equal(batch[i], alone), (type(batch_targets).__name__, i)
        assert np.abs(batch - states).max() > 1e-3
