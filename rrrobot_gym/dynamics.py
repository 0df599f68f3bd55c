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
from typing import NamedTuple

import numpy as np

from .numerics import sincos
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


def rotation_rows(qw, qx, qy, qz):
    """Rows of R(quat), body to world, each a 3-tuple of components."""
    # Each product once (on a batch's arrays the task code's rotations are a numpy call per operation).
    xx, yy, zz = qx * qx, qy * qy, qz * qz
    xy, xz, yz = qx * qy, qx * qz, qy * qz
    wx, wy, wz = qw * qx, qw * qy, qw * qz
    return (
        (1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)),
        (2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)),
        (2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)),
    )


class Constants(NamedTuple):
    """Numbers that depend only on (params, depth), computed once per configuration.

    Made by :func:`constants`; the integrators pass it to :func:`derivative_kernel`
    so that a derivative evaluation does no parameter arithmetic. The hot functions
    unpack it whole (one tuple unpack is cheaper than attribute look-ups on floats).
    """

    radius: float  # m, r
    leg_length: float  # m, l
    mass_tip: float  # kg, Ml
    depth: float  # m, h
    gravity: float  # m/s^2, g
    damping: float  # N m s/rad, k
    leg_inertia: float  # kg m^2, D = Ml l^2
    inv_leg_inertia: float  # 1/(kg m^2)
    ixx0: float  # kg m^2, Ixx about the centre before the legs' cos^2 terms
    iyy: float  # kg m^2
    izz0: float  # kg m^2
    ml_r: float  # kg m, Ml r
    mb_r: float  # kg m, Mb r
    total_h2: float  # kg m^2, M h^2
    two_ml: float  # kg, 2 Ml
    neg_ml: float  # kg, -Ml
    neg_ml_l2: float  # kg m^2, -Ml l^2
    ml_h: float  # kg m, Ml h
    total_h: float  # kg m, M h
    weight: float  # N, M g


def constants(params: RobotParams, depth: float) -> Constants:
    """The per-configuration constants of the equations of motion (see :class:`Constants`)."""
    r, l, ml, mb, ms = params.radius, params.leg_length, params.mass_tip, params.mass_bottom, params.mass_pin
    h = float(depth)
    tip_sq = l * l + r * r
    return Constants(
        radius=r,
        leg_length=l,
        mass_tip=ml,
        depth=h,
        gravity=params.gravity,
        damping=params.damping,
        leg_inertia=ml * l * l,
        inv_leg_inertia=1.0 / (ml * l * l),
        # Inertia about the centre: Ixx = ixx0 - Ml (l^2 cos^2 phi1 + l^2 cos^2 phi2),
        # Izz = izz0 + the same (since sin^2 = 1 - cos^2); Iyy does not depend on the legs.
        ixx0=(mb + 2.0 * ms) * r * r + 2.0 * ml * tip_sq,
        iyy=mb * r * r + 2.0 * ml * l * l,
        izz0=2.0 * ms * r * r + 2.0 * ml * r * r,
        ml_r=ml * r,
        mb_r=mb * r,
        total_h2=params.total_mass * h * h,
        two_ml=2.0 * ml,
        neg_ml=-ml,
        neg_ml_l2=-ml * l * l,
        ml_h=ml * h,
        total_h=params.total_mass * h,
        weight=params.total_mass * params.gravity,
    )


def _leg_trig(phi1, phi2):
    """cos and sin of both leg angles (times nothing): (c1, s1, c2, s2)."""
    if isinstance(phi1, float):  # (arithmetic alone: the compiled stepper's bits, on any CPU)
        s1, c1 = sincos(phi1)
        s2, c2 = sincos(phi2)
        return c1, s1, c2, s2
    # numpy's float64 sin and cos have no SIMD kernel and cost ~15x a tan: use the
    # half-angle tangent t, cos = 2/(1+t^2) - 1, sin = t (2/(1+t^2)) (errors ~1e-16
    # absolute; t stays finite in float64 since phi/2 is never exactly pi/2).
    t1 = np.tan(0.5 * phi1)
    t2 = np.tan(0.5 * phi2)
    w1 = 2.0 / (1.0 + t1 * t1)
    w2 = 2.0 / (1.0 + t2 * t2)
    return w1 - 1.0, t1 * w1, w2 - 1.0, t2 * w2


