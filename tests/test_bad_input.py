"""Bad input raises an error that names the problem, never a NaN or a numpy traceback."""

import numpy as np
import pytest

from rrrobot_gym.control import Gait, HeldTargets, RampTargets, table2_gait
from rrrobot_gym.params import PDGains, RobotParams
from rrrobot_gym.simulation import SimConfig, advance, check_state, initial_state, simulate, simulate_reference


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


@pytest.mark.parametrize("value", ["big", "0.12", True, np.bool_(False), np.array(True), np.array("0.12"),
                                   np.complex128(0.12 + 1j)])
def test_non_numeric_parameter_is_a_type_error(value):
    # (float() takes a string of digits and a bool: neither is a radius, a gain or a weight)
    with pytest.raises(TypeError, match="radius must be a real number"):
        RobotParams(radius=value)
    with pytest.raises(TypeError, match="kp must be a real number"):
        PDGains(kp=value)
    with pytest.raises(TypeError, match="torque_limit must be a real number"):
        SimConfig(torque_limit=value)


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
        HeldTargets(np.zeros(7))  # (1 to 6 legs)
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


# --- What an exploratory pass over the public API found crashing deep inside numpy, hanging,
# or returning a wrong shape without a word; each now names its problem.


@pytest.mark.parametrize("backend", ["numpy", "auto"])
def test_leg_targets_for_another_number_of_robots_are_refused_on_every_path(backend):
    """The numpy path integrated a (13,) state under two robots' targets into a (13, 2) array."""
    config = SimConfig(backend=backend)
    with pytest.raises(ValueError, match=r"one robot's state takes leg targets that are numbers"):
        advance(config, initial_state(), 0.0, 0.05, HeldTargets(np.ones((2, 2))))
    for robots in (3, 30):  # robot by robot, and batched
        with pytest.raises(ValueError, match=f"the leg targets are for 2 robots, the state has {robots}"):
            advance(config, initial_state(robots), 0.0, 0.05, HeldTargets(np.ones((2, 2))))
    with pytest.raises(TypeError, match="leg_targets"):
        advance(config, initial_state(), 0.0, 0.05, None)

    class Grid:  # a source whose values are (N, 2): not one entry a robot
        def leg_targets(self, t):
            return (np.ones((3, 2)), 0.0), (0.0, 0.0), (0.0, 0.0)

    with pytest.raises(ValueError, match=r"numbers or \(N,\) arrays, one entry a robot, got shape \(3, 2\)"):
        advance(config, initial_state(3), 0.0, 0.05, Grid())
    with pytest.raises(ValueError, match="the leg targets are for 2 robots"):
        simulate(config, HeldTargets(np.ones((2, 2))), 0.1, state=initial_state(3))


@pytest.mark.parametrize("backend", ["numpy", "auto"])
def test_one_robots_targets_in_a_batch_of_one_row_drive_every_robot(backend):
    """(1, 2) targets are one robot's: the same run as (2,) on one state and on a batch (the numpy
    path returned (13, 1) for the first and raised IndexError for the second)."""
    config = SimConfig(backend=backend)
    angles = np.array([[1.2, 1.9]])
    for targets in (HeldTargets(angles), RampTargets(angles - 0.3, angles, 0.0, 0.05)):
        one = advance(config, initial_state(), 0.0, 0.05, targets)
        assert one.shape == (13,)
        if isinstance(targets, HeldTargets):
            flat = HeldTargets(angles[0])
        else:
            flat = RampTargets(angles[0] - 0.3, angles[0], 0.0, 0.05)
        np.testing.assert_array_equal(one, advance(config, initial_state(), 0.0, 0.05, flat))
        np.testing.assert_array_equal(advance(config, initial_state(3), 0.0, 0.05, targets), np.tile(one, (3, 1)))


