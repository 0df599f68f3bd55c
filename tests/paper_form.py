"""Test oracle: the RRRobot equations of motion in the paper's own form.

An independent implementation of eq. (1)-(4) of "legless locomotion" (see
``/work/shared/paper/legless-locomotion.txt`` and ``/work/shared/MODEL.md``):
Euler-angle coordinates, Lagrange's equations derived symbolically with sympy,
and, on a plane, the two rolling constraints enforced by Lagrange multipliers.
It shares no code with ``rrrobot_gym`` and is meant only to be compared with it
in the tests; it is slow (tight tolerances) and singular at theta1 = +-pi/2.

Glossary
--------
Frames
    world  x, y horizontal, z up; the floor is the plane z = 0.
    body   origin at the centre of the hemispherical shell, z up when upright.
Point masses (body-frame positions)
    Mb  bottom of the shell         (0, 0, -r)
    Ms  leg 1 pin / leg 2 pin       (0, -r, 0) / (0, +r, 0)
    Ml  leg 1 tip / leg 2 tip       (l cos phi1, -r, l sin phi1) / (l cos phi2, +r, l sin phi2)
Coordinates
    theta1, theta2, theta3  the paper's ZXY fixed angles: rotations about the X,
                            Z and Y axes, R = Ry(theta3) @ Rx(theta1) @ Rz(theta2),
                            R maps body-frame vectors to the world frame [rad].
    phi1, phi2              leg angles about the body Y axis; 0 = leg along +X,
                            pi/2 = leg straight up [rad].
    x, y                    contact point on the floor; the centre is (x, y, r) [m].
Models
    "plane"  q = (x, y, theta1, theta2, theta3, phi1, phi2): the shell rolls without
             slip, eq. (1) with the constraint rows A(q) of eq. (2):
                 A = [[1, 0, 0,         r sin th1,         -r, 0, 0],
                      [0, 1, r cos th3, r cos th1 sin th3,  0, 0, 0]],   A qdot = 0.
    "pivot"  q = (theta1, theta2, theta3, phi1, phi2): the centre is held fixed
             (spherical joint at height r), eq. (3); the contact point is then
             integrated from eq. (4), i.e. xdot = r w_y, ydot = -r w_x.
World-frame angular velocity w (from skew(w) = Rdot R^T)
    w_x = cos th3 th1dot + cos th1 sin th3 th2dot
    w_y = th3dot - sin th1 th2dot
    w_z = -sin th3 th1dot + cos th1 cos th3 th2dot
Sign conventions
    Equations of motion:  M(q) qdd + C(q, qd) qd + G(q) = Q + A(q)^T lam.
    Each step solves  [[M, A^T], [A, 0]] [qdd; -lam] = [Q - C qd - G; -Adot qd],
    so lam is the multiplier of eq. (1): the horizontal contact force on the shell,
    lam = m_total * (COM acceleration in x, y) (not returned).
    Q on (phi1, phi2) is the leg torque (tau1, tau2), the generalised force on
    phi_k itself: a positive tau_k drives phi_k up, i.e. turns leg k from +X towards
    +Z, which is a torque from the shell on leg k about the body -Y axis.
    Damping: a torque k w on the body, k = ``damping`` (default -0.01 N m s/rad,
    negative = dissipative); its generalised force is Q_theta = (dw/dthetadot)^T k w
    and it does no work on x, y or the legs.
    Potential energy: V = sum m_i g z_i with the centre at height r (both models).

The velocity-level constraint is not projected: the plane model starts from
velocities that satisfy A qdot = 0 and keeps them through the acceleration-level
constraint Adot qdot + A qdd = 0 only.  Returned angles are not wrapped;
compare attitudes through the rotation matrix.
"""

from __future__ import annotations

import functools
import math
from typing import Callable, NamedTuple

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp

MODELS = ("plane", "pivot")

