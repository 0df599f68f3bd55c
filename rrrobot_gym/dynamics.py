"""Equations of motion of the legless-robot family: the one implementation in this project.

Everything else (integrators, the Gymnasium environments, the benchmarks, the command line)
calls :func:`state_derivative` or the kernels below it. This module imports no Gymnasium:
physics is a pure function of (state, control, params). The paper's RRRobot is the family's
default member (:class:`rrrobot_gym.params.RobotParams`).

Glossary
--------
Frames
    world: z up, the ground is the plane z = 0.
    body: origin at the shell's centre, z up when the robot rests upright.
Shell
    A massless half-ellipsoid, semi-axes (a, b, c) along body x, y, z, open side up;
    A = diag(a^2, b^2, c^2). (r, r, r) is the paper's sphere.
Masses (body-frame positions)
    Mb    bottom of the shell, (0, 0, -c)
    Ms_k  leg k's pin, at its hinge H_k
    Ml_k  leg k's tip, p_k = H_k + r_k, r_k = l_k (cos phi_k u_k + sin phi_k v_k): the leg swings
          in the plane of its orthonormal u_k (phi = 0) and v_k (phi = pi/2) (``params.Leg``)
Coordinates (9 + 2L numbers a robot of L legs, layout :func:`state_fields`)
    x, y        m    the contact point on the ground
    quat        -    unit quaternion (w, x, y, z), body to world: v_world = R(quat) v_body
    leg_angles  rad  phi_1 .. phi_L
    body_rate   rad/s  Omega, the body's angular velocity in BODY coordinates
    leg_rates   rad/s  phidot_1 .. phidot_L
Speeds
    u = (Omega, phidot_1 .. phidot_L). The world-frame angular velocity is w = R Omega.
Derived symbols
    n    world up in body coordinates, n = R^T z, the third row of R; ndot = n x Omega
    s    the contact point in body coordinates: the shell's support point under the world's
         down direction, s = -A n / sqrt(n^T A n); the centre is sqrt(n^T A n) above the ground
    d    the point the body turns about: s on a plane (rolling contact), 0 for the Pivoting
         Dynamics model (a spherical joint at the centre); ``rolling`` is 1 or 0
    rho_i  p_i - d, a mass's position relative to that point
    e_k  d p_k / d phi_k = l_k (-sin phi_k u_k + cos phi_k v_k); d e_k / d phi_k = -r_k
    S, G   sum_i m_i p_i (the first moment about the centre), and G = S - M d
Constraints
    Plane: the shell's material point at the contact has zero velocity, so the centre moves as
    -Omega x s (body coordinates). The speeds above are independent, so this holds exactly by
    construction (no multipliers, no drift at velocity level). Both models move the contact
    point on the ground with the shell's rolling kinematics, xdot, ydot = the horizontal part of
    R sdot (for a sphere the paper's eq. (2)/(4): xdot = r w_y, ydot = -r w_x).

Derivation (Kane's equations with the speeds u)
    A mass moves with (body coordinates) v_i = Omega x rho_i + e_k phidot_k (tips), so its
    partial velocities are -[rho_i]x (for Omega) and e_k (for phidot_k). Its acceleration with
    u' = 0 is b_i = Omega x (Omega x rho_i) + 2 phidot_k Omega x e_k - phidot_k^2 r_k - Omega x ddot
    (ddot = sdot on a plane: the contact moves over an ellipsoid; on a sphere the last term
    cancels the first's part from d). Then M u' = sum_i J_i^T (F_i - m_i b_i) + Q, with gravity
    F_i = -m_i g n, the damping torque k Omega on the body and the leg torques tau_k on phi_k:
        Omega rows  M_w Omega' + sum_k c_k phi_k'' = k Omega - g G x n - Omega x (M_w Omega)
                        + G x (Omega x ddot) - sum_k m_k rho_k x (2 phidot_k Omega x e_k - phidot_k^2 r_k)
        leg k       c_k . Omega' + D_k phi_k'' = tau_k - m_k g n . e_k
                        - m_k ((e_k . Omega)(Omega . rho_k) - (e_k . rho_k) |Omega|^2) + m_k e_k . (Omega x ddot)
    with M_w = sum_i m_i (|rho_i|^2 1 - rho_i rho_i^T), c_k = m_k rho_k x e_k, D_k = m_k l_k^2. The
    leg block is diagonal, so a Schur complement leaves one symmetric 3x3 solve per robot, done
    by cofactors. The kernel takes both rows' gravity and Omega x ddot terms as one vector
    g n - Omega x ddot, and M_w from the second moment about d, Q = sum_i m_i rho_i rho_i^T =
    J - S d^T - d G^T (J: the second moment about the centre), as M_w = tr(Q) 1 - Q.

The kernels read and write one flat sequence ``w`` at offsets and a stride: state component j at
``w[at + j * step]``. The numpy backend passes a list of Python floats (one robot) or of (N,)
arrays (a batch) with step 1; the compiled stepper (:mod:`rrrobot_gym.compiled`) its work array
with a block of robots side by side (step: the block's size), which lets it take the robots in
SIMD lanes. A leg loop runs over the layout's tuple, whose length numba knows when it compiles.
The public array helpers at the bottom take states shaped (..., 9 + 2L).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .numerics import select, sincos
from .params import MAX_LEGS, RobotParams, check_model


class StateFields(NamedTuple):
    """Where each field of a state of ``num_legs`` legs lies (slices of the last axis)."""

    size: int
    position: slice
    quat: slice
    leg_angles: slice
    body_rate: slice
    leg_rates: slice


def state_fields(num_legs: int) -> StateFields:
    """The state layout of a robot of ``num_legs`` legs (see the glossary)."""
    legs = int(num_legs)
    return StateFields(9 + 2 * legs, slice(0, 2), slice(2, 6), slice(6, 6 + legs), slice(6 + legs, 9 + legs),
                       slice(9 + legs, 9 + 2 * legs))  # fmt: skip


_PAPER = state_fields(2)
STATE_SIZE, QUAT, LEG_ANGLES, BODY_RATE, LEG_RATES = _PAPER.size, _PAPER.quat, _PAPER.leg_angles, _PAPER.body_rate, _PAPER.leg_rates
"""The default robot's layout (two legs, 13 numbers); a robot's own: ``state_fields(params.num_legs)``."""
STATE_FIELDS = tuple((name, part.start, part.stop) for name, part in zip(
    ("x", "quat", "leg_angles", "body_rate", "leg_rates"), (slice(0, 1), QUAT, LEG_ANGLES, BODY_RATE, LEG_RATES)))
STATE_FIELDS = (("x", 0, 1), ("y", 1, 2)) + STATE_FIELDS[1:]
"""(name, start, stop) of each field in the default robot's state vector."""


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
    """The scalars of the equations of motion of one robot (or each robot's, as (N,) arrays), made
    once per configuration by :func:`constants`; the legs' geometry is the layout beside it. The
    hot functions unpack it whole (one tuple unpack is cheaper than attribute look-ups on floats)."""

    a2: float  # m^2, a^2
    b2: float  # m^2, b^2
    c2: float  # m^2, c^2
    pole: float  # m, c: the centre's height upright (the pivot's, for its energy)
    rolling: float  # 1 on a plane (the body turns about the contact point), 0 pivoting
    gravity: float  # m/s^2, g
    damping: float  # N m s/rad, k
    leg_length: float  # m, the robot's leg length (a leg's: times its layout's ratio)
    mass_tip: float  # kg, the robot's tip mass (a leg's: times its layout's ratio)
    total_mass: float  # kg, M
    weight: float  # N, M g
    jxx: float  # kg m^2, the second moment sum m x x^T about the centre of the masses fixed in the body (bottom, pins)
    jxy: float
    jxz: float
    jyy: float
    jyz: float
    jzz: float
    sx: float  # kg m, their first moment about the centre
    sy: float
    sz: float


