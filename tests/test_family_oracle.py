"""The family oracle (``tests/family_oracle.py``) against known answers.

The oracle derives the equations of motion of the legless-robot family (1 to 6 legs,
half-ellipsoid shells) with sympy's KanesMethod. On the paper's robot it must give today's
production kernel; on the rest of the family it must conserve energy, account for the work of the
joint torques and the damping, keep the pivot's vertical angular momentum, roll without slip and
obey Newton's second law with its own ground force.
"""

import math

import numpy as np
import pytest

from family_oracle import (
    default_legs,
    oracle_centre,
    oracle_derivative,
    oracle_energy,
    oracle_ground_force,
    oracle_simulate,
)
from rrrobot_gym import dynamics
from rrrobot_gym.params import RobotParams

SPHERE = (0.12, 0.12, 0.12)
OBLATE = (0.12, 0.12, 0.09)
PROLATE = (0.12, 0.10, 0.15)
MODELS = ("plane", "pivot")

# One worker for all (pyproject runs pytest-xdist with --dist loadgroup): each process derives the
# equations it uses once, seconds each, and two workers would derive the same ones twice.
pytestmark = pytest.mark.xdist_group("family_oracle")


def _robot(shell_axes, num_legs, damping=0.0):
    """The oracle's keywords for a default family member (the paper's masses), without ``model``."""
    return dict(shell_axes=shell_axes, legs=default_legs(num_legs, shell_axes), mass_bottom=0.3, damping=damping)


def _family_states(rng, num_legs, n, max_tilt=0.6, max_rate=1.5):
    """n random states (n, 9 + 2L): tilt <= max_tilt, any heading, legs anywhere in [-0.8, 2.4]."""
    states = np.zeros((n, 9 + 2 * num_legs))
    states[:, :2] = rng.uniform(-1, 1, (n, 2))
    tilt_axis = rng.uniform(-np.pi, np.pi, n)
    tilt = rng.uniform(0.0, max_tilt, n)
    heading = rng.uniform(-np.pi, np.pi, n)
    # heading about body z, then the tilt about a horizontal axis: q = q_tilt (x) q_heading
    tilt_q = np.stack([np.cos(tilt / 2), np.sin(tilt / 2) * np.cos(tilt_axis), np.sin(tilt / 2) * np.sin(tilt_axis), 0 * tilt], -1)
    heading_q = np.stack([np.cos(heading / 2), 0 * heading, 0 * heading, np.sin(heading / 2)], -1)
    states[:, 2:6] = dynamics.quat_multiply(tilt_q, heading_q)
    states[:, 6 : 6 + num_legs] = rng.uniform(-0.8, 2.4, (n, num_legs))
    states[:, 6 + num_legs : 9 + num_legs] = rng.uniform(-max_rate, max_rate, (n, 3))
    states[:, 9 + num_legs :] = rng.uniform(-3 * max_rate, 3 * max_rate, (n, num_legs))
    return states


def _tilted_spinning_start(num_legs):
    """Tilted 0.5 rad, spinning at 3 rad/s about body z and rocking, the legs spread and moving."""
    state = np.zeros(9 + 2 * num_legs)
    axis = np.array([1.0, 0.4, 0.0]) / math.hypot(1.0, 0.4)
    state[2], state[3:6] = math.cos(0.25), math.sin(0.25) * axis
    state[6 : 6 + num_legs] = np.linspace(0.4, 2.6, num_legs)
    state[6 + num_legs : 9 + num_legs] = (0.8, -1.2, 3.0)
    state[9 + num_legs :] = np.linspace(-2.0, 2.5, num_legs)
    return state


