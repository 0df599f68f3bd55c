"""The native batched vector env: per-env agreement with the single env, autoreset, failures."""

import math
import pickle
import warnings

import gymnasium
import numpy as np
import pytest
from conftest import array_transcendentals_one_ulp_off
from gymnasium.vector import AsyncVectorEnv, AutoresetMode, SyncVectorEnv

import rrrobot_gym  # noqa: F401  (registers RRRobot-v0)
from rrrobot_gym import compiled, dynamics
from rrrobot_gym.envs import RRRobotVectorEnv, task
from rrrobot_gym.simulation import initial_state

# Both envs step from t = 0 and integrate one robot (numba: robot by robot or in lane blocks,
# the same arithmetic) to the bit (test below); numpy batches of more than a few robots take
# array arithmetic and the task code's batch reductions round differently, so the rest of this
# file compares to rounding.
STATE_TOLERANCE = 1e-9
OBS_TOLERANCE = 1e-6  # float32 observations


def near_tilt_limit_state():
    state = initial_state()
    state[dynamics.QUAT] = dynamics.quat_from_paper_angles([0.0, 0.0, 1.45])  # pitched about body y: the rim, not a leg, lands
    state[dynamics.BODY_RATE] = (0.0, 4.0, 0.0)
    return state


def sync_reference(num_envs, **kwargs):
    """Gymnasium's own SAME_STEP vectoriser over copies of the registered single env."""
    return SyncVectorEnv(
        [lambda: gymnasium.make("RRRobot-v0", **kwargs) for _ in range(num_envs)],
        autoreset_mode=AutoresetMode.SAME_STEP,
    )


def assert_infos_match(ours, theirs):
    """Same keys where set, same masks, same values (to rounding)."""
    for key in theirs:
        if key.startswith("_"):
            continue
        mask = theirs["_" + key]
        np.testing.assert_array_equal(ours["_" + key], mask, err_msg=key)
        if key == "final_obs":
            for a, b in zip(ours[key][mask], theirs[key][mask]):
                np.testing.assert_allclose(a, b, atol=OBS_TOLERANCE)
        elif key == "final_info":
            assert_infos_match(ours[key], theirs[key])
        elif ours[key].dtype.kind in "US":  # (info["termination"])
            np.testing.assert_array_equal(ours[key][mask], theirs[key][mask], err_msg=key)
        else:
            np.testing.assert_allclose(ours[key][mask], theirs[key][mask], atol=STATE_TOLERANCE, err_msg=key)
    # Keys we report that the reference does not have must be masked out everywhere.
    for key in set(ours) - set(theirs):
        if not key.startswith("_"):
            assert not ours["_" + key].any(), key


def test_make_vec_gives_the_native_batched_env_declaring_same_step_autoreset():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env = gymnasium.make_vec("RRRobot-v0", num_envs=4, model="pivot")
    assert type(env) is RRRobotVectorEnv
    assert env.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP
    assert env.max_episode_steps == 1000
    assert env.config.sim.model == "pivot"
    assert env.observation_space.shape == (4, 15) and env.action_space.shape == (4, 2)
    assert env.single_observation_space == gymnasium.make("RRRobot-v0").observation_space
    obs, info = env.reset(seed=0)
    assert obs.shape == (4, 15) and obs.dtype == np.float32
    assert info["_x_position"].all()