PER_ROBOT = ("mass_bottom", "mass_pin", "mass_tip", "leg_length", "damping")
"""The fields of RobotParams :func:`constants` takes per robot ((N,) arrays) from ``values``."""


def leg_layout(params: RobotParams) -> tuple:
    """The legs' geometry as the kernels take it, one tuple a leg: (H_x, H_y, H_z, u_x, u_y, u_z, v_x,
    v_y, v_z, length / params.leg_length, tip mass / params.mass_tip) (m, unit vectors, ratios)."""
    lengths, masses = params.leg_lengths, params.leg_masses
    return tuple((*leg.hinge, *leg.zero, *leg.up, length / params.leg_length, tip / params.mass_tip)
                 for leg, length, (_, tip) in zip(params.legs, lengths, masses))  # fmt: skip


def constants(params: RobotParams, model: str, values: dict | None = None) -> Constants:
    """The constants of the equations of motion of ``params`` on ``model`` ("plane" or "pivot");
    ``values`` maps names of :data:`PER_ROBOT` to (N,) arrays, each robot's own (a leg with a
    value of its own scales it alike)."""
    get = (lambda name: getattr(params, name)) if values is None else (lambda name: values.get(name, getattr(params, name)))
    a, b, c = params.shell_axes
    mass_bottom, mass_pin, mass_tip, leg_length = get("mass_bottom"), get("mass_pin"), get("mass_tip"), get("leg_length")
    # the bottom's and the pins' second and first moments about the centre: fixed in the body
    jzz = mass_bottom * (c * c)
    jxx = jyy = jxy = jxz = jyz = sx = sy = 0.0 * mass_bottom
    sz = -mass_bottom * c
    total = mass_bottom
    for leg, (pin, tip) in zip(params.legs, params.leg_masses):
        pin_mass = mass_pin * (pin / params.mass_pin) if params.mass_pin else 0.0 * mass_pin + pin
        hx, hy, hz = leg.hinge
        jxx, jyy, jzz = jxx + pin_mass * (hx * hx), jyy + pin_mass * (hy * hy), jzz + pin_mass * (hz * hz)
        jxy, jxz, jyz = jxy + pin_mass * (hx * hy), jxz + pin_mass * (hx * hz), jyz + pin_mass * (hy * hz)
        sx, sy, sz = sx + pin_mass * hx, sy + pin_mass * hy, sz + pin_mass * hz
        total = total + (pin_mass + mass_tip * (tip / params.mass_tip))
    return Constants(
        a2=a * a, b2=b * b, c2=c * c, pole=c, rolling=1.0 if check_model(model) == "plane" else 0.0,
        gravity=params.gravity, damping=get("damping"), leg_length=leg_length, mass_tip=mass_tip, total_mass=total,
        weight=total * params.gravity, jxx=jxx, jxy=jxy, jxz=jxz, jyy=jyy, jyz=jyz, jzz=jzz, sx=sx, sy=sy, sz=sz,
    )  # fmt: skip


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


