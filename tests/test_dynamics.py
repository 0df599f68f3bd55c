"""Physics of the equations of motion: conservation laws, the rolling constraint, structure."""

import numpy as np
import pytest
from scipy.integrate import cumulative_simpson, solve_ivp

from conftest import random_states
from rrrobot_gym import dynamics
from rrrobot_gym.control import pd_torque, table2_gait
from rrrobot_gym.params import RobotParams
from rrrobot_gym.simulation import SimConfig, advance, simulate, simulate_reference


def _free_derivative(params, model, torque=(0.0, 0.0)):
    f = dynamics.derivative_function(params, model)
    return lambda t, y: np.array(f(y.tolist(), torque))


@pytest.mark.parametrize("model", ["plane", "pivot"])
def test_energy_is_conserved_without_torque_or_damping(model, rng):
    params = RobotParams(damping=0.0)
    for start in random_states(rng, 3):
        sol = solve_ivp(_free_derivative(params, model), (0, 3), start, method="DOP853", rtol=1e-11, atol=1e-11)
        energy = dynamics.total_energy(sol.y.T, params, model)
        kinetic0 = energy[0] - dynamics.total_energy(
            np.concatenate([start[:8], np.zeros(5)]), params, model
        )
        assert kinetic0 > 1e-3  # the start really moves
        assert np.ptp(energy) / abs(energy[0]) < 1e-9


@pytest.mark.parametrize("params", [RobotParams(), RobotParams(shell_axes=(0.13, 0.11, 0.10), num_legs=3)],
                         ids=["paper", "triaxial-3"])
def test_the_pivots_momentum_rate_is_the_angular_momentum_theorem(params, rng):
    """The pivot's steppers integrate the body's angular momentum about the centre, p = M_w Omega +
    sum c_k phidot_k, with p' = p x Omega + k Omega - g G x n (the kernel's ``momentum``). Against
    the rate of p along the Kane equations' flow, by central differences: the leg torques drive the
    legs but leave p' alone, and the other rows are the rate form's."""
    legs = params.num_legs
    k, layout = dynamics.constants(params, "pivot"), dynamics.leg_layout(params)
    rate_form = dynamics.derivative_function(params, "pivot")
    momentum_form = dynamics.derivative_function(params, "pivot", momentum=True)
    body = slice(6 + legs, 9 + legs)

    def momentum(c):
        c = list(c)
        dynamics.to_momentum(c, 0, 1, k, layout)
        return np.array(c)

    for _ in range(20):
        quat = rng.normal(size=4)
        c = np.concatenate([rng.normal(size=2), quat / np.linalg.norm(quat), rng.uniform(-3.0, 3.0, legs),
                            rng.normal(size=3) * 2.0, rng.normal(size=legs) * 6.0])  # fmt: skip
        torque = tuple(rng.normal(size=legs) * 0.5)
        d = np.array(rate_form(c.tolist(), torque))
        eps = 1e-6
        expected = (momentum(c + eps * d)[body] - momentum(c - eps * d)[body]) / (2.0 * eps)
        p = momentum(c)
        got = np.array(momentum_form(p.tolist(), torque))
        np.testing.assert_allclose(got[body], expected, rtol=1e-7, atol=1e-7 * np.abs(expected).max())
        others = np.r_[0 : 6 + legs, 9 + legs : 9 + 2 * legs]
        np.testing.assert_allclose(got[others], d[others], rtol=1e-12, atol=1e-12)
        back = list(p)
        dynamics.from_momentum(back, 0, 1, k, layout)
        np.testing.assert_allclose(back, c, rtol=1e-14, atol=1e-14)


FAMILY = {
    "oblate-2": RobotParams(damping=0.0, shell_axes=(0.12, 0.12, 0.09)),
    "prolate-2": RobotParams(damping=0.0, shell_axes=(0.11, 0.11, 0.14)),
    "triaxial-3": RobotParams(damping=0.0, shell_axes=(0.13, 0.11, 0.10), num_legs=3),
    "sphere-4": RobotParams(damping=0.0, num_legs=4),
    "oblate-4": RobotParams(damping=0.0, shell_axes=(0.14, 0.12, 0.09), num_legs=4),
}