@pytest.mark.parametrize("ending", ["time limit", "tilt limit"])
def test_each_sub_env_matches_a_single_env_with_seed_plus_i_across_autoresets(ending):
    num_envs, limit = 3, 5
    ours = RRRobotVectorEnv(num_envs=num_envs, max_episode_steps=limit)
    theirs = sync_reference(num_envs, max_episode_steps=limit)
    options = {"state": near_tilt_limit_state()} if ending == "tilt limit" else None
    obs_a, info_a = ours.reset(seed=21, options=options)
    obs_b, info_b = theirs.reset(seed=21, options=options)
    np.testing.assert_allclose(obs_a, obs_b, atol=OBS_TOLERANCE)
    assert_infos_match(info_a, info_b)
    # Gentle legs for the time limit: wild ones leave the model (leg on the floor, a hop) first.
    scale = 0.05 if ending == "time limit" else 1.2
    actions = np.random.default_rng(1).uniform(-scale, scale, (3 * limit, num_envs, 2)).astype(np.float32)
    ended = {"terminated": 0, "truncated": 0}
    for action in actions:
        obs_a, reward_a, term_a, trunc_a, info_a = ours.step(action)
        obs_b, reward_b, term_b, trunc_b, info_b = theirs.step(action)
        np.testing.assert_allclose(obs_a, obs_b, atol=OBS_TOLERANCE)
        np.testing.assert_allclose(reward_a, reward_b, atol=STATE_TOLERANCE)
        np.testing.assert_array_equal(term_a, term_b)
        np.testing.assert_array_equal(trunc_a, trunc_b)
        assert_infos_match(info_a, info_b)
        ended["terminated"] += term_a.sum()
        ended["truncated"] += trunc_a.sum()
    # The scenario really exercised the autoreset it is named after.
    assert ended["terminated" if ending == "tilt limit" else "truncated"] >= num_envs


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_the_single_env_and_a_one_robot_vector_env_step_alike_to_the_bit(backend):
    """The same actions give the same states, observations and rewards, bit for bit: both envs
    advance from t = 0 (a ramp's time is relative to its step). With numba, sub-envs of a batch
    of 40 (a lane block of 32 and leftovers robot by robot) keep the single env's states too.
    numpy's array transcendentals are one ulp off (another CPU's SIMD kernels): one robot's floats
    and a batch's arrays must not depend on them."""
    if backend == "numba" and not compiled.available():
        pytest.skip("numba is not installed")
    kwargs = {"reset_noise_scale": 0.01, "target_direction": 0.3, "terminate_outside_model": False, "backend": backend}
    sizes = (1, 40) if backend == "numba" else (1,)
    for num_envs in sizes:  # (numba compiles here, and could not while numpy is patched)
        warm = RRRobotVectorEnv(num_envs=num_envs, **kwargs)
        warm.reset(seed=5)
        warm.step(np.zeros((num_envs, 2), dtype=np.float32))
    single = gymnasium.make("RRRobot-v0", **kwargs)
    single.reset(seed=5)
    single.step(np.zeros(2, dtype=np.float32))
    with array_transcendentals_one_ulp_off():
        for num_envs in sizes:
            vector = RRRobotVectorEnv(num_envs=num_envs, **kwargs)
            vector.reset(seed=5)
            checked = sorted({0, num_envs - 1})
            singles = {i: gymnasium.make("RRRobot-v0", **kwargs).unwrapped for i in checked}
            for i, single in singles.items():
                single.reset(seed=5 + i)
            for k in range(40):
                phases = np.array([0.0, 1.5]) + 0.1 * np.arange(num_envs)[:, None]
                actions = (0.3 * np.sin(0.4 * k + phases)).astype(np.float32)
                obs, reward, *_ = vector.step(actions)
                for i, single in singles.items():
                    single_obs, single_reward, *_ = single.step(actions[i])
                    np.testing.assert_array_equal(single.state, vector.states[i])
                    if num_envs == 1:
                        np.testing.assert_array_equal(single_obs, obs[i])
                        assert single_reward == reward[i]


def test_seeding_is_deterministic_and_a_seed_list_can_keep_sub_env_generators():
    a, b = RRRobotVectorEnv(num_envs=3), RRRobotVectorEnv(num_envs=3)
    obs_a, _ = a.reset(seed=[5, 6, 7])
    obs_b, _ = b.reset(seed=5)
    np.testing.assert_array_equal(obs_a, obs_b)
    again, _ = a.reset(seed=[5, None, 7])  # sub-env 1 continues its generator
    np.testing.assert_array_equal(again[[0, 2]], obs_a[[0, 2]])
    assert not np.array_equal(again[1], obs_a[1])
    other, _ = b.reset(seed=99)
    assert not np.array_equal(other, obs_b)


