"""The model's validity envelope: the ground force and the legs' clearance."""

import dataclasses

import numpy as np
import pytest

from conftest import random_states
from rrrobot_gym import dynamics, validity
from rrrobot_gym.control import table2_gait
from rrrobot_gym.params import RobotParams
from rrrobot_gym.simulation import SimConfig, StepRecord, _derivative_fn, simulate_reference


def _record(normal, tangential, step):
    """A hand-made StepRecord of an upright body: the force (tangential, 0, normal)."""
    normal, tangential = np.asarray(normal, dtype=float), np.asarray(tangential, dtype=float)
    samples, robots = normal.shape
    force = np.stack([tangential, np.zeros_like(normal), normal], axis=-1)
    return StepRecord(
        times=step * np.arange(samples), step=step, torque=np.zeros((samples, robots, 2)), force=force,
        normal=normal, leg_clearance=np.ones((samples, robots, 2)), leg_rates=np.zeros((samples, robots, 2)),
    )  # fmt: skip


def _centre_of_mass(states, params):
    r = params.radius
    phi = states[:, dynamics.LEG_ANGLES]
    l = params.leg_length
    # the two tips' first moment: (l cos phi_k, -+r, l sin phi_k) summed (the y parts cancel)
    moment = params.mass_tip * np.stack([l * np.cos(phi).sum(1), np.zeros(len(phi)), l * np.sin(phi).sum(1)], axis=1)
    moment[:, 2] -= params.mass_bottom * r
    rot = dynamics.rotation_matrix(states[:, dynamics.QUAT])
    centre = np.stack([states[:, 0], states[:, 1], np.full(len(states), r)], axis=1)
    return centre + np.einsum("nij,nj->ni", rot, moment) / params.total_mass


def test_ground_force_equals_mass_times_centre_of_mass_acceleration_minus_gravity(rng):
    """Newton's second law for the whole robot, with a_com from finite differences of its path."""
    config = SimConfig(model="plane")
    params = config.robot
    gait = table2_gait(2)
    traj = simulate_reference(config, gait, 1.0, state=random_states(rng, 1)[0], sample_dt=1e-4)
    derivative = _derivative_fn(config, gait)
    com = _centre_of_mass(traj.states, params)
    for k in (2000, 5000, 8000):
        accel = (com[k + 1] - 2 * com[k] + com[k - 1]) / 1e-8
        expected_world = params.total_mass * (accel + np.array([0.0, 0.0, params.gravity]))
        force, normal = validity.ground_force(traj.states[k], derivative(traj.times[k], traj.states[k]), params, "plane")
        rot = dynamics.rotation_matrix(traj.states[k, dynamics.QUAT])
        np.testing.assert_allclose(rot @ force[0], expected_world, rtol=0, atol=2e-4 * params.total_mass * params.gravity)
        assert normal[0] == pytest.approx(expected_world[2], abs=2e-4 * params.total_mass * params.gravity)


def test_ground_carries_the_weight_at_rest():
    params = RobotParams()
    state = np.r_[0, 0, 1, 0, 0, 0, np.pi / 2, np.pi / 2, 0, 0, 0, 0, 0]
    derivative = np.array(dynamics.state_derivative(state.tolist(), (0.0, 0.0), params, "plane"))
    force, normal = validity.ground_force(state, derivative, params, "plane")
    assert normal[0] == pytest.approx(params.total_mass * params.gravity, rel=1e-12)
    assert validity.friction_ratio(force, normal)[0] == pytest.approx(0.0, abs=1e-12)


def test_leg_clearance_is_the_height_of_the_leg_tips(rng):
    params = RobotParams()
    states = random_states(rng, 20, max_tilt=1.2)
    clearance = validity.leg_clearance(states, params)
    rot = dynamics.rotation_matrix(states[:, dynamics.QUAT])
    for k, side in ((0, -1.0), (1, 1.0)):
        phi = states[:, 6 + k]
        tip = np.stack([params.leg_length * np.cos(phi), np.full_like(phi, side * params.radius), params.leg_length * np.sin(phi)], 1)
        height = params.radius + np.einsum("nij,nj->ni", rot, tip)[:, 2]
        np.testing.assert_allclose(clearance[:, k], height, atol=1e-14)
    # a leg pointing down on a robot rolled 70 degrees onto that side is in the floor
    state = random_states(rng, 1)[0]
    state[dynamics.QUAT] = dynamics.quat_from_paper_angles([1.2, 0.0, 0.0])
    state[dynamics.LEG_ANGLES] = (-0.5, np.pi / 2)
    low, high = validity.leg_clearance(state, params)[0]
    assert low < 0.0 < high


