"""Integrating the RRRobot: fixed-step RK4 for stepping, solve_ivp as the reference.

Both paths evaluate :func:`rrrobot_gym.dynamics.state_derivative`; the leg servo is
evaluated inside every derivative call (a continuous-time PD controller), so a
scripted gait's targets are tracked between steps, not sampled once per step.

States are arrays shaped (13,) for one robot or (N, 13) for a batch (layout in
:data:`rrrobot_gym.dynamics.STATE_FIELDS`). Internally a batch is integrated
component-first, (13, N), so each component is a contiguous array; one robot is
integrated on Python floats, which is several times faster than numpy at N = 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import dynamics
from .control import pd_torque
from .params import PDGains, RobotParams, check_model, rotation_point_depth

INTEGRATORS = ("rk4",)
"""Fixed-step integrators for stepping (``SimConfig.integrator``)."""

DEFAULT_TIMESTEP = 1.0 / 300.0
"""s, RK4 step of the defaults; keeps the contact point within 1 mm of the
rtol=1e-10 reference after 50 s of every Table II gait on both models
(``tests/test_accuracy.py``; ``python -m benchmarks.work_precision``)."""


@dataclass(frozen=True)
class SimConfig:
    """Everything that fixes how a robot is simulated."""

    model: str = "plane"  # "plane" (rolling contact) or "pivot" (Pivoting Dynamics model)
    robot: RobotParams = field(default_factory=RobotParams)
    gains: PDGains = field(default_factory=PDGains)
    integrator: str = "rk4"
    timestep: float = DEFAULT_TIMESTEP  # s, the fixed integration step

    def __post_init__(self):
        check_model(self.model)
        if self.integrator not in INTEGRATORS:
            raise ValueError(f"unknown integrator {self.integrator!r}: expected one of {', '.join(INTEGRATORS)}")
        if not isinstance(self.robot, RobotParams):
            raise TypeError(f"SimConfig.robot must be a RobotParams, got {type(self.robot).__name__}")
        if not isinstance(self.gains, PDGains):
            raise TypeError(f"SimConfig.gains must be a PDGains, got {type(self.gains).__name__}")
        try:
            step = float(self.timestep)
        except (TypeError, ValueError):
            raise TypeError(f"SimConfig.timestep must be a number, got {self.timestep!r}") from None
        if not (math.isfinite(step) and step > 0.0):
            raise ValueError(f"SimConfig.timestep must be a positive finite number of seconds, got {self.timestep}")
        object.__setattr__(self, "timestep", step)

    @property
    def depth(self) -> float:
        """m, h: depth of the point the body turns about (r on a plane, 0 pivoting)."""
        return rotation_point_depth(self.model, self.robot)


class NumericalFailure(RuntimeError):
    """The integration produced a non-finite state (the step was too large for the scene)."""


def initial_state(num_robots: int | None = None, leg_angles=(0.5 * math.pi, 0.5 * math.pi)):
    """The paper's start: at rest at the origin, upright, legs at ``leg_angles`` (vertical).

    Returns shape (13,) when ``num_robots`` is None, else (num_robots, 13).
    """
    state = np.zeros(dynamics.STATE_SIZE)
    state[dynamics.QUAT] = (1.0, 0.0, 0.0, 0.0)
    state[dynamics.LEG_ANGLES] = leg_angles
    if num_robots is None:
        return state
    if int(num_robots) != num_robots or num_robots < 1:
        raise ValueError(f"num_robots must be a positive integer, got {num_robots!r}")
    return np.tile(state, (int(num_robots), 1))


def check_state(state):
    """Validate a state array and return it as float64 with unit quaternions.

    Raises ValueError naming the problem: a wrong shape, NaN/inf, or a quaternion
    that is too far from unit length to be one (a norm outside [0.5, 2]).
    """
    try:
        arr = np.array(state, dtype=float)
    except (TypeError, ValueError):
        raise TypeError("state must be an array of numbers") from None
    if arr.ndim not in (1, 2) or arr.shape[-1] != dynamics.STATE_SIZE:
        raise ValueError(f"state must have shape (13,) or (N, 13), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("state contains NaN or inf")
    norm = np.linalg.norm(arr[..., dynamics.QUAT], axis=-1)
    if np.any((norm < 0.5) | (norm > 2.0)):
        raise ValueError(f"state quaternion (entries 2:6) must be a unit quaternion, got norm {norm.min():.3g}")
    arr[..., dynamics.QUAT] /= norm[..., None]
    return arr


def _derivative_fn(config: SimConfig, targets, kinematic_legs: bool = False):
    """f(t, y) for a component-first state y: shape (13,) (one robot) or (13, N)."""
    params, depth, gains = config.robot, config.depth, config.gains

    def f(t, y):
        comps = y.tolist() if y.ndim == 1 else y
        target = targets.leg_targets(t)
        if kinematic_legs:
            deriv = dynamics.state_derivative(comps, None, params, depth, leg_accel=target[2])
        else:
            tau = pd_torque(gains, (comps[6], comps[7]), (comps[11], comps[12]), target)
            deriv = dynamics.state_derivative(comps, tau, params, depth)
        return np.array(deriv)

    return f


def _normalize_quat(y):
    y[2:6] /= np.sqrt(y[2] * y[2] + y[3] * y[3] + y[4] * y[4] + y[5] * y[5])


def _rk4_steps(f, t, y, h, n_steps):
    """n_steps classical Runge-Kutta steps of size h, renormalising the quaternion after each."""
    half = 0.5 * h
    for _ in range(n_steps):
        k1 = f(t, y)
        k2 = f(t + half, y + half * k1)
        k3 = f(t + half, y + half * k2)
        k4 = f(t + h, y + h * k3)
        y = y + (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
        _normalize_quat(y)
        t += h
    return y


def advance(config: SimConfig, state, t0: float, duration: float, targets, *, check=True):
    """Integrate ``state`` from time t0 over ``duration`` seconds with fixed steps.

    The step is the largest that divides ``duration`` evenly and is no larger than
    ``config.timestep``. Returns the new state (same shape as ``state``).
    Raises :class:`NumericalFailure` if the result is not finite.
    """
    if check:
        state = check_state(state)
    if duration < 0.0 or not math.isfinite(duration):
        raise ValueError(f"duration must be a non-negative finite number of seconds, got {duration}")
    n_steps = max(1, math.ceil(duration / config.timestep - 1e-9)) if duration > 0 else 0
    if n_steps == 0:
        return np.array(state)
    y = np.ascontiguousarray(state.T)
    y = _rk4_steps(_derivative_fn(config, targets), t0, y, duration / n_steps, n_steps)
    out = y.T.copy()
    if not np.all(np.isfinite(out)):
        raise NumericalFailure(
            f"non-finite state after integrating {duration} s from t={t0} with step {duration / n_steps:.3g} s "
            f"(model {config.model!r}); reduce the timestep or the gains"
        )
    return out


@dataclass(frozen=True)
class Trajectory:
    """Sampled states of one robot or a batch: ``times`` (T,) s, ``states`` (T, 13) or (T, N, 13)."""

    times: np.ndarray
    states: np.ndarray
    config: SimConfig

    @property
    def x(self):
        """Contact point x, m."""
        return self.states[..., 0]

    @property
    def y(self):
        """Contact point y, m."""
        return self.states[..., 1]

    @property
    def quat(self):
        """Unit quaternions (w, x, y, z), body to world."""
        return self.states[..., dynamics.QUAT]

    @property
    def leg_angles(self):
        """phi_1, phi_2, rad."""
        return self.states[..., dynamics.LEG_ANGLES]

    @property
    def body_rate_world(self):
        """The body's angular velocity in world coordinates, rad/s."""
        return dynamics.world_body_rate(self.states)

    @property
    def theta(self):
        """The paper's angles (theta_1, theta_2, theta_3), rad, unwrapped along time."""
        return np.unwrap(dynamics.paper_angles(self.quat), axis=0)

    @property
    def energy(self):
        """Total energy, J."""
        return dynamics.total_energy(self.states, self.config.robot, self.config.model)


