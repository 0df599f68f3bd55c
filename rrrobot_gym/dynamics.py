"""Equations of motion of the RRRobot: the one implementation in this project.

Everything else (integrators, the Gymnasium environments, the benchmarks, the
command line) calls :func:`state_derivative` or the helpers below it. This
module imports no Gymnasium: physics is a pure function of (state, control, params).

Glossary
--------
Frames
    world: z up, the ground is the plane z = 0.
    body: origin at the centre of the sphere, z up when the robot rests upright;
        the legs are pinned on the rim at the two ends of the body Y axis.
Masses (body-frame positions)
    Mb  bottom of the shell, (0, 0, -r)
    Ms  leg pins, (0, -r, 0) for leg 1 and (0, +r, 0) for leg 2
    Ml  leg tips, p_k = (l cos phi_k, -+r, l sin phi_k)
Coordinates (13 numbers a robot, layout in :data:`STATE_FIELDS`)
    x, y        m    contact point on the ground (directly below the centre)
    quat        -    unit quaternion (w, x, y, z), body to world: v_world = R(quat) v_body
    leg_angles  rad  phi_1, phi_2: 0 is horizontal along +X, pi/2 straight up
    body_rate   rad/s  Omega, the body's angular velocity in BODY coordinates
    leg_rates   rad/s  phi_1dot, phi_2dot
Speeds
    u = (Omega, phi_1dot, phi_2dot). The world-frame angular velocity is w = R Omega.
Derived symbols
    n    world up (0, 0, 1) in body coordinates, n = R^T z = third row of R
    h    depth below the centre of the point the body turns about (``rotation_point_depth``):
         h = r on a plane (rolling contact), h = 0 for the Pivoting Dynamics model
    s_i  p_i + h n, a mass's position relative to that point
    e_k  d p_k / d phi_k = (-l sin phi_k, 0, l cos phi_k)
    a_k  d^2 p_k / d phi_k^2 = (-l cos phi_k, 0, -l sin phi_k)
Constraints
    Plane: the body's material point at the contact has zero velocity, so the
    centre moves as v_c = w x (h z). The speeds above are independent, so this
    holds exactly by construction (no multipliers, no drift at velocity level).
    Both models move the contact point by the paper's eq. (2)/(4):
    xdot = r w_y, ydot = -r w_x.

Derivation (Kane's equations with the speeds u)
    A mass moves with (body coordinates) v_i = Omega x s_i + e_i phidot_k, so its
    partial velocities are -[s_i]x (for Omega) and e_k (for phidot_k). The
    acceleration with u' = 0 is b_i = Omega x (Omega x p_i) + 2 phidot Omega x e_i
    + phidot^2 a_i; h drops out of it because z is constant in the world. Then
        M u' = sum_i J_i^T (F_i - m_i b_i) + Q,
    with gravity F_i = -m_i g n, the damping torque k Omega on the body and the
    leg torques tau_k on phi_k. M's leg block is diagonal (Ml l^2), so a Schur
    complement leaves one symmetric 3x3 solve per robot, done by cofactors.

Every function here takes components: a sequence whose items are Python floats
(one robot; fastest for a single env) or numpy arrays of shape (N,) (a batch).
The public array helpers at the bottom take states shaped (..., 13).
"""

from __future__ import annotations

import math

import numpy as np

from .params import RobotParams, rotation_point_depth

STATE_FIELDS = (
    ("x", 0, 1),
    ("y", 1, 2),
    ("quat", 2, 6),
    ("leg_angles", 6, 8),
    ("body_rate", 8, 11),
    ("leg_rates", 11, 13),
)
"""(name, start, stop) of each field in a state vector."""
STATE_SIZE = 13
QUAT = slice(2, 6)
LEG_ANGLES = slice(6, 8)
BODY_RATE = slice(8, 11)
LEG_RATES = slice(11, 13)


def _trig(sample):
    """sin and cos that suit the component type: math for floats, numpy for arrays."""
    if isinstance(sample, float):
        return math.sin, math.cos
    return np.sin, np.cos


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def rotation_rows(qw, qx, qy, qz):
    """Rows of R(quat), body to world, each a 3-tuple of components."""
    return (
        (1.0 - 2.0 * (qy * qy + qz * qz), 2.0 * (qx * qy - qw * qz), 2.0 * (qx * qz + qw * qy)),
        (2.0 * (qx * qy + qw * qz), 1.0 - 2.0 * (qx * qx + qz * qz), 2.0 * (qy * qz - qw * qx)),
        (2.0 * (qx * qz - qw * qy), 2.0 * (qy * qz + qw * qx), 1.0 - 2.0 * (qx * qx + qy * qy)),
    )