def _cross(ax, ay, az, bx, by, bz):
    """a x b."""
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


def _sqrt(x):
    """The square root of a float (math's: a ValueError for a negative one, as the float stepper's
    other math) or of an array (numpy's); both correctly rounded, as numba's."""
    return math.sqrt(x) if isinstance(x, float) else np.sqrt(x)


def _shell(n, omega, k):
    """(s, sdot, height): the contact point in body coordinates, its rate over the shell
    (ndot = n x Omega), and the centre's height above the ground, sqrt(n^T A n); on a sphere of
    radius c (A = c^2 1, n a unit vector) these are -c n, -c ndot and c, without a root or a
    division (:func:`select`: one robot's kernel, specialised, keeps only the sphere's)."""
    nx, ny, nz = n
    ox, oy, oz = omega
    a2, b2, c2, c = k[0], k[1], k[2], k[3]
    ndx, ndy, ndz = _cross(nx, ny, nz, ox, oy, oz)
    anx, any_, anz = a2 * nx, b2 * ny, c2 * nz
    q2 = nx * anx + ny * any_ + nz * anz
    height = _sqrt(q2)
    inv = 1.0 / height
    # d/dt (-A n / sqrt(n^T A n)) = (A n (A n . ndot) / (n^T A n) - A ndot) / sqrt(n^T A n)
    t = (anx * ndx + any_ * ndy + anz * ndz) * (inv * inv)
    sphere = (a2 == c2) & (b2 == c2)
    s = (select(sphere, -c * nx, -anx * inv), select(sphere, -c * ny, -any_ * inv), select(sphere, -c * nz, -anz * inv))
    sdot = (select(sphere, -c * ndx, (anx * t - a2 * ndx) * inv), select(sphere, -c * ndy, (any_ * t - b2 * ndy) * inv),
            select(sphere, -c * ndz, (anz * t - c2 * ndz) * inv))  # fmt: skip
    return s, sdot, select(sphere, c, height)


def _leg(leg, phi, k):
    """A leg's (tip mass, D = m l^2, r (tip from pin), p (tip from centre), e = dp/dphi), body
    coordinates, at angle ``phi``."""
    hx, hy, hz, ux, uy, uz, vx, vy, vz, length_ratio, mass_ratio = leg
    length, mass = k[7] * length_ratio, k[8] * mass_ratio
    sin_phi, cos_phi = sincos(phi)
    lc, ls = length * cos_phi, length * sin_phi
    rx, ry, rz = lc * ux + ls * vx, lc * uy + ls * vy, lc * uz + ls * vz
    e = (lc * vx - ls * ux, lc * vy - ls * uy, lc * vz - ls * uz)
    return mass, mass * (length * length), (rx, ry, rz), (hx + rx, hy + ry, hz + rz), e


def _moments(first, second, mass, p):
    """``first`` and ``second`` (a first moment about the centre, and a second one's upper triangle
    xx, xy, xz, yy, yz, zz) with a mass at p added: m p and m p p^T."""
    px, py, pz = p
    sx, sy, sz = first
    xx, xy, xz, yy, yz, zz = second
    return ((sx + mass * px, sy + mass * py, sz + mass * pz),
            (xx + mass * (px * px), xy + mass * (px * py), xz + mass * (px * pz), yy + mass * (py * py), yz + mass * (py * pz),
             zz + mass * (pz * pz)))  # fmt: skip


def _body(k, rolling_point, legs_first_moment, legs_second_moment):
    """(M_w, G): the inertia about the point d the body turns about (upper triangle) and the first
    moment about it, from the second moment sum m x x^T and the first moment S about the centre of
    the fixed masses (k) plus the tips' (``legs_second_moment``, ``legs_first_moment``)."""
    dx, dy, dz = rolling_point
    sx, sy, sz = k[17] + legs_first_moment[0], k[18] + legs_first_moment[1], k[19] + legs_first_moment[2]
    lxx, lxy, lxz, lyy, lyz, lzz = legs_second_moment
    total = k[9]
    # G = S - M d; the second moment about d, Q = J - S d^T - d S^T + M d d^T = J - S d^T - d G^T;
    # and M_w = tr(Q) 1 - Q
    gx, gy, gz = sx - total * dx, sy - total * dy, sz - total * dz
    qxx, qyy, qzz = k[11] + lxx - dx * (sx + gx), k[14] + lyy - dy * (sy + gy), k[16] + lzz - dz * (sz + gz)
    m_w = (
        qyy + qzz,
        sx * dy + dx * gy - (k[12] + lxy),
        sx * dz + dx * gz - (k[13] + lxz),
        qxx + qzz,
        sy * dz + dy * gz - (k[15] + lyz),
        qxx + qyy,
    )
    return m_w, (gx, gy, gz)


