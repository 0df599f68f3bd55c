"""Numerical stability under abuse (short versions; long ones: ``python -m benchmarks.stress``).

Hundreds of robots under random and bang-bang leg targets, extreme
gains and masses, starts near the tilt limit and spinning starts. What must hold:
nothing NaN, unit quaternions stay unit, energy changes only by the work the servo
and the damping do, and where the model cannot go on (a step beyond the servo's
stability limit, a robot spinning too fast for the step, a singular robot) it says
so by name instead of returning garbage.
"""


import numpy as np
import pytest

from rrrobot_gym import dynamics
from rrrobot_gym.control import HeldTargets
from rrrobot_gym.params import PDGains, RobotParams
from rrrobot_gym.simulation import NumericalFailure, SimConfig, advance, initial_state, stable_step_limit
from stress_scenes import bang_bang_targets, random_targets, run_scene, start_states

N_ROBOTS = 500
N_CONTROL_STEPS = 50


@pytest.fixture
def rng():
    return np.random.default_rng(5)


@pytest.mark.parametrize("model", ["plane", "pivot"])
@pytest.mark.parametrize("policy", ["random", "bang-bang"])
@pytest.mark.parametrize("legs", ["servo", "kinematic"])
@pytest.mark.slow
def test_extreme_leg_targets_keep_states_finite_and_quaternions_unit(model, policy, legs, rng):
    config = SimConfig(model=model, legs=legs, timestep="auto" if legs == "kinematic" else 1.0 / 300.0)
    targets = random_targets(rng, N_ROBOTS) if policy == "random" else bang_bang_targets(N_ROBOTS)
    result = run_scene(config, start_states(rng, N_ROBOTS), targets, N_CONTROL_STEPS)
    assert result.finite
    assert result.max_quat_norm_error < 1e-12
    # (Kinematic legs end each control step at their targets by construction, so that is not
    # checked here; tests/test_skip_work.py checks the body's motion under them.)
    if legs == "servo":
        assert result.max_leg_rate > 10.0  # the targets really drive the legs hard


@pytest.mark.parametrize("model", ["plane", "pivot"])
@pytest.mark.parametrize("policy", ["random", "bang-bang"])
@pytest.mark.slow
def test_energy_changes_only_by_the_work_of_servo_and_damping(model, policy, rng):
    """E(t) - E(0) = W(t), W the integral of tau . phidot + k |Omega|^2, under violent targets.

    The books are kept with steps 10x finer than the default: the work needs the
    servo's power resolved (see ``run_scene``).
    """
    n = 50
    targets = random_targets(rng, n) if policy == "random" else bang_bang_targets(n)
    result = run_scene(SimConfig(model=model), start_states(rng, n), targets, 10, energy_refinement=10)
    assert result.finite
    assert result.energy_balance_error < 1e-3
    assert result.max_energy_gain_over_work < 1e-3  # J: no energy from nowhere


@pytest.mark.parametrize(
    "change",
    [{"gains": PDGains(kp=200.0, kd=5.0)}, {"robot": RobotParams(mass_tip=1e-4)}],
    ids=["stiff-gains", "tiny-leg-mass"],
)
def test_stiff_servo_refuses_the_default_step_and_runs_with_auto(change, rng):
    with pytest.raises(ValueError, match="beyond the stability limit"):
        SimConfig(**change)
    config = SimConfig(timestep="auto", **change)
    assert config.step < stable_step_limit(config.model, config.robot, config.gains)
    result = run_scene(config, start_states(rng, 20), random_targets(rng, 20), 2)
    assert result.finite and result.max_quat_norm_error < 1e-12


@pytest.mark.parametrize(
    "change",
    [{"gains": PDGains(kp=1e-3, kd=1e-5)}, {"robot": RobotParams(mass_tip=1.0, mass_bottom=1.0)}],
    ids=["soft-gains", "heavy-masses"],
)
def test_soft_gains_and_heavy_masses_run_at_the_default_step(change, rng):
    result = run_scene(SimConfig(**change), start_states(rng, N_ROBOTS), random_targets(rng, N_ROBOTS), 20)
    assert result.finite and result.max_quat_norm_error < 1e-12


@pytest.mark.parametrize("model", ["plane", "pivot"])
def test_starts_near_the_tilt_limit_report_crossings_cleanly(model, rng):
    state = start_states(rng, N_ROBOTS, max_tilt=0.0)
    tilt = np.radians(rng.uniform(80.0, 89.9, N_ROBOTS))
    state[:, 2], state[:, 3], state[:, 4], state[:, 5] = np.cos(tilt / 2), np.sin(tilt / 2), 0.0, 0.0
    result = run_scene(SimConfig(model=model), state, random_targets(rng, N_ROBOTS), 10)
    assert result.finite
    assert 0 < result.crossed_tilt_limit <= N_ROBOTS  # some fall past the rim: reported, not NaN
    assert np.all(np.isfinite(dynamics.tilt(result.final_state)))


@pytest.mark.parametrize("model", ["plane", "pivot"])
def test_spinning_start_stays_finite(model, rng):
    state = start_states(rng, N_ROBOTS)
    state[:, 10] = rng.uniform(-50.0, 50.0, N_ROBOTS)  # rad/s about the body's own axis
    result = run_scene(SimConfig(model=model), state, random_targets(rng, N_ROBOTS), 10)
    assert result.finite and result.max_quat_norm_error < 1e-12


def test_spinning_too_fast_for_the_step_raises_numerical_failure_naming_the_cause():
    state = initial_state(4)
    state[:, 10] = 2000.0  # rad/s: h |Omega| = 6.7 at 1/300 s, past RK4's stability
    with pytest.raises(NumericalFailure, match="turns too fast for the step"):
        advance(SimConfig(), state, 0.0, 0.5, HeldTargets([1.0, 1.0]))
    with pytest.raises(NumericalFailure, match="turns too fast for the step"):
        advance(SimConfig(), state[0], 0.0, 0.5, HeldTargets([1.0, 1.0]))


def test_a_step_beyond_the_servo_stability_limit_is_refused_by_name():
    limit = stable_step_limit("plane", RobotParams(), PDGains())
    assert 1.0 / 300.0 < limit < 1.0 / 100.0
    with pytest.raises(ValueError, match=r"beyond the stability limit .* Use a smaller timestep"):
        SimConfig(timestep=1.05 * limit)
    SimConfig(timestep=0.95 * limit)


def test_a_robot_with_a_singular_mass_matrix_is_refused_by_name():
    with pytest.raises(ValueError, match="singular"):
        SimConfig(model="pivot", robot=RobotParams(mass_bottom=0.0), timestep="auto")
