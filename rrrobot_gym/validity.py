"""Where the model stops describing a real robot: contact force and leg clearance.

The RRRobot model (``shared/MODEL.md``) assumes a shell that rolls without slip and never
leaves the ground, and legs that never touch it. The equations of motion hold these
true by construction, so they cannot tell when a motion needs an impossible force: a
controller free to whip the legs can demand a pull from the ground (a hop), more grip
than a floor gives, or push a leg through the floor. These functions measure that.

Kinematics only: the accelerations come from :func:`rrrobot_gym.dynamics.state_derivative`
(the one implementation of the equations of motion). With the speeds of ``dynamics``
(body-frame Omega, leg rates; glossary there), the centre of mass accelerates as

    m a_com = Omega' x (m h n + S) + Omega x (Omega x S)
              + sum_k Ml (e_k phi_k'' + 2 phi_k' Omega x e_k + a_k phi_k'^2),

in body coordinates (S = sum m p, the first moment about the centre), and the ground
pushes on the shell with F = m a_com + m g n. Its normal part is N = F . n.
"""

from __future__ import annotations

import numpy as np

from . import dynamics
from .params import RobotParams, rotation_point_depth


def _leg_vectors(leg_angles, params: RobotParams):
    """Tip positions p_k, e_k = dp/dphi and a_k = d2p/dphi2, body frame, each (N, 2, 3)."""
    r, l = params.radius, params.leg_length
    c, s = np.cos(leg_angles), np.sin(leg_angles)
    side = np.array([-r, r])
    tips = np.stack([l * c, np.broadcast_to(side, c.shape), l * s], axis=-1)
    e = np.stack([-l * s, np.zeros_like(c), l * c], axis=-1)
    a = np.stack([-l * c, np.zeros_like(c), -l * s], axis=-1)
    return tips, e, a


def up_in_body(quat):
    """World up seen from the body, n = R^T z (the third row of R), shape (N, 3)."""
    q = np.asarray(quat, dtype=float)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1)


def leg_clearance(states, params: RobotParams):
    """Height of each leg tip above the ground (m), shape (N, 2); the centre is at height r."""
    states = np.atleast_2d(np.asarray(states, dtype=float))
    tips, _, _ = _leg_vectors(states[:, dynamics.LEG_ANGLES], params)
    n = up_in_body(states[:, dynamics.QUAT])
    return params.radius + np.einsum("nkj,nj->nk", tips, n)


def ground_force(states, derivatives, params: RobotParams, model: str):
    """The ground's force on the shell (N), body coordinates, shape (N, 3), and its normal part (N,).

    ``derivatives`` are the state derivatives (N, 13) at ``states`` (from
    :func:`rrrobot_gym.dynamics.state_derivative` with the torques that acted). For the
    pivot model this is the force of the spherical joint instead.
    """
    states = np.atleast_2d(np.asarray(states, dtype=float))
    derivatives = np.atleast_2d(np.asarray(derivatives, dtype=float))
    h = rotation_point_depth(model, params)
    omega = states[:, dynamics.BODY_RATE]
    omega_dot = derivatives[:, dynamics.BODY_RATE]
    rates = states[:, dynamics.LEG_RATES]
    accels = derivatives[:, dynamics.LEG_RATES]
    tips, e, a = _leg_vectors(states[:, dynamics.LEG_ANGLES], params)
    n = up_in_body(states[:, dynamics.QUAT])
    first_moment = params.mass_tip * tips.sum(axis=1)
    first_moment[:, 2] -= params.mass_bottom * params.radius
    mass_accel = np.cross(omega_dot, params.total_mass * h * n + first_moment)
    mass_accel += np.cross(omega, np.cross(omega, first_moment))
    leg_accel = e * accels[..., None] + 2 * rates[..., None] * np.cross(omega[:, None, :], e) + a * rates[..., None] ** 2
    mass_accel += params.mass_tip * leg_accel.sum(axis=1)
    force = mass_accel + params.total_mass * params.gravity * n
    return force, np.einsum("nj,nj->n", force, n)


def friction_ratio(force, normal):
    """|tangential| / normal force: the friction coefficient the no-slip contact needs (inf if N <= 0)."""
    n_hat_part = np.linalg.norm(force, axis=-1) ** 2 - normal**2
    tangential = np.sqrt(np.maximum(n_hat_part, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(normal > 0, tangential / np.where(normal > 0, normal, 1.0), np.inf)


def envelope(states, leg_targets, config):
    """The model-validity measures of robots under held leg targets, each (N,).

    ``config`` is a :class:`rrrobot_gym.simulation.SimConfig`; ``leg_targets`` (N, 2) rad are
    the servo targets acting (target rate 0). Returns ``normal_force`` (N, the ground's push
    on the shell; for the pivot model the joint's), ``friction_ratio`` (the friction
    coefficient the no-slip contact needs), ``tangential_force`` (N) and ``leg_clearance``
    (m, the lower leg tip's height above the ground).
    """
    from .control import pd_torque

    states = np.atleast_2d(np.asarray(states, dtype=float))
    leg_targets = np.atleast_2d(np.asarray(leg_targets, dtype=float))
    params = config.robot
    comps = [states[:, i] for i in range(dynamics.STATE_SIZE)]
    zero = np.zeros(len(states))
    torque = pd_torque(
        config.gains,
        (comps[6], comps[7]),
        (comps[11], comps[12]),
        ((leg_targets[:, 0], leg_targets[:, 1]), (zero, zero), (zero, zero)),
    )
    derivative = np.stack(dynamics.state_derivative(comps, torque, params, config.depth), axis=-1)
    force, normal = ground_force(states, derivative, params, config.model)
    return {
        "normal_force": normal,
        "tangential_force": np.sqrt(np.maximum(np.einsum("nj,nj->n", force, force) - normal**2, 0.0)),
        "friction_ratio": friction_ratio(force, normal),
        "leg_clearance": leg_clearance(states, params).min(axis=1),
    }


def unprovided_force(normal, tangential, friction_coefficient):
    """N: the part of the needed ground force a floor cannot give (0 while the model holds).

    A pull (normal < 0: the shell would hop) and grip beyond ``friction_coefficient`` times
    the push (it would slip). None: unlimited grip (the paper's no-slip contact).
    """
    pull = np.maximum(-normal, 0.0)
    if friction_coefficient is None:
        return pull
    return pull + np.maximum(tangential - friction_coefficient * np.maximum(normal, 0.0), 0.0)