def _up_vector(qw, qx, qy, qz):
    """n = R^T z (world up in body coordinates), the third row of R."""
    tqx, tqy, tqz = qx + qx, qy + qy, qz + qz
    return qx * tqz - qw * tqy, qy * tqz + qw * tqx, 1.0 - (qx * tqx + qy * tqy)


def _configuration(phi1, phi2, n, k):
    """Configuration-dependent terms shared by the dynamics, the energy and the mass matrix.

    Returns (legs, inertia, first_moment, m_omega, coupling), where legs holds, per leg,
    (l cos phi, l sin phi, s_y) with s_y the y of s = p + h n, the tip relative to
    the turning point; inertia and m_omega are upper triangles (xx, xy, xz, yy, yz, zz)
    of I_c and of M_omega; first_moment is (S_x, S_z) (S_y cancels between the legs);
    coupling is (c_1, c_2), c_k = Ml s_k x e_k.
    """
    r, l, ml, h, _, _, _, _, ixx0, iyy0, izz0, ml_r, mb_r, total_h2, _, neg_ml, neg_ml_l2, ml_h, _, _ = k
    nx, ny, nz = n
    cos1, sin1, cos2, sin2 = _leg_trig(phi1, phi2)
    lc1, ls1, lc2, ls2 = l * cos1, l * sin1, l * cos2, l * sin2
    m2 = ml * (lc1 * lc1 + lc2 * lc2)
    ixx, iyy, izz = ixx0 - m2, iyy0, izz0 + m2
    ixy = ml_r * (lc1 - lc2)
    ixz = neg_ml * (lc1 * ls1 + lc2 * ls2)
    iyz = ml_r * (ls1 - ls2)
    sx = ml * (lc1 + lc2)
    sz = ml * (ls1 + ls2) - mb_r
    inertia = (ixx, ixy, ixz, iyy, iyz, izz)
    if h == 0.0:
        # Pivoting: s = p, M_omega = I_c, and c_k = Ml p_k x e_k = Ml (p_y lc, -l^2, p_y ls).
        c_y = neg_ml_l2
        c1 = (-ml_r * lc1, c_y, -ml_r * ls1)
        c2 = (ml_r * lc2, c_y, ml_r * ls2)
        return ((lc1, ls1, -r), (lc2, ls2, r)), inertia, (sx, sz), inertia, (c1, c2)
    # M_omega = I_c + h^2 M (1 - n n^T) + h (2 (S.n) 1 - S n^T - n S^T): inertia about the turning point.
    hsx, hsz = h * sx, h * sz
    mt = total_h2
    mnx, mny, mnz = mt * nx, mt * ny, mt * nz
    diag = mt + 2.0 * (hsx * nx + hsz * nz)
    ax, az = mnx + hsx, mnz + hsz
    m_omega = (
        ixx + diag - nx * (ax + hsx),
        ixy - ny * ax,
        ixz - nz * ax - hsz * nx,
        iyy + diag - ny * mny,
        iyz - ny * az,
        izz + diag - nz * (az + hsz),
    )
    # c_k = Ml s_k x e_k = Ml (s_y lc, -(l^2 + h (nx lc + nz ls)), s_y ls), using p_k.e_k = 0.
    hny = h * ny
    sy1, sy2 = hny - r, hny + r
    ml_sy1, ml_sy2 = ml * sy1, ml * sy2
    c1 = (ml_sy1 * lc1, neg_ml_l2 - ml_h * (nx * lc1 + nz * ls1), ml_sy1 * ls1)
    c2 = (ml_sy2 * lc2, neg_ml_l2 - ml_h * (nx * lc2 + nz * ls2), ml_sy2 * ls2)
    return ((lc1, ls1, sy1), (lc2, ls2, sy2)), inertia, (sx, sz), m_omega, (c1, c2)