def test_times_and_tolerances_are_numbers_checked_by_name():
    config = SimConfig(backend="numpy")
    with pytest.raises(ValueError, match="t0 must be finite"):  # (was a NumericalFailure, "try a smaller timestep")
        advance(config, initial_state(), float("nan"), 0.05, table2_gait(1))
    with pytest.raises(TypeError, match="duration must be a real number"):
        advance(config, initial_state(), 0.0, None, table2_gait(1))
    with pytest.raises(ValueError, match="rtol must be finite"):  # (scipy ran on, never finishing)
        simulate_reference(config, table2_gait(1), 0.05, rtol=float("nan"))
    with pytest.raises(ValueError, match="rtol must be positive"):
        simulate_reference(config, table2_gait(1), 0.05, rtol=0.0, atol=0.0)
    with pytest.raises(ValueError, match=r"is 1e\+302 samples, more than 1e\+08"):  # (numpy's "maximum allowed size")
        simulate(config, table2_gait(1), 1e300)
    with pytest.raises(ValueError, match=r"is inf samples"):  # (an OverflowError from round())
        simulate(config, table2_gait(1), 1e300, sample_dt=1e-300)


def test_a_servo_or_a_body_beyond_floating_point_is_named_not_an_overflow_inside():
    """kp = 1e308 raised OverflowError ("complex exponentiation"), a radius of 1e300 m numpy's
    LinAlgError ("Eigenvalues did not converge"), with nothing naming the parameter."""
    for timestep in (1 / 300, "auto"):
        for gains in (PDGains(kp=1e308), PDGains(kd=1e200)):
            with pytest.raises(ValueError, match="fastest pole overflows floating point"):
                SimConfig(gains=gains, timestep=timestep)
    with pytest.raises(ValueError, match="beyond the stability limit"):  # (large but finite: the step is named)
        SimConfig(gains=PDGains(kp=1e300))
    for robot in (RobotParams(radius=1e300), RobotParams(leg_length=1e200)):
        with pytest.raises(ValueError, match="mass matrix .* overflows"):
            SimConfig(robot=robot)


def test_start_helpers_name_their_arguments():
    with pytest.raises(ValueError, match="leg_angles must be finite"):  # (returned a NaN state)
        initial_state(leg_angles=(np.nan, 0.0))
    with pytest.raises(ValueError, match="leg_angles must be one number a leg"):
        initial_state(leg_angles=np.ones(7))
    with pytest.raises(ValueError, match="unknown gait"):  # (was "unhashable type")
        table2_gait([1])
    batch = initial_state(2)
    batch[1, 2] = 3.0
    with pytest.raises(ValueError, match="got norm 3"):  # the bad one, not the batch's least
        check_state(batch)


def test_the_period_analysis_names_what_it_cannot_use():
    from rrrobot_gym import analysis

    with pytest.raises(ValueError, match="need gravity > 0"):  # (ZeroDivisionError)
        analysis.table1(RobotParams(gravity=0.0))
    with pytest.raises(TypeError, match="must be a rrrobot_gym.params.RobotParams"):  # (AttributeError: __dict__)
        analysis.table1({"radius": 0.1})
    with pytest.raises(ValueError, match="eps must be a small positive rotation"):  # (LinAlgError)
        analysis.small_oscillation_periods("plane", eps=0.0)
    with pytest.raises(ValueError, match="two or more samples"):  # ("cannot convert float NaN to integer")
        analysis.period_average([], [], 1.0)
    with pytest.raises(ValueError, match="period must be a positive number"):
        analysis.period_average([0.0, 1.0, 2.0], [0.0, 1.0, 2.0], float("nan"))


@pytest.mark.parametrize("backend", ["numpy", "auto"])
def test_a_blow_up_from_a_singular_mass_matrix_says_so(backend):
    """No bottom or pin mass: the plane's mass matrix is regular in most configurations (so
    SimConfig takes it) but singular upright, where the run starts; it blew up as 'no single cause'."""
    from rrrobot_gym.simulation import NumericalFailure

    config = SimConfig(robot=RobotParams(mass_bottom=0.0, mass_pin=0.0), timestep="auto", backend=backend)
    with pytest.raises(NumericalFailure, match="mass matrix is singular at the start state"):
        simulate(config, table2_gait(1), 0.1)