def _point_masses(states, legs, shell_axes, mass_bottom):
    """(masses (K,), positions (..., K, 3), velocities relative to the shell (..., K, 3)), body frame,
    of the bottom, the pins and the tips, from the leg dicts alone (not from the oracle)."""
    num_legs = len(legs)
    shape = states.shape[:-1]
    masses = [mass_bottom] + [leg["mass_pin"] for leg in legs] + [leg["mass_tip"] for leg in legs]
    positions = [np.broadcast_to([0.0, 0.0, -shell_axes[2]], shape + (3,))]
    velocities = [np.zeros(shape + (3,))]
    for leg in legs:
        positions.append(np.broadcast_to(np.asarray(leg["hinge"], float), shape + (3,)))
        velocities.append(np.zeros(shape + (3,)))
    for k, leg in enumerate(legs):
        phi, rate = states[..., 6 + k, None], states[..., 9 + num_legs + k, None]
        u, v = np.asarray(leg["u"], float), np.asarray(leg["v"], float)
        positions.append(leg["hinge"] + leg["length"] * (np.cos(phi) * u + np.sin(phi) * v))
        velocities.append(leg["length"] * rate * (-np.sin(phi) * u + np.cos(phi) * v))
    return np.array(masses), np.stack(positions, -2), np.stack(velocities, -2)


def _rotations(states):
    quat = states[..., 2:6] / np.linalg.norm(states[..., 2:6], axis=-1, keepdims=True)
    return dynamics.rotation_matrix(quat)


def _central_difference(values, h, order):
    """First (order 1) or second (order 2) derivative along axis 0 of samples every h s, to fourth
    order, at the interior points values[2:-2]."""
    v = values
    if order == 1:
        return (v[:-4] - 8 * v[1:-3] + 8 * v[3:-1] - v[4:]) / (12 * h)
    return (-v[:-4] + 16 * v[1:-3] - 30 * v[2:-2] + 16 * v[3:-1] - v[4:]) / (12 * h * h)


# ---------------------------------------------------------------------------
# The paper's robot: the oracle is today's kernel


def test_default_legs_place_the_papers_two_legs():
    r = RobotParams().radius
    legs = default_legs(2, (r, r, r))
    assert [leg["hinge"].tolist() for leg in legs] == [[0.0, -r, 0.0], [0.0, r, 0.0]]
    for leg in legs:
        assert leg["u"].tolist() == [1.0, 0.0, 0.0] and leg["v"].tolist() == [0.0, 0.0, 1.0]
        assert (leg["length"], leg["mass_pin"], leg["mass_tip"]) == (0.1, 0.053, 0.057)


def test_default_legs_are_spread_evenly_on_the_rim_with_unit_tangent_swing_planes():
    a, b, c = PROLATE
    for num_legs in range(1, 7):
        legs = default_legs(num_legs, PROLATE)
        assert len(legs) == num_legs
        for k, leg in enumerate(legs):
            theta = math.radians(-90 + k * 360 / num_legs)
            np.testing.assert_allclose(leg["hinge"], [a * math.cos(theta), b * math.sin(theta), 0.0], atol=1e-15)
            hx, hy, _ = leg["hinge"]
            normal = np.array([hx / a**2, hy / b**2, 0.0])  # the rim's outward normal
            assert abs(leg["u"] @ normal) < 1e-15 and abs(np.linalg.norm(leg["u"]) - 1) < 1e-15
            assert leg["u"][0] > 0 or (leg["u"][0] == 0 and leg["u"][1] > 0)


MEMBERS = {
    "paper": RobotParams(),
    "oblate-2": RobotParams(shell_axes=OBLATE),
    "triaxial-3": RobotParams(shell_axes=(0.13, 0.11, 0.10), num_legs=3),
    "sphere-4": RobotParams(num_legs=4),
    "prolate-1": pytest.param(RobotParams(shell_axes=PROLATE, num_legs=1), marks=pytest.mark.slow),
    "oblate-6": pytest.param(RobotParams(shell_axes=OBLATE, num_legs=6, leg_length=0.08), marks=pytest.mark.slow),
}
"""Family members the production kernel is checked on: the paper's robot and one of each kind."""


