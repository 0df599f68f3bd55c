"""Stable-Baselines3 on RRRobot-v0: its checker on the single env, the batched adapter."""

import warnings

import gymnasium
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from stable_baselines3.common.env_checker import check_env  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv  # noqa: E402

import rrrobot_gym  # noqa: E402,F401  (registers RRRobot-v0)
from rrrobot_gym import dynamics  # noqa: E402
from rrrobot_gym.envs import RRRobotSB3VecEnv  # noqa: E402
from rrrobot_gym.simulation import initial_state  # noqa: E402

OBS_TOLERANCE = 1e-6
VALUE_TOLERANCE = 1e-9


def test_sb3_check_env_passes_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(gymnasium.make("RRRobot-v0"))
        check_env(gymnasium.make("RRRobot-v0", exclude_current_positions_from_observation=False, model="pivot"))


def assert_sb3_steps_match(ours, theirs):
    obs_a, rewards_a, dones_a, infos_a = ours
    obs_b, rewards_b, dones_b, infos_b = theirs
    np.testing.assert_allclose(obs_a, obs_b, atol=OBS_TOLERANCE)
    np.testing.assert_allclose(rewards_a, rewards_b, atol=1e-5)  # SB3 keeps rewards in float32
    np.testing.assert_array_equal(dones_a, dones_b)
    for info_a, info_b in zip(infos_a, infos_b):
        assert set(info_a) == set(info_b)
        for key, value in info_b.items():
            if isinstance(value, str):  # (info["termination"])
                assert info_a[key] == value, key
                continue
            atol = OBS_TOLERANCE if key == "terminal_observation" else VALUE_TOLERANCE
            np.testing.assert_allclose(info_a[key], value, atol=atol, err_msg=key)


UNLIMITED_LEGS = {"torque_limit": None, "leg_rate_limit": None, "leg_accel_limit": None}
"""The paper's PD legs: random targets end episodes within a few steps, at different steps."""


@pytest.mark.parametrize("env_kwargs", [{}, UNLIMITED_LEGS], ids=["servo", "unlimited"])
def test_adapter_behaves_like_dummy_vec_env_over_single_envs_across_autoresets(env_kwargs):
    """SB3's own reference: DummyVecEnv over copies of the single env, same seeds. With the paper's
    legs some envs end while others go on (their infos filled when read, the ended ones' at once)."""
    num_envs, limit = 3, 4
    ours = RRRobotSB3VecEnv(num_envs=num_envs, max_episode_steps=limit, **env_kwargs)
    theirs = DummyVecEnv([lambda: gymnasium.make("RRRobot-v0", max_episode_steps=limit, **env_kwargs)] * num_envs)
    ours.seed(8)
    theirs.seed(8)
    np.testing.assert_allclose(ours.reset(), theirs.reset(), atol=OBS_TOLERANCE)
    actions = np.random.default_rng(2).uniform(-1.1, 1.1, (3 * limit, num_envs, 2)).astype(np.float32)
    finished = mixed = 0
    for action in actions:
        step_a, step_b = ours.step(action), theirs.step(action)
        assert_sb3_steps_match(step_a, step_b)
        finished += step_a[2].sum()
        mixed += 0 < step_a[2].sum() < num_envs
        for info_a, info_b in zip(ours.reset_infos, theirs.reset_infos):
            assert info_a == pytest.approx(info_b, abs=VALUE_TOLERANCE)
    assert finished >= 3 * num_envs  # every env hits the time limit 3 times; random legs may also touch down
    assert mixed > 0 or env_kwargs == {}


