"""The env's step in one compiled call (task.CompiledTask) against the numpy task code, its reference:
the same observations, rewards, terminations, truncations and infos to the bit, over episodes that
end (terminations, truncations, autoresets), for the single env and the vector env. Both call the
same kernels, which use only operations IEEE 754 rounds exactly (rrrobot_gym.numerics): both runs
take numpy's array transcendentals one ulp off (as another CPU's SIMD kernels may be) while the
compiled code keeps libm's, so a quantity that came from one of them would fail here on any machine."""

import gymnasium
import numpy as np
import pytest

import rrrobot_gym  # noqa: F401  (registers the env)
from rrrobot_gym import compiled
from rrrobot_gym.envs import RRRobotVectorEnv, task

from conftest import array_transcendentals_one_ulp_off

pytestmark = pytest.mark.skipif(not compiled.available(), reason="numba not installed")

SCENES = {
    "default": {},
    "randomized": {"randomize": "default"},
    # the other branches: pivot, targets held, no motion profile, clock and positions, a survival reward
    "pivot-held-clock": {"model": "pivot", "action_hold": "zero_order", "leg_accel_limit": None, "clock_frequency": 3.0,
                         "exclude_current_positions_from_observation": False, "healthy_reward": 1.0},
    "no-friction-limit": {"friction_coefficient": None, "terminate_outside_model": False, "ctrl_cost_weight": 0.5},
}  # fmt: skip


def assert_same(a, b, where):
    """a == b to the bit (NaN where NaN), dicts with their keys in the same order."""
    if isinstance(a, dict):
        assert list(a) == list(b), where
        for key in a:
            assert_same(a[key], b[key], f"{where}[{key!r}]")
    elif isinstance(a, (tuple, list)) or (isinstance(a, np.ndarray) and a.dtype == object):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{i}]")
    elif a is None:
        assert b is None, where
    else:
        assert type(a) is type(b), where
        assert np.shape(a) == np.shape(b) and np.asarray(a).dtype == np.asarray(b).dtype, where
        assert np.array_equal(a, b, equal_nan=np.asarray(a).dtype.kind in "fc"), f"{where}: {a} != {b}"


def vector_run(compiled_step: bool, steps: int, num_envs: int = 12, **kwargs):
    env = RRRobotVectorEnv(num_envs=num_envs, max_episode_steps=60, backend="numba", **kwargs)
    assert (env.compiled_task is not None) == task.CompiledTask.applies(env.config)
    if not compiled_step:
        env.compiled_task = None
    rng = np.random.default_rng(1)
    results = [env.reset(seed=3)]
    for _ in range(steps):
        results.append(env.step(rng.uniform(-1.2, 1.2, (num_envs, 2)).astype(np.float32)))
    return results, env


def both_with_numpy_one_ulp_off(run):
    """(run(True), run(False)) with numpy's array transcendentals one ulp off, after a short run of
    each without (numba compiles the steppers they take there, and cannot while they are patched)."""
    run(True, warm_up=True), run(False, warm_up=True)
    with array_transcendentals_one_ulp_off():
        return run(True), run(False)


@pytest.mark.parametrize("scene", SCENES)
def test_vector_env_compiled_step_is_the_numpy_step(scene):
    def run(compiled_step, warm_up=False):
        return vector_run(compiled_step, 1 if warm_up else 150, **SCENES[scene])

    (fused, env), (reference, _) = both_with_numpy_one_ulp_off(run)
    assert env.compiled_task is not None
    for i, (a, b) in enumerate(zip(fused, reference)):
        assert_same(a, b, f"step {i}")
    terminated = sum(int(r[2].sum()) for r in fused[1:])
    truncated = sum(int(r[3].sum()) for r in fused[1:])
    assert terminated + truncated > 10  # episodes ended and sub-envs were reset within the run
    if scene in ("default", "randomized"):  # (the others end by the time limit here)
        assert terminated > 0


@pytest.mark.parametrize("scene", ["default", "randomized"])
def test_single_env_compiled_step_is_the_numpy_step(scene):
    def run(compiled_step, warm_up=False):
        env = gymnasium.make("RRRobot-v0", backend="numba", max_episode_steps=80, **SCENES[scene])
        assert env.unwrapped.compiled_task is not None
        if not compiled_step:
            env.unwrapped.compiled_task = None
        rng = np.random.default_rng(2)
        results, ends = [env.reset(seed=5)], 0
        for _ in range(1 if warm_up else 300):
            results.append(env.step(rng.uniform(-1.2, 1.2, 2)))
            if results[-1][2] or results[-1][3]:
                results.append(env.reset())
                ends += 1
        return results, ends

    (fused, ends), (reference, _) = both_with_numpy_one_ulp_off(run)
    assert ends > 3
    for i, (a, b) in enumerate(zip(fused, reference)):
        assert_same(a, b, f"step {i}")


def test_a_blow_up_fails_one_robot_alike():
    """A sub-env whose integration blows up (numerical failure) keeps its last finite state and
    observation and ends, the others step on: the same in both."""
    start = task.start_states(np.zeros((4, 10)))
    start[2, 8:11] = 1e30  # a spin no step survives

    def run(compiled_step, warm_up=False):
        env = RRRobotVectorEnv(num_envs=4, backend="numba")
        if not compiled_step:
            env.compiled_task = None
        results = [env.reset(seed=0, options={"state": start})]
        for _ in range(1 if warm_up else 3):
            results.append(env.step(np.full((4, 2), 0.3)))
        return results

    fused, reference = both_with_numpy_one_ulp_off(run)
    assert fused[1][4]["final_info"]["numerical_failure"].tolist() == [False, False, True, False]
    for i, (a, b) in enumerate(zip(fused, reference)):
        assert_same(a, b, f"step {i}")


def test_scenes_the_compiled_step_does_not_cover_run_the_numpy_step():
    assert task.CompiledTask.applies(task.make_task_config(backend="numba"))
    for kwargs in ({"backend": "numpy"}, {"contact_quadrature": "trapezoid"}, {"timestep": "auto"},
                   {"legs": "kinematic", **task.IDEAL_SERVO._asdict()}):  # fmt: skip
        assert RRRobotVectorEnv(num_envs=2, **kwargs).compiled_task is None, kwargs
    assert RRRobotVectorEnv(num_envs=2, backend="numba", workers=2).compiled_task is None