class _Terms:
    """Configuration-dependent quantities shared by the dynamics and the energy."""

    __slots__ = ("rows", "n", "tips", "e", "a", "s", "inertia", "first_moment", "m_omega", "coupling", "leg_mass")

    def __init__(self, c, params: RobotParams, depth: float):
        _, _, qw, qx, qy, qz, phi1, phi2 = c[:8]
        sin, cos = _trig(phi1)
        r, l, ml, h = params.radius, params.leg_length, params.mass_tip, depth
        mfix_x = (params.mass_bottom + 2.0 * params.mass_pin) * r * r
        self.rows = rotation_rows(qw, qx, qy, qz)
        n = self.rows[2]
        self.n = n
        c1, s1, c2, s2 = cos(phi1), sin(phi1), cos(phi2), sin(phi2)
        lc1, ls1, lc2, ls2 = l * c1, l * s1, l * c2, l * s2
        self.tips = ((lc1, -r, ls1), (lc2, r, ls2))
        self.e = ((-ls1, 0.0, lc1), (-ls2, 0.0, lc2))
        self.a = ((-lc1, 0.0, -ls1), (-lc2, 0.0, -ls2))
        # Inertia about the centre, body frame: the fixed masses plus both tips.
        tip_sq = l * l + r * r
        ixx = mfix_x + ml * (2.0 * tip_sq - (lc1 * lc1 + lc2 * lc2))
        iyy = params.mass_bottom * r * r + 2.0 * ml * l * l
        izz = 2.0 * params.mass_pin * r * r + ml * (2.0 * tip_sq - (ls1 * ls1 + ls2 * ls2))
        ixy = -ml * r * (lc2 - lc1)
        ixz = -ml * (lc1 * ls1 + lc2 * ls2)
        iyz = -ml * r * (ls2 - ls1)
        self.inertia = (ixx, ixy, ixz, iyy, iyz, izz)
        # First moment sum m p (its y part cancels between the two legs).
        sx = ml * (lc1 + lc2)
        sz = ml * (ls1 + ls2) - params.mass_bottom * r
        self.first_moment = (sx, 0.0, sz)
        # M_omega = I_c + h^2 m (1 - n n^T) + h (2 (S.n) 1 - S n^T - n S^T): inertia about the turning point.
        if h == 0.0:
            self.m_omega = self.inertia
            self.s = self.tips
        else:
            mt = params.total_mass * h * h
            sn2 = 2.0 * h * (sx * n[0] + sz * n[2])
            nx, ny, nz = n
            self.m_omega = (
                ixx + mt * (1.0 - nx * nx) + sn2 - 2.0 * h * sx * nx,
                ixy - mt * nx * ny - h * sx * ny,
                ixz - mt * nx * nz - h * (sx * nz + sz * nx),
                iyy + mt * (1.0 - ny * ny) + sn2,
                iyz - mt * ny * nz - h * sz * ny,
                izz + mt * (1.0 - nz * nz) + sn2 - 2.0 * h * sz * nz,
            )
            self.s = tuple(tuple(p[i] + h * n[i] for i in range(3)) for p in self.tips)
        # Mass-matrix coupling between Omega and phidot_k: Ml s_k x e_k.
        self.coupling = tuple(tuple(ml * v for v in _cross(sk, ek)) for sk, ek in zip(self.s, self.e))
        self.leg_mass = ml * l * l


def _sym_matvec(m, v):
    m00, m01, m02, m11, m12, m22 = m
    return (
        m00 * v[0] + m01 * v[1] + m02 * v[2],
        m01 * v[0] + m11 * v[1] + m12 * v[2],
        m02 * v[0] + m12 * v[1] + m22 * v[2],
    )


def _sym_solve(m, b):
    """Solve the symmetric 3x3 system m x = b by cofactors (m: upper triangle, row-wise)."""
    a, bb, c, d, e, f = m
    c00, c01, c02 = d * f - e * e, c * e - bb * f, bb * e - c * d
    c11, c12, c22 = a * f - c * c, bb * c - a * e, a * d - bb * bb
    inv_det = 1.0 / (a * c00 + bb * c01 + c * c02)
    return (
        (c00 * b[0] + c01 * b[1] + c02 * b[2]) * inv_det,
        (c01 * b[0] + c11 * b[1] + c12 * b[2]) * inv_det,
        (c02 * b[0] + c12 * b[1] + c22 * b[2]) * inv_det,
    )