def _momentum_parts(w, at, step, k, layout):
    """(M_w, h) of the state at ``w[at + j * step]`` on the pivot (the body turning about the centre):
    the inertia M_w (upper triangle) and the legs' part h = sum_k c_k phidot_k of the body's angular
    momentum about the centre, p = M_w Omega + h (body coordinates). The kernel's own operations, so
    a specialised kernel shares them (:mod:`rrrobot_gym.specialise`)."""
    num_legs = len(layout)
    first, second = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    hx = hy = hz = 0.0
    for m in range(num_legs):
        mass, _, _, (px, py, pz), (ex, ey, ez) = _leg(layout[m], w[at + (6 + m) * step], k)
        first, second = _moments(first, second, mass, (px, py, pz))
        c1, c2, c3 = _cross(px, py, pz, ex, ey, ez)
        c1, c2, c3 = mass * c1, mass * c2, mass * c3
        rate = w[at + (9 + num_legs + m) * step]
        hx, hy, hz = hx + c1 * rate, hy + c2 * rate, hz + c3 * rate
    m_w, _ = _body(k, (0.0, 0.0, 0.0), first, second)
    return m_w, (hx, hy, hz)


def _rate_of_momentum(w, at, step, k, layout):
    """Omega of a pivot state whose body rows hold its angular momentum p: M_w^-1 (p - h)."""
    num_legs = len(layout)
    m_w, (hx, hy, hz) = _momentum_parts(w, at, step, k, layout)
    lx, ly, lz = w[at + (6 + num_legs) * step], w[at + (7 + num_legs) * step], w[at + (8 + num_legs) * step]
    return _sym_solve(m_w, lx - hx, ly - hy, lz - hz)


def integrates_momentum(model: str) -> bool:
    """Whether the steppers (both backends) integrate the body's angular momentum about the centre
    rather than its rate on ``model``: on the pivot, where the body turns about a fixed point, the
    momentum's rate is free of the leg torques, so the servo's fast and kinked recoil reaches the
    body only through the leg rates (docs/notes/servo_accuracy.md: the shipped policy's 5 s windows
    26.7 mm from the reference at 1/300 s with the rate, 0.6 mm with the momentum and the motor's
    rounded corners). On a plane the contact moves, and the rate stays."""
    return model == "pivot"


def to_momentum(w, at, step, k, layout):
    """The pivot state at ``w[at + j * step]``'s body rows, Omega, replaced by the body's angular
    momentum about the centre p = M_w Omega + sum_k c_k phidot_k: the variable the pivot's
    steppers integrate (:func:`derivative_kernel`'s ``momentum``)."""
    num_legs = len(layout)
    body = at + (6 + num_legs) * step
    m_w, (hx, hy, hz) = _momentum_parts(w, at, step, k, layout)
    lx, ly, lz = _sym_apply(m_w, w[body], w[body + step], w[body + 2 * step])
    w[body], w[body + step], w[body + 2 * step] = lx + hx, ly + hy, lz + hz


def from_momentum(w, at, step, k, layout):
    """:func:`to_momentum` undone: the body rows' p replaced by Omega."""
    body = at + (6 + len(layout)) * step
    ox, oy, oz = _rate_of_momentum(w, at, step, k, layout)
    w[body], w[body + step], w[body + 2 * step] = ox, oy, oz