def test_finished_episodes_carry_terminal_observation_and_say_whether_time_ran_out():
    venv = RRRobotSB3VecEnv(gymnasium.make_vec("RRRobot-v0", num_envs=2, max_episode_steps=2))
    venv.reset()
    _, _, dones, infos = venv.step(np.zeros((2, 2), dtype=np.float32))
    assert not dones.any() and not any(info["TimeLimit.truncated"] for info in infos)
    _, _, dones, infos = venv.step(np.zeros((2, 2), dtype=np.float32))
    assert dones.all()
    assert all(info["TimeLimit.truncated"] for info in infos)  # PPO bootstraps these
    assert all(info["terminal_observation"].shape == (15,) for info in infos)

    tipping = initial_state()
    tipping[dynamics.QUAT] = dynamics.quat_from_paper_angles([0.0, 0.0, 1.45])  # pitched about body y: the rim, not a leg, lands
    tipping[dynamics.BODY_RATE] = (0.0, 4.0, 0.0)
    venv = RRRobotSB3VecEnv(num_envs=2)
    venv.set_options({"state": tipping})
    venv.reset()
    for _ in range(20):
        _, _, dones, infos = venv.step(np.zeros((2, 2), dtype=np.float32))
        if dones.any():
            break
    assert dones.all()
    assert not any(info["TimeLimit.truncated"] for info in infos)  # a real end: no bootstrap
    assert all(info["tilt"] >= dynamics.TILT_LIMIT for info in infos)
    assert all(np.all(np.isfinite(info["terminal_observation"])) for info in infos)


def test_adapter_refuses_a_next_step_vector_env_and_mixed_arguments():
    next_step = gymnasium.make_vec("RRRobot-v0", num_envs=2, vectorization_mode="sync")
    with pytest.raises(ValueError, match="SAME_STEP"):
        RRRobotSB3VecEnv(next_step)
    with pytest.raises(TypeError, match="not both"):
        RRRobotSB3VecEnv(gymnasium.make_vec("RRRobot-v0", num_envs=2), num_envs=2)


def test_get_attr_set_attr_and_env_method_follow_vec_env_semantics_per_index():
    venv = RRRobotSB3VecEnv(num_envs=3, render_mode="rgb_array")
    venv.set_options({"target_direction": [0.1, 0.2, 0.3]})
    venv.reset()
    # per-robot attributes give env i its own row; shared ones their value once per index
    assert venv.get_attr("episode_target_directions") == pytest.approx([0.1, 0.2, 0.3])
    assert venv.get_attr("episode_target_directions", indices=[2, 0]) == pytest.approx([0.3, 0.1])
    states = venv.get_attr("states", indices=1)
    np.testing.assert_array_equal(states[0], venv.vector_env.states[1])
    assert venv.get_attr("dt", indices=[0, 2]) == [pytest.approx(0.05)] * 2
    # a per-index set changes that env only: its commanded heading, seen in the next observation
    venv.set_attr("episode_target_directions", -1.0, indices=[1])
    assert venv.get_attr("episode_target_directions") == pytest.approx([0.1, -1.0, 0.3])
    obs, *_ = venv.step(np.zeros((3, 2), dtype=np.float32))
    np.testing.assert_allclose(obs[:, 13], np.cos([0.1, -1.0, 0.3]), atol=1e-6)
    venv.set_attr("episode_target_directions", 0.5)
    assert venv.get_attr("episode_target_directions") == pytest.approx([0.5] * 3)
    # the batched env's frames, one per requested env
    frames = venv.env_method("render", indices=[2])
    assert len(frames) == 1
    np.testing.assert_array_equal(frames[0], venv.vector_env.render()[2])
    assert len(venv.env_method("render")) == 3
    # a shared attribute or a whole-batch method cannot act on some envs only: a clear error
    venv.set_attr("render_mode", "rgb_array")
    with pytest.raises(ValueError, match="share one batched env"):
        venv.set_attr("render_mode", None, indices=[0])
    with pytest.raises(ValueError, match="share one batched env"):
        venv.env_method("reset", indices=[0, 1])
    with pytest.raises(ValueError, match="simulation state"):
        venv.set_attr("states", np.zeros(13), indices=[0])
    assert len(venv.env_method("reset", seed=0)) == 3
    # a value or an index that is not one is named (NaN headings, out-of-range indices went through)
    with pytest.raises(ValueError, match="episode_target_directions must be finite"):
        venv.set_attr("episode_target_directions", np.nan, indices=[1])
    with pytest.raises(TypeError, match="episode_target_directions must be a real number"):
        venv.set_attr("episode_target_directions", [0.1, 0.2], indices=[0])
    with pytest.raises(ValueError, match="max_episode_steps"):
        venv.set_attr("max_episode_steps", -5)
    with pytest.raises(ValueError, match="num_envs is fixed"):
        venv.set_attr("num_envs", 5)
    for call in (lambda: venv.get_attr("dt", indices=[99]), lambda: venv.env_method("render", indices=[5]),
                 lambda: venv.env_is_wrapped(object, indices=[3])):  # fmt: skip
        with pytest.raises(IndexError, match="not among the 3 envs"):
            call()
    assert venv.get_attr("episode_target_directions", indices=-1) == venv.get_attr("episode_target_directions", indices=2)
    venv.set_attr("max_episode_steps", 9, indices=[-1, -2, -3])  # (every env, counted from the end)
    assert venv.get_attr("max_episode_steps") == [9] * 3