def _rotation_products(qw, qx, qy, qz):
    """(xx, yy, zz, xy, xz, yz, wx, wy, wz), the products of the rotation matrix of q: q_a q_b 2 / |q|^2."""
    # 2 / |q|^2 rather than 2: RK4's stage quaternions are slightly off unit length, and this
    # keeps R a rotation there, so the contact kinematics stay exactly symmetric under yaw.
    two_over_norm = 2.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
    tqx, tqy, tqz = qx * two_over_norm, qy * two_over_norm, qz * two_over_norm
    return qx * tqx, qy * tqy, qz * tqz, qx * tqy, qx * tqz, qy * tqz, qw * tqx, qw * tqy, qw * tqz


def _sym_cofactors(m):
    """Cofactors (c00, c01, c02, c11, c12, c22) of a symmetric 3x3 m (upper triangle, row-wise)
    and 1 / det m."""
    a, bb, c, d, e, f = m
    c00, c01, c02 = d * f - e * e, c * e - bb * f, bb * e - c * d
    c11, c12, c22 = a * f - c * c, bb * c - a * e, a * d - bb * bb
    return (c00, c01, c02, c11, c12, c22), 1.0 / (a * c00 + bb * c01 + c * c02)


def _sym_apply(m, b0, b1, b2):
    """m b for a symmetric 3x3 m given as its upper triangle (row-wise)."""
    a, bb, c, d, e, f = m
    return a * b0 + bb * b1 + c * b2, bb * b0 + d * b1 + e * b2, c * b0 + e * b1 + f * b2


def _sym_solve(m, b0, b1, b2):
    """Solve the symmetric 3x3 system m x = b by cofactors (m: upper triangle, row-wise);
    scaling the result rather than the cofactors saves three products a solve."""
    cof, inv_det = _sym_cofactors(m)
    x0, x1, x2 = _sym_apply(cof, b0, b1, b2)
    return x0 * inv_det, x1 * inv_det, x2 * inv_det