def _sample_times(duration: float, sample_dt: float):
    if not (math.isfinite(duration) and duration > 0.0):
        raise ValueError(f"duration must be a positive finite number of seconds, got {duration}")
    if not (math.isfinite(sample_dt) and sample_dt > 0.0):
        raise ValueError(f"sample_dt must be a positive finite number of seconds, got {sample_dt}")
    n = max(1, round(duration / sample_dt))
    return np.linspace(0.0, duration, n + 1)


def simulate(config: SimConfig, targets, duration: float, *, state=None, sample_dt: float = 0.01):
    """Run the fixed-step integrator and sample the state every ``sample_dt`` seconds.

    ``state`` defaults to :func:`initial_state` (one robot). Time starts at 0.
    """
    state = check_state(initial_state() if state is None else state)
    times = _sample_times(duration, sample_dt)
    out = np.empty((len(times),) + state.shape)
    out[0] = state
    for i in range(1, len(times)):
        out[i] = advance(config, out[i - 1], times[i - 1], times[i] - times[i - 1], targets, check=False)
    return Trajectory(times, out, config)


def simulate_reference(
    config: SimConfig,
    targets,
    duration: float,
    *,
    state=None,
    sample_dt: float = 0.01,
    rtol: float = 1e-10,
    atol: float = 1e-10,
    method: str = "DOP853",
):
    """Adaptive high-accuracy integration with ``scipy.integrate.solve_ivp`` (the reference).

    The quaternion is not renormalised during the solve (its drift is bounded by the
    tolerances); samples are normalised on output.
    """
    from scipy.integrate import solve_ivp

    state = check_state(initial_state() if state is None else state)
    times = _sample_times(duration, sample_dt)
    shape = state.shape
    f = _derivative_fn(config, targets)
    if state.ndim == 1:
        fun = f
    else:

        def fun(t, flat):
            return f(t, flat.reshape(dynamics.STATE_SIZE, -1)).ravel()

    sol = solve_ivp(fun, (0.0, times[-1]), state.T.ravel(), method=method, t_eval=times, rtol=rtol, atol=atol)
    if not sol.success:
        raise NumericalFailure(f"reference integration failed: {sol.message}")
    out = sol.y.reshape(dynamics.STATE_SIZE, *shape[:-1], len(times))
    out = np.moveaxis(out, 0, -1)
    out = np.moveaxis(out, -2, 0) if out.ndim == 3 else out
    out = np.ascontiguousarray(out)
    out[..., dynamics.QUAT] /= np.linalg.norm(out[..., dynamics.QUAT], axis=-1, keepdims=True)
    return Trajectory(times, out, config)