@pytest.mark.parametrize("model", ["plane", "pivot"])
@pytest.mark.parametrize("params", FAMILY.values(), ids=FAMILY)
def test_the_familys_energy_is_conserved_with_the_legs_held(params, model, rng):
    """Legs held (prescribed at rest: kinematic, no acceleration) and no damping: the shell rocks
    and spins, on an ellipsoid the contact running over it, and the energy stays put."""
    legs = params.num_legs
    f = dynamics.derivative_function(params, model, kinematic=True)
    start = np.zeros(9 + 2 * legs)
    start[2:6] = (np.cos(0.25), np.sin(0.25) * 0.6, np.sin(0.25) * 0.8, 0.0)  # tilted 0.5 rad
    start[6 : 6 + legs] = rng.uniform(0.2, 2.6, legs)  # (held: rates 0)
    start[6 + legs : 9 + legs] = (0.8, -0.5, 3.0)  # rocking and spinning
    sol = solve_ivp(lambda t, y: np.array(f(y.tolist(), (0.0,) * legs)), (0, 3), start, method="DOP853",
                    rtol=1e-11, atol=1e-11)  # fmt: skip
    energy = dynamics.total_energy(sol.y.T, params, model)
    assert np.ptp(np.linalg.norm(sol.y[2:6], axis=0)) < 1e-8  # (a unit quaternion, to the solver's tolerance)
    assert np.ptp(sol.y[6 : 6 + legs], axis=1).max() == 0.0  # the legs really held
    assert np.ptp(dynamics.paper_angles(sol.y[2:6].T)[:, 0]) > 0.1  # it rocked
    assert np.ptp(energy) / abs(energy[0]) < 1e-9


@pytest.mark.parametrize("model", ["plane", "pivot"])
def test_energy_changes_by_servo_work_plus_damping_loss(model):
    """dE/dt = tau . phidot + k |w|^2 along a driven, damped gait."""
    config = SimConfig(model=model)
    gait = table2_gait(3)
    traj = simulate_reference(config, gait, 3.0, sample_dt=1e-4)
    states = traj.states
    torque = np.array(
        [pd_torque(config.gains, s[6:8], s[11:13], gait.leg_targets(t)) for t, s in zip(traj.times, states)]
    )
    power = np.sum(torque * states[:, dynamics.LEG_RATES], axis=1)
    power += config.robot.damping * np.sum(states[:, dynamics.BODY_RATE] ** 2, axis=1)
    # Simpson's rule: the servo's start transient (pole ~ -366 1/s) is too sharp for a trapezoid.
    work = cumulative_simpson(power, x=traj.times, initial=0.0)
    energy_change = traj.energy - traj.energy[0]
    assert np.max(np.abs(energy_change)) > 1e-3
    assert np.max(np.abs(energy_change - work)) < 1e-5 * np.max(np.abs(energy_change))


def _body_points_world(states, body_point, radius):
    """World positions of a body-fixed point along a plane trajectory; centre at (x, y, r)."""
    rot = dynamics.rotation_matrix(states[:, dynamics.QUAT])
    centre = np.stack([states[:, 0], states[:, 1], np.full(len(states), radius)], axis=1)
    return centre + rot @ body_point