def derivative_kernel(c, leg_torque, k: Constants, leg_accel=None, torque_out=None, contact_out=None):
    """:func:`state_derivative` with the constants precomputed by :func:`constants`.

    This is the implementation; the integrators call it directly to skip the per-call
    parameter arithmetic. With ``leg_accel`` (kinematic legs), a list ``torque_out`` receives
    the two leg torques that motion takes (from the legs' rows, D phi'' + c_k . Omega' = f_leg +
    tau). A list ``contact_out`` receives :func:`contact_kernel`'s seven values for this state
    and the derivative returned, from the terms already computed here (the integrators' record).
    Returns the 13 derivative components as a tuple.
    """
    qw, qx, qy, qz = c[2], c[3], c[4], c[5]
    rate1, rate2 = c[11], c[12]
    r, _, ml, h, g, damping, inertia_leg, inv_d, _, _, _, _, _, _, two_ml, neg_ml, _, _, total_h, weight = k

    # Attitude products; rows 0 and 1 of R give the world rate for the contact
    # kinematics (eq. 2 and 4: xdot = r w_y, ydot = -r w_x), row 2 is n.
    xx, yy, zz, xy, xz, yz, wx, wy, wz = _rotation_products(qw, qx, qy, qz)
    nx, ny, nz = xz - wy, yz + wx, 1.0 - (xx + yy)

    legs, inertia, (sx, sz), m_omega, (c1, c2) = _configuration(c[6], c[7], (nx, ny, nz), k)
    ox, oy, oz = c[8], c[9], c[10]
    w_x = (1.0 - yy - zz) * ox + (xy - wz) * oy + (xz + wy) * oz
    w_y = (xy + wz) * ox + (1.0 - xx - zz) * oy + (yz - wx) * oz
    # qdot = 1/2 q (x) (0, Omega) for a body-frame rate.
    hox, hoy, hoz = 0.5 * ox, 0.5 * oy, 0.5 * oz
    dqw = -(qx * hox + qy * hoy + qz * hoz)
    dqx = qw * hox + qy * hoz - qz * hoy
    dqy = qw * hoy + qz * hox - qx * hoz
    dqz = qw * hoz + qx * hoy - qy * hox

    ixx, ixy, ixz, iyy, iyz, izz = inertia

    # Generalised forces minus the velocity-dependent inertial terms, Omega rows:
    # damping k Omega, gyroscopic -Omega x (I Omega), gravity -g S x n with S = (sx, 0, sz).
    lx = ixx * ox + ixy * oy + ixz * oz
    ly = ixy * ox + iyy * oy + iyz * oz
    lz = ixz * ox + iyz * oy + izz * oz
    gsx, gsz = g * sx, g * sz
    f0 = damping * ox - (oy * lz - oz * ly) + gsz * ny
    f1 = damping * oy - (oz * lx - ox * lz) + (gsx * nz - gsz * nx)
    f2 = damping * oz - (ox * ly - oy * lx) - gsx * ny
    n_omega = nx * ox + ny * oy + nz * oz
    if h != 0.0:
        # -h n x (Omega (Omega.S) - S |Omega|^2): the centre's acceleration about the turning point.
        h_os = h * (ox * sx + oz * sz)
        h_osq = h * (ox * ox + oy * oy + oz * oz)
        vx, vy, vz = ox * h_os - sx * h_osq, oy * h_os, oz * h_os - sz * h_osq
        f0 = f0 - (ny * vz - nz * vy)
        f1 = f1 - (nz * vx - nx * vz)
        f2 = f2 - (nx * vy - ny * vx)

    # Each leg, with e = (-ls, 0, lc), p = (lc, p_y, ls), a = -(lc, 0, ls):
    # Omega rows lose Ml s x b_rel, b_rel = 2 phidot Omega x e + phidot^2 a, where
    # s x (Omega x e) = h (n.e) Omega - (s.Omega) e (as p.e = 0) and
    # s x a = (-s_y ls, -h (n.e), s_y lc); the leg row gets
    # e.(F - Ml b) = -Ml ((Omega.e)(Omega.p) + g n.e), since e.(Omega x (Omega x p)) = (Omega.e)(Omega.p).
    (lc1, ls1, sy1), (lc2, ls2, sy2) = legs
    r_oy = r * oy
    ne1, ne2 = nz * lc1 - nx * ls1, nz * lc2 - nx * ls2
    p_omega1, p_omega2 = lc1 * ox + ls1 * oz - r_oy, lc2 * ox + ls2 * oz + r_oy
    f_leg1 = neg_ml * ((lc1 * oz - ls1 * ox) * p_omega1 + g * ne1)
    f_leg2 = neg_ml * ((lc2 * oz - ls2 * ox) * p_omega2 + g * ne2)
    a1, a2 = two_ml * rate1, two_ml * rate2
    cc1, cc2 = ml * rate1 * rate1, ml * rate2 * rate2
    if h != 0.0:
        h_n_omega = h * n_omega
        hne1, hne2 = h * ne1, h * ne2
        a_hne = a1 * hne1 + a2 * hne2
        d1 = a1 * (p_omega1 + h_n_omega) - cc1 * sy1
        d2 = a2 * (p_omega2 + h_n_omega) - cc2 * sy2
        f0 = f0 - (a_hne * ox + d1 * ls1 + d2 * ls2)
        f1 = f1 - (a_hne * oy - (cc1 * hne1 + cc2 * hne2))
        f2 = f2 - (a_hne * oz - (d1 * lc1 + d2 * lc2))
    else:
        d1 = a1 * p_omega1 - cc1 * sy1
        d2 = a2 * p_omega2 - cc2 * sy2
        f0 = f0 - (d1 * ls1 + d2 * ls2)
        f2 = f2 + (d1 * lc1 + d2 * lc2)

    c1x, c1y, c1z = c1
    c2x, c2y, c2z = c2
    if leg_accel is None:
        # Schur complement of the diagonal leg block (Ml l^2 on each leg).
        fl1, fl2 = f_leg1 + leg_torque[0], f_leg2 + leg_torque[1]
        h1x, h1y, h1z = c1x * inv_d, c1y * inv_d, c1z * inv_d
        h2x, h2y, h2z = c2x * inv_d, c2y * inv_d, c2z * inv_d
        m_red = (
            m_omega[0] - (c1x * h1x + c2x * h2x),
            m_omega[1] - (c1x * h1y + c2x * h2y),
            m_omega[2] - (c1x * h1z + c2x * h2z),
            m_omega[3] - (c1y * h1y + c2y * h2y),
            m_omega[4] - (c1y * h1z + c2y * h2z),
            m_omega[5] - (c1z * h1z + c2z * h2z),
        )
        rhs = (f0 - (h1x * fl1 + h2x * fl2), f1 - (h1y * fl1 + h2y * fl2), f2 - (h1z * fl1 + h2z * fl2))
        od0, od1, od2 = _sym_solve(m_red, rhs[0], rhs[1], rhs[2])
        acc1 = fl1 * inv_d - (h1x * od0 + h1y * od1 + h1z * od2)
        acc2 = fl2 * inv_d - (h2x * od0 + h2y * od1 + h2z * od2)
    else:
        acc1, acc2 = leg_accel[0], leg_accel[1]
        od0, od1, od2 = _sym_solve(
            m_omega, f0 - (c1x * acc1 + c2x * acc2), f1 - (c1y * acc1 + c2y * acc2), f2 - (c1z * acc1 + c2z * acc2)
        )
        if torque_out is not None:
            torque_out[:] = (
                inertia_leg * acc1 + (c1x * od0 + c1y * od1 + c1z * od2) - f_leg1,
                inertia_leg * acc2 + (c2x * od0 + c2y * od1 + c2z * od2) - f_leg2,
            )
    if contact_out is not None:
        contact_out[:] = _contact_force(
            (nx, ny, nz), legs, (sx, sz), (ox, oy, oz), (rate1, rate2), (od0, od1, od2), (acc1, acc2),
            r, ml, total_h, weight,
        )  # fmt: skip
    return (r * w_y, -r * w_x, dqw, dqx, dqy, dqz, rate1, rate2, od0, od1, od2, acc1, acc2)


