"""Test oracle: the equations of motion of the legless-robot family, derived by sympy.

The family (1 to 6 legs, half-ellipsoid shells) is the paper's RRRobot generalised; see the
glossary below. This module derives its equations with ``sympy.physics.mechanics.KanesMethod``:
sympy forms every velocity and acceleration by differentiating positions, and on a plane it
eliminates the rolling constraint (three dependent speeds, the centre's velocity) itself. It
shares no code with ``rrrobot_gym`` (whose equations are written out by hand) and is meant only
to be compared with it in the tests.

One derivation per (number of legs, model) serves every geometry: the shell's semi-axes, the
masses and each leg's hinge, swing plane and length are symbols, given numbers only when the
lambdified functions are called. Each derivation is made once a process (``functools.lru_cache``);
:func:`derivation_seconds` says how long it took.

Glossary
--------
Frames
    N  world: z up, the ground is the plane z = 0.
    B  body: origin at the shell's centre O, z up when the robot rests upright. R (body to world)
       is the unit quaternion q's rotation matrix.
    L_k  leg k's frame, turning relative to B about the hinge axis w_k = u_k x v_k at phidot_k.
Shell
    A massless half-ellipsoid, semi-axes (a, b, c) along B's x, y, z, open side up;
    A = diag(a^2, b^2, c^2). (r, r, r) is the paper's sphere.
Point masses (positions in B, relative to O)
    bottom  Mb    (0, 0, -c)
    pin k   Ms_k  H_k
    tip k   Ml_k  T_k = H_k + l_k (cos phi_k u_k + sin phi_k v_k); u_k, v_k orthonormal,
                  phi = 0 along u, pi/2 along v.
Coordinates of the derivation
    n = (n_x, n_y, n_z)  world up in B, n = R^T z. Gravity and a flat ground do not care about
                         heading or position, so the dynamics depend on the attitude only
                         through n; its kinematic equation is n' = n x Omega.
    phi_k                leg angles, phi_k' = phidot_k.
Speeds
    independent  Omega = (Omega_x, Omega_y, Omega_z), the body's angular velocity in B; phidot_k.
    dependent (plane only)  v = (v_x, v_y, v_z), O's velocity in B.
Constraints
    plane  rolling without slip: the shell's material point at the contact has zero velocity,
           v + Omega x s(n) = 0, with s(n) = -A n / sqrt(n^T A n) the support point under the
           world's down direction (the contact, in B). The centre's height is sqrt(n^T A n).
    pivot  the Pivoting Dynamics model: O is held fixed (a spherical joint at the centre).
    Both   the contact point (x, y) on the ground moves as d/dt (x, y) = the horizontal part of
           R s', with s' = ds(n(t))/dt (for a sphere: xdot = r w_y, ydot = -r w_x).
Loads
    gravity -m g n on every point mass; the damping torque k Omega on B; the joint torque tau_k
    w_k on L_k and -tau_k w_k on B (so tau_k is the generalised force on phi_k: a positive tau
    drives phi_k up). The legs are massless rods: L_k carries only its tip's particle.
Energy
    kinetic: sum over the point masses of m |v|^2 / 2.
    potential: g (M z_c + sum_i m_i p_i . n) on the plane, with z_c = sqrt(n^T A n) and M the
    total mass; g (M c + sum_i m_i p_i . n) for the pivot (the centre held at its resting height
    c; for a sphere both are today's "centre at height r").
State (9 + 2L numbers, ``rrrobot_gym``'s layout for L = 2)
    [x, y, qw, qx, qy, qz, phi_1..phi_L, Omega_x, Omega_y, Omega_z, phidot_1..phidot_L]
Derivative
    [xdot, ydot, qdot = q (x) (0, Omega) / 2, phidot (L), Omegadot (3), phiddot (L)].

A leg is a dict {"hinge": H (3,), "u": (3,), "v": (3,), "length": l, "mass_pin": Ms,
"mass_tip": Ml} (m, kg); :func:`default_legs` gives the family's default placement.
"""

from __future__ import annotations