def test_material_contact_point_does_not_slip_on_a_plane(rng):
    """The shell's material point at the contact has zero velocity (rolling without slip).

    Differentiates the world position of that body-fixed point numerically along a
    simulated trajectory; a wrong sign in the contact kinematics would give 2 r |w|.
    """
    config = SimConfig(model="plane")
    r = config.robot.radius
    start = random_states(rng, 1)[0]
    traj = simulate_reference(config, table2_gait(1), 1.0, state=start, sample_dt=1e-4)
    for k in (2000, 5000, 8000):
        rot = dynamics.rotation_matrix(traj.states[k, dynamics.QUAT])
        contact_in_body = rot.T @ np.array([0.0, 0.0, -r])
        pos = _body_points_world(traj.states[k - 1 : k + 2], contact_in_body, r)
        velocity = (pos[2] - pos[0]) / (2e-4)
        centre_speed = np.hypot(*np.gradient(traj.x, traj.times)[k : k + 1], *np.gradient(traj.y, traj.times)[k : k + 1])
        assert centre_speed > 1e-3  # the robot is rolling at this instant
        assert np.linalg.norm(velocity) < 1e-5
        # the lowest point of the shell is that contact point, at ground level
        assert abs(pos[1, 2]) < 1e-12


@pytest.mark.parametrize("gait_number", [1, 2, 3])
def test_ground_pushes_up_during_every_gait(gait_number):
    """The normal force m (g + a_com,z) stays positive: the robot never leaves the ground.

    The rolling model assumes contact; a negative normal force would mean a hop.
    """
    config = SimConfig(model="plane")
    p = config.robot
    traj = simulate(config, table2_gait(gait_number), 10.0, sample_dt=0.001)
    rot = dynamics.rotation_matrix(traj.quat)
    phi = traj.leg_angles
    r, l = p.radius, p.leg_length
    moment = np.zeros((len(traj.times), 3))
    moment[:, 2] -= p.mass_bottom * r
    for k, side in ((0, -1.0), (1, 1.0)):
        moment += p.mass_tip * np.stack([l * np.cos(phi[:, k]), np.full_like(phi[:, k], side * r), l * np.sin(phi[:, k])], 1)
    com_z = r + np.einsum("tij,tj->ti", rot, moment)[:, 2] / p.total_mass
    accel_z = np.gradient(np.gradient(com_z, traj.times), traj.times)
    normal = p.total_mass * (p.gravity + accel_z)
    assert normal[10:-10].min() > 0.2 * p.total_mass * p.gravity


@pytest.mark.parametrize("model", ["plane", "pivot"])
def test_mass_matrix_is_symmetric_positive_definite(model, rng):
    mats = dynamics.mass_matrix(random_states(rng, 50), RobotParams(), model)
    assert np.allclose(mats, np.swapaxes(mats, -1, -2), atol=0.0)
    assert np.linalg.eigvalsh(mats).min() > 0.0


@pytest.mark.parametrize("model", ["plane", "pivot"])
def test_mass_matrix_matches_kinetic_energy_of_the_point_masses(model, rng):
    """1/2 u^T M u equals 1/2 sum m |v|^2 with v from finite differences of mass positions:
    on a plane the centre rides above the rolling contact, pivoting it stays put."""
    params = RobotParams(damping=0.0)
    config = SimConfig(model=model, robot=params)
    start = random_states(rng, 1)[0]
    traj = simulate_reference(config, table2_gait(2), 0.2, state=start, sample_dt=1e-4)
    k = 1000
    r, l = params.radius, params.leg_length
    masses = [params.mass_bottom, params.mass_pin, params.mass_pin, params.mass_tip, params.mass_tip]
    kinetic = 0.0
    for j, m in enumerate(masses):
        pos = []
        for s in traj.states[k - 1 : k + 2]:
            phi = s[dynamics.LEG_ANGLES]
            body = [(0, 0, -r), (0, -r, 0), (0, r, 0), (l * np.cos(phi[0]), -r, l * np.sin(phi[0])), (l * np.cos(phi[1]), r, l * np.sin(phi[1]))][j]
            centre = np.array([s[0], s[1], r]) if model == "plane" else np.array([0.0, 0.0, r])
            pos.append(centre + dynamics.rotation_matrix(s[dynamics.QUAT]) @ np.array(body))
        v = (pos[2] - pos[0]) / 2e-4
        kinetic += 0.5 * m * v @ v
    u = traj.states[k, 8:13]
    from_matrix = 0.5 * u @ dynamics.mass_matrix(traj.states[k], params, model) @ u
    assert from_matrix == pytest.approx(kinetic, rel=1e-6)