def test_a_numerical_blow_up_in_one_sub_env_leaves_the_others_running():
    env = RRRobotVectorEnv(num_envs=3, reset_noise_scale=0.0, target_direction=0.0)
    starts = initial_state(3)
    starts[1, dynamics.BODY_RATE] = (1e30, 0.0, 0.0)  # finite, but the first step overflows
    obs0, _ = env.reset(seed=0, options={"state": starts})
    single = gymnasium.make("RRRobot-v0", reset_noise_scale=0.0, target_direction=0.0)
    single.reset(seed=0)
    action = np.array([[0.05, -0.04]] * 3, dtype=np.float32)
    obs, reward, terminated, truncated, info = env.step(action)
    single_obs, single_reward, *_ = single.step(action[0])

    np.testing.assert_array_equal(terminated, [False, True, False])
    assert info["final_info"]["numerical_failure"][1] and info["final_info"]["_numerical_failure"][1]
    np.testing.assert_array_equal(info["final_obs"][1], obs0[1])  # the last finite observation
    assert reward[1] == 0.0
    assert np.all(np.isfinite(obs))
    for i in (0, 2):  # unaffected by their neighbour's blow-up
        np.testing.assert_allclose(obs[i], single_obs, atol=OBS_TOLERANCE)
        assert reward[i] == pytest.approx(single_reward, abs=STATE_TOLERANCE)


def test_a_robot_whose_observation_overflows_reports_the_state_it_keeps():
    """A finite float64 state whose float32 observation overflows (a contact point at 1e39 m)
    fails; it keeps its last state, and its info (tilt, upright contact point) describes that
    state, not the one the integrator reached."""
    env = RRRobotVectorEnv(num_envs=2, reset_noise_scale=0.0, target_direction=0.0,
                           exclude_current_positions_from_observation=False)  # fmt: skip
    starts = initial_state(2)
    starts[:, dynamics.QUAT] = dynamics.quat_from_paper_angles(np.array([0.1, 0.2, 0.05]))
    starts[:, dynamics.BODY_RATE] = (0.5, -0.3, 0.2)  # the attitude moves within a step
    _, start_info = env.reset(seed=0, options={"state": starts})
    # (reset refuses such a start: the state is put where a run could have taken it)
    env.states[1, 0] = 1e39
    kept = task.reset_info(env.states[1:].copy(), np.zeros(1), env.config)
    _, _, terminated, _, info = env.step(np.zeros((2, 2), dtype=np.float32))
    np.testing.assert_array_equal(terminated, [False, True])
    final = info["final_info"]
    assert final["numerical_failure"][1]
    for key in ("tilt", "x_upright", "y_upright"):
        assert final[key][1] == kept[key][0]
    assert final["x_upright"][1] > 1e38  # (the state kept, not the reset's)
    assert info["tilt"][0] != start_info["tilt"][0]  # (the other robot's attitude did move)


@pytest.mark.parametrize(
    "call, error, message",
    [
        (lambda: RRRobotVectorEnv(num_envs=0), ValueError, "num_envs"),
        (lambda: RRRobotVectorEnv(num_envs=2, max_episode_steps=0), ValueError, "max_episode_steps"),
        (lambda: RRRobotVectorEnv(num_envs=2, render_mode="human"), ValueError, "render_mode"),
        (lambda: RRRobotVectorEnv(num_envs=2, frame_skip=-3), ValueError, "frame_skip"),
        # (made and reset, then the first step failed allocating 80 TiB for its record)
        (lambda: RRRobotVectorEnv(num_envs=2, frame_skip=10**12), ValueError, "frame_skip must be at most 1e"),
        # (each robot's 1e5 substeps fit, the batch's record would not: 36 GB at the first step)
        (lambda: RRRobotVectorEnv(num_envs=4096, frame_skip=10**5), ValueError, "frame_skip x num_envs must be at most 1e"),
        (lambda: RRRobotVectorEnv(num_envs=2, model="moon"), ValueError, "model"),
        (lambda: RRRobotVectorEnv(num_envs=2, color="red"), TypeError, "color"),
        (lambda: RRRobotVectorEnv(num_envs=2).reset(seed=[1, 2, 3]), ValueError, "seed"),
        (lambda: RRRobotVectorEnv(num_envs=2).reset(options={"state": initial_state(3)}), ValueError, "shape"),
        # (numpy's broadcast and conversion errors before)
        (lambda: RRRobotVectorEnv(num_envs=4).reset(options={"target_direction": [0.1, 0.2]}), ValueError,
         r"a number or 4 numbers \(rad\), got shape \(2,\)"),
        (lambda: RRRobotVectorEnv(num_envs=2).reset(options={"target_direction": "abc"}), TypeError, "target_direction"),
        (lambda: RRRobotVectorEnv(num_envs=2).reset(options={"target_direction": [[0.1, 0.2]]}), ValueError,
         r"got shape \(1, 2\)"),
        # (drew starts past the rim, or overflowed inside numpy's uniform)
        (lambda: RRRobotVectorEnv(num_envs=2, reset_noise_scale=3.0), ValueError, "reset_noise_scale must be below pi/2"),
        (lambda: RRRobotVectorEnv(num_envs=2, reset_noise_scale=1e308), ValueError, "reset_noise_scale"),
        # (the phase overflowed, and every episode ended as a numerical failure)
        (lambda: RRRobotVectorEnv(num_envs=2, clock_frequency=1e308), ValueError, r"clock_frequency must be below pi / dt"),
    ],
)
def test_bad_construction_and_reset_arguments_raise_naming_the_problem(call, error, message):
    with pytest.raises(error, match=message):
        call()


