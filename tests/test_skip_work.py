"""The options that skip work a scene does not need: kinematic legs and a scene-derived step."""

import math

import numpy as np
import pytest

from rrrobot_gym import dynamics
from rrrobot_gym.control import HeldTargets, table2_gait
from rrrobot_gym.params import PDGains
from rrrobot_gym.simulation import (
    SimConfig,
    advance,
    initial_state,
    servo_fastest_rate,
    simulate,
    simulate_reference,
    stable_step_limit,
)


def test_kinematic_legs_are_the_limit_of_an_ever_stiffer_servo():
    """Kinematic legs move the body as the PD servo does as its gains grow (critically damped).

    Comparing the kinematic legs' angles with the gait would hold by construction (the
    integrator writes the path's end into the state); the body's motion does not. From a
    start on the gait (nothing to blend in), the contact path of the servo approaches the
    kinematic one as 1/kp: 3.0, 0.78, 0.20 mm over 2 s of Gait 1 at kp = 2, 8, 32 N m/rad.
    """
    gait = table2_gait(1)
    start = initial_state()
    angles, rates, _ = gait.leg_targets(0.0)
    start[dynamics.LEG_ANGLES], start[dynamics.LEG_RATES] = angles, rates
    kinematic = simulate(SimConfig(legs="kinematic", timestep=0.01), gait, 2.0, state=start, sample_dt=0.05)
    leg_inertia = 5.7e-4  # kg m^2, Ml l^2
    gaps = []
    for kp in (2.0, 8.0, 32.0):
        gains = PDGains(kp=kp, kd=2.0 * math.sqrt(kp * leg_inertia))
        servo = simulate(SimConfig(gains=gains, timestep="auto"), gait, 2.0, state=start, sample_dt=0.05)
        gaps.append(np.max(np.hypot(servo.x - kinematic.x, servo.y - kinematic.y)))
    assert gaps[0] > 1e-3  # m: the default servo lags visibly
    assert gaps[1] < 0.35 * gaps[0] and gaps[2] < 0.35 * gaps[1]
    assert gaps[2] < 3e-4


def test_kinematic_legs_reach_held_targets_at_rest_by_the_end_of_the_control_step():
    state = initial_state(3)
    state[:, dynamics.LEG_RATES] = (2.0, -1.0)
    targets = np.array([[0.5, 1.0], [1.5, 1.5], [2.0, 0.0]])
    out = advance(SimConfig(legs="kinematic", timestep=0.01), state, 0.0, 0.05, HeldTargets(targets))
    np.testing.assert_allclose(out[:, dynamics.LEG_ANGLES], targets, atol=1e-12)
    assert np.all(out[:, dynamics.LEG_RATES] == 0.0)
    assert np.any(np.abs(out[:, dynamics.BODY_RATE]) > 1e-3)  # the body felt the legs move


@pytest.mark.parametrize("model", ["plane", "pivot"])
def test_kinematic_legs_at_one_step_per_control_step_stay_close_to_their_reference(model):
    config = SimConfig(model=model, legs="kinematic", timestep=0.05)
    gait = table2_gait(3)
    fast = simulate(config, gait, 5.0, sample_dt=0.05)
    ref = simulate_reference(config, gait, 5.0, sample_dt=0.05)
    assert np.max(np.hypot(fast.x - ref.x, fast.y - ref.y)) < 1e-4  # m


@pytest.mark.slow
def test_kinematic_legs_are_a_different_model_from_the_servo():
    """The PD servo lags its target; infinitely stiff legs do not: the paths part by millimetres."""
    gait = table2_gait(1)
    kin = simulate_reference(SimConfig(legs="kinematic"), gait, 5.0, sample_dt=0.05)
    servo = simulate_reference(SimConfig(), gait, 5.0, sample_dt=0.05)
    assert 1e-4 < np.hypot(kin.x[-1] - servo.x[-1], kin.y[-1] - servo.y[-1]) < 2e-2


def test_auto_step_shrinks_with_stiffer_servo_and_stays_inside_stability():
    base = SimConfig(timestep="auto")
    stiff = SimConfig(timestep="auto", gains=PDGains(kp=2.0, kd=0.5))
    assert stiff.step < base.step / 5
    for config in (base, stiff, SimConfig(model="pivot", timestep="auto")):
        assert config.step < 0.81 * stable_step_limit(config.model, config.robot, config.gains)
    assert SimConfig(model="pivot", timestep="auto").step > 2 * base.step  # the pivot allows more
    assert servo_fastest_rate("plane", base.robot, base.gains) > servo_fastest_rate("pivot", base.robot, base.gains)


def test_auto_step_on_the_pivot_model_tracks_the_reference():
    config = SimConfig(model="pivot", timestep="auto")
    gait = table2_gait(1)
    fast = simulate(config, gait, 5.0, sample_dt=0.05)
    ref = simulate_reference(config, gait, 5.0, sample_dt=0.05)
    assert np.max(np.hypot(fast.x - ref.x, fast.y - ref.y)) < 2e-4  # m


@pytest.mark.parametrize("legs", ["servo", "kinematic"])
def test_one_robot_on_floats_and_a_batch_on_arrays_give_the_same_motion(legs):
    rng = np.random.default_rng(3)
    states = initial_state(5)
    states[:, dynamics.LEG_ANGLES] += rng.uniform(-1, 1, (5, 2))
    states[:, dynamics.BODY_RATE] = rng.uniform(-1, 1, (5, 3))
    targets = rng.uniform(0, 3, (5, 2))
    config = SimConfig(legs=legs, timestep=1 / 300 if legs == "servo" else 0.025, backend="numpy")
    batch = advance(config, states, 0.0, 0.5, HeldTargets(targets))
    for i in range(5):
        one = advance(config, states[i], 0.0, 0.5, HeldTargets(targets[i]))
        np.testing.assert_allclose(one, batch[i], atol=1e-12)