def test_friction_ratio_is_infinite_without_a_push_from_the_ground():
    force = np.array([[1.0, 0.0, 0.0], [0.3, 0.4, 2.0]])
    normal = np.array([0.0, 2.0])
    ratio = validity.friction_ratio(force, normal)
    assert np.isinf(ratio[0]) and ratio[1] == pytest.approx(0.25)


def test_spells_without_contact_count_what_was_carried_in_and_restart_on_contact():
    """Lift-off bookkeeping over a hand-made record: robot 0 touches down twice, robot 1 never
    does (its spell carried in keeps growing), robot 2 starts on the ground, lifts off, lands."""
    step = 0.01
    normal = np.array(
        [
            [1.0, -1.0, 2.0],
            [-1.0, -1.0, -1.0],
            [-1.0, 0.0, -1.0],  # a normal force of exactly 0 is no contact
            [1.0, -1.0, 1.0],
            [-1.0, -1.0, 1.0],
            [-1.0, -1.0, 1.0],
            [-1.0, -1.0, 1.0],
        ]
    )
    record = _record(normal, np.zeros_like(normal), step)
    carried = np.array([0.02, 0.02, 0.0])
    measures, after = validity.step_measures(record, SimConfig(model="plane"), None, carried)
    # robot 0: spells 0.01, 0.02 (the carried 0.02 ended at the first sample), then 0.03 at the end
    # robot 1: carried 0.02 plus all seven samples; robot 2: one spell of 0.02, landed
    np.testing.assert_allclose(measures["liftoff_time"], [0.03, 0.09, 0.02], rtol=1e-12)
    np.testing.assert_allclose(after, [0.03, 0.09, 0.0], rtol=1e-12, atol=0)
    np.testing.assert_allclose(measures["liftoff_fraction"], [5 / 7, 1.0, 2 / 7], rtol=1e-12)
    # a longer spell carried in than any within the step is the longest
    measures, _ = validity.step_measures(record, SimConfig(model="plane"), None, np.array([0.5, 0.0, 0.5]))
    np.testing.assert_allclose(measures["liftoff_time"], [0.5, 0.07, 0.5], rtol=1e-12)
    # a step in contact throughout ends the spells carried in, and its longest is the carried one
    grounded = dataclasses.replace(record, normal=np.abs(normal) + 0.5)
    measures, after = validity.step_measures(grounded, SimConfig(model="plane"), None, carried)
    np.testing.assert_array_equal(measures["liftoff_time"], carried)
    np.testing.assert_array_equal(after, [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(measures["liftoff_fraction"], [0.0, 0.0, 0.0])


def test_step_measures_summarise_the_record_sample_by_sample():
    """Each summary against its definition, written out on a hand-made record: robots 0 and 1
    push on every sample (the in-contact shortcut), robot 2 loses contact once (the general path)."""
    rng = np.random.default_rng(3)
    samples, robots, step = 6, 3, 0.01
    force = rng.normal(0.0, 1.0, (samples, robots, 3))
    force[..., 2] = rng.uniform(0.5, 3.0, (samples, robots))  # upright body: the normal is F_z
    force[2, 2, 2] = -0.2
    torque, rates = rng.normal(0.0, 0.3, (samples, robots, 2)), rng.normal(0.0, 5.0, (samples, robots, 2))
    clearance = rng.uniform(0.01, 0.05, (samples, robots, 2))
    record = StepRecord(
        times=step * np.arange(samples), step=step, torque=torque, force=force, normal=force[..., 2].copy(),
        leg_clearance=clearance, leg_rates=rates,
    )  # fmt: skip
    measures, _ = validity.step_measures(record, SimConfig(model="plane"), None, np.zeros(robots))
    grip = np.hypot(force[..., 0], force[..., 1]) / force[..., 2]
    np.testing.assert_allclose(measures["friction_ratio"][:2], grip[:, :2].max(axis=0), rtol=1e-12)
    assert measures["friction_ratio"][2] == np.inf  # a pull: no friction holds it
    np.testing.assert_allclose(measures["normal_force"], force[..., 2].min(axis=0), rtol=1e-12)
    np.testing.assert_allclose(measures["torque_rms"], np.sqrt((torque**2).mean(axis=(0, 2))), rtol=1e-12)
    np.testing.assert_allclose(measures["torque_peak"], np.abs(torque).max(axis=(0, 2)), rtol=1e-12)
    np.testing.assert_allclose(measures["leg_rate_peak"], np.abs(rates).max(axis=(0, 2)), rtol=1e-12)
    np.testing.assert_allclose(measures["leg_clearance"], clearance.min(axis=(0, 2)), rtol=1e-12)
    np.testing.assert_allclose(measures["liftoff_fraction"], [0.0, 0.0, 1 / samples], rtol=1e-12)
    # without the pull, all three take the in-contact path and agree with the same definitions
    record = dataclasses.replace(record, normal=np.abs(record.normal), force=np.abs(force))
    measures, _ = validity.step_measures(record, SimConfig(model="plane"), None, np.zeros(robots))
    grip = np.hypot(force[..., 0], force[..., 1]) / np.abs(force[..., 2])
    np.testing.assert_allclose(measures["friction_ratio"], grip.max(axis=0), rtol=1e-12)
    np.testing.assert_array_equal(measures["liftoff_fraction"], np.zeros(robots))


def test_the_trapezoid_quadrature_integrates_the_line_between_samples_and_its_zero_crossings():
    """Worked by hand, step h = 0.01 s, four samples, friction 0.5:
    robot 0 pushes 10 N throughout and needs 7, then 3 N of grip (beyond the floor's 5: +2, then -2):
    the line from +2 to -2 is above 0 for half a step, a triangle of 0.5 h N s (rectangle: 2 h);
    robot 1 pulls between samples 0 and 3 (normal 1, -1, -3, 1 N, no grip needed): off the ground
    from 0.5 h to 2.75 h, a pull of 0.25 h + 2 h + 1.125 h N s (rectangle: 4 h), spell 2.25 h;
    robot 2 lets go after 1.5 h (normal 1, 1, -1, -1) and is still off at the end, the last
    substep held: off 2.5 h, pulling 0.25 h + h + h = 2.25 h N s."""
    h, mu = 0.01, 0.5
    normal = np.array([[10.0, 1.0, 1.0], [10.0, -1.0, 1.0], [10.0, -3.0, -1.0], [10.0, 1.0, -1.0]])
    tangential = np.array([[7.0, 0.0, 0.0], [3.0, 0.0, 0.0], [3.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    config = SimConfig(model="plane")
    mass = config.robot.total_mass
    carried = np.array([0.0, 0.0, 0.003])  # robot 2 was off 3 ms before the step, and landed at its start
    measures, after = validity.step_measures(_record(normal, tangential, h), config, mu, carried, "trapezoid")
    np.testing.assert_allclose(measures["slip_velocity"] * mass, [0.5 * h, 3.375 * h, 2.25 * h], rtol=1e-12)
    np.testing.assert_allclose(measures["liftoff_time"], [0.0, 2.25 * h, 2.5 * h], rtol=1e-12)
    np.testing.assert_allclose(measures["liftoff_fraction"], [0.0, 2.25 / 4, 2.5 / 4], rtol=1e-12)
    np.testing.assert_allclose(after, [0.0, 0.0, 2.5 * h], rtol=1e-12)
    # the rectangle rule on the same samples: each sample for its whole step
    measures, after = validity.step_measures(_record(normal, tangential, h), config, mu, carried)
    np.testing.assert_allclose(measures["slip_velocity"] * mass, [2 * h, 4 * h, 2 * h], rtol=1e-12)
    np.testing.assert_allclose(measures["liftoff_time"], [0.0, 2 * h, 2 * h], rtol=1e-12)
    # a spell carried into a step that starts off the ground runs on until the line crosses 0
    off_at_start = np.array([[-2.0], [2.0], [2.0]])
    measures, after = validity.step_measures(_record(off_at_start, np.zeros((3, 1)), h), config, None, [0.004], "trapezoid")
    np.testing.assert_allclose(measures["liftoff_time"], [0.004 + 0.5 * h], rtol=1e-12)
    np.testing.assert_allclose(after, [0.0], atol=0)
    # a longer spell carried in than any within the step is the longest, as under the rectangle rule
    measures, _ = validity.step_measures(_record(normal, tangential, h), config, mu, [0.0, 0.0, 0.03], "trapezoid")
    np.testing.assert_allclose(measures["liftoff_time"], [0.0, 2.25 * h, 0.03], rtol=1e-12)
    # a NaN sample (the integrator's failure, which the env raises on) is not hidden by either rule
    broken = normal.copy()
    broken[1, 0] = np.nan
    for quadrature in validity.QUADRATURES:
        measures, _ = validity.step_measures(_record(broken, tangential, h), config, mu, None, quadrature)
        assert np.isnan(measures["slip_velocity"][0]) and not np.isnan(measures["slip_velocity"][1:]).any()
    # a step in contact with the grip held throughout: nothing missing, whatever the quadrature
    held = _record(np.full((4, 1), 10.0), np.full((4, 1), 4.9), h)
    measures, _ = validity.step_measures(held, config, mu, None, "trapezoid")
    assert measures["slip_velocity"][0] == 0.0 and measures["liftoff_time"][0] == 0.0


def test_an_unknown_quadrature_is_named():
    record = _record(np.full((2, 1), 10.0), np.zeros((2, 1)), 0.01)
    with pytest.raises(ValueError, match="unknown quadrature 'simpson'"):
        validity.step_measures(record, SimConfig(model="plane"), 1.0, None, "simpson")


def test_the_trapezoid_measures_equal_a_fine_grid_on_the_lines_between_samples():
    """Against brute force: the normal force and the grip beyond the floor's drawn as lines
    between random samples (the last held), evaluated on a grid 4000 times finer than the
    step; the spells are the grid's runs without contact, the missing impulse its sum."""
    rng = np.random.default_rng(7)
    h, mu, fine = 0.01, 0.5, 4000
    config = SimConfig(model="plane")
    for samples in (1, 2, 3, 5, 8) * 4:
        normal = np.round(rng.normal(0.3, 1.0, (samples, 4)), 1)  # (exact zeros among them)
        tangential = np.abs(rng.normal(0.0, 1.0, (samples, 4)))
        carried = rng.uniform(0.0, 0.03, 4)  # (ended at the first sample where it is in contact)
        measures, after = validity.step_measures(_record(normal, tangential, h), config, mu, carried, "trapezoid")
        grid = (np.arange(samples * fine) + 0.5) / fine  # midpoints, in steps
        k = np.minimum(grid.astype(int), samples - 1)
        s = np.where(k < samples - 1, grid - k, 0.0)[:, None]  # the last substep holds its sample
        nxt = np.minimum(k + 1, samples - 1)
        line = lambda v: v[k] * (1 - s) + v[nxt] * s  # noqa: E731
        beyond = tangential - mu * np.maximum(normal, 0.0)
        impulse = (np.maximum(-line(normal), 0.0) + np.maximum(line(beyond), 0.0)).sum(axis=0) * h / fine
        np.testing.assert_allclose(measures["slip_velocity"] * config.robot.total_mass, impulse, rtol=1e-6)
        off = line(normal) <= 0.0
        for robot in range(4):
            # runs of the grid's points without contact, the first one extended by the carried spell
            edges = np.flatnonzero(np.diff(np.r_[0, off[:, robot].astype(int), 0]))
            runs = (edges[1::2] - edges[0::2]) * h / fine
            if off[0, robot]:
                runs[0] += carried[robot]
            longest = max(runs.max(initial=0.0), carried[robot])
            assert measures["liftoff_time"][robot] == pytest.approx(longest, abs=2 * h / fine)
            assert after[robot] == pytest.approx(runs[-1] if off[-1, robot] else 0.0, abs=2 * h / fine)
            assert measures["liftoff_fraction"][robot] == pytest.approx(off[:, robot].mean(), abs=2 / fine / samples)


def test_measures_name_a_bad_floor_or_spell_and_a_nan_force_stays_nan():
    record = StepRecord(times=np.zeros(2), step=0.01, torque=np.zeros((2, 2)), force=np.array([[1.0, 0.0, 2.0]] * 2),
                        normal=np.array([2.0, -1.0]), leg_clearance=np.ones((2, 2)), leg_rates=np.zeros((2, 2)))  # fmt: skip
    config = SimConfig()
    for mu in (-1.0, 0.0, float("nan")):  # (-1 gave a slip of 0.57 m/s)
        with pytest.raises(ValueError, match="friction_coefficient must be positive"):
            validity.step_measures(record, config, mu)
    with pytest.raises(ValueError, match="contact_lost must be spells of seconds >= 0"):  # (gave liftoff_time -5)
        validity.step_measures(record, config, 1.0, contact_lost=[-5.0])
    force = np.array([[1.0, 0.0, 2.0]] * 3)
    np.testing.assert_array_equal(validity.friction_ratio(force, np.array([np.nan, 0.0, 2.0])), [np.nan, np.inf, 0.5])