def _contact_force(n, legs, first_moment, omega, rates, omega_dot, leg_accels, r, ml, total_h, weight):
    """Newton's second law for the whole robot: the force on the shell from the ground
    (pivot: the joint) in body coordinates, its part along world up, and each leg tip's
    height above the ground. See :func:`contact_kernel`; ``legs`` as :func:`_configuration`'s."""
    nx, ny, nz = n
    (lc1, ls1, _), (lc2, ls2, _) = legs
    sx, sz = first_moment
    ox, oy, oz = omega
    dox, doy, doz = omega_dot
    # Omega' x (m h n + S)
    ax, ay, az = total_h * nx + sx, total_h * ny, total_h * nz + sz
    fx = doy * az - doz * ay
    fy = doz * ax - dox * az
    fz = dox * ay - doy * ax
    # Omega x (Omega x S) = Omega (Omega.S) - S |Omega|^2
    o_s = ox * sx + oz * sz
    o_sq = ox * ox + oy * oy + oz * oz
    fx = fx + ox * o_s - sx * o_sq
    fy = fy + oy * o_s
    fz = fz + oz * o_s - sz * o_sq
    # Each leg: Ml (e phi'' + 2 phi' Omega x e + a phi'^2), e = (-ls, 0, lc), a = -(lc, 0, ls).
    (rate1, rate2), (acc1, acc2) = rates, leg_accels
    two_rate1, two_rate2 = 2.0 * rate1, 2.0 * rate2
    rate1_sq, rate2_sq = rate1 * rate1, rate2 * rate2
    fx = fx + ml * (two_rate1 * (oy * lc1) - ls1 * acc1 - lc1 * rate1_sq)
    fy = fy - ml * (two_rate1 * (oz * ls1 + ox * lc1))
    fz = fz + ml * (lc1 * acc1 + two_rate1 * (oy * ls1) - ls1 * rate1_sq)
    fx = fx + ml * (two_rate2 * (oy * lc2) - ls2 * acc2 - lc2 * rate2_sq)
    fy = fy - ml * (two_rate2 * (oz * ls2 + ox * lc2))
    fz = fz + ml * (lc2 * acc2 + two_rate2 * (oy * ls2) - ls2 * rate2_sq)
    fx = fx + weight * nx
    fy = fy + weight * ny
    fz = fz + weight * nz
    normal = fx * nx + fy * ny + fz * nz
    clearance1 = r + lc1 * nx - r * ny + ls1 * nz
    clearance2 = r + lc2 * nx + r * ny + ls2 * nz
    return fx, fy, fz, normal, tangential_force(fx, fy, fz, normal), clearance1, clearance2