@pytest.mark.parametrize("stretch", [1e-12, -1e-12, 1e-7])
def test_a_spheres_contact_in_closed_form_is_the_ellipsoids_in_the_limit(stretch, rng):
    """A sphere's contact point -c n, its rate -c ndot and the centre's height c are what the
    ellipsoid's formulas give for a shell stretched from it by ``stretch`` (to that order): the
    closed form the kernel takes for a sphere is the general one's limit, not a formula of its own."""
    c = 0.12
    sphere = dynamics.constants(RobotParams(), "plane")
    stretched = sphere._replace(c2=(c * (1.0 + stretch)) ** 2)  # (the sphere's pole c kept)
    for _ in range(50):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        omega = tuple(rng.normal(size=3) * 5.0)
        exact = dynamics._shell(tuple(n), omega, sphere)
        near = dynamics._shell(tuple(n), omega, stretched)
        np.testing.assert_allclose(exact[0], -c * n, rtol=0, atol=1e-17)
        assert exact[2] == c
        scale = 2.0 * abs(stretch) + 1e-15
        np.testing.assert_allclose(near[0], exact[0], rtol=0, atol=scale * c)
        np.testing.assert_allclose(near[1], exact[1], rtol=0, atol=scale * c * 10.0 * np.linalg.norm(omega))
        assert near[2] == pytest.approx(c, rel=scale)


@pytest.mark.parametrize("model", ["plane", "pivot"])
def test_batch_gives_the_same_trajectories_as_single_runs(model, rng):
    config = SimConfig(model=model)
    starts = random_states(rng, 4)
    gait = table2_gait(3)
    batch = advance(config, starts, 0.0, 1.0, gait)
    for i in range(len(starts)):
        single = advance(config, starts[i], 0.0, 1.0, gait)
        np.testing.assert_allclose(batch[i], single, rtol=0, atol=1e-12)


@pytest.mark.parametrize("model", ["plane", "pivot"])
def test_attitude_round_trips_through_paper_angles(model, rng):
    config = SimConfig(model=model)
    states = advance(config, random_states(rng, 8, max_tilt=0.4), 0.0, 2.0, table2_gait(1))
    theta = dynamics.paper_angles(states[:, dynamics.QUAT])
    rebuilt = dynamics.quat_from_paper_angles(theta)
    np.testing.assert_allclose(
        dynamics.rotation_matrix(rebuilt), dynamics.rotation_matrix(states[:, dynamics.QUAT]), atol=1e-12
    )


@pytest.mark.parametrize("model", ["plane", "pivot"])
def test_the_recorded_force_is_newtons_for_the_accelerations_whatever_drives_them(model, rng):
    # The record a servo evaluation makes (the torques given) equals the one of legs driven with the
    # accelerations that evaluation gave (kinematic: the torques then come out): the ground's force
    # is a function of the state and its accelerations, and the torques are the motion's.
    params = RobotParams()
    servo = dynamics.derivative_function(params, model, record=True)
    kinematic = dynamics.derivative_function(params, model, kinematic=True, record=True)
    for state in random_states(rng, 50, max_tilt=1.2, max_rate=4.0):
        c = state.tolist()
        c[2:6] = (np.array(c[2:6]) * rng.uniform(0.999, 1.001)).tolist()  # RK stages are off unit length
        derivative, record = servo(c, (0.3, -0.2))
        again, kinematic_record = kinematic(c, derivative[11:13])
        np.testing.assert_allclose(again, derivative, rtol=0, atol=1e-11 * max(1.0, np.abs(derivative).max()))
        np.testing.assert_allclose(kinematic_record, record, rtol=0, atol=1e-11)
        assert record[:2] == [0.3, -0.2]