def _oracle_robot(params: RobotParams) -> dict:
    """The oracle's keywords for ``params`` (any legs), without ``model``."""
    legs = [dict(hinge=leg.hinge, u=leg.zero, v=leg.up, length=length, mass_pin=pin, mass_tip=tip)
            for leg, length, (pin, tip) in zip(params.legs, params.leg_lengths, params.leg_masses)]  # fmt: skip
    return dict(shell_axes=params.shell_axes, legs=legs, mass_bottom=params.mass_bottom, gravity=params.gravity,
                damping=params.damping)


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("params", MEMBERS.values(), ids=MEMBERS)
def test_the_production_kernel_equals_the_symbolic_oracle(params, model, rng):
    """rrrobot_gym.dynamics (written by hand, Kane's equations with the ellipsoid's support point)
    against the sympy derivation (KanesMethod with the rolling constraint eliminated by sympy):
    derivatives, energies and the recorded ground force, at random states and torques."""
    robot, legs = _oracle_robot(params), params.num_legs
    states = _family_states(rng, legs, 200)
    torques = rng.uniform(-0.3, 0.3, (200, legs))
    ours = oracle_derivative(states, torques, model=model, **robot)
    kernel, record = dynamics.state_derivative(list(states.T), list(torques.T), params, model, record=True)
    kernel = np.stack(kernel, -1)
    # each component against the largest of its kind over the states (the rates reach ~1e3 rad/s^2)
    scale = np.max(np.abs(kernel), axis=0)
    assert np.max(np.abs(ours - kernel) / scale) < 1e-10
    # one state at a time (the integrator's path) gives the same numbers
    for state, torque, expected in zip(states[:5], torques[:5], kernel[:5]):
        assert np.max(np.abs(oracle_derivative(state, torque, model=model, **robot) - expected) / scale) < 1e-10
    energy = oracle_energy(states, model=model, **robot)
    assert np.max(np.abs(energy - dynamics.total_energy(states, params, model))) < 1e-10 * np.max(np.abs(energy))
    force = oracle_ground_force(states, kernel, model=model, frame="body", **robot)
    np.testing.assert_allclose(np.stack(record[legs : legs + 3], -1), force, rtol=0, atol=1e-10 * params.total_mass * 9.81)


# ---------------------------------------------------------------------------
# The family: conservation laws and constraints


@pytest.mark.parametrize("model", MODELS)
def test_power_is_the_joint_torques_work_plus_the_damping_loss(model, rng):
    """dE/dt = sum_k tau_k phidot_k + k |Omega|^2 at random states of an ellipsoid with two legs:
    the loads' generalised forces, which free motion does not test."""
    robot = _robot(OBLATE, 2, damping=-0.03)
    states = _family_states(rng, 2, 20)
    torques = rng.uniform(-0.3, 0.3, (20, 2))
    derivative = oracle_derivative(states, torques, model=model, **robot)
    h = 1e-5
    power = (oracle_energy(states + h * derivative, model=model, **robot)
             - oracle_energy(states - h * derivative, model=model, **robot)) / (2 * h)  # fmt: skip
    expected = np.sum(torques * states[:, 11:13], axis=-1) - 0.03 * np.sum(states[:, 8:11] ** 2, axis=-1)
    assert np.max(np.abs(power - expected)) < 1e-7 * np.max(np.abs(expected))


def _free_run(shell_axes, num_legs, model, duration, h):
    robot = _robot(shell_axes, num_legs)
    times = np.arange(0.0, duration + h / 2, h)
    _, states = oracle_simulate(_tilted_spinning_start(num_legs), None, duration, model=model, t_eval=times, **robot)
    return robot, times, states