def tangential_force(fx, fy, fz, normal):
    """The part of a force (fx, fy, fz) along the ground, sqrt(|F|^2 - normal^2), given its part
    ``normal`` along world up (0 where rounding makes the square negative); floats or arrays.
    What the step record holds (:func:`contact_kernel`), and what a record made by hand is given."""
    along_sq = fx * fx + fy * fy + fz * fz - normal * normal
    if isinstance(along_sq, float):
        return math.sqrt(along_sq) if not along_sq < 0.0 else 0.0
    return np.sqrt(np.maximum(along_sq, 0.0))


class ContactConstants(NamedTuple):
    """What :func:`contact_kernel` needs of a configuration (made by :func:`contact_constants`)."""

    radius: float  # m
    leg_length: float  # m
    mass_tip: float  # kg
    depth: float  # m, h
    gravity: float  # m/s^2
    total_mass: float  # kg
    mb_r: float  # kg m, Mb r


def contact_constants(params: RobotParams, depth: float) -> ContactConstants:
    return ContactConstants(
        params.radius, params.leg_length, params.mass_tip, float(depth), params.gravity,
        params.total_mass, params.mass_bottom * params.radius,
    )  # fmt: skip


def contact_kernel(c, d, k: ContactConstants):
    """The ground's force on the shell and the legs' clearance, from a state and its derivative.

    ``c`` and ``d`` are the 13 state and derivative components (floats or (N,) arrays; ``d``
    from :func:`derivative_kernel` with the torques that acted). Newton's second law for the
    whole robot gives the force the ground (pivot model: the spherical joint) applies to
    the shell, body coordinates: F = m a_com + m g n, with

        m a_com = Omega' x (m h n + S) + Omega x (Omega x S)
                  + sum_k Ml (e_k phi_k'' + 2 phi_k' Omega x e_k + a_k phi_k'^2)

    (S = sum m p, the first moment about the centre; S_y = 0). Kinematics only: the
    accelerations are the derivative's, so this is no second copy of the dynamics.

    Returns (F_x, F_y, F_z, normal, tangential, clearance_1, clearance_2): body-frame force
    (N), its component along world up (N), its magnitude along the ground (N, the grip rolling
    needs), and each leg tip's height above the ground (m).
    """
    qw, qx, qy, qz = c[2], c[3], c[4], c[5]
    l, ml = k.leg_length, k.mass_tip
    two_over_norm = 2.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
    tqx, tqy, tqz = qx * two_over_norm, qy * two_over_norm, qz * two_over_norm
    # n as derivative_kernel forms it, product for product: the record it makes is this function's
    n = (qx * tqz - qw * tqy, qy * tqz + qw * tqx, 1.0 - (qx * tqx + qy * tqy))
    cos1, sin1, cos2, sin2 = _leg_trig(c[6], c[7])
    lc1, ls1, lc2, ls2 = l * cos1, l * sin1, l * cos2, l * sin2
    first_moment = (ml * (lc1 + lc2), ml * (ls1 + ls2) - k.mb_r)
    return _contact_force(
        n, ((lc1, ls1, None), (lc2, ls2, None)), first_moment, (c[8], c[9], c[10]), (c[11], c[12]),
        (d[8], d[9], d[10]), (d[11], d[12]), k.radius, ml, k.total_mass * k.depth, k.total_mass * k.gravity,
    )  # fmt: skip