@pytest.mark.parametrize("name", ["forward_reward_weight", "ctrl_cost_weight", "healthy_reward"])
def test_a_reward_weight_that_would_overflow_the_reward_is_refused(name):
    # (1e308 times a step's velocity or effort was an inf reward, and inf - inf a NaN, without a word)
    # (and SB3's adapter casts rewards to float32: 1e100 gave inf there)
    from rrrobot_gym.envs import RRRobotSB3VecEnv

    for too_large in (1e308, 1e100):
        with pytest.raises(ValueError, match=f"{name} must be at most 1e\\+30 in size"):
            RRRobotVectorEnv(num_envs=2, **{name: too_large})
    env = RRRobotSB3VecEnv(num_envs=2, **{name: 1e30})  # the largest taken: its float32 rewards stay finite
    env.reset()
    rewards = np.array([env.step(np.ones((2, 2)))[1] for _ in range(6)])  # (past the start-up grace)
    assert rewards.dtype == np.float32 and np.isfinite(rewards).all() and np.abs(rewards).max() > 1e25


@pytest.mark.parametrize(
    "action, message",
    [
        (np.zeros((2,)), "shape"),
        (np.zeros((3, 3)), "shape"),
        (np.array([[0.0, 0.0], [0.0, np.nan], [0.0, 0.0]]), "NaN"),
    ],
)
def test_bad_batched_actions_raise_value_error(action, message):
    env = RRRobotVectorEnv(num_envs=3)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        env.step(action)


def test_rgb_array_renders_one_uint8_frame_per_sub_env():
    env = gymnasium.make_vec("RRRobot-v0", num_envs=2, render_mode="rgb_array", width=200, height=100)
    env.reset(seed=0)
    env.step(np.zeros((2, 2), dtype=np.float32))
    frames = env.render()
    assert len(frames) == 2
    assert all(frame.shape == (100, 200, 3) and frame.dtype == np.uint8 for frame in frames)
    env.close()
    env.close()


def test_vector_env_pickles_with_its_arguments():
    env = RRRobotVectorEnv(num_envs=2, max_episode_steps=7, ctrl_cost_weight=0.5)
    clone = pickle.loads(pickle.dumps(env))
    assert clone.num_envs == 2 and clone.max_episode_steps == 7 and clone.config == env.config


@pytest.mark.slow
def test_async_vector_env_rebuilds_the_env_in_fresh_subprocesses():
    """Spawned workers start a new interpreter, where the env must be rebuilt from scratch.

    Worker 0 gets a pickled env instance (EzPickle records the constructor arguments);
    worker 1 makes one by the module-qualified id, which imports and registers the package.
    """
    from rrrobot_gym.envs import RRRobotEnv

    kwargs = dict(target_direction=0.5 * math.pi, ctrl_cost_weight=0.05)
    instance = gymnasium.wrappers.TimeLimit(RRRobotEnv(**kwargs), max_episode_steps=3)
    async_env = AsyncVectorEnv(
        [lambda: instance, lambda: gymnasium.make("rrrobot_gym:RRRobot-v0", max_episode_steps=3, **kwargs)],
        context="spawn",
        autoreset_mode=AutoresetMode.SAME_STEP,
    )
    try:
        native = RRRobotVectorEnv(num_envs=2, max_episode_steps=3, **kwargs)
        obs_a, _ = async_env.reset(seed=3)
        obs_b, _ = native.reset(seed=3)
        np.testing.assert_allclose(obs_a, obs_b, atol=OBS_TOLERANCE)
        action = np.array([[0.2, -0.7], [1.0, 0.1]], dtype=np.float32)
        for _ in range(4):  # across the time limit at step 3
            obs_a, reward_a, _, trunc_a, _ = async_env.step(action)
            obs_b, reward_b, _, trunc_b, _ = native.step(action)
            np.testing.assert_allclose(reward_a, reward_b, atol=STATE_TOLERANCE)
            np.testing.assert_array_equal(trunc_a, trunc_b)
    finally:
        async_env.close()


