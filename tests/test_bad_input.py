"""Bad input raises an error that names the problem, never a NaN or a numpy traceback."""

import numpy as np
import pytest

from rrrobot_gym.control import Gait, HeldTargets, table2_gait
from rrrobot_gym.params import PDGains, RobotParams
from rrrobot_gym.simulation import SimConfig, advance, check_state, initial_state, simulate


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"mass_tip": -0.05}, "mass_tip"),
        ({"mass_bottom": -1.0}, "mass_bottom"),
        ({"radius": 0.0}, "radius"),
        ({"leg_length": -0.1}, "leg_length"),
        ({"gravity": float("nan")}, "gravity"),
        ({"damping": 0.01}, "damping"),
    ],
)
def test_invalid_robot_parameters_are_named(kwargs, words):
    with pytest.raises(ValueError, match=words):
        RobotParams(**kwargs)


def test_non_numeric_parameter_is_a_type_error():
    with pytest.raises(TypeError, match="radius"):
        RobotParams(radius="big")


@pytest.mark.parametrize("kwargs, words", [({"kp": 0.0}, "kp"), ({"kd": -1.0}, "kd"), ({"kp": float("inf")}, "kp")])
def test_invalid_gains_are_named(kwargs, words):
    with pytest.raises(ValueError, match=words):
        PDGains(**kwargs)


def test_unknown_model_integrator_or_gait_is_named():
    with pytest.raises(ValueError, match="unknown model 'moon'"):
        SimConfig(model="moon")
    with pytest.raises(ValueError, match="unknown integrator 'euler'"):
        SimConfig(integrator="euler")
    with pytest.raises(ValueError, match="unknown gait 4"):
        table2_gait(4)
    with pytest.raises(ValueError, match="timestep"):
        SimConfig(timestep=-0.01)


@pytest.mark.parametrize(
    "state, words",
    [
        (np.zeros(12), "shape"),
        (np.zeros((2, 3, 13)), "shape"),
        (np.full(13, np.nan), "NaN"),
        (np.zeros(13), "quaternion"),
    ],
)
def test_bad_states_are_rejected_with_the_reason(state, words):
    with pytest.raises(ValueError, match=words):
        check_state(state)
    with pytest.raises(ValueError, match=words):
        advance(SimConfig(), state, 0.0, 0.1, table2_gait(1))


def test_bad_leg_targets_and_gaits_are_rejected():
    with pytest.raises(ValueError, match="shape"):
        HeldTargets(np.zeros(3))
    with pytest.raises(ValueError, match="NaN"):
        HeldTargets([np.nan, 0.0])
    with pytest.raises(ValueError, match="phase"):
        Gait(phase=(0.0, 1.0, 2.0))


def test_bad_durations_are_rejected():
    with pytest.raises(ValueError, match="duration"):
        simulate(SimConfig(), table2_gait(1), -1.0)
    with pytest.raises(ValueError, match="sample_dt"):
        simulate(SimConfig(), table2_gait(1), 1.0, sample_dt=0.0)
    with pytest.raises(ValueError, match="duration"):
        advance(SimConfig(), initial_state(), 0.0, float("nan"), table2_gait(1))


def test_travel_summary_refuses_a_trajectory_shorter_than_two_periods():
    from rrrobot_gym.analysis import travel_summary

    times = np.linspace(0.0, 1.0, 101)
    with pytest.raises(ValueError, match="two periods"):
        travel_summary(times, times, times, period=0.785)