def derivative_kernel(w, at, out, step, k: Constants, layout, drive, scratch, kinematic: bool, record, momentum=False):
    """The time derivative of the state at ``w[at + j * step]`` into ``w[out + j * step]`` (see the
    module docstring). ``w[drive + m * step]`` is leg m's torque (N m, from the shell on the leg),
    or with ``kinematic`` its prescribed acceleration (rad/s^2). ``w[scratch ...]`` holds 4 values a
    leg while this runs. With ``record`` >= 0, the step record's values go to ``w[record + j * step]``:
    each leg's torque (``kinematic``: the one its motion takes), the ground's force on the shell
    in body coordinates (pivot: the joint's; Newton's second law for the whole robot with these
    accelerations), its part along world up, its magnitude along the ground, and each leg tip's
    height above the ground (2L + 5 values).

    With ``momentum`` (the pivot only), the body rows hold the body's angular momentum about the
    centre p instead of Omega (:func:`to_momentum`), and its derivative is p' (body coordinates):
    p' = p x Omega + k Omega - g G x n, the angular momentum theorem about the fixed centre, on
    which the leg torques do not act. The pivot's steppers integrate p: the servo's recoil on the
    body, fast and kinked where the motor saturates, then enters the body only through the leg
    rates, which RK4 follows at its order (docs/notes/servo_accuracy.md)."""
    num_legs = len(layout)
    qw, qx, qy, qz = w[at + 2 * step], w[at + 3 * step], w[at + 4 * step], w[at + 5 * step]
    if momentum:
        ox, oy, oz = _rate_of_momentum(w, at, step, k, layout)
    else:
        ox, oy, oz = w[at + (6 + num_legs) * step], w[at + (7 + num_legs) * step], w[at + (8 + num_legs) * step]
    gravity, damping, rolling = k[5], k[6], k[4]
    xx, yy, zz, xy, xz, yz, wx, wy, wz = _rotation_products(qw, qx, qy, qz)
    nx, ny, nz = xz - wy, yz + wx, 1.0 - (xx + yy)
    (sx, sy, sz), (sdx, sdy, sdz), height = _shell((nx, ny, nz), (ox, oy, oz), k)
    # the point the body turns about and its rate over the shell (0 for the pivot)
    dx, dy, dz = rolling * sx, rolling * sy, rolling * sz
    ddx, ddy, ddz = rolling * sdx, rolling * sdy, rolling * sdz
    wdx, wdy, wdz = _cross(ox, oy, oz, ddx, ddy, ddz)  # Omega x ddot
    o_sq = ox * ox + oy * oy + oz * oz
    fall_x, fall_y, fall_z = gravity * nx - wdx, gravity * ny - wdy, gravity * nz - wdz  # g n - Omega x ddot
    # Pass over the legs: the tips' inertia and first moment, each leg's coupling c_k and force
    # (into the scratch rows), their Schur terms, and the tips' velocity-dependent terms.
    first, second = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # the tips' moments about the centre
    tx = ty = tz = bx = by = bz = 0.0  # sum m rho x b_leg, and sum m b_leg
    rxx = rxy = rxz = ryy = ryz = rzz = fx = fy = fz = 0.0  # sum c c^T / D, and sum c f / D
    for m in range(num_legs):
        mass, inertia, (rx, ry, rz), (px, py, pz), (ex, ey, ez) = _leg(layout[m], w[at + (6 + m) * step], k)
        rate = w[at + (9 + num_legs + m) * step]
        first, second = _moments(first, second, mass, (px, py, pz))
        hx, hy, hz = px - dx, py - dy, pz - dz  # rho
        c1, c2, c3 = _cross(hx, hy, hz, ex, ey, ez)
        c1, c2, c3 = mass * c1, mass * c2, mass * c3
        # b_leg = 2 phidot Omega x e - phidot^2 r
        gx, gy, gz = _cross(ox, oy, oz, ex, ey, ez)
        two_rate, rate_sq = 2.0 * rate, rate * rate
        blx, bly, blz = two_rate * gx - rate_sq * rx, two_rate * gy - rate_sq * ry, two_rate * gz - rate_sq * rz
        ux, uy, uz = _cross(hx, hy, hz, blx, bly, blz)
        tx, ty, tz = tx + mass * ux, ty + mass * uy, tz + mass * uz
        bx, by, bz = bx + mass * blx, by + mass * bly, bz + mass * blz
        # e . (g n - Omega x ddot + Omega x (Omega x rho)), Omega x (Omega x rho) = Omega (Omega.rho) - rho |Omega|^2
        o_h = ox * hx + oy * hy + oz * hz
        force = -mass * (ex * (fall_x + (ox * o_h - hx * o_sq)) + ey * (fall_y + (oy * o_h - hy * o_sq))
                         + ez * (fall_z + (oz * o_h - hz * o_sq)))  # fmt: skip
        w[scratch + 4 * m * step] = c1
        w[scratch + (4 * m + 1) * step] = c2
        w[scratch + (4 * m + 2) * step] = c3
        drive_m = w[drive + m * step]
        if kinematic:
            w[scratch + (4 * m + 3) * step] = force
            fx, fy, fz = fx + c1 * drive_m, fy + c2 * drive_m, fz + c3 * drive_m  # sum c phi''
        else:
            force = force + drive_m
            w[scratch + (4 * m + 3) * step] = force
            inv = 1.0 / inertia
            h1, h2, h3 = c1 * inv, c2 * inv, c3 * inv
            rxx, rxy, rxz = rxx + c1 * h1, rxy + c1 * h2, rxz + c1 * h3
            ryy, ryz, rzz = ryy + c2 * h2, ryz + c2 * h3, rzz + c3 * h3
            fx, fy, fz = fx + h1 * force, fy + h2 * force, fz + h3 * force
    m_w, (gx, gy, gz) = _body(k, (dx, dy, dz), first, second)
    # Omega rows: k Omega - G x (g n - Omega x ddot) - Omega x (M_w Omega) - sum m rho x b_leg
    lx, ly, lz = _sym_apply(m_w, ox, oy, oz)
    a1, a2, a3 = _cross(gx, gy, gz, fall_x, fall_y, fall_z)
    j1, j2, j3 = _cross(ox, oy, oz, lx, ly, lz)
    f0 = damping * ox - a1 - j1 - tx - fx
    f1 = damping * oy - a2 - j2 - ty - fy
    f2 = damping * oz - a3 - j3 - tz - fz
    if kinematic:
        od0, od1, od2 = _sym_solve(m_w, f0, f1, f2)
    else:
        m_red = (m_w[0] - rxx, m_w[1] - rxy, m_w[2] - rxz, m_w[3] - ryy, m_w[4] - ryz, m_w[5] - rzz)
        od0, od1, od2 = _sym_solve(m_red, f0, f1, f2)
    # the leg accelerations (kinematic: the torques their motion takes), and the rest of the derivative
    ax = ay = az = 0.0  # sum m e phi''
    for m in range(num_legs):
        c1, c2, c3 = w[scratch + 4 * m * step], w[scratch + (4 * m + 1) * step], w[scratch + (4 * m + 2) * step]
        force = w[scratch + (4 * m + 3) * step]
        length, mass = k[7] * layout[m][9], k[8] * layout[m][10]
        inertia = mass * (length * length)  # (as _leg's)
        c_od = c1 * od0 + c2 * od1 + c3 * od2
        if kinematic:
            accel = w[drive + m * step]
            torque = inertia * accel + c_od - force
        else:
            accel = (force - c_od) * (1.0 / inertia)  # (the first pass's 1 / D)
            torque = w[drive + m * step]
        w[out + (9 + num_legs + m) * step] = accel
        w[out + (6 + m) * step] = w[at + (9 + num_legs + m) * step]
        if record >= 0:
            _, _, _, (px, py, pz), (ex, ey, ez) = _leg(layout[m], w[at + (6 + m) * step], k)
            w[record + m * step] = torque
            w[record + (5 + num_legs + m) * step] = height + (px * nx + py * ny + pz * nz)
            ma = mass * accel
            ax, ay, az = ax + ma * ex, ay + ma * ey, az + ma * ez
    if momentum:  # p' = p x Omega + k Omega - G x g n (here g n - Omega x ddot = g n: ddot = 0)
        lx, ly, lz = w[at + (6 + num_legs) * step], w[at + (7 + num_legs) * step], w[at + (8 + num_legs) * step]
        v1, v2, v3 = _cross(lx, ly, lz, ox, oy, oz)
        w[out + (6 + num_legs) * step] = damping * ox - a1 + v1
        w[out + (7 + num_legs) * step] = damping * oy - a2 + v2
        w[out + (8 + num_legs) * step] = damping * oz - a3 + v3
    else:
        w[out + (6 + num_legs) * step] = od0
        w[out + (7 + num_legs) * step] = od1
        w[out + (8 + num_legs) * step] = od2
    # the contact point on the ground: R sdot (rows 0 and 1 of R)
    w[out] = (1.0 - yy - zz) * sdx + (xy - wz) * sdy + (xz + wy) * sdz
    w[out + step] = (xy + wz) * sdx + (1.0 - xx - zz) * sdy + (yz - wx) * sdz
    # qdot = 1/2 q (x) (0, Omega) for a body-frame rate.
    hox, hoy, hoz = 0.5 * ox, 0.5 * oy, 0.5 * oz
    w[out + 2 * step] = -(qx * hox + qy * hoy + qz * hoz)
    w[out + 3 * step] = qw * hox + qy * hoz - qz * hoy
    w[out + 4 * step] = qw * hoy + qz * hox - qx * hoz
    w[out + 5 * step] = qw * hoz + qx * hoy - qy * hox
    if record >= 0:
        # Newton: F = Omega' x G + Omega x (Omega x G) - M Omega x ddot + sum m (e phi'' + b_leg) + M g n
        total, weight = k[9], k[10]
        p1, p2, p3 = _cross(od0, od1, od2, gx, gy, gz)
        q1, q2, q3 = _cross(ox, oy, oz, gx, gy, gz)
        r1, r2, r3 = _cross(ox, oy, oz, q1, q2, q3)
        force_x = p1 + r1 - total * wdx + ax + bx + weight * nx
        force_y = p2 + r2 - total * wdy + ay + by + weight * ny
        force_z = p3 + r3 - total * wdz + az + bz + weight * nz
        normal = force_x * nx + force_y * ny + force_z * nz
        w[record + num_legs * step] = force_x
        w[record + (num_legs + 1) * step] = force_y
        w[record + (num_legs + 2) * step] = force_z
        w[record + (num_legs + 3) * step] = normal
        w[record + (num_legs + 4) * step] = tangential_force(force_x, force_y, force_z, normal)