def test_the_gait_clock_is_observed_alike_by_the_single_and_the_vector_env():
    kwargs = dict(clock_frequency=8.0, reset_noise_scale=0.0, target_direction=0.0)
    single = gymnasium.make("RRRobot-v0", **kwargs)
    vector = RRRobotVectorEnv(num_envs=2, **kwargs)
    obs, _ = single.reset(seed=0)
    vobs, _ = vector.reset(seed=0)
    assert obs.shape == (17,) and vobs.shape == (2, 17)
    np.testing.assert_allclose(obs[15:17], [0.0, 1.0])
    for k in range(1, 4):
        obs, *_ = single.step(np.zeros(2, dtype=np.float32))
        vobs, *_ = vector.step(np.zeros((2, 2), dtype=np.float32))
        expected = [np.sin(8.0 * 0.05 * k), np.cos(8.0 * 0.05 * k)]
        np.testing.assert_allclose(obs[15:17], expected, atol=1e-6)
        np.testing.assert_allclose(vobs[:, 15:17], [expected, expected], atol=1e-6)


def test_env_signatures_and_the_arguments_table_list_exactly_the_task_config_fields():
    """TaskConfig is the one definition of the env keywords: both envs' signatures (what
    help() and IDEs show) and the docstring's Arguments table are generated from it."""
    import dataclasses
    import inspect

    from rrrobot_gym.envs.rrrobot_v0 import RRRobotEnv
    from rrrobot_gym.envs.task import TaskConfig

    fields = {f.name: f.default for f in dataclasses.fields(TaskConfig)}
    render = {"render_mode": None, "width": 800, "height": 400}
    for env_class, own in ((RRRobotEnv, {}), (RRRobotVectorEnv, {"num_envs": 1, "max_episode_steps": 1000, "workers": 1})):
        parameters = inspect.signature(env_class).parameters
        assert {name: p.default for name, p in parameters.items()} == {**own, **fields, **render}
        assert all(parameters[name].annotation != inspect.Parameter.empty for name in fields)
    arguments = RRRobotEnv.__doc__.split("## Arguments")[1].split("## Version History")[0]
    table = [line.split("|")[1].strip() for line in arguments.splitlines() if line.strip().startswith("| `")]
    assert table == [f"`{name}`" for name in [*fields, *render]]
    assert all(f.metadata["doc"] for f in dataclasses.fields(TaskConfig))


@pytest.mark.parametrize("n", [7, task.FINITE_BY_DOT_MIN + 9])
def test_finite_rows_flags_exactly_the_rows_with_inf_or_nan(n):
    # small batches reduce each row, large ones take a dot product with zeros: the same verdicts
    rng = np.random.default_rng(n)
    states = rng.normal(size=(n, 13)) * 1e3
    observations = rng.normal(size=(n, 17)).astype(np.float32)
    bad = rng.choice(n, size=5, replace=False)
    states[bad[0], 3] = np.nan
    states[bad[1], 12] = -np.inf
    observations[bad[2], 0] = np.inf
    observations[bad[3], 16] = np.nan
    states[bad[4], 0:2] = 1e308  # huge but finite (a sum of the row would overflow): fine
    expected = np.ones(n, dtype=bool)
    expected[bad[:4]] = False
    assert np.array_equal(task.finite_rows(states, observations), expected)


def test_the_reset_noise_bound_keeps_every_start_inside_the_rim():
    """Just below the bound the widest draws still start upright of the rim (a tilt is below pi/2
    while both tilting angles are), so reset never hands out a start the model has left."""
    env = RRRobotVectorEnv(num_envs=2000, reset_noise_scale=0.999 * dynamics.TILT_LIMIT)
    _, info = env.reset(seed=0)
    assert info["tilt"].max() < dynamics.TILT_LIMIT
    assert info["tilt"].max() > 0.9 * dynamics.TILT_LIMIT  # (the draws do reach near the rim)