KERNELS = (_leg_trig, _rotation_products, _configuration, _sym_cofactors, _sym_apply, _sym_solve,
           tangential_force, _contact_force, derivative_kernel, contact_kernel)
"""The functions :mod:`rrrobot_gym.compiled` compiles (each calls only the ones before it, and
:data:`rrrobot_gym.numerics.KERNELS`)."""


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
    return derivative_kernel(c, leg_torque, constants(params, depth), leg_accel)


def energy_components(c, params: RobotParams, depth: float):
    """Kinetic and potential energy (J), with the centre at height r in both models."""
    k = constants(params, depth)
    ox, oy, oz = c[8], c[9], c[10]
    n = _up_vector(c[2], c[3], c[4], c[5])
    _, _, (sx, sz), mo, (c1, c2) = _configuration(c[6], c[7], n, k)
    kinetic = 0.5 * (
        mo[0] * ox * ox + mo[3] * oy * oy + mo[5] * oz * oz
        + 2.0 * (mo[1] * ox * oy + mo[2] * ox * oz + mo[4] * oy * oz)
    )  # fmt: skip
    kinetic = kinetic + c[11] * (c1[0] * ox + c1[1] * oy + c1[2] * oz)
    kinetic = kinetic + c[12] * (c2[0] * ox + c2[1] * oy + c2[2] * oz)
    kinetic = kinetic + 0.5 * k.leg_inertia * (c[11] * c[11] + c[12] * c[12])
    potential = params.gravity * (params.total_mass * params.radius + sx * n[0] + sz * n[2])
    return kinetic, potential


# ---------------------------------------------------------------------------
# Array helpers: states shaped (..., 13), leading axes are batch axes.


def _shaped(values, size: int, what: str) -> np.ndarray:
    """``values`` as a float array shaped (..., size), or an error naming ``what``: these helpers
    index the last axis, so a wrong length would fail inside numpy or, worse, read other numbers."""
    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{what} must be numbers shaped (..., {size}), got {type(values).__name__}") from None
    if array.ndim == 0 or array.shape[-1] != size:
        raise ValueError(f"{what} must have shape (..., {size}), got shape {array.shape}")
    return array


def not_rotations(quat) -> np.ndarray:
    """Which quaternions (..., 4) are no attitude: finite, with a norm outside [0.5, 2], the bound
    :func:`rrrobot_gym.simulation.check_state` takes (a zero quaternion gives the identity, and a
    norm that overflows, from components past ~1e154, is out too). NaN and inf are not flagged."""
    quat = np.asarray(quat, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):
        norm = np.sqrt(np.sum(quat * quat, axis=-1))
    return np.all(np.isfinite(quat), axis=-1) & ~((norm >= 0.5) & (norm <= 2.0))


def _unit_quaternions(quat, what: str) -> np.ndarray:
    """Quaternions (..., 4), refused where :func:`not_rotations`. NaN and inf pass, as in any
    arithmetic: the diagnosis of a failed run still reads its attitude."""
    quat = _shaped(quat, 4, what)
    off = not_rotations(quat)
    if np.any(off):
        with np.errstate(over="ignore"):
            norm = np.linalg.norm(quat[off][0])
        raise ValueError(f"{what} must be unit quaternions (w, x, y, z), got norm {norm:.3g}")
    return quat


def _states(state, what: str = "state") -> np.ndarray:
    """States (..., 13), their quaternions checked (:func:`_unit_quaternions`)."""
    state = _shaped(state, STATE_SIZE, what)
    _unit_quaternions(state[..., QUAT], f"{what}'s entries 2:6")
    return state


def _components(state):
    """View a (..., 13) state as a list of 13 component arrays."""
    return [state[..., i] for i in range(STATE_SIZE)]