def tangential_force(fx, fy, fz, normal):
    """The part of a force (fx, fy, fz) along the ground, sqrt(|F|^2 - normal^2), given its part
    ``normal`` along world up (0 where rounding makes the square negative); floats or arrays.
    What the step record holds (:func:`derivative_kernel`), and what a record made by hand is given."""
    along_sq = fx * fx + fy * fy + fz * fz - normal * normal
    if isinstance(along_sq, float):
        return math.sqrt(along_sq) if not along_sq < 0.0 else 0.0
    return np.sqrt(np.maximum(along_sq, 0.0))


KERNELS = (_rotation_products, _sym_cofactors, _sym_apply, _sym_solve, _cross, _sqrt, _shell, _leg, _moments, _body, tangential_force,
           _momentum_parts, _rate_of_momentum, derivative_kernel, to_momentum, from_momentum)  # fmt: skip
"""The functions :mod:`rrrobot_gym.compiled` compiles (each calls only the ones before it, and
:data:`rrrobot_gym.numerics.KERNELS`)."""


def kernel_work(num_legs: int):
    """(size, at, out, drive, scratch, record) of a work list for :func:`derivative_kernel` with step 1:
    the state, the derivative, the legs' drive, the scratch and the record, one after another."""
    n = 9 + 2 * num_legs
    return 2 * n + 7 * num_legs + 5, 0, n, 2 * n, 2 * n + num_legs, 2 * n + 5 * num_legs