def test_step_infos_filled_on_reading_are_the_batch_info_per_env():
    """A step's infos (filled from the batch's arrays when read) hold what the vector env's info
    says of each env, in its order, and read, copied, pickled or printed as dicts; a key SB3 asks
    of every env (``episode``) that the batch lacks is absent."""
    import copy
    import json
    import pickle

    venv = RRRobotSB3VecEnv(num_envs=3, max_episode_steps=None)
    venv.seed(0)
    venv.reset()
    twin = RRRobotSB3VecEnv(num_envs=3, max_episode_steps=None).vector_env
    twin.reset(seed=0)
    actions = np.array([[0.1, -0.2], [0.0, 0.3], [-0.1, 0.1]], dtype=np.float32)
    _, _, dones, infos = venv.step(actions)
    _, _, _, _, batch = twin.step(actions)
    assert not dones.any()
    keys = [key for key in batch if not key.startswith("_")]
    for i, info in enumerate(infos):
        assert info.get("episode") is None and "episode" not in info and "x_position" in info
        expected = {**{key: batch[key][i].item() for key in keys}, "TimeLimit.truncated": False}
        assert info["tilt"] == expected["tilt"]
        assert list(info.items()) == list(expected.items()) and info == expected and len(info) == len(expected)
        for same in (info.copy(), dict(info), {**info}, copy.deepcopy(info), pickle.loads(pickle.dumps(info))):
            assert list(same.items()) == list(expected.items())
        assert json.loads(json.dumps(info)) == expected and repr(info) == repr(expected)


def test_infos_beside_autoresets_hold_each_envs_own_keys_in_the_batch_order():
    """Randomized robots: a reset's info holds the robot drawn, which the envs going on in the same
    step lack. Each env's info (filled when read, or built at once for an ended env) is the batch's
    row for it, key for key in the batch's order, its masks respected."""
    venv = RRRobotSB3VecEnv(num_envs=4, max_episode_steps=6, **UNLIMITED_LEGS, randomize="default")
    batches, step = [], venv.vector_env.step

    def recording_step(actions):  # (keeps each step's vector info, the adapter's input)
        result = step(actions)
        batches.append(result[4])
        return result

    venv.vector_env.step = recording_step

    def row(batch, i, skip=("final_obs", "final_info")):
        return {key: values[i].item() for key, values in batch.items()
                if not key.startswith("_") and key not in skip and batch["_" + key][i]}

    venv.seed(3)
    venv.reset()
    mixed = 0
    for action in np.random.default_rng(4).uniform(-1.0, 1.0, (20, 4, 2)).astype(np.float32):
        _, _, dones, infos = venv.step(action)
        batch = batches[-1]
        mixed += 0 < dones.sum() < 4
        for i, info in enumerate(infos):
            if dones[i]:
                expected = row(batch["final_info"], i)
                assert list(venv.reset_infos[i].items()) == list(row(batch, i).items())
                assert "randomized_mass_tip" in venv.reset_infos[i]
                np.testing.assert_array_equal(info.pop("terminal_observation"), batch["final_obs"][i])
                info.pop("TimeLimit.truncated")  # (tested above)
            else:
                expected = {**row(batch, i), "TimeLimit.truncated": False}
                assert "randomized_mass_tip" not in info
            assert list(info.items()) == list(expected.items())
    assert mixed > 0