import functools
import math
import time
from typing import Callable, NamedTuple, Sequence

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me
from scipy.integrate import solve_ivp

MODELS = ("plane", "pivot")
MAX_LEGS = 6
LEG_KEYS = ("hinge", "u", "v", "length", "mass_pin", "mass_tip")


# ---------------------------------------------------------------------------
# The family's description
# ---------------------------------------------------------------------------


def _cos_sin_degrees(angle_deg: float) -> tuple[float, float]:
    """cos and sin of an angle in degrees, exact at multiples of 90 degrees."""
    quarter = angle_deg / 90.0
    if quarter == round(quarter):
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[int(round(quarter)) % 4]
    rad = math.radians(angle_deg)
    return math.cos(rad), math.sin(rad)


def default_legs(num_legs: int, shell_axes, length: float = 0.1, mass_pin: float = 0.053, mass_tip: float = 0.057):
    """The family's default placement of ``num_legs`` legs on the rim of a shell of semi-axes
    ``shell_axes`` = (a, b, c): hinge k (k = 1..L) at theta_k = -90 deg + (k - 1) 360 deg / L,
    H_k = (a cos theta_k, b sin theta_k, 0); u_k the unit rim tangent, signed so that u_x > 0 (or
    u_y > 0 where u_x = 0); v_k = (0, 0, 1). Two legs on (r, r, r) are the paper's robot."""
    if not 1 <= int(num_legs) <= MAX_LEGS:
        raise ValueError(f"num_legs must be 1 to {MAX_LEGS}, got {num_legs!r}")
    a, b, _ = (float(x) for x in shell_axes)
    legs = []
    for k in range(1, int(num_legs) + 1):
        cos_t, sin_t = _cos_sin_degrees(-90.0 + (k - 1) * 360.0 / num_legs)
        tangent = np.array([-a * sin_t, b * cos_t, 0.0])
        tangent /= np.linalg.norm(tangent)
        if tangent[0] < 0.0 or (tangent[0] == 0.0 and tangent[1] < 0.0):
            tangent = -tangent
        legs.append({
            "hinge": np.array([a * cos_t, b * sin_t, 0.0]),
            "u": tangent + 0.0,  # (+ 0.0: no negative zeros)
            "v": np.array([0.0, 0.0, 1.0]),
            "length": float(length),
            "mass_pin": float(mass_pin),
            "mass_tip": float(mass_tip),
        })  # fmt: skip
    return legs


def _parameter_values(shell_axes, legs, mass_bottom, gravity, damping) -> list:
    """Numbers in :func:`_derive`'s parameter order: a, b, c, Mb, g, k, then per leg
    H (3), u (3), v (3), l, Ms, Ml."""
    axes = [float(x) for x in shell_axes]
    if len(axes) != 3 or min(axes) <= 0.0:
        raise ValueError(f"shell_axes must be three positive numbers, got {shell_axes!r}")
    values = [*axes, float(mass_bottom), float(gravity), float(damping)]
    for i, leg in enumerate(legs):
        missing = set(LEG_KEYS) - set(leg)
        if missing:
            raise ValueError(f"leg {i + 1} lacks {sorted(missing)}")
        u, v = np.asarray(leg["u"], dtype=float), np.asarray(leg["v"], dtype=float)
        if abs(u @ u - 1.0) > 1e-12 or abs(v @ v - 1.0) > 1e-12 or abs(u @ v) > 1e-12:
            raise ValueError(f"leg {i + 1}'s u and v must be orthonormal, got {u} and {v}")
        values += [*np.asarray(leg["hinge"], dtype=float).reshape(3), *u, *v]
        values += [float(leg["length"]), float(leg["mass_pin"]), float(leg["mass_tip"])]
    return values


# ---------------------------------------------------------------------------
# The derivation
# ---------------------------------------------------------------------------