def derivative_function(params: RobotParams, model: str, kinematic: bool = False, record: bool = False, k=None,
                        momentum: bool = False):
    """f(c, leg_drive): :func:`state_derivative` of ``params`` on ``model`` with its constants made
    once (the numpy stepper's and the tools' fast path); ``k``: constants of its own (each robot's);
    ``momentum`` (the pivot's steppers): the body rows hold p, :func:`derivative_kernel`'s."""
    k, layout = constants(params, model) if k is None else k, leg_layout(params)
    size, at, out, drive, scratch, rec = kernel_work(len(layout))
    legs = len(layout)

    def f(c, leg_drive):
        w = [*c, *([0.0] * (size - out))]
        w[drive : drive + legs] = leg_drive
        derivative_kernel(w, at, out, 1, k, layout, drive, scratch, kinematic, rec if record else -1, momentum)
        return (w[out:drive], w[rec:]) if record else w[out:drive]

    return f


def state_derivative(c, leg_drive, params: RobotParams, model: str, kinematic: bool = False, record: bool = False):
    """Time derivative of a state, in components.

    Args:
        c: the 9 + 2L state components (layout :func:`state_fields`), floats or (N,) arrays.
        leg_drive: L numbers or (N,) arrays: the joint torques from the shell on each leg (N m), or
            with ``kinematic`` the legs' prescribed accelerations (rad/s^2).
        params: the robot; model: "plane" or "pivot".
        record: also return the step record's values (:func:`derivative_kernel`).

    Returns:
        The derivative components, in the same layout (and the record's, if asked).
    """
    return derivative_function(params, model, kinematic, record)(c, leg_drive)


def energy_components(c, params: RobotParams, model: str):
    """Kinetic and potential energy (J) of state components ``c``: the centre at its height over
    the ground on a plane, at the shell's upright height c pivoting (a sphere: r in both)."""
    k, layout = constants(params, model), leg_layout(params)
    num_legs = len(layout)
    mass_w, couplings, inertias, first_moment, height = _configuration(c, k, layout)
    ox, oy, oz = c[6 + num_legs], c[7 + num_legs], c[8 + num_legs]
    mo = mass_w
    kinetic = 0.5 * (
        mo[0] * ox * ox + mo[3] * oy * oy + mo[5] * oz * oz
        + 2.0 * (mo[1] * ox * oy + mo[2] * ox * oz + mo[4] * oy * oz)
    )  # fmt: skip
    for m in range(num_legs):
        rate = c[9 + num_legs + m]
        cx, cy, cz = couplings[m]
        kinetic = kinetic + rate * (cx * ox + cy * oy + cz * oz) + 0.5 * inertias[m] * rate * rate
    n = _up_vector(c[2], c[3], c[4], c[5])
    centre = height if k.rolling else k.pole
    potential = k.gravity * (k.total_mass * centre + first_moment[0] * n[0] + first_moment[1] * n[1] + first_moment[2] * n[2])
    return kinetic, potential


def _up_vector(qw, qx, qy, qz):
    """n = R^T z (world up in body coordinates), the third row of R."""
    tqx, tqy, tqz = qx + qx, qy + qy, qz + qz
    return qx * tqz - qw * tqy, qy * tqz + qw * tqx, 1.0 - (qx * tqx + qy * tqy)


def _configuration(c, k, layout):
    """(M_w, each leg's c_k, each leg's D_k, S (about the centre), the centre's height) of state
    components ``c``: the mass matrix's parts, for the energy and :func:`mass_matrix`."""
    num_legs = len(layout)
    n = _up_vector(c[2], c[3], c[4], c[5])
    omega = (c[6 + num_legs], c[7 + num_legs], c[8 + num_legs])
    s, _, height = _shell(n, omega, k)
    d = (k.rolling * s[0], k.rolling * s[1], k.rolling * s[2])
    first, second = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    couplings, inertias = [], []
    for m in range(num_legs):
        mass, leg_inertia, _, (px, py, pz), e = _leg(layout[m], c[6 + m], k)
        first, second = _moments(first, second, mass, (px, py, pz))
        cx, cy, cz = _cross(px - d[0], py - d[1], pz - d[2], *e)
        couplings.append((mass * cx, mass * cy, mass * cz))
        inertias.append(leg_inertia)
    mass_w, _ = _body(k, d, first, second)
    centre_moment = (k.sx + first[0], k.sy + first[1], k.sz + first[2])
    return mass_w, couplings, inertias, centre_moment, height


# ---------------------------------------------------------------------------
# Array helpers: states shaped (..., 9 + 2L), leading axes are batch axes.


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


def legs_of(size: int, what: str = "state") -> int:
    """The number of legs of a state of ``size`` numbers (9 + 2L), or a ValueError naming ``what``."""
    legs = (int(size) - 9) // 2
    if 9 + 2 * legs != size or not 1 <= legs <= MAX_LEGS:
        raise ValueError(f"{what} must have 9 + 2L entries on its last axis (L = 1 to {MAX_LEGS} legs; 13 for the "
                         f"paper's robot), got {size}")
    return legs


def _states(state, what: str = "state", num_legs: int | None = None) -> np.ndarray:
    """States (..., 9 + 2L), their quaternions checked (:func:`_unit_quaternions`): L = ``num_legs``,
    or any the last axis gives."""
    if num_legs is None:
        state = np.asarray(state, dtype=float) if not isinstance(state, np.ndarray) else state
        num_legs = legs_of(state.shape[-1], what) if state.ndim else 2
    state = _shaped(state, 9 + 2 * num_legs, what)
    _unit_quaternions(state[..., QUAT], f"{what}'s entries 2:6")
    return state