def mass_matrix(state, params: RobotParams, model: str):
    """The 5x5 generalised mass matrix for the speeds (Omega, phi_1dot, phi_2dot), shape (..., 5, 5)."""
    state = _states(state)
    comps = _components(state)
    k = constants(params, rotation_point_depth(model, params))
    n = _up_vector(comps[2], comps[3], comps[4], comps[5])
    _, _, _, m_omega, coupling = _configuration(comps[6], comps[7], n, k)
    out = np.zeros(state.shape[:-1] + (5, 5))
    idx = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
    for (i, j), v in zip(idx, m_omega):
        out[..., i, j] = v
        out[..., j, i] = v
    for k_leg in range(2):
        for i in range(3):
            out[..., i, 3 + k_leg] = coupling[k_leg][i]
            out[..., 3 + k_leg, i] = coupling[k_leg][i]
        out[..., 3 + k_leg, 3 + k_leg] = k.leg_inertia
    return out


def total_energy(state, params: RobotParams, model: str):
    """Kinetic plus potential energy (J) of each robot, shape (...)."""
    state = _states(state)
    kin, pot = energy_components(_components(state), params, rotation_point_depth(model, params))
    return np.asarray(kin + pot)


def rotation_matrix(quat):
    """R (body to world) from unit quaternions (..., 4) in (w, x, y, z) order, shape (..., 3, 3)."""
    quat = _unit_quaternions(quat, "quat")
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
    theta = _shaped(theta, 3, "theta (the paper's angles)")
    half = 0.5 * theta
    qx = np.stack([np.cos(half[..., 0]), np.sin(half[..., 0]), 0 * half[..., 0], 0 * half[..., 0]], -1)
    qz = np.stack([np.cos(half[..., 1]), 0 * half[..., 1], 0 * half[..., 1], np.sin(half[..., 1])], -1)
    qy = np.stack([np.cos(half[..., 2]), 0 * half[..., 2], np.sin(half[..., 2]), 0 * half[..., 2]], -1)
    return quat_multiply(quat_multiply(qy, qx), qz)


def quat_multiply(p, q):
    """Hamilton product p (x) q of quaternions (..., 4), (w, x, y, z) order."""
    p = _shaped(p, 4, "p")
    q = _shaped(q, 4, "q")
    pw, pv = p[..., 0], p[..., 1:]
    qw, qv = q[..., 0], q[..., 1:]
    w = pw * qw - np.sum(pv * qv, axis=-1)
    v = pw[..., None] * qv + qw[..., None] * pv + np.cross(pv, qv)
    return np.concatenate([w[..., None], v], axis=-1)


def world_body_rate(state):
    """World-frame angular velocity w = R Omega, shape (..., 3), rad/s."""
    state = _states(state)
    return np.einsum("...ij,...j->...i", rotation_matrix(state[..., QUAT]), state[..., BODY_RATE])


def tilt(state):
    """Angle between the body z axis and the world z axis, shape (...), rad."""
    state = _states(state)
    q = state[..., QUAT]
    nz = 1.0 - 2.0 * (q[..., 1] ** 2 + q[..., 2] ** 2)
    return np.arccos(np.clip(nz, -1.0, 1.0))


TILT_LIMIT = 0.5 * math.pi
"""rad: at this tilt the hemisphere's rim touches the ground and the rolling model ends."""


MIRROR_STATE_SIGNS = np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 1.0, 1.0, -1.0, 1.0, -1.0, 1.0, 1.0])
"""Signs of the state's entries under :func:`mirror_states` (after the legs are exchanged)."""


def mirror_states(states):
    """The mirror images of states (..., 13) in the world's x-z plane (y -> -y).

    The robot is symmetric in its own x-z plane once its legs are exchanged (leg 1's pin is
    at y = -r, leg 2's at +r, both turning about the body y axis), and so are gravity, the
    ground and the damping; so the mirror image of a motion is a motion, with each leg
    driven as its twin was. The contact point's y changes sign; the attitude R becomes
    M R M (M = diag(1, -1, 1)): the quaternion's x and z change sign; the body rate, a
    pseudovector, becomes -M w (x and z change sign); the leg angles and rates are
    exchanged, unchanged in value.
    """
    states = _shaped(states, STATE_SIZE, "states")
    out = states * MIRROR_STATE_SIGNS
    out[..., LEG_ANGLES] = states[..., LEG_ANGLES][..., ::-1]
    out[..., LEG_RATES] = states[..., LEG_RATES][..., ::-1]
    return out