class _Oracle(NamedTuple):
    """One (L, model)'s lambdified terms. Each takes (n (3), phi (L), Omega (3), phidot (L),
    parameters) as flat positional numbers (floats, or equal-shaped arrays for a batch);
    ``dynamics`` also the torques (L) after phidot, ``ground`` the accelerations after them."""

    num_legs: int
    model: str
    dynamics: dict  # "scalar"/"array" -> f(...) -> [Kane's mass matrix (row-major), forcing]
    contact_rate: dict  # -> s' (3), body frame
    support: dict  # -> s (3), body frame
    energy: dict  # -> [kinetic, potential]
    ground: dict  # -> the ground's (pivot: the joint's) force on the robot, body frame (3)
    num_speeds: int  # speeds in Kane's system: 3 + L, and the 3 dependent ones on a plane
    seconds: float  # derivation and lambdify, s


def _lambdified(args, outputs) -> dict:
    """``outputs`` lambdified twice, their common subexpressions found once: on floats (``math``'s
    functions, about three times faster than numpy's on one state) and on arrays."""
    common = sp.cse(outputs)
    return {
        "scalar": sp.lambdify(args, outputs, modules="math", cse=lambda _: common),
        "array": sp.lambdify(args, outputs, modules="numpy", cse=lambda _: common),
    }