def state_derivative(c, leg_torque, params: RobotParams, depth: float, leg_accel=None):
    """Time derivative of a state, in components.

    Args:
        c: the 13 state components (layout :data:`STATE_FIELDS`), floats or (N,) arrays.
        leg_torque: (tau_1, tau_2), N m, joint torques from the shell on each leg.
            Ignored when ``leg_accel`` is given.
        params: the robot.
        depth: h, m, from :func:`rrrobot_gym.params.rotation_point_depth`.
        leg_accel: optional (phi_1ddot, phi_2ddot), rad/s^2: prescribe the legs'
            motion (kinematic legs) instead of integrating their servo dynamics.

    Returns:
        The 13 derivative components, in the same layout.
    """
    qw, qx, qy, qz = c[2], c[3], c[4], c[5]
    omega = (c[8], c[9], c[10])
    leg_rates = (c[11], c[12])
    t = _Terms(c, params, depth)
    n, ml, g, h = t.n, params.mass_tip, params.gravity, depth

    # Contact kinematics (eq. 2 and 4) with w = R Omega.
    w_x = _dot(t.rows[0], omega)
    w_y = _dot(t.rows[1], omega)
    r = params.radius
    # Attitude: qdot = 1/2 q (x) (0, Omega) for a body-frame rate.
    dq = (
        -0.5 * (qx * omega[0] + qy * omega[1] + qz * omega[2]),
        0.5 * (qw * omega[0] + qy * omega[2] - qz * omega[1]),
        0.5 * (qw * omega[1] + qz * omega[0] - qx * omega[2]),
        0.5 * (qw * omega[2] + qx * omega[1] - qy * omega[0]),
    )

    # Generalised forces minus the velocity-dependent inertial terms, Omega rows.
    s_mom = t.first_moment
    gyro = _cross(omega, _sym_matvec(t.inertia, omega))
    omega_sq = _dot(omega, omega)
    grav = _cross(s_mom, n)
    k = params.damping
    f_omega = [k * omega[i] - gyro[i] - g * grav[i] for i in range(3)]
    if h != 0.0:
        os_ = _dot(omega, s_mom)
        oos = tuple(omega[i] * os_ - s_mom[i] * omega_sq for i in range(3))
        turn = _cross(n, oos)
        f_omega = [f_omega[i] - h * turn[i] for i in range(3)]
    f_leg = []
    for k_leg in range(2):
        e, a, p, s = t.e[k_leg], t.a[k_leg], t.tips[k_leg], t.s[k_leg]
        rate = leg_rates[k_leg]
        oe = _cross(omega, e)
        b_rel = tuple(2.0 * rate * oe[i] + rate * rate * a[i] for i in range(3))
        sb = _cross(s, b_rel)
        f_omega = [f_omega[i] - ml * sb[i] for i in range(3)]
        # e.(Omega x (Omega x p)) = (Omega.e)(Omega.p), since e.p = 0.
        f_leg.append(-ml * (_dot(omega, e) * _dot(omega, p) + g * _dot(e, n)))

    c1, c2 = t.coupling
    d = t.leg_mass
    if leg_accel is None:
        f_leg = [f_leg[0] + leg_torque[0], f_leg[1] + leg_torque[1]]
        # Schur complement of the diagonal leg block.
        mo = t.m_omega
        inv_d = 1.0 / d
        m_red = (
            mo[0] - (c1[0] * c1[0] + c2[0] * c2[0]) * inv_d,
            mo[1] - (c1[0] * c1[1] + c2[0] * c2[1]) * inv_d,
            mo[2] - (c1[0] * c1[2] + c2[0] * c2[2]) * inv_d,
            mo[3] - (c1[1] * c1[1] + c2[1] * c2[1]) * inv_d,
            mo[4] - (c1[1] * c1[2] + c2[1] * c2[2]) * inv_d,
            mo[5] - (c1[2] * c1[2] + c2[2] * c2[2]) * inv_d,
        )
        rhs = tuple(f_omega[i] - (c1[i] * f_leg[0] + c2[i] * f_leg[1]) * inv_d for i in range(3))
        omega_dot = _sym_solve(m_red, rhs)
        leg_acc = ((f_leg[0] - _dot(c1, omega_dot)) * inv_d, (f_leg[1] - _dot(c2, omega_dot)) * inv_d)
    else:
        leg_acc = (leg_accel[0], leg_accel[1])
        rhs = tuple(f_omega[i] - c1[i] * leg_acc[0] - c2[i] * leg_acc[1] for i in range(3))
        omega_dot = _sym_solve(t.m_omega, rhs)

    return (
        r * w_y,
        -r * w_x,
        dq[0],
        dq[1],
        dq[2],
        dq[3],
        leg_rates[0],
        leg_rates[1],
        omega_dot[0],
        omega_dot[1],
        omega_dot[2],
        leg_acc[0],
        leg_acc[1],
    )


def energy_components(c, params: RobotParams, depth: float):
    """Kinetic and potential energy (J), with the centre at height r in both models."""
    omega = (c[8], c[9], c[10])
    leg_rates = (c[11], c[12])
    t = _Terms(c, params, depth)
    kinetic = 0.5 * _dot(omega, _sym_matvec(t.m_omega, omega))
    for k_leg in range(2):
        kinetic = kinetic + leg_rates[k_leg] * _dot(t.coupling[k_leg], omega)
        kinetic = kinetic + 0.5 * t.leg_mass * leg_rates[k_leg] * leg_rates[k_leg]
    potential = params.gravity * (params.total_mass * params.radius + _dot(t.first_moment, t.n))
    return kinetic, potential