@pytest.mark.parametrize("vector", [True, False])
def test_a_start_whose_observation_overflows_float32_is_refused_at_reset(vector):
    """A finite float64 state beyond float32's range gave an observation with inf, from reset
    (step already refused to hand one out)."""
    start = initial_state()
    start[dynamics.BODY_RATE.start] = 1e39
    env = RRRobotVectorEnv(num_envs=3) if vector else gymnasium.make("RRRobot-v0").unwrapped
    env.reset(seed=0)
    expected, _ = env.reset()  # the next unseeded start
    env.reset(seed=0)
    kept = (env.states if vector else env.state).copy()
    for seed in (None, 5):
        with pytest.raises(ValueError, match="non-finite observation"):
            env.reset(seed=seed, options={"state": start})
    np.testing.assert_array_equal(env.states if vector else env.state, kept)  # a refused reset changes nothing,
    assert env.np_random_seed == 0
    np.testing.assert_array_equal(env.reset()[0], expected)  # its random generators included (it drew, or reseeded)


def test_numpy_integer_seeds_seed_the_vector_env_as_ints_and_a_bad_one_changes_nothing():
    # (the sub-envs took it, then Gymnasium's own seeding refused it: "Seed must be a python integer")
    env = RRRobotVectorEnv(num_envs=2)
    np.testing.assert_array_equal(env.reset(seed=np.int64(3))[0], env.reset(seed=3)[0])
    assert env.np_random_seed == 3
    np.testing.assert_array_equal(env.reset(seed=np.arange(3, 5))[0], env.reset(seed=[3, 4])[0])
    env.reset(seed=0)
    expected, _ = env.reset()
    env.reset(seed=0)
    for bad in ([5, -1], [5, 2.5], -1):  # (refused part-way: sub-env 0 had been reseeded with 5)
        with pytest.raises(ValueError, match="seed"):
            env.reset(seed=bad)
    np.testing.assert_array_equal(env.reset()[0], expected)


def test_headings_written_by_a_caller_are_checked():
    env = RRRobotVectorEnv(num_envs=3, reset_noise_scale=0.0)
    env.reset(seed=0)
    before = env.states.copy()
    env.episode_target_directions[1] = np.nan  # a row: checked by the next step, before it moves anything
    with pytest.raises(ValueError, match="episode_target_directions must be finite"):
        env.step(np.zeros((3, 2), dtype=np.float32))
    np.testing.assert_array_equal(env.states, before)
    with pytest.raises(TypeError, match="episode_target_directions must be a number or 3 numbers"):
        env.episode_target_directions = "abc"  # the whole attribute: checked at once
    env.episode_target_directions = [0.1, 0.2, 0.3]
    obs, *_ = env.step(np.zeros((3, 2), dtype=np.float32))
    np.testing.assert_allclose(obs[:, 13], np.cos([0.1, 0.2, 0.3]), atol=1e-6)
    with pytest.raises(ValueError, match="max_episode_steps"):  # (a string reached numpy in the next step)
        env.max_episode_steps = "x"


def test_a_heading_past_a_full_turn_is_refused_as_degrees_given_for_radians():
    """target_direction is in radians: 90 (degrees meant) is refused, with the conversion, by
    both envs' keyword, their reset options and the vector env's heading setters."""
    full_turn = 2.0 * np.pi
    for make in (lambda **kw: gymnasium.make("RRRobot-v0", **kw), lambda **kw: RRRobotVectorEnv(num_envs=2, **kw)):
        with pytest.raises(ValueError, match=r"target_direction is in radians: 90.0 .*np.deg2rad\(90.0\)"):
            make(target_direction=90)
        env = make(target_direction=full_turn)  # a full turn is a heading still
        env.reset(seed=0)
        with pytest.raises(ValueError, match=r"options\['target_direction'\] is in radians: -7.0"):
            env.reset(options={"target_direction": -7.0})
    env = RRRobotVectorEnv(num_envs=2)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="episode_target_directions is in radians: 45.0"):
        env.episode_target_directions = [0.5, 45.0]
    env.episode_target_directions[1] = 180.0  # a row written in place: checked by the next step
    with pytest.raises(ValueError, match="episode_target_directions is in radians: 180.0"):
        env.step(np.zeros((2, 2), dtype=np.float32))