def test_a_blow_up_from_a_non_finite_start_is_still_a_numerical_failure():
    """The singular-matrix diagnosis must not fail itself (eigvalsh on a NaN matrix) and replace
    the NumericalFailure with numpy's LinAlgError."""
    from rrrobot_gym.simulation import NumericalFailure

    state = initial_state()
    state[3] = np.nan
    for backend in ("numpy", "auto"):
        with pytest.raises(NumericalFailure):
            advance(SimConfig(backend=backend), state, 0.0, 0.05, HeldTargets((1.5, 1.5)), check=False)


@pytest.mark.parametrize("quat", [[0.0, 0.0, 0.0, 0.0], [1e200, 0.0, 0.0, 0.0]])
def test_a_blow_up_from_a_start_with_no_attitude_is_a_numerical_failure_that_says_so(quat):
    # (advance(check=False) takes the state as given; the diagnosis reads its tilt and mass matrix,
    # whose helpers refuse such a quaternion, and must name it instead of raising their ValueError)
    from rrrobot_gym.simulation import NumericalFailure

    state = initial_state()
    state[2:6] = quat
    for backend in ("numpy", "auto"):
        for start in (state, np.stack([initial_state(), state])):
            with pytest.raises(NumericalFailure, match=r"quaternion \(entries 2:6\) is no rotation"):
                advance(SimConfig(backend=backend), start, 0.0, 0.05, HeldTargets((1.5, 1.5)), check=False)


_UPRIGHT = initial_state()


@pytest.mark.parametrize(
    "call, error, words",
    [
        # (each of these returned a number for the wrong input, or failed inside numpy)
        (lambda d: d.tilt(_UPRIGHT[:12]), ValueError, r"state must have 9 \+ 2L entries on its last axis .*got 12"),
        (lambda d: d.paper_angles(np.ones(5)), ValueError, r"quat must have shape \(\.\.\., 4\), got shape \(5,\)"),
        (lambda d: d.rotation_matrix([1.0, 0.0, 0.0]), ValueError, r"quat must have shape \(\.\.\., 4\)"),
        (lambda d: d.rotation_matrix("wxyz"), TypeError, "quat must be numbers"),
        (lambda d: d.rotation_matrix(np.zeros(4)), ValueError, "quat must be unit quaternions .* norm 0"),
        (lambda d: d.rotation_matrix([1e200, 0.0, 0.0, 0.0]), ValueError, "quat must be unit quaternions .* norm inf"),
        (lambda d: d.world_body_rate(_UPRIGHT[:2]), ValueError, r"state must have 9 \+ 2L entries"),
        (lambda d: d.world_body_rate(np.r_[_UPRIGHT[:2], 3.0, _UPRIGHT[3:]]), ValueError, "entries 2:6 must be unit"),
        (lambda d: d.mass_matrix(np.ones((3, 12)), RobotParams(), "plane"), ValueError, r"got shape \(3, 12\)"),
        (lambda d: d.total_energy(_UPRIGHT[None, :12], RobotParams(), "pivot"), ValueError, r"\(\.\.\., 13\)"),
        (lambda d: d.quat_from_paper_angles([0.1, 0.2]), ValueError, r"theta \(the paper's angles\) must have shape"),
        (lambda d: d.quat_multiply(np.ones(3), np.ones(4)), ValueError, r"p must have shape \(\.\.\., 4\)"),
        (lambda d: d.mirror_states(np.ones(4)), ValueError, r"states must have shape \(\.\.\., 13\)"),
    ],
)
def test_the_dynamics_array_helpers_name_a_wrong_shape_or_a_quaternion_that_is_none(call, error, words):
    from rrrobot_gym import dynamics

    with pytest.raises(error, match=words):
        call(dynamics)


def test_the_dynamics_array_helpers_still_pass_nan_through():
    # (the blow-up diagnosis reads a failed run's attitude: NaN in, NaN out, as arithmetic does)
    from rrrobot_gym import dynamics

    assert np.isnan(dynamics.tilt(np.full(13, np.nan)))
    assert np.isnan(dynamics.rotation_matrix(np.full(4, np.nan))).all()
    np.testing.assert_allclose(dynamics.tilt(np.stack([_UPRIGHT, _UPRIGHT])), 0.0)