# Order of the physical parameters in every lambdified function.
_PARAM_NAMES = ("radius", "leg_length", "mass_bottom", "mass_pin", "mass_tip", "gravity")
_PARAM_DEFAULTS = {
    "radius": 0.12,  # r [m]
    "leg_length": 0.1,  # l [m]
    "mass_bottom": 0.3,  # Mb [kg]
    "mass_pin": 0.053,  # Ms [kg]
    "mass_tip": 0.057,  # Ml [kg]
    "gravity": 9.81,  # g [m/s^2]
}

TorqueFn = Callable[[float, np.ndarray, np.ndarray], np.ndarray]


def _check_model(model) -> None:
    if model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")


def _param_vector(params: dict) -> list:
    """Physical keywords -> values in _PARAM_NAMES order, defaults filled in."""
    unknown = set(params) - set(_PARAM_NAMES)
    if unknown:
        raise TypeError(f"unknown parameter(s): {sorted(unknown)}")
    merged = {**_PARAM_DEFAULTS, **params}
    return [float(merged[name]) for name in _PARAM_NAMES]


# ---------------------------------------------------------------------------
# Attitude helpers (numpy)
# ---------------------------------------------------------------------------


def rotation_from_angles(theta) -> np.ndarray:
    """Body-to-world rotation R = Ry(theta3) @ Rx(theta1) @ Rz(theta2)."""
    th1, th2, th3 = np.asarray(theta, dtype=float)
    c1, s1 = np.cos(th1), np.sin(th1)
    c2, s2 = np.cos(th2), np.sin(th2)
    c3, s3 = np.cos(th3), np.sin(th3)
    rot_x = np.array([[1.0, 0.0, 0.0], [0.0, c1, -s1], [0.0, s1, c1]])
    rot_z = np.array([[c2, -s2, 0.0], [s2, c2, 0.0], [0.0, 0.0, 1.0]])
    rot_y = np.array([[c3, 0.0, s3], [0.0, 1.0, 0.0], [-s3, 0.0, c3]])
    return rot_y @ rot_x @ rot_z


def _omega_map(theta) -> np.ndarray:
    """E(theta) with w_world = E @ theta_dot (columns: d w / d theta_k dot)."""
    th1, _, th3 = np.asarray(theta, dtype=float)
    c1, s1 = np.cos(th1), np.sin(th1)
    c3, s3 = np.cos(th3), np.sin(th3)
    return np.array(
        [
            [c3, c1 * s3, 0.0],
            [0.0, -s1, 1.0],
            [-s3, c1 * c3, 0.0],
        ]
    )


def omega_world_from_rates(theta, theta_dot) -> np.ndarray:
    """World-frame angular velocity of the body from the paper's angle rates."""
    return _omega_map(theta) @ np.asarray(theta_dot, dtype=float)


def _contact_velocity(theta, theta_dot, radius) -> np.ndarray:
    """(xdot, ydot) of the contact point from eq. (2)/(4): A qdot = 0 solved for x, y."""
    th1, _, th3 = theta
    d1, d2, d3 = theta_dot
    x_dot = radius * (d3 - np.sin(th1) * d2)
    y_dot = -radius * (np.cos(th3) * d1 + np.cos(th1) * np.sin(th3) * d2)
    return np.array([x_dot, y_dot])


# ---------------------------------------------------------------------------
# Symbolic derivation (once per model)
# ---------------------------------------------------------------------------


class _Compiled(NamedTuple):
    """Lambdified terms of one model; every function takes (q, qd, params)."""

    n_coordinates: int
    dynamics: Callable  # -> (M, C qd, G) or, on a plane, (M, C qd, G, A, Adot qd)
    energy: Callable  # -> (T, V)


def _sym_rotation(th1, th2, th3) -> sp.Matrix:
    rot_x = sp.Matrix([[1, 0, 0], [0, sp.cos(th1), -sp.sin(th1)], [0, sp.sin(th1), sp.cos(th1)]])
    rot_z = sp.Matrix([[sp.cos(th2), -sp.sin(th2), 0], [sp.sin(th2), sp.cos(th2), 0], [0, 0, 1]])
    rot_y = sp.Matrix([[sp.cos(th3), 0, sp.sin(th3)], [0, 1, 0], [-sp.sin(th3), 0, sp.cos(th3)]])
    return rot_y * rot_x * rot_z