@functools.lru_cache(maxsize=None)
def _derive(num_legs: int, model: str) -> _Oracle:
    """Kane's equations of the family member with ``num_legs`` legs in ``model``, every geometric
    and mass parameter a symbol."""
    if model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
    if not 1 <= num_legs <= MAX_LEGS:
        raise ValueError(f"num_legs must be 1 to {MAX_LEGS}, got {num_legs!r}")
    start = time.perf_counter()
    L = num_legs
    a, b, c, mass_bottom, g, damping = sp.symbols("a b c M_b g k", real=True)
    params = [a, b, c, mass_bottom, g, damping]
    n = me.dynamicsymbols("n_x n_y n_z")
    phi = me.dynamicsymbols(f"phi_1:{L + 1}")
    omega = me.dynamicsymbols("Omega_x Omega_y Omega_z")
    phidot = me.dynamicsymbols(f"phidot_1:{L + 1}")
    tau = sp.symbols(f"tau_1:{L + 1}", real=True)

    world = me.ReferenceFrame("N")
    body = me.ReferenceFrame("B")
    body.set_ang_vel(world, omega[0] * body.x + omega[1] * body.y + omega[2] * body.z)

    def in_body(xyz):
        return xyz[0] * body.x + xyz[1] * body.y + xyz[2] * body.z

    up = in_body(n)
    centre = me.Point("O")
    centre.set_vel(body, 0)
    particles, loads = [], [(body, damping * body.ang_vel_in(world))]
    positions = []  # (mass, position relative to O) for the potential

    def point_mass(name, position, mass):
        point = centre.locatenew(name, position)
        particles.append(me.Particle(name, point, mass))
        loads.append((point, -mass * g * up))
        positions.append((mass, position))
        return point

    fixed_points = [point_mass("bottom", -c * body.z, mass_bottom)]
    tips = []
    # n' = n x Omega: n is fixed in the world, so in B it turns backwards.
    kinematics = list(sp.Matrix(n).diff(me.dynamicsymbols._t) - sp.Matrix(n).cross(sp.Matrix(omega)))
    for k in range(L):
        hinge = in_body(sp.symbols(f"H_{k + 1}x H_{k + 1}y H_{k + 1}z", real=True))
        u_vec = in_body(sp.symbols(f"u_{k + 1}x u_{k + 1}y u_{k + 1}z", real=True))
        v_vec = in_body(sp.symbols(f"v_{k + 1}x v_{k + 1}y v_{k + 1}z", real=True))
        length, mass_pin, mass_tip = sp.symbols(f"l_{k + 1} M_s{k + 1} M_l{k + 1}", real=True)
        params += [*hinge.to_matrix(body), *u_vec.to_matrix(body), *v_vec.to_matrix(body), length, mass_pin, mass_tip]
        fixed_points.append(point_mass(f"pin{k + 1}", hinge, mass_pin))
        tips.append(point_mass(f"tip{k + 1}", hinge + length * (sp.cos(phi[k]) * u_vec + sp.sin(phi[k]) * v_vec), mass_tip))
        axis = u_vec.cross(v_vec)
        leg_frame = me.ReferenceFrame(f"L{k + 1}")
        leg_frame.set_ang_vel(world, body.ang_vel_in(world) + phidot[k] * axis)
        loads += [(leg_frame, tau[k] * axis), (body, -tau[k] * axis)]
        kinematics.append(phi[k].diff(me.dynamicsymbols._t) - phidot[k])

    sigma = sp.sqrt(a**2 * n[0] ** 2 + b**2 * n[1] ** 2 + c**2 * n[2] ** 2)  # the centre's height on a plane
    support = -(a**2 * n[0] * body.x + b**2 * n[1] * body.y + c**2 * n[2] * body.z) / sigma
    coordinates, speeds = [*n, *phi], [*omega, *phidot]
    if model == "plane":
        v_centre = me.dynamicsymbols("v_x v_y v_z")
        centre.set_vel(world, in_body(v_centre))
        rolling = (centre.vel(world) + body.ang_vel_in(world).cross(support)).to_matrix(body)
        kane = me.KanesMethod(world, coordinates, speeds, kd_eqs=kinematics,
                              u_dependent=v_centre, velocity_constraints=list(rolling))  # fmt: skip
        # v in terms of the independent speeds, for the energy and the forcing
        v_of_omega = dict(zip(v_centre, (-body.ang_vel_in(world).cross(support)).to_matrix(body)))
        potential_height = sigma
    else:
        v_centre = []
        centre.set_vel(world, 0)
        kane = me.KanesMethod(world, coordinates, speeds, kd_eqs=kinematics)
        v_of_omega = {}
        potential_height = c
    for point in fixed_points:
        point.v2pt_theory(centre, world, body)
    for point in tips:
        point.v1pt_theory(centre, world, body)  # (its velocity in B, from its position's derivative)
    kane.kanes_equations(particles, loads)

    # To plain symbols for lambdify: first the time derivatives (from the kinematic equations),
    # then the dependent speeds, then the functions of time themselves.
    t = me.dynamicsymbols._t
    qdot_map = {n[0].diff(t): n[1] * omega[2] - n[2] * omega[1], n[1].diff(t): n[2] * omega[0] - n[0] * omega[2],
                n[2].diff(t): n[0] * omega[1] - n[1] * omega[0], **{p.diff(t): pd for p, pd in zip(phi, phidot)}}  # fmt: skip
    accel = sp.symbols(f"Omegadot_x Omegadot_y Omegadot_z phiddot_1:{L + 1}", real=True)
    udot_map = {s.diff(t): a_ for s, a_ in zip(speeds, accel)}
    # (a tip's velocity in B comes from its position's derivative, so its acceleration holds phi'')
    udot_map.update({p.diff(t, 2): a_ for p, a_ in zip(phi, accel[3:])})
    plain = {f: sp.Symbol(f.func.__name__, real=True) for f in [*n, *phi, *omega, *phidot]}

    # v' = d/dt (-Omega x s(n)), put in before v itself
    v_dot = {v.diff(t): me.msubs(sp.diff(e, t), qdot_map, udot_map) for v, e in v_of_omega.items()}

    def to_plain(expr):
        expr = me.msubs(expr, qdot_map)
        if v_of_omega:
            expr = me.msubs(me.msubs(expr, v_dot), v_of_omega)
        return me.msubs(me.msubs(expr, udot_map), plain)

    total_mass = sum(m for m, _ in positions)
    kinetic = to_plain(sum(p.kinetic_energy(world) for p in particles))
    potential = g * (total_mass * potential_height + sum(m * pos.dot(up) for m, pos in positions))
    ground = sum((p.mass * p.point.acc(world) for p in particles), me.Vector(0)) + total_mass * g * up
    mass_matrix, forcing = kane.mass_matrix, kane.forcing
    # Kane's system over all its speeds' rates: on a plane its last 3 rows are the rolling
    # constraint differentiated, and its last 3 columns the rates of v (solved for, not used).
    num_speeds = mass_matrix.shape[0]
    dyn_outputs = [to_plain(e) for e in [*mass_matrix, *forcing]]
    state_args = [plain[f] for f in [*n, *phi, *omega, *phidot]]
    oracle = _Oracle(
        num_legs=L,
        model=model,
        dynamics=_lambdified([*state_args, *tau, *params], dyn_outputs),
        contact_rate=_lambdified([*state_args, *params], [to_plain(e) for e in support.dt(body).to_matrix(body)]),
        support=_lambdified([*state_args, *params], [to_plain(e) for e in support.to_matrix(body)]),
        energy=_lambdified([*state_args, *params], [kinetic, to_plain(potential)]),
        ground=_lambdified([*state_args, *accel, *params], [to_plain(e) for e in ground.to_matrix(body)]),
        num_speeds=num_speeds,
        seconds=0.0,
    )
    return oracle._replace(seconds=time.perf_counter() - start)