def _check_free_run(shell_axes, num_legs, model, duration):
    """Energy conserved, the contact kinematics (the material point at the contact still on a
    plane), the pivot's vertical angular momentum; returns the numbers checked."""
    h = 2e-4  # (the free legs swing fast: a finite difference's fourth-order error is 1e-5 at 1e-3 s)
    robot, times, states = _free_run(shell_axes, num_legs, model, duration, h)
    energy = oracle_energy(states, model=model, **robot)
    rot = _rotations(states)
    omega = np.einsum("...ij,...j->...i", rot, states[:, 6 + num_legs : 9 + num_legs])
    assert np.max(np.arccos(np.clip(rot[:, 2, 2], -1, 1))) > 0.3  # it rocks: the checks are not trivial
    drift = np.max(np.abs(energy - energy[0])) / abs(energy[0])
    assert drift < 1e-10

    # The shell's material point at the contact: c + R s, moving at v_c + w x R s = 0 (plane);
    # on the pivot the same holds for the rolling centre its contact kinematics imply.
    centre = oracle_centre(states, model=model, **robot)
    support_world = np.concatenate([states[:, :2], np.zeros((len(states), 1))], -1) - centre
    slip = _central_difference(centre, h, 1) + np.cross(omega, support_world)[2:-2]
    slip_speed = np.max(np.linalg.norm(slip, axis=-1)) / np.max(np.linalg.norm(np.cross(omega, support_world), axis=-1))
    assert slip_speed < 1e-7
    numbers = {"energy_drift": drift, "slip_over_speed": slip_speed}

    if model == "pivot":
        # The joint force acts at the centre and gravity's moment about it is horizontal, so the
        # world-vertical angular momentum about the centre is conserved (computed here, by hand).
        masses, positions, velocities = _point_masses(states, robot["legs"], shell_axes, robot["mass_bottom"])
        body_rate = states[:, None, 6 + num_legs : 9 + num_legs]
        world_pos = np.einsum("tij,tkj->tki", rot, positions)
        world_vel = np.einsum("tij,tkj->tki", rot, np.cross(body_rate, positions) + velocities)
        momentum = np.einsum("k,tki->ti", masses, np.cross(world_pos, world_vel))
        spin = momentum[:, 2]  # (against the whole vector's size: one leg's start barely spins)
        numbers["spin_drift"] = np.max(np.abs(spin - spin[0])) / np.max(np.linalg.norm(momentum, axis=-1))
        assert numbers["spin_drift"] < 1e-10
    return numbers


@pytest.mark.parametrize("model", MODELS)
def test_oblate_shell_conserves_energy_and_rolls_without_slip(model):
    _check_free_run(OBLATE, 2, model, duration=1.0)


FAMILY_RUNS = [(OBLATE, 2), (PROLATE, 2), (OBLATE, 3), (PROLATE, 4)]


@pytest.mark.slow
@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize(("shell_axes", "num_legs"), FAMILY_RUNS, ids=["oblate-2", "prolate-2", "oblate-3", "prolate-4"])
def test_family_conserves_energy_and_rolls_without_slip(shell_axes, num_legs, model):
    _check_free_run(shell_axes, num_legs, model, duration=4.0)


@pytest.mark.slow
@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("num_legs", [1, 5, 6])
def test_every_leg_count_derives_and_conserves_energy(num_legs, model):
    _check_free_run(PROLATE, num_legs, model, duration=0.5)


def test_ground_force_is_the_mass_times_the_centre_of_mass_acceleration_plus_the_weight():
    """Newton's second law for the whole robot on the plane, the centre of mass's acceleration by
    finite differences of its position along a driven run of an oblate shell."""
    model, num_legs, h, duration = "plane", 2, 2e-4, 0.5
    robot = _robot(OBLATE, num_legs, damping=-0.01)

    def torque_targets(t):
        return math.pi / 2 + 0.3 * np.sin(8 * t + np.array([0.0, math.pi])), 2.4 * np.cos(8 * t + np.array([0.0, math.pi]))

    def torque(t, angles, rates):  # a PD servo on a sinusoid gait: every term of the force acts
        target, target_rate = torque_targets(t)
        return 2.0 * (target - angles) + 0.05 * (target_rate - rates)

    start = _tilted_spinning_start(num_legs)
    start[6:8], start[11:13] = torque_targets(0.0)  # (no servo transient at the start)
    times = np.arange(0.0, duration + h / 2, h)
    _, states = oracle_simulate(start, torque, duration, model=model, t_eval=times, **robot)
    torques = np.array([torque(t, s[6:8], s[11:13]) for t, s in zip(times, states)])
    force = oracle_ground_force(states, oracle_derivative(states, torques, model=model, **robot), model=model, **robot)
    masses, positions, _ = _point_masses(states, robot["legs"], OBLATE, robot["mass_bottom"])
    total = masses.sum()
    com = oracle_centre(states, model=model, **robot) + np.einsum(
        "tij,tj->ti", _rotations(states), np.einsum("k,tkj->tj", masses, positions) / total
    )
    expected = total * _central_difference(com, h, 2) + total * 9.81 * np.array([0.0, 0.0, 1.0])
    assert np.max(np.abs(force[2:-2] - expected)) < 1e-6 * total * 9.81
    assert np.ptp(force[:, 2]) > 0.1 * total * 9.81  # the normal force swings: not just the weight