@functools.lru_cache(maxsize=None)
def _compiled(model: str) -> _Compiled:
    """Derive M, C qd, G (and A, Adot qd on a plane) with sympy and lambdify them."""
    _check_model(model)
    r, l, mb, ms, ml, g = sp.symbols("r l M_b M_s M_l g", positive=True)
    params = [r, l, mb, ms, ml, g]  # same order as _PARAM_NAMES
    th1, th2, th3, ph1, ph2 = sp.symbols("theta1 theta2 theta3 phi1 phi2", real=True)
    attitude_and_legs = [th1, th2, th3, ph1, ph2]
    if model == "plane":
        x, y = sp.symbols("x y", real=True)
        q = [x, y, *attitude_and_legs]
        centre = sp.Matrix([x, y, r])
    else:
        q = attitude_and_legs
        centre = sp.Matrix([0, 0, r])
    qd = [sp.Symbol(f"{c.name}_dot", real=True) for c in q]
    q_vec, qd_vec = sp.Matrix(q), sp.Matrix(qd)

    rot = _sym_rotation(th1, th2, th3)
    point_masses = [
        (mb, sp.Matrix([0, 0, -r])),
        (ms, sp.Matrix([0, -r, 0])),
        (ms, sp.Matrix([0, r, 0])),
        (ml, sp.Matrix([l * sp.cos(ph1), -r, l * sp.sin(ph1)])),
        (ml, sp.Matrix([l * sp.cos(ph2), r, l * sp.sin(ph2)])),
    ]

    # T = 1/2 sum m |d/dt (c + R p)|^2 = 1/2 qd^T M qd with M = sum m J^T J.
    n = len(q)
    mass_matrix = sp.zeros(n, n)
    potential = sp.Integer(0)
    for mass, body_position in point_masses:
        world_position = centre + rot * body_position
        jac = world_position.jacobian(q_vec)
        mass_matrix += mass * (jac.T * jac)
        potential += mass * g * world_position[2]
    kinetic = (qd_vec.T * mass_matrix * qd_vec)[0, 0] / 2

    # Lagrange: d/dt(dT/dqd) - dT/dq = M qdd + [d(M qd)/dq] qd - dT/dq.
    momentum = mass_matrix * qd_vec
    coriolis = momentum.jacobian(q_vec) * qd_vec - sp.Matrix([kinetic]).jacobian(q_vec).T
    gravity_vec = sp.Matrix([potential]).jacobian(q_vec).T

    outputs = [mass_matrix, coriolis, gravity_vec]
    if model == "plane":
        # Rolling constraint rows omega^1, omega^2 of eq. (2), written as printed.
        constraint = sp.Matrix(
            [
                [1, 0, 0, r * sp.sin(th1), -r, 0, 0],
                [0, 1, r * sp.cos(th3), r * sp.cos(th1) * sp.sin(th3), 0, 0, 0],
            ]
        )
        constraint_bias = (constraint * qd_vec).jacobian(q_vec) * qd_vec  # Adot qd
        outputs += [constraint, constraint_bias]

    # Scalar math.sin/cos on Python floats is about three times faster than numpy
    # on 0-d values; the functions are called one state at a time anyway.
    args = [q, qd, params]
    modules = [{"sin": math.sin, "cos": math.cos}, "numpy"]
    dynamics = sp.lambdify(args, outputs, modules=modules, cse=True)
    energy = sp.lambdify(args, [kinetic, potential], modules=modules, cse=True)
    return _Compiled(n_coordinates=n, dynamics=dynamics, energy=energy)


# ---------------------------------------------------------------------------
# Integration
# ---------------------------------------------------------------------------