def _components(state):
    """View a (..., 9 + 2L) state as a list of its component arrays."""
    return [state[..., i] for i in range(state.shape[-1])]


def mass_matrix(state, params: RobotParams, model: str):
    """The generalised mass matrix for the speeds (Omega, phidot_1 .. phidot_L), shape (..., 3 + L, 3 + L)."""
    state = _states(state, num_legs=params.num_legs)
    k, layout = constants(params, model), leg_layout(params)
    mass_w, couplings, inertias, _, _ = _configuration(_components(state), k, layout)
    size = 3 + params.num_legs
    out = np.zeros(state.shape[:-1] + (size, size))
    idx = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
    for (i, j), v in zip(idx, mass_w):
        out[..., i, j] = v
        out[..., j, i] = v
    for m, (coupling, inertia) in enumerate(zip(couplings, inertias)):
        for i in range(3):
            out[..., i, 3 + m] = coupling[i]
            out[..., 3 + m, i] = coupling[i]
        out[..., 3 + m, 3 + m] = inertia
    return out


def total_energy(state, params: RobotParams, model: str):
    """Kinetic plus potential energy (J) of each robot, shape (...)."""
    state = _states(state, num_legs=params.num_legs)
    kin, pot = energy_components(_components(state), params, model)
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
    """World-frame angular velocity w = R Omega, shape (..., 3), rad/s, of states (..., 9 + 2L)."""
    state = _states(state)
    rate = state_fields(legs_of(state.shape[-1])).body_rate
    return np.einsum("...ij,...j->...i", rotation_matrix(state[..., QUAT]), state[..., rate])


def tilt(state):
    """Angle between the body z axis and the world z axis, shape (...), rad."""
    state = _states(state)
    q = state[..., QUAT]
    nz = 1.0 - 2.0 * (q[..., 1] ** 2 + q[..., 2] ** 2)
    return np.arccos(np.clip(nz, -1.0, 1.0))


TILT_LIMIT = 0.5 * math.pi
"""rad: at this tilt the hemisphere's rim touches the ground and the rolling model ends."""


def mirror_legs(params: RobotParams | None = None):
    """How the mirror image in the body's x-z plane (y -> -y) maps the robot's legs onto each other:
    a tuple, for each leg k, of (the leg j its mirror image is, whether it is flipped), or None where
    the robot has no such symmetry. Leg j is leg k's image if its hinge and swing plane are leg
    k's mirrored (and its length and masses equal): ``zero`` mirrored to j's (phi_j = phi_k) or to
    its opposite (flipped: phi_j = pi - phi_k), ``up`` mirrored to j's. The shell, the bottom mass,
    gravity and the ground are symmetric already. The paper's robot: ((1, False), (0, False))."""
    params = RobotParams() if params is None else params
    mirrored = [((h[0], -h[1], h[2]), (u[0], -u[1], u[2]), (v[0], -v[1], v[2]))
                for h, u, v in ((leg.hinge, leg.zero, leg.up) for leg in params.legs)]  # fmt: skip
    sizes = list(zip(params.leg_lengths, params.leg_masses))

    def close(a, b):
        return all(abs(x - y) <= 1e-12 * (1.0 + abs(x)) for x, y in zip(a, b))

    out = []
    for k, (hinge, zero, up) in enumerate(mirrored):
        for j, leg in enumerate(params.legs):
            if sizes[j] != sizes[k] or not (close(leg.hinge, hinge) and close(leg.up, up)):
                continue
            if close(leg.zero, zero):
                out.append((j, False))
                break
            if close(leg.zero, tuple(-x for x in zero)):
                out.append((j, True))
                break
        else:
            return None
    return tuple(out)


def mirror_states(states, params: RobotParams | None = None):
    """The mirror images of states (..., 9 + 2L) in the world's x-z plane (y -> -y), for a robot with
    that symmetry (:func:`mirror_legs`; the paper's by default).

    Gravity, the ground and the damping are symmetric, and so is the robot once its legs are
    mapped onto their images; so the mirror image of a motion is a motion, with each leg driven
    as its image was. The contact point's y changes sign; the attitude R becomes M R M
    (M = diag(1, -1, 1)): the quaternion's x and z change sign; the body rate, a pseudovector,
    becomes -M w (x and z change sign); each leg takes its image's angle and rate (a flipped one:
    pi - angle, -rate).
    """
    params = RobotParams() if params is None else params
    legs = mirror_legs(params)
    if legs is None:
        raise ValueError(f"this robot has no mirror symmetry in its x-z plane (its legs are not placed in mirrored "
                         f"pairs): {params.legs}")
    fields = state_fields(params.num_legs)
    states = _shaped(states, fields.size, "states")
    out = states.copy()
    out[..., 1] = -states[..., 1]
    out[..., 3], out[..., 5] = -states[..., 3], -states[..., 5]
    rate = fields.body_rate.start
    out[..., rate], out[..., rate + 2] = -states[..., rate], -states[..., rate + 2]
    angle, leg_rate = fields.leg_angles.start, fields.leg_rates.start
    for k, (j, flipped) in enumerate(legs):
        out[..., angle + j] = math.pi - states[..., angle + k] if flipped else states[..., angle + k]
        out[..., leg_rate + j] = -states[..., leg_rate + k] if flipped else states[..., leg_rate + k]
    return out