def derivation_seconds(num_legs: int, model: str) -> float:
    """s this process took to derive and lambdify (L, model)'s equations (derived now if not yet)."""
    return _derive(int(num_legs), model).seconds


# ---------------------------------------------------------------------------
# Numbers
# ---------------------------------------------------------------------------


def _rotation(quat: np.ndarray) -> np.ndarray:
    """R (body to world), (..., 3, 3), of quaternions (..., 4) in (w, x, y, z) order, each
    scaled to unit length first."""
    q = quat / np.linalg.norm(quat, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)  # fmt: skip


def _quaternion_rate(quat: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """q (x) (0, Omega) / 2 for a body-frame rate Omega."""
    w, v = quat[..., :1], quat[..., 1:]
    return 0.5 * np.concatenate([-np.sum(v * omega, axis=-1, keepdims=True), w * omega + np.cross(v, omega)], axis=-1)


class _Prepared(NamedTuple):
    oracle: _Oracle
    state: np.ndarray  # (..., 9 + 2L)
    rotation: np.ndarray  # (..., 3, 3)
    args: list  # n, phi, Omega, phidot: floats (one state) or arrays (a batch)
    params: list
    batch: bool


def _prepare(state, *, shell_axes, legs, mass_bottom, gravity, damping, model) -> _Prepared:
    num_legs = len(legs)
    oracle = _derive(num_legs, model)
    state = np.asarray(state, dtype=float)
    if state.shape[-1:] != (9 + 2 * num_legs,):
        raise ValueError(f"a state of {num_legs} legs has {9 + 2 * num_legs} numbers, got shape {state.shape}")
    rotation = _rotation(state[..., 2:6])
    n = rotation[..., 2, :]  # R^T z: the third row of R
    columns = [n[..., 0], n[..., 1], n[..., 2]] + [state[..., i] for i in range(6, 6 + num_legs)]
    columns += [state[..., i] for i in range(6 + num_legs, 9 + 2 * num_legs)]
    batch = state.ndim > 1
    if not batch:
        columns = [float(x) for x in columns]
    params = _parameter_values(shell_axes, legs, mass_bottom, gravity, damping)
    return _Prepared(oracle, state, rotation, columns, params, batch)


def _call(fn: dict, prepared: _Prepared, *extra) -> np.ndarray:
    """A lambdified function's outputs, stacked on a last axis: (k,) or (..., k)."""
    if not prepared.batch:
        return np.array(fn["scalar"](*prepared.args, *extra, *prepared.params), dtype=float)
    shape = prepared.state.shape[:-1]
    out = fn["array"](*prepared.args, *extra, *prepared.params)
    return np.stack([np.broadcast_to(np.asarray(x, dtype=float), shape) for x in out], axis=-1)


def _torques(leg_torques, prepared: _Prepared) -> list:
    num_legs = prepared.oracle.num_legs
    tau = np.broadcast_to(np.asarray(leg_torques, dtype=float), prepared.state.shape[:-1] + (num_legs,))
    return [float(x) for x in tau] if not prepared.batch else [tau[..., k] for k in range(num_legs)]


def _derivative_one(oracle: _Oracle, params: list, state: np.ndarray, leg_torques) -> np.ndarray:
    """:func:`oracle_derivative` of one state (9 + 2L,), in floats: the integrator's path."""
    L, size = oracle.num_legs, oracle.num_speeds
    c = state.tolist()
    qw, qx, qy, qz = c[2:6]
    two = 2.0 / (qw * qw + qx * qx + qy * qy + qz * qz)  # (R of q / |q|)
    xx, yy, zz, xy, xz, yz = qx * qx * two, qy * qy * two, qz * qz * two, qx * qy * two, qx * qz * two, qy * qz * two
    wx, wy, wz = qw * qx * two, qw * qy * two, qw * qz * two
    row_x, row_y = (1.0 - yy - zz, xy - wz, xz + wy), (xy + wz, 1.0 - xx - zz, yz - wx)
    n = (xz - wy, yz + wx, 1.0 - xx - yy)  # R^T z, the third row of R
    args = [*n, *c[6 : 6 + L], *c[6 + L :]]
    values = oracle.dynamics["scalar"](*args, *[float(x) for x in leg_torques], *params)
    mass_matrix = np.array(values[: size * size]).reshape(size, size)
    rates = np.linalg.solve(mass_matrix, np.array(values[size * size :]))  # (Omega', phi'', and v' on a plane)
    s_rate = oracle.contact_rate["scalar"](*args, *params)
    ox, oy, oz = c[6 + L : 9 + L]
    return np.array([
        row_x[0] * s_rate[0] + row_x[1] * s_rate[1] + row_x[2] * s_rate[2],
        row_y[0] * s_rate[0] + row_y[1] * s_rate[1] + row_y[2] * s_rate[2],
        0.5 * -(qx * ox + qy * oy + qz * oz),
        0.5 * (qw * ox + qy * oz - qz * oy),
        0.5 * (qw * oy + qz * ox - qx * oz),
        0.5 * (qw * oz + qx * oy - qy * ox),
        *c[9 + L :],
        *rates[: 3 + L].tolist(),
    ])  # fmt: skip


def oracle_derivative(state, leg_torques, *, shell_axes, legs, mass_bottom, gravity=9.81, damping=-0.01, model):
    """The time derivative of ``state`` (9 + 2L,) or a batch (..., 9 + 2L) of them.

    ``leg_torques``: (L,) or (..., L), N m, the joint torque on each leg (positive drives phi up).
    ``shell_axes``: (a, b, c), m. ``legs``: L dicts (module docstring; :func:`default_legs`).
    ``mass_bottom``: kg; ``gravity``: m/s^2; ``damping``: k, N m s/rad (torque k Omega on the
    shell); ``model``: "plane" or "pivot". Returns the derivative in the state's layout.
    """
    p = _prepare(state, shell_axes=shell_axes, legs=legs, mass_bottom=mass_bottom, gravity=gravity,
                 damping=damping, model=model)  # fmt: skip
    if not p.batch:
        return _derivative_one(p.oracle, p.params, p.state, _torques(leg_torques, p))
    L, size = p.oracle.num_legs, p.oracle.num_speeds
    values = _call(p.oracle.dynamics, p, *_torques(leg_torques, p))
    mass_matrix = values[..., : size * size].reshape(values.shape[:-1] + (size, size))
    forcing = values[..., size * size :]
    rates = np.linalg.solve(mass_matrix, forcing[..., None])[..., 0]
    contact = np.einsum("...ij,...j->...i", p.rotation, _call(p.oracle.contact_rate, p))
    state = p.state
    return np.concatenate([
        contact[..., :2],
        _quaternion_rate(state[..., 2:6], state[..., 6 + L : 9 + L]),
        state[..., 9 + L :],
        rates[..., : 3 + L],
    ], axis=-1)  # fmt: skip


def oracle_energy(state, *, shell_axes, legs, mass_bottom, gravity=9.81, damping=-0.01, model):
    """Kinetic plus potential energy (J) of ``state`` (9 + 2L,) or (..., 9 + 2L): shape () or (...).
    ``damping`` is accepted (and ignored) so that the keywords match :func:`oracle_derivative`'s."""
    p = _prepare(state, shell_axes=shell_axes, legs=legs, mass_bottom=mass_bottom, gravity=gravity,
                 damping=damping, model=model)  # fmt: skip
    kinetic_potential = _call(p.oracle.energy, p)
    return kinetic_potential[..., 0] + kinetic_potential[..., 1]


def oracle_ground_force(state, derivative, *, shell_axes, legs, mass_bottom, gravity=9.81, damping=-0.01,
                        model, frame="world"):  # fmt: skip
    """The ground's force on the robot (the pivot model: the joint's), N, (3,) or (..., 3):
    sum_i m_i a_i + M g z, each point mass's acceleration formed by sympy from the state and the
    derivative's Omega' and phi'' (give the derivative the torques that acted made). ``frame``:
    "world" (its z is the normal force) or "body"."""
    p = _prepare(state, shell_axes=shell_axes, legs=legs, mass_bottom=mass_bottom, gravity=gravity,
                 damping=damping, model=model)  # fmt: skip
    L = p.oracle.num_legs
    derivative = np.broadcast_to(np.asarray(derivative, dtype=float), p.state.shape)
    accel = derivative[..., 6 + L :]
    extra = [float(x) for x in accel] if not p.batch else [accel[..., i] for i in range(3 + L)]
    force = _call(p.oracle.ground, p, *extra)
    if frame == "body":
        return force
    if frame != "world":
        raise ValueError(f"frame must be 'world' or 'body', got {frame!r}")
    return np.einsum("...ij,...j->...i", p.rotation, force)


def oracle_centre(state, *, shell_axes, legs, mass_bottom, gravity=9.81, damping=-0.01, model):
    """The shell centre's world position, (3,) or (..., 3): the contact point (x, y, 0) minus R s.
    (On the pivot model, where the centre is held, this is where a rolling centre would be.)"""
    p = _prepare(state, shell_axes=shell_axes, legs=legs, mass_bottom=mass_bottom, gravity=gravity,
                 damping=damping, model=model)  # fmt: skip
    support_world = np.einsum("...ij,...j->...i", p.rotation, _call(p.oracle.support, p))
    contact = np.concatenate([p.state[..., :2], np.zeros(p.state.shape[:-1] + (1,))], axis=-1)
    return contact - support_world


TorqueLaw = Callable[[float, np.ndarray, np.ndarray], Sequence[float]]
"""(t, leg angles (L,), leg rates (L,)) -> the L leg torques, N m."""


def oracle_simulate(state0, torque: TorqueLaw | None, duration: float, *, shell_axes, legs, mass_bottom,
                    gravity=9.81, damping=-0.01, model, t_eval=None, rtol=1e-12, atol=1e-12):  # fmt: skip
    """Integrate the oracle from ``state0`` for ``duration`` s with scipy's DOP853.

    ``torque``: a :data:`TorqueLaw` or None (free legs). Returns (times (T,), states (T, 9 + 2L))
    at ``t_eval`` (default: the solver's own steps). The quaternion is integrated as it comes
    (no renormalisation): at these tolerances its norm stays 1 to ~1e-12.
    """
    L = len(legs)
    oracle = _derive(L, model)
    params = _parameter_values(shell_axes, legs, mass_bottom, gravity, damping)
    zero = np.zeros(L)

    def rhs(t, state):
        tau = zero if torque is None else torque(t, state[6 : 6 + L], state[9 + L :])
        return _derivative_one(oracle, params, state, tau)

    sol = solve_ivp(rhs, (0.0, float(duration)), np.asarray(state0, dtype=float), method="DOP853",
                    t_eval=t_eval, rtol=rtol, atol=atol)  # fmt: skip
    if not sol.success:
        raise RuntimeError(f"oracle integration failed: {sol.message}")
    return sol.t, sol.y.T