def _initial_state(model, theta, theta_dot, phi, phi_dot, x, y, radius) -> np.ndarray:
    """Integrator state at t = 0.

    plane: (q, qd) with q = (x, y, theta1..3, phi1, phi2), 14 numbers; the initial
           (x_dot, y_dot) is the one the rolling constraint imposes.
    pivot: (q, qd, x, y) with q = (theta1..3, phi1, phi2), 12 numbers.
    """
    theta = np.asarray(theta, dtype=float).reshape(3)
    theta_dot = np.asarray(theta_dot, dtype=float).reshape(3)
    phi = np.asarray(phi, dtype=float).reshape(2)
    phi_dot = np.asarray(phi_dot, dtype=float).reshape(2)
    if model == "plane":
        xy_dot = _contact_velocity(theta, theta_dot, radius)
        return np.concatenate([[x, y], theta, phi, xy_dot, theta_dot, phi_dot])
    return np.concatenate([theta, phi, theta_dot, phi_dot, [x, y]])


def _state_to_dict(model, state, radius) -> dict:
    """The returned quantities of :func:`simulate_paper_form` from one state vector."""
    if model == "plane":
        x, y = state[0], state[1]
        x_dot, y_dot = state[7], state[8]
        angles, rates = state[2:7], state[9:14]
    else:
        angles, rates = state[0:5], state[5:10]
        x, y = state[10], state[11]
        x_dot, y_dot = _contact_velocity(angles[:3], rates[:3], radius)
    theta, theta_dot = angles[:3].copy(), rates[:3].copy()
    return {
        "x": float(x),
        "y": float(y),
        "x_dot": float(x_dot),
        "y_dot": float(y_dot),
        "theta": theta,
        "theta_dot": theta_dot,
        "phi": angles[3:].copy(),
        "phi_dot": rates[3:].copy(),
        "rotation": rotation_from_angles(theta),
        "omega_world": omega_world_from_rates(theta, theta_dot),
    }


def _make_rhs(model, torque: TorqueFn | None, damping: float, params: list) -> Callable:
    """f(t, state) for solve_ivp, in the state layout of :func:`_initial_state`."""
    terms = _compiled(model)
    n = terms.n_coordinates
    radius = params[0]

    def generalised_force(t, angles, rates):
        """Q on (theta1..3, phi1, phi2): damping on the body, torques on the legs."""
        force = np.zeros(5)
        if torque is not None:
            force[3:] = np.asarray(torque(t, angles[3:].copy(), rates[3:].copy()), dtype=float)
        if damping != 0.0:
            omega_map = _omega_map(angles[:3])
            force[:3] = omega_map.T @ (damping * (omega_map @ rates[:3]))
        return force

    if model == "plane":
        kkt = np.zeros((n + 2, n + 2))
        kkt_rhs = np.zeros(n + 2)

        def rhs(t, state):
            q, qd = state[:n], state[n:]
            values = state.tolist()
            mass_matrix, coriolis, gravity_vec, constraint, constraint_bias = terms.dynamics(
                values[:n], values[n:], params
            )
            force = np.zeros(n)
            force[2:] = generalised_force(t, q[2:], qd[2:])
            kkt[:n, :n] = mass_matrix
            kkt[:n, n:] = constraint.T
            kkt[n:, :n] = constraint
            kkt_rhs[:n] = force - np.ravel(coriolis) - np.ravel(gravity_vec)
            kkt_rhs[n:] = -np.ravel(constraint_bias)
            solution = np.linalg.solve(kkt, kkt_rhs)  # (qdd, -lambda)
            return np.concatenate([qd, solution[:n]])

        return rhs

    def rhs(t, state):
        q, qd = state[:n], state[n : 2 * n]
        values = state.tolist()
        mass_matrix, coriolis, gravity_vec = terms.dynamics(values[:n], values[n : 2 * n], params)
        force = generalised_force(t, q, qd)
        qdd = np.linalg.solve(mass_matrix, force - np.ravel(coriolis) - np.ravel(gravity_vec))
        # eq. (4): the contact point follows the attitude rates.
        return np.concatenate([qd, qdd, _contact_velocity(q[:3], qd[:3], radius)])

    return rhs