# ---------------------------------------------------------------------------
# Array helpers: states shaped (..., 13), leading axes are batch axes.


def _components(state):
    """View a (..., 13) state as a list of 13 component arrays."""
    return [state[..., i] for i in range(STATE_SIZE)]


def mass_matrix(state, params: RobotParams, model: str):
    """The 5x5 generalised mass matrix for the speeds (Omega, phi_1dot, phi_2dot), shape (..., 5, 5)."""
    state = np.asarray(state, dtype=float)
    t = _Terms(_components(state), params, rotation_point_depth(model, params))
    out = np.zeros(state.shape[:-1] + (5, 5))
    idx = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
    for (i, j), v in zip(idx, t.m_omega):
        out[..., i, j] = v
        out[..., j, i] = v
    for k_leg in range(2):
        for i in range(3):
            out[..., i, 3 + k_leg] = t.coupling[k_leg][i]
            out[..., 3 + k_leg, i] = t.coupling[k_leg][i]
        out[..., 3 + k_leg, 3 + k_leg] = t.leg_mass
    return out


def total_energy(state, params: RobotParams, model: str):
    """Kinetic plus potential energy (J) of each robot, shape (...)."""
    state = np.asarray(state, dtype=float)
    kin, pot = energy_components(_components(state), params, rotation_point_depth(model, params))
    return np.asarray(kin + pot)


def rotation_matrix(quat):
    """R (body to world) from unit quaternions (..., 4) in (w, x, y, z) order, shape (..., 3, 3)."""
    quat = np.asarray(quat, dtype=float)
    rows = rotation_rows(quat[..., 0], quat[..., 1], quat[..., 2], quat[..., 3])
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


def paper_angles(quat):
    """The paper's ZXY fixed angles (theta_1, theta_2, theta_3), shape (..., 3), rad.

    R = Ry(theta_3) Rx(theta_1) Rz(theta_2): theta_1 is the rotation about X,
    theta_2 about Z and theta_3 about Y. Singular at theta_1 = +-pi/2, which is why
    the simulation itself integrates a quaternion.
    """
    rot = rotation_matrix(quat)
    theta1 = np.arcsin(np.clip(-rot[..., 1, 2], -1.0, 1.0))
    theta2 = np.arctan2(rot[..., 1, 0], rot[..., 1, 1])
    theta3 = np.arctan2(rot[..., 0, 2], rot[..., 2, 2])
    return np.stack([theta1, theta2, theta3], axis=-1)


def quat_from_paper_angles(theta):
    """Unit quaternion (w, x, y, z) of R = Ry(theta_3) Rx(theta_1) Rz(theta_2), shape (..., 4)."""
    theta = np.asarray(theta, dtype=float)
    half = 0.5 * theta
    qx = np.stack([np.cos(half[..., 0]), np.sin(half[..., 0]), 0 * half[..., 0], 0 * half[..., 0]], -1)
    qz = np.stack([np.cos(half[..., 1]), 0 * half[..., 1], 0 * half[..., 1], np.sin(half[..., 1])], -1)
    qy = np.stack([np.cos(half[..., 2]), 0 * half[..., 2], np.sin(half[..., 2]), 0 * half[..., 2]], -1)
    return quat_multiply(quat_multiply(qy, qx), qz)


def quat_multiply(p, q):
    """Hamilton product p (x) q of quaternions (..., 4), (w, x, y, z) order."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    pw, pv = p[..., 0], p[..., 1:]
    qw, qv = q[..., 0], q[..., 1:]
    w = pw * qw - np.sum(pv * qv, axis=-1)
    v = pw[..., None] * qv + qw[..., None] * pv + np.cross(pv, qv)
    return np.concatenate([w[..., None], v], axis=-1)


def world_body_rate(state):
    """World-frame angular velocity w = R Omega, shape (..., 3), rad/s."""
    state = np.asarray(state, dtype=float)
    return np.einsum("...ij,...j->...i", rotation_matrix(state[..., QUAT]), state[..., BODY_RATE])


def tilt(state):
    """Angle between the body z axis and the world z axis, shape (...), rad."""
    state = np.asarray(state, dtype=float)
    q = state[..., QUAT]
    nz = 1.0 - 2.0 * (q[..., 1] ** 2 + q[..., 2] ** 2)
    return np.arccos(np.clip(nz, -1.0, 1.0))


TILT_LIMIT = 0.5 * math.pi
"""rad: at this tilt the hemisphere's rim touches the ground and the rolling model ends."""