# ---------------------------------------------------------------------------
# Public API
# ---------------------------------------------------------------------------


def energy_paper_form(
    model, theta, theta_dot, phi, phi_dot, x_dot=None, y_dot=None, **params
) -> float:
    """Total energy T + V [J] of the paper-form model.

    ``params`` are the physical keywords of :func:`simulate_paper_form`
    (radius, leg_length, mass_bottom, mass_pin, mass_tip, gravity).  On a plane,
    x_dot and y_dot default to the values the rolling constraint imposes; the
    pivot model has no translational kinetic energy and ignores them.  The
    potential is measured with the centre at height r in both models; x, y do
    not enter the energy.
    """
    _check_model(model)
    p = _param_vector(params)
    terms = _compiled(model)
    theta = np.asarray(theta, dtype=float)
    theta_dot = np.asarray(theta_dot, dtype=float)
    angles = [*theta, *np.asarray(phi, dtype=float)]
    rates = [*theta_dot, *np.asarray(phi_dot, dtype=float)]
    if model == "plane":
        if (x_dot is None) != (y_dot is None):
            raise ValueError("give both x_dot and y_dot, or neither")
        if x_dot is None:
            x_dot, y_dot = _contact_velocity(theta, theta_dot, p[0])
        q = [0.0, 0.0, *angles]
        qd = [float(x_dot), float(y_dot), *rates]
    else:
        q, qd = angles, rates
    kinetic, potential = terms.energy([float(v) for v in q], [float(v) for v in qd], p)
    return float(kinetic + potential)


def simulate_paper_form(
    model,
    *,
    theta,
    theta_dot,
    phi,
    phi_dot,
    x=0.0,
    y=0.0,
    t_final,
    torque,
    damping=-0.01,
    radius=0.12,
    leg_length=0.1,
    mass_bottom=0.3,
    mass_pin=0.053,
    mass_tip=0.057,
    gravity=9.81,
    rtol=1e-12,
    atol=1e-12,
) -> dict:
    """Integrate eq. (1)-(2) ("plane") or eq. (3)-(4) ("pivot") from t = 0 to t_final.

    Arguments are in SI units and the glossary's conventions.  ``torque`` is
    ``torque(t, phi, phi_dot) -> (tau1, tau2)`` [N m], or None for no torque.
    On a plane the initial (x_dot, y_dot) is set from the rolling constraint.

    Returns a dict of the state at t_final: "x", "y" (contact point, floats),
    "theta" (3,), "theta_dot" (3,), "phi" (2,), "phi_dot" (2,), "rotation"
    (3, 3, body to world), "omega_world" (3,), and also "x_dot", "y_dot": the
    contact point's velocity (on a plane the integrated coordinate rates, whose
    difference from eq. (4) is the rolling-constraint residual; when pivoting,
    eq. (4) itself).
    """
    _check_model(model)
    if t_final < 0:
        raise ValueError("t_final must be >= 0")
    params = _param_vector(
        dict(
            radius=radius,
            leg_length=leg_length,
            mass_bottom=mass_bottom,
            mass_pin=mass_pin,
            mass_tip=mass_tip,
            gravity=gravity,
        )
    )
    state0 = _initial_state(model, theta, theta_dot, phi, phi_dot, x, y, radius)
    rhs = _make_rhs(model, torque, damping, params)
    if t_final == 0:
        return _state_to_dict(model, state0, radius)
    sol = solve_ivp(rhs, (0.0, float(t_final)), state0, method="DOP853", rtol=rtol, atol=atol)
    if not sol.success:
        raise RuntimeError(f"paper-form integration failed: {sol.message}")
    return _state_to_dict(model, sol.y[:, -1], radius)
