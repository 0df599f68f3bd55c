"""Integrating the RRRobot: fixed-step stepping (:mod:`rrrobot_gym.integrators`), solve_ivp as the reference.

Both paths evaluate :func:`rrrobot_gym.dynamics.derivative_kernel`; the leg servo is
evaluated inside every derivative call (a continuous-time PD controller), so a scripted
gait's targets are tracked between steps, not sampled once per step.

Options that skip work a scene does not need (``SimConfig``): ``legs="kinematic"``
(the legs follow a smooth path exactly; the stiff servo leaves the integration) and
``timestep="auto"`` (a step derived from the gains, masses and model). A step beyond
the servo's stability limit is refused at construction.

States are arrays shaped (9 + 2L,) for one robot of L legs or (N, 9 + 2L) for a batch (layout
:func:`rrrobot_gym.dynamics.state_fields`; 13 numbers for the paper's two legs). The numpy backend
steps a list of components: Python floats for one robot (several times faster than numpy at N = 1),
(N,) arrays for a batch.
"""

from __future__ import annotations

import cmath
import difflib
import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from . import compiled, dynamics
from .control import limit_torque, pd_torque
from .integrators import INTEGRATORS
from .params import MAX_LEGS, PDGains, RobotParams, check_model, real_number, whole_number

LEG_MODES = ("servo", "kinematic")
"""How the legs move (``SimConfig.legs``): "servo" integrates the PD servo with the
body (the paper's model); "kinematic" makes the legs follow a smooth path to their
targets exactly, so the stiff servo leaves the integration (see :func:`advance`)."""

BACKENDS = ("auto", "numpy", "numba")
"""How :func:`advance` integrates (``SimConfig.backend``): "numba", the compiled stepper of
:mod:`rrrobot_gym.compiled` (for the scenes and targets it covers); "numpy", :data:`INTEGRATORS`
on Python floats and numpy arrays; "auto" (default), numba where installed and covering, else numpy."""

DEFAULT_TIMESTEP = 1.0 / 300.0
"""s, RK4 step of the defaults; keeps the contact point within 1 mm of the
rtol=1e-10 reference after 50 s of every Table II gait on both models
(``tests/test_paper_results.py``; ``python -m benchmarks.work_precision``)."""

@dataclass(frozen=True)
class SimConfig:
    """Everything that fixes how a robot is simulated."""

    model: str = "plane"  # "plane" (rolling contact) or "pivot" (Pivoting Dynamics model)
    robot: RobotParams = field(default_factory=RobotParams)
    gains: PDGains = field(default_factory=PDGains)
    integrator: str = "rk4"
    timestep: float | str = DEFAULT_TIMESTEP  # s, the fixed integration step, or "auto" (see `step`)
    legs: str = "servo"  # "servo" (PD servo dynamics) or "kinematic" (legs follow a smooth path exactly)
    torque_limit: float | None = None  # N m, the leg motors' stall torque; None: unlimited (the paper's servo)
    leg_rate_limit: float | None = None  # rad/s, the motors' no-load speed (needs torque_limit); None: unlimited
    # BACKENDS: how, not what, is integrated, so not in the repr (which keys tests/reference_paths.py)
    backend: str = field(default="auto", repr=False)

    def __post_init__(self):
        check_model(self.model)
        if self.backend not in BACKENDS:
            raise ValueError(f"unknown backend {self.backend!r}: expected one of {', '.join(BACKENDS)}")
        if self.backend == "numba":
            if not compiled.available():
                raise ImportError("SimConfig.backend='numba' needs numba: pip install 'rrrobot_gym[fast]' (or numba)")
            if not compiled.supports(self):
                raise ValueError(
                    f"SimConfig.backend='numba' compiles servo legs with integrator {', '.join(map(repr, compiled.INTEGRATORS))} only, got legs "
                    f"{self.legs!r} and integrator {self.integrator!r}: use backend 'auto' or 'numpy'"
                )
        for name in ("torque_limit", "leg_rate_limit"):
            value = getattr(self, name)
            if value is not None:
                value = real_number(f"SimConfig.{name}", value)
                if value <= 0.0:
                    raise ValueError(f"SimConfig.{name} must be positive or None, got {value}")
                object.__setattr__(self, name, value)
        if self.leg_rate_limit is not None and self.torque_limit is None:
            raise ValueError(
                "SimConfig.leg_rate_limit needs a torque_limit: the motor model's torque falls linearly "
                "from the stall torque (torque_limit) to 0 at the no-load speed (leg_rate_limit)"
            )
        if self.legs == "kinematic" and self.torque_limit is not None:
            raise ValueError("SimConfig.torque_limit applies to servo legs; kinematic legs follow their path whatever it takes: "
                             "give torque_limit=None and leg_rate_limit=None with legs='kinematic'")
        if self.integrator not in INTEGRATORS:
            raise ValueError(f"unknown integrator {self.integrator!r}: expected one of {', '.join(INTEGRATORS)}")
        if self.legs not in LEG_MODES:
            raise ValueError(f"unknown leg mode {self.legs!r}: expected one of {', '.join(LEG_MODES)}")
        if not isinstance(self.robot, RobotParams):
            raise TypeError(f"SimConfig.robot must be a RobotParams, got {type(self.robot).__name__}")
        if not isinstance(self.gains, PDGains):
            raise TypeError(f"SimConfig.gains must be a PDGains, got {type(self.gains).__name__}")
        if self.legs == "servo" and not math.isfinite(servo_fastest_rate(self.model, self.robot, self.gains)):
            raise ValueError(
                f"the leg servo's fastest pole overflows floating point (kp={self.gains.kp}, kd={self.gains.kd}, "
                f"{self.model} model, {self.robot}): no step can follow it"
            )
        if isinstance(self.timestep, str):
            if self.timestep != "auto":
                raise ValueError(f"SimConfig.timestep must be a number of seconds or 'auto', got {self.timestep!r}")
            if INTEGRATORS[self.integrator].AUTO_STEP_FACTOR is None:
                raise ValueError(
                    f"SimConfig.timestep='auto' is not calibrated for integrator {self.integrator!r}: give it a fixed step"
                )
            object.__setattr__(self, "_step", scene_timestep(self.model, self.robot, self.gains, self.legs, self.integrator))
            return
        try:
            step = float(self.timestep)
        except (TypeError, ValueError):
            raise TypeError(f"SimConfig.timestep must be a number of seconds or 'auto', got {self.timestep!r}") from None
        if not (math.isfinite(step) and step > 0.0):
            raise ValueError(f"SimConfig.timestep must be a positive finite number of seconds, got {self.timestep}")
        object.__setattr__(self, "timestep", step)
        object.__setattr__(self, "_step", step)
        if self.legs == "servo":
            limit = stable_step_limit(self.model, self.robot, self.gains, self.integrator)
            if step > limit:
                raise ValueError(
                    f"SimConfig.timestep {step:.4g} s is beyond the stability limit {limit:.4g} s of "
                    f"{self.integrator} for the leg servo (kp={self.gains.kp}, kd={self.gains.kd}, tip mass "
                    f"{self.robot.mass_tip} kg, model {self.model!r}; fastest servo pole "
                    f"{servo_fastest_rate(self.model, self.robot, self.gains):.4g} 1/s): the run would blow up. "
                    + "Use a smaller timestep, timestep='auto', or legs='kinematic'"
                    + (" with torque_limit=None and leg_rate_limit=None" if self.torque_limit is not None else "")
                )

    @property
    def step(self) -> float:
        """s, the step actually used: ``timestep``, or the scene-derived step when it is "auto"."""
        return self._step

    @property
    def fields(self) -> dynamics.StateFields:
        """The layout of this robot's states (:func:`rrrobot_gym.dynamics.state_fields`)."""
        return dynamics.state_fields(self.robot.num_legs)


class NumericalFailure(RuntimeError):
    """The integration produced a non-finite state (the step was too large for the scene)."""


def initial_state(num_robots: int | None = None, leg_angles=None, num_legs: int = 2):
    """The paper's start: at rest at the origin, upright, legs at ``leg_angles`` (None: every one
    of ``num_legs`` vertical, pi/2).

    Returns shape (9 + 2L,) when ``num_robots`` is None, else (num_robots, 9 + 2L).
    """
    if leg_angles is None:
        leg_angles = (0.5 * math.pi,) * whole_number("num_legs", num_legs)
    try:
        angles = np.array(leg_angles, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"leg_angles must be one number a leg (rad), got {leg_angles!r}") from None
    if angles.ndim != 1 or not 1 <= len(angles) <= MAX_LEGS:
        raise ValueError(f"leg_angles must be one number a leg (rad), got shape {angles.shape}")
    if not np.all(np.isfinite(angles)):
        raise ValueError(f"leg_angles must be finite, got {leg_angles!r}")
    fields = dynamics.state_fields(len(angles))
    state = np.zeros(fields.size)
    state[fields.quat] = (1.0, 0.0, 0.0, 0.0)
    state[fields.leg_angles] = angles
    if num_robots is None:
        return state
    return np.tile(state, (whole_number("num_robots", num_robots), 1))


def check_state(state, num_legs: int = 2):
    """Validate a state array of a robot of ``num_legs`` legs and return it as float64 with unit quaternions.

    Raises ValueError naming the problem: a wrong shape, NaN/inf, or a quaternion
    that is too far from unit length to be one (a norm outside [0.5, 2]).
    """
    try:
        arr = np.array(state, dtype=float)
    except (TypeError, ValueError):
        raise TypeError("state must be an array of numbers") from None
    size = dynamics.state_fields(num_legs).size
    if arr.ndim not in (1, 2) or arr.shape[-1] != size:
        legs = f" ({num_legs} legs)" if num_legs != 2 else ""
        raise ValueError(f"state must have shape ({size},) or (N, {size}){legs}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("state contains NaN or inf")
    norm = np.linalg.norm(arr[..., dynamics.QUAT], axis=-1)
    off = (norm < 0.5) | (norm > 2.0)
    if np.any(off):
        raise ValueError(f"state quaternion (entries 2:6) must be a unit quaternion, got norm {norm[off].flat[0]:.3g}")
    arr[..., dynamics.QUAT] /= norm[..., None]
    return arr


# ---------------------------------------------------------------------------
# The scene's time scales: a step derived from gains, masses and model.


def _regular(mass) -> np.ndarray:
    """(K,) bool: which of the finite mass matrices (K, 3 + L, 3 + L) are regular, their least eigenvalue
    above 1e-9 of their largest (a singular one: some motion moves no mass)."""
    eig = np.linalg.eigvalsh(mass)
    return eig[:, 0] > 1e-9 * eig[:, -1]


@functools.lru_cache(maxsize=64)
def _effective_leg_inverse_inertia(model: str, robot: RobotParams) -> float:
    """1/kg m^2, the largest eigenvalue of the legs' block of M^-1 over attitudes and leg angles.

    The legs' effective inertia is the Schur complement D - C^T M_omega^-1 C: the body
    recoils when a leg is driven, so a leg is lighter than Ml l^2 (on a plane about
    a quarter of it). The maximum sits on a grid of tilts (up to the limit) and leg angles.
    """
    angles = np.linspace(-math.pi, math.pi, 13)
    legs, fields = robot.num_legs, dynamics.state_fields(robot.num_legs)
    # every combination of the grid's leg angles up to two legs; from three, 600 drawn (seeded) combinations
    combos = np.stack(np.meshgrid(*[angles] * legs, indexing="ij"), -1).reshape(-1, legs) if legs <= 2 else (
        np.random.default_rng(0).choice(angles, size=(600, legs)))  # fmt: skip
    tilts, axes = np.meshgrid(np.linspace(0.0, dynamics.TILT_LIMIT, 7), np.linspace(0, math.pi, 5), indexing="ij")
    states = np.zeros((len(combos), tilts.size, fields.size))
    states[..., 2] = np.cos(0.5 * tilts.ravel())
    states[..., 3] = np.sin(0.5 * tilts.ravel()) * np.cos(axes.ravel())
    states[..., 4] = np.sin(0.5 * tilts.ravel()) * np.sin(axes.ravel())
    states[..., fields.leg_angles] = combos[:, None, :]
    with np.errstate(over="ignore", invalid="ignore"):
        mass = dynamics.mass_matrix(states.reshape(-1, fields.size), robot, model)
    if not np.all(np.isfinite(mass)):  # (eigvalsh would fail on it as "did not converge")
        raise ValueError(
            f"the generalised mass matrix of {robot} ({model} model) overflows: masses times lengths squared "
            f"must stay within floating point (are the lengths in m and the masses in kg?)"
        )
    # Skip configurations where M is singular (e.g. no bottom mass and every mass on one
    # line): the dynamics is undefined there and no step size helps.
    regular = _regular(mass)
    if not np.any(regular):
        raise ValueError(
            f"the generalised mass matrix of {robot} ({model} model) is singular in every configuration: "
            f"some motion moves no mass (e.g. with mass_bottom = 0 the pivoting shell has no inertia about "
            f"the legs' axis), so the dynamics is undefined"
        )
    inverse = np.linalg.inv(mass[regular])
    return float(np.linalg.eigvalsh(inverse[:, 3:, 3:]).max())


def servo_poles(model: str, robot: RobotParams, gains: PDGains) -> tuple:
    """1/s, the two poles of the stiffest leg-servo mode over all configurations.

    Each leg obeys I_eff phi'' + kd phi' + kp phi = ... with I_eff as small as
    1/max eig(M^-1 legs block): poles (-kd mu +- sqrt((kd mu)^2 - 4 kp mu)) / 2, mu = 1/I_eff.
    """
    mu = _effective_leg_inverse_inertia(model, robot)
    damping = gains.kd * mu  # (products, not **: an overflow gives inf, named by SimConfig, not OverflowError)
    disc = complex(damping * damping - 4.0 * gains.kp * mu)
    root = cmath.sqrt(disc)  # (an overflowing discriminant gives an infinite pole, not OverflowError)
    return (0.5 * (-damping - root), 0.5 * (-damping + root))


def servo_fastest_rate(model: str, robot: RobotParams, gains: PDGains) -> float:
    """1/s, |lambda| of the fastest pole of the leg servo, over all configurations."""
    return max(abs(p) for p in servo_poles(model, robot, gains))


def stable_step_limit(model: str, robot: RobotParams, gains: PDGains, integrator: str = "rk4") -> float:
    """s, the largest step at which ``integrator`` stays stable on the leg servo's fastest poles."""
    amplification = INTEGRATORS[integrator].amplification
    poles = [p for p in servo_poles(model, robot, gains) if p != 0]
    lo, hi = 0.0, 10.0 / max(abs(p) for p in poles)
    for _ in range(60):  # bisection on the first step where some pole is amplified
        mid = 0.5 * (lo + hi)
        if all(amplification(mid * p) <= 1.0 + 1e-12 for p in poles):
            lo = mid
        else:
            hi = mid
    return lo


KINEMATIC_STEP = 1.0 / 40.0
"""s, the auto step with kinematic legs: the fastest remaining motion is the body
rocking (~7 rad/s) driven at the gait frequency (8 rad/s). At 1/40 s the contact error
after 50 s is ~0.03 mm (1/20 s: ~0.4 mm; ``benchmarks.work_precision``)."""


def scene_timestep(model: str, robot: RobotParams, gains: PDGains, legs: str = "servo", integrator: str = "rk4") -> float:
    """s, a step derived from the scene rather than one fixed number (``timestep="auto"``).

    Servo legs: the stiffest motion is the overdamped leg servo, |lambda| =
    :func:`servo_fastest_rate`; h = the integrator's ``AUTO_STEP_FACTOR[model]`` / |lambda|, and never
    more than 0.8 of the stability limit (:func:`stable_step_limit`). Kinematic legs:
    the servo is gone and the body's rocking sets the step (:data:`KINEMATIC_STEP`).
    """
    if legs == "kinematic":
        return KINEMATIC_STEP
    return min(
        INTEGRATORS[integrator].AUTO_STEP_FACTOR[model] / servo_fastest_rate(model, robot, gains),
        0.8 * stable_step_limit(model, robot, gains, integrator),
        KINEMATIC_STEP,
    )


# ---------------------------------------------------------------------------
# Leg paths for the kinematic-legs mode.


def _blend_coefficients(offset, rate_offset, duration):
    """Quintic b(s), s in [0, duration], with b(0) = offset, b'(0) = rate_offset, b''(0) = 0
    and b = b' = b'' = 0 at the end (a minimum-jerk transition)."""
    return offset, rate_offset * duration, duration


def _blend(coeffs, s):
    """b, b', b'' of :func:`_blend_coefficients` at time s after its start."""
    b0, v0d, dur = coeffs
    tau = min(max(s / dur, 0.0), 1.0) if isinstance(s, float) else np.clip(s / dur, 0.0, 1.0)
    t2 = tau * tau
    t3 = t2 * tau
    # Hermite quintic basis: H0 = 1 - 10t^3 + 15t^4 - 6t^5, H1 = t - 6t^3 + 8t^4 - 3t^5.
    h0 = 1.0 + t3 * (-10.0 + tau * (15.0 - 6.0 * tau))
    h0d = t2 * (-30.0 + tau * (60.0 - 30.0 * tau))
    h0dd = tau * (-60.0 + tau * (180.0 - 120.0 * tau))
    h1 = tau + t3 * (-6.0 + tau * (8.0 - 3.0 * tau))
    h1d = 1.0 + t2 * (-18.0 + tau * (32.0 - 15.0 * tau))
    h1dd = tau * (-36.0 + tau * (96.0 - 60.0 * tau))
    return (b0 * h0 + v0d * h1, (b0 * h0d + v0d * h1d) / dur, (b0 * h0dd + v0d * h1dd) / (dur * dur))


class SmoothStart:
    """A leg-target source that starts at given leg angles and rates and blends into ``targets``.

    path(t) = targets(t) + b(t - t_start), b a minimum-jerk quintic from the start's
    offset to zero over ``blend_time`` seconds. Used by the kinematic-legs mode, where
    the legs follow their path exactly, so a path must start where the legs are.
    """

    def __init__(self, targets, leg_angles, leg_rates, t_start: float = 0.0, blend_time: float = 0.2):
        if not (math.isfinite(blend_time) and blend_time > 0.0):
            raise ValueError(f"blend_time must be a positive number of seconds, got {blend_time}")
        self.targets = targets
        self.t_start = float(t_start)
        angles, rates, _ = targets.leg_targets(self.t_start)
        self._coeffs = tuple(_blend_coefficients(phi - a, rate - r, blend_time)
                             for phi, rate, a, r in zip(leg_angles, leg_rates, angles, rates))  # fmt: skip

    def leg_targets(self, t):
        blends = [_blend(coeffs, t - self.t_start) for coeffs in self._coeffs]
        return tuple(tuple(v + b[j] for v, b in zip(values, blends)) for j, values in enumerate(self.targets.leg_targets(t)))


# ---------------------------------------------------------------------------
# Fixed-step integration.

def _stage_fns(config: SimConfig, targets, blend=None, scene=None, momentum: bool = False):
    """(f, first) for components c (floats or (N,) arrays): f(t, c) -> the derivative's
    components; first(t, c) -> (the same, the record's values of this state: the kernel's, then
    the leg rates, :func:`rrrobot_gym.compiled.record_rows` in all).

    The steppers call ``first`` (through the recorder) at the start of every substep and ``f``
    at the other stages, so the torques the integrator applied come from the evaluation it
    makes anyway (:func:`rrrobot_gym.dynamics.derivative_kernel`). ``blend`` = (t0, one set of
    coefficients a leg) adds a transition path to the targets (kinematic legs). ``scene`` =
    (constants, gains, torque limit, rate limit) replaces the config's (per-robot parameters,
    :func:`_robot_scene`). ``momentum`` (the pivot's steppers, :func:`_integrate`): the states'
    body rows hold the body's angular momentum (:func:`rrrobot_gym.dynamics.to_momentum`).
    """
    if scene is None:
        k = dynamics.constants(config.robot, config.model)
        gains, torque_limit, rate_limit = config.gains, config.torque_limit, config.leg_rate_limit
    else:
        k, gains, torque_limit, rate_limit = scene
    legs = config.robot.num_legs
    kinematic = config.legs == "kinematic"
    derivative = dynamics.derivative_function(config.robot, config.model, kinematic, k=k, momentum=momentum)
    recorded = dynamics.derivative_function(config.robot, config.model, kinematic, record=True, k=k, momentum=momentum)
    leg_targets = targets.leg_targets
    rates = slice(9 + legs, 9 + 2 * legs)

    if kinematic:

        def driving(t, c):  # the legs' prescribed accelerations
            accels = leg_targets(t)[2]
            if blend is None:
                return accels
            return [a + _blend(coeffs, t - blend[0])[2] for a, coeffs in zip(accels, blend[1])]

    else:

        def driving(t, c):  # the servo's torques
            torques = pd_torque(gains, c[6 : 6 + legs], c[rates], leg_targets(t))
            return torques if torque_limit is None else limit_torque(torques, c[rates], torque_limit, rate_limit)

    def f(t, c):
        return derivative(c, driving(t, c))

    def first(t, c):
        values, record = recorded(c, driving(t, c))
        return values, [*record, *c[rates]]

    return f, first


def _derivative_fn(config: SimConfig, targets):
    """f(t, y) for a component-first state y: shape (9 + 2L,) (one robot) or (9 + 2L, N), as an array."""
    f, _ = _stage_fns(config, targets)

    def g(t, y):
        return np.array(f(t, y.tolist() if y.ndim == 1 else list(y)))

    return g


def _leg_path_end(targets, blend, t_end):
    """Leg angles and rates of the kinematic path at t_end: where the legs must be."""
    angles, rates, _ = targets.leg_targets(t_end)
    if blend is None:
        return list(angles), list(rates)
    blends = [_blend(coeffs, t_end - blend[0]) for coeffs in blend[1]]
    return [a + b[0] for a, b in zip(angles, blends)], [r + b[1] for r, b in zip(rates, blends)]


@dataclass(frozen=True)
class StepRecord:
    """What an :func:`advance` did, sampled at the start of every integration substep.

    Made by the integrator from the first-stage derivative it evaluates anyway: the torques it
    applied (after any motor limit; kinematic legs: what the prescribed motion took) and Newton's
    force for the motion it integrated (:func:`rrrobot_gym.dynamics.derivative_kernel`).

    Shapes: S samples, L legs; one robot: (S,), (S, L), (S, 3); a batch of N: (S, N), (S, N, L), (S, N, 3).
    :meth:`summary` gives each robot's extremes over the samples (what the env's measures read).
    """

    times: np.ndarray  # (S,) s, the substep starts
    step: float  # s, the substep length: each sample stands for this much time
    torque: np.ndarray  # (S, [N,] L) N m, leg torques applied (shell on leg)
    force: np.ndarray  # (S, [N,] 3) N, the ground's force on the shell, body frame (pivot: the joint's)
    normal: np.ndarray  # (S, [N]) N, its component along world up
    leg_clearance: np.ndarray  # (S, [N,] L) m, each leg tip's height above the ground
    leg_rates: np.ndarray  # (S, [N,] L) rad/s
    # the integrator's own tangential values (dynamics.derivative_kernel's), where it made the record
    _tangential: np.ndarray | None = field(default=None, init=False, repr=False, compare=False)
    # the summary the compiled stepper made of its record ((6, [N]), SUMMARY_KEYS), where it did
    _summary: np.ndarray | None = field(default=None, init=False, repr=False, compare=False)

    @property
    def tangential(self) -> np.ndarray:
        """(S, [N]) N, the force's magnitude along the ground (the grip rolling needs),
        sqrt(|force|^2 - normal^2): as the integrator recorded it, or from ``force`` and ``normal``
        for a record made by hand (or changed with ``dataclasses.replace``)."""
        if self._tangential is not None:
            return self._tangential
        return dynamics.tangential_force(self.force[..., 0], self.force[..., 1], self.force[..., 2], self.normal)

    def summary(self) -> dict:
        """Per robot, over the samples: a dict keyed :data:`SUMMARY_KEYS` of ([N],) arrays.

        The compiled stepper's own summary where it made one; else computed here, to the same
        numbers (a NaN wins a min or max; the squares are summed sample by sample).
        """
        if self._summary is not None:
            return dict(zip(SUMMARY_KEYS, self._summary))
        samples = self.normal.shape[0]
        if samples == 0:
            raise ValueError("a StepRecord of no samples has no summary (advance records at least one substep)")
        normal = self.normal.reshape(samples, -1)
        num_robots = normal.shape[1]
        legs = self.torque.shape[-1]
        torque = self.torque.reshape(samples, num_robots, legs)
        with np.errstate(divide="ignore", invalid="ignore"):  # (a normal force of 0: see SUMMARY_KEYS)
            ratio = self.tangential.reshape(samples, num_robots) / normal
        squares = torque[..., 0] * torque[..., 0]
        for m in range(1, legs):  # (leg by leg, as the compiled stepper sums)
            squares = squares + torque[..., m] * torque[..., m]
        values = (
            normal.min(axis=0),
            ratio.max(axis=0),
            self.leg_clearance.reshape(samples, num_robots, legs).min(axis=(0, 2)),
            np.add.accumulate(squares, axis=0)[-1],  # (sample by sample: numpy's sum may pair them)
            _largest_magnitude(torque),
            _largest_magnitude(self.leg_rates.reshape(samples, num_robots, legs)),
        )
        shape = self.normal.shape[1:]
        return {key: value.reshape(shape) for key, value in zip(SUMMARY_KEYS, values)}


SUMMARY_KEYS = ("least_normal", "most_ratio", "least_clearance", "torque_squares", "peak_torque", "peak_leg_rate")
"""What :meth:`StepRecord.summary` reports of each robot, over the record's samples: the least
normal force (N); the greatest tangential / normal (the grip rolling needs, where every sample
pushes: a sample with normal <= 0 makes it inf or NaN); the least leg clearance (m, every leg);
the sum of every leg's squared torque (N^2 m^2); the peak |torque| (N m, every leg) and the peak
|leg rate| (rad/s, every leg)."""


def _largest_magnitude(values):
    """max |v| per robot over samples and legs of (S, N, L) values (a max and a min: no array of magnitudes)."""
    return np.maximum(values.max(axis=(0, 2)), -values.min(axis=(0, 2)))




class _Recorder:
    """The steppers' ``first``: evaluates a substep's first stage and keeps what it applied."""

    def __init__(self, first, n_steps: int, num_robots: int | None, legs: int):
        self._first = first
        self._rows = [] if num_robots is None else np.empty((n_steps, compiled.record_rows(legs), num_robots))
        self._i = 0

    def __call__(self, t, c):
        derivative, row = self._first(t, c)
        if isinstance(self._rows, list):
            self._rows.append(row)
        else:
            self._rows[self._i] = row
            self._i += 1
        return derivative

    @property
    def rows(self):
        """What was recorded: (S, record_rows) floats for one robot, (S, record_rows, N) for a batch."""
        return np.asarray(self._rows, dtype=float)

    @staticmethod
    def record_of(rows, t0: float, h: float, summary=None) -> StepRecord:
        """The :class:`StepRecord` of recorded rows ((S, R) or (S, R, N), R = record_rows(L)) and the
        compiled stepper's summary of them, if it made one."""
        if rows.ndim == 3:  # (S, R, N) -> fields with the robot axis before the vector axis
            rows = rows.transpose(0, 2, 1)
        legs = (rows.shape[-1] - 5) // 3
        record = StepRecord(
            times=t0 + h * np.arange(len(rows)),
            step=h,
            torque=rows[..., 0:legs],
            force=rows[..., legs : legs + 3],
            normal=rows[..., legs + 3],
            leg_clearance=rows[..., legs + 5 : 2 * legs + 5],
            leg_rates=rows[..., 2 * legs + 5 : 3 * legs + 5],
        )
        object.__setattr__(record, "_tangential", rows[..., legs + 4])
        object.__setattr__(record, "_summary", summary)
        return record


AUTO_RATE_FACTOR = 0.3
"""With ``timestep="auto"``, h x (fastest rate at the start of an advance) stays below this:
the body's spin and the legs' rates (or, kinematic, the peak rate of their path) set
a limit of their own that gains and masses cannot predict (bang-bang kinematic
targets, a top-heavy robot falling over)."""


def _rate_limited_step(state, path_rate: float) -> float:
    fields = dynamics.state_fields(dynamics.legs_of(state.shape[-1]))
    body = float(np.max(np.linalg.norm(np.atleast_2d(state)[:, fields.body_rate], axis=-1)))
    legs = float(np.max(np.abs(state[..., fields.leg_rates])))
    fastest = max(body, legs, path_rate)
    return AUTO_RATE_FACTOR / fastest if fastest > 0.0 else math.inf


def _diagnose(config: SimConfig, state, t0: float, duration: float, h: float) -> str:
    """The message of a NumericalFailure: what blew up and the likely cause, from the start state."""
    state = np.atleast_2d(state)
    causes = []
    no_attitude = dynamics.not_rotations(state[:, dynamics.QUAT])  # (advance(check=False) takes any state)
    if np.any(no_attitude):
        causes.append("the start state's quaternion (entries 2:6) is no rotation (a norm far from 1): start "
                      "from a unit quaternion, or let advance check the state")
        state = state[~no_attitude]
    fields = config.fields
    with np.errstate(all="ignore"):
        body_rate = float(np.max(np.linalg.norm(state[:, fields.body_rate], axis=-1), initial=0.0))
        leg_rate = float(np.max(np.abs(state[:, fields.leg_rates]), initial=0.0))
        tilt = float(np.max(dynamics.tilt(state), initial=0.0))
    if config.legs == "servo":
        limit = stable_step_limit(config.model, config.robot, config.gains, config.integrator)
        if h > 0.8 * limit:
            causes.append(f"the step {h:.3g} s is near or past the leg servo's stability limit {limit:.3g} s")
    # Gyroscopic and leg-swing motion at rate w needs h w well below ~2.8 for RK4.
    fastest = max(body_rate, leg_rate)
    if h * fastest > 1.0:
        causes.append(f"the robot turns too fast for the step (|Omega| up to {body_rate:.3g} rad/s, leg rates up to "
                      f"{leg_rate:.3g} rad/s; h x rate = {h * fastest:.2g}, keep it below ~1)")  # fmt: skip
    if tilt >= dynamics.TILT_LIMIT:
        causes.append(f"the tilt {math.degrees(tilt):.1f} deg is past the rim limit of 90 deg, where the model ends")
    with np.errstate(all="ignore"):
        mass = dynamics.mass_matrix(state, config.robot, config.model)
    mass = mass[np.isfinite(mass).all(axis=(1, 2))]  # (eigvalsh fails on a non-finite one)
    if len(mass) and not np.all(_regular(mass)):
        causes.append("the generalised mass matrix is singular at the start state: some motion there moves no mass "
                      "(e.g. with mass_bottom = mass_pin = 0 and the legs upright), so the dynamics is undefined")
    if not causes:
        causes.append("no single cause found: try a smaller timestep; check masses and gains for extreme ratios")
    return (
        f"non-finite state after integrating {duration} s from t={t0} with step {h:.3g} s "
        f"({config.integrator}, model {config.model!r}, {config.legs} legs): " + "; ".join(causes)
    )


# ---------------------------------------------------------------------------
# Per-robot parameters (domain randomisation): advance's ``robots``.

PER_ROBOT_FIELDS = ("mass_bottom", "mass_pin", "mass_tip", "leg_length", "damping", "kp", "kd", "torque_limit", "leg_rate_limit")
"""What :func:`advance`'s ``robots`` may set per robot: fields of ``RobotParams`` (kg, m, N m s/rad),
of ``PDGains`` (N m/rad, N m s/rad) and ``SimConfig``'s motor limits (N m, rad/s); a leg with a
length or mass of its own scales it alike. The shell and gravity do not vary."""

_SERVO_FIELDS = ("kp", "kd", "torque_limit", "leg_rate_limit")


def robot_values(config: SimConfig, robots, num_robots: int | None) -> dict:
    """Every name of :data:`PER_ROBOT_FIELDS` to a (N,) float array (N = ``num_robots``, 1 for
    None, one robot's state): ``robots``' values, checked, the config's for names left out (the
    limits None where the config has none). ``robots`` maps names to (N,) arrays or numbers.

    Raises naming the problem: an unknown name, a wrong shape, NaN/inf, a mass, leg length, kp
    or limit <= 0, kd < 0, damping > 0, a motor limit where the config has no torque_limit,
    servo values with kinematic legs.
    """
    if not isinstance(robots, Mapping):
        raise TypeError(f"robots must be a dict from names of PER_ROBOT_FIELDS to values, got {type(robots).__name__}")
    for name in robots:
        if name not in PER_ROBOT_FIELDS:
            close = difflib.get_close_matches(str(name), PER_ROBOT_FIELDS, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            if name in ("radius", "gravity", "shell_axes"):
                hint = " (the shell and gravity are the config's for every robot)"
            raise ValueError(f"unknown per-robot parameter {name!r}{hint}: expected some of {', '.join(PER_ROBOT_FIELDS)}")
    if config.legs == "kinematic" and any(name in robots for name in _SERVO_FIELDS):
        raise ValueError(f"robots sets {', '.join(n for n in _SERVO_FIELDS if n in robots)}: servo values, and "
                         "kinematic legs have no servo")  # fmt: skip
    if config.torque_limit is None and ("torque_limit" in robots or "leg_rate_limit" in robots):
        raise ValueError("robots sets a motor limit (torque_limit or leg_rate_limit), and the config has no torque_limit: "
                         "give SimConfig a torque_limit to turn the motor model on")  # fmt: skip
    n = 1 if num_robots is None else num_robots
    defaults = {**{name: getattr(config.robot, name) for name in PER_ROBOT_FIELDS[:5]}, "kp": config.gains.kp,
                "kd": config.gains.kd, "torque_limit": config.torque_limit, "leg_rate_limit": config.leg_rate_limit}  # fmt: skip
    values = {}
    for name, default in defaults.items():
        if name not in robots:
            values[name] = None if default is None else np.full(n, float(default))
            continue
        value = np.asarray(robots[name])
        if value.dtype.kind not in "fiu":
            raise TypeError(f"robots[{name!r}] must be real numbers, got {value.dtype} values")
        if value.ndim > 1 or (value.ndim == 1 and len(value) != n):
            wanted = "one robot's state takes a number or shape (1,)" if num_robots is None else f"(N,) = ({n},) for {n} robots"
            raise ValueError(f"robots[{name!r}] has shape {value.shape}: {wanted}")
        value = np.array(np.broadcast_to(value, (n,)), dtype=float)
        bad = ~np.isfinite(value)
        if not bad.any():
            bad = value > 0.0 if name == "damping" else value < 0.0 if name == "kd" else ~(value > 0.0)
        if bad.any():
            i = int(np.argmax(bad))
            rule = {"damping": "<= 0 (the paper's sign: torque k*w with k < 0 dissipates)", "kd": ">= 0"}.get(name, "positive")
            raise ValueError(f"robots[{name!r}] must be finite and {rule}, got {float(value[i])!r} for robot {i}")
        values[name] = value
    return values


def _robot_scene(config: SimConfig, values: dict):
    """(constants, gains, torque limit, rate limit) of :func:`robot_values`' robots, each field an
    (N,) array (the shell's and gravity the config's floats; a limit None where the config has none)."""
    gains = compiled._Gains(values["kp"], values["kd"])
    return dynamics.constants(config.robot, config.model, values), gains, values["torque_limit"], values["leg_rate_limit"]


def total_mass(config: SimConfig, values: dict) -> np.ndarray:
    """kg, (N,): each robot's total mass, from :func:`robot_values`' values."""
    return dynamics.constants(config.robot, config.model, values).total_mass


def _scene_row(scene, i: int):
    """Robot i's part of a per-robot scene, on Python floats (None for None)."""
    if scene is None:
        return None
    k, gains, torque_limit, rate_limit = scene

    def row(fields):
        return [v if isinstance(v, float) else float(v[i]) for v in fields]

    return (dynamics.Constants(*row(k)), compiled._Gains(*row(gains)),
            None if torque_limit is None else float(torque_limit[i]), None if rate_limit is None else float(rate_limit[i]))  # fmt: skip


def advance(
    config: SimConfig, state, t0: float, duration: float, targets, *, check=True, record=False, workers: int = 1,
    robots=None,
):
    """Integrate ``state`` from time t0 over ``duration`` seconds with fixed steps.

    The step is the largest that divides ``duration`` evenly and is no larger than
    ``config.step``. Returns the new state (same shape as ``state``), and with
    ``record=True`` also a :class:`StepRecord`: ``(state, record)``.

    With ``config.legs == "kinematic"`` the legs follow the targets' own path exactly when
    they are on it at t0, else a minimum-jerk quintic onto that path over ``duration``; only
    the body's equations are integrated.

    ``workers`` > 1 shares a batch's robots among that many of numba's threads (the compiled
    stepper only), bit-identical to one worker.

    ``check`` validates the state (:func:`check_state`) and the targets against it
    (:func:`check_targets`); callers that made both themselves, as the envs do, pass False.
    Raises :class:`NumericalFailure` if the result is not finite.

    ``robots`` gives each robot parameters of its own: a dict from names of
    :data:`PER_ROBOT_FIELDS` to (N,) arrays, one entry a robot (one robot's state: N = 1), or numbers
    (every robot); names left out take the config's values (always checked: :func:`robot_values`).
    Each robot then steps exactly as it would alone with a config of its own values, record
    included. The step is still the config's, checked against ``config.robot`` and
    ``config.gains`` only: parameters that stiffen the servo (a larger kp or kd, a lighter leg)
    need a step within their own :func:`stable_step_limit`.
    """
    t0 = real_number("t0", t0)
    duration = real_number("duration", duration)
    if check:
        state = check_state(state, config.robot.num_legs)
        check_targets(targets, state, t0)
    workers = whole_number("workers", workers)
    values = None if robots is None else robot_values(config, robots, None if np.ndim(state) == 1 else len(state))
    if duration < 0.0:
        raise ValueError(f"duration must be a non-negative finite number of seconds, got {duration}")
    if duration == 0.0:
        if record:
            raise ValueError("advance(record=True) needs a positive duration: a record of no substeps is empty")
        return np.array(state)
    blend = None
    path_rate = 0.0
    fields = config.fields
    if config.legs == "kinematic":
        angles, target_rates, _ = targets.leg_targets(t0)
        legs, rates = state[..., fields.leg_angles], state[..., fields.leg_rates]
        off_angle = [legs[..., m] - a for m, a in enumerate(angles)]
        off_rate = [rates[..., m] - r for m, r in enumerate(target_rates)]
        if max(float(np.max(np.abs(v))) for v in off_angle + off_rate) > 1e-9:
            blend = (t0, tuple(_blend_coefficients(a, r, duration) for a, r in zip(off_angle, off_rate)))
            # A minimum-jerk move of b0 in T peaks at 1.875 b0 / T.
            path_rate = float(np.max(np.abs(off_angle))) * 1.875 / duration + float(np.max(np.abs(off_rate)))
        path_rate += float(np.max(np.abs(np.asarray(target_rates, dtype=float))))
    step = config.step
    if config.timestep == "auto":
        step = min(step, _rate_limited_step(state, path_rate))
    n_steps, h = _substeps(duration, step)
    scene = None if values is None else _robot_scene(config, values)
    out, rows, summary = _advance_rows(config, state, t0, targets, blend, record, workers, n_steps, h, scene)
    if config.legs == "kinematic":
        # The legs' path is known exactly: remove the integrator's tiny drift from it.
        angles, rates = _leg_path_end(targets, blend, t0 + duration)
        for m, (angle, rate) in enumerate(zip(angles, rates)):
            out[..., fields.leg_angles.start + m], out[..., fields.leg_rates.start + m] = angle, rate
    if not np.isfinite(out).all():
        raise NumericalFailure(_diagnose(config, state, t0, duration, h))
    if record:
        return out, _Recorder.record_of(rows, t0, h, summary)
    return out


def check_targets(targets, state, t0: float = 0.0) -> None:
    """Raise naming the problem unless ``targets`` is a leg-target source for the robots of
    ``state`` ((9 + 2L,) or (N, 9 + 2L), checked): one with a ``leg_targets(t)`` method whose values
    at ``t0`` are one a leg, each a number (every robot's) or an (N,) array (one per robot)."""
    if not callable(getattr(targets, "leg_targets", None)):
        raise TypeError(
            "targets must be a leg-target source with a leg_targets(t) method (rrrobot_gym.control's Gait, "
            f"HeldTargets or RampTargets), got {type(targets).__name__}"
        )
    robots = 1 if state.ndim == 1 else state.shape[0]
    legs = dynamics.legs_of(state.shape[-1])
    values = targets.leg_targets(t0)
    if any(len(v) != legs for v in values):
        raise ValueError(f"the leg targets are for {len(values[0])} legs, the robot has {legs}")
    for value in (v for triple in values for v in triple):
        shape = np.shape(value)
        if not shape:
            continue
        if state.ndim == 1:
            raise ValueError(f"one robot's state takes leg targets that are numbers, got arrays of shape {shape}")
        if len(shape) > 1:
            raise ValueError(f"leg targets must be numbers or (N,) arrays, one entry a robot, got shape {shape}")
        if shape[0] != robots:
            raise ValueError(f"the leg targets are for {shape[0]} robots, the state has {robots}")


def _substeps(duration: float, step: float):
    """(n, h): the fewest substeps of at most ``step`` that divide ``duration`` evenly."""
    n_steps = max(1, math.ceil(duration / step - 1e-9))
    return n_steps, duration / n_steps


def _advance_rows(config: SimConfig, state, t0, targets, blend, record, workers, n_steps, h, scene=None):
    """The integration of :func:`advance`: (the states after n_steps of h, the record's rows or
    None, the compiled stepper's summary or None); ``scene``: per-robot (:func:`_robot_scene`) or None."""
    described = _compiled_targets(config, targets)
    if described is not None:
        return compiled.integrate(config, described, state, t0, h, n_steps, record, workers, scene)
    if workers > 1:
        raise ValueError(
            f"advance(workers={workers}) shares robots among numba's threads, and this scene runs on numpy "
            f"(backend {config.backend!r}, {config.legs} legs, integrator {config.integrator!r}, "
            f"targets {type(targets).__name__}{'' if compiled.available() else ', numba not installed'}): use workers=1"
        )
    if state.ndim == 1:
        try:
            out, recorder = _integrate(config, targets, blend, state.tolist(), t0, h, n_steps, record, _scene_row(scene, 0))
        except (OverflowError, ValueError, ZeroDivisionError):  # math.* on inf/NaN floats
            raise NumericalFailure(_diagnose(config, state, t0, n_steps * h, h)) from None
        return np.array(out), None if recorder is None else recorder.rows, None
    if state.shape[0] <= ROW_BY_ROW_MAX:
        return (*_integrate_rows(config, targets, blend, state, t0, h, n_steps, record, scene), None)
    return (*_integrate_batch(config, targets, blend, state, t0, h, n_steps, record, scene), None)


def takes_compiled(config: SimConfig) -> bool:
    """True if :func:`advance` runs this config's scene on the compiled stepper (for leg targets
    it knows): not ``backend="numpy"``, a scene it covers, and numba asked for or installed."""
    if config.backend == "numpy" or not compiled.supports(config):
        return False
    return config.backend == "numba" or compiled.available()


def _compiled_targets(config: SimConfig, targets):
    """The targets as :func:`rrrobot_gym.compiled.target_arrays` describes them if :func:`advance`
    takes the compiled stepper for this scene and these targets, else None."""
    if not takes_compiled(config):
        return None
    described = compiled.target_arrays(targets)
    if described is not None:
        return described
    if config.backend == "numba":
        raise TypeError(
            f"backend 'numba' knows the leg targets of rrrobot_gym.control (RampTargets, HeldTargets, Gait) and "
            f"gait_search.SinusoidGait without a ramp, not {type(targets).__name__}: use backend 'auto' or "
            f"'numpy' for it"
        )
    return None


def _integrate(config: SimConfig, targets, blend, y, t0: float, h: float, n_steps: int, record: bool, scene=None):
    """Run the configured integrator on the state components y (Python floats, or (N,) arrays):
    (y after n_steps steps of h, the recorder or None); ``scene`` as :func:`_stage_fns` takes it."""
    momentum = dynamics.integrates_momentum(config.model)
    f, first = _stage_fns(config, targets, blend, scene, momentum)
    legs = config.robot.num_legs
    recorder = _Recorder(first, n_steps, None if isinstance(y[0], float) else len(y[0]), legs) if record else None
    if momentum:  # (the body rows hold the momentum inside the call only)
        k, layout = (dynamics.constants(config.robot, config.model) if scene is None else scene[0]), dynamics.leg_layout(config.robot)
        y = list(y)
        dynamics.to_momentum(y, 0, 1, k, layout)
    y = INTEGRATORS[config.integrator].step(f, recorder or f, t0, y, h, n_steps)
    if momentum:
        dynamics.from_momentum(y, 0, 1, k, layout)
    return y, recorder



ROW_BY_ROW_MAX = 20
"""A batch of at most this many robots is integrated one robot at a time on Python floats, where
numpy's per-call overhead costs more than the loop (docs/notes/layout.md). It depends on the size only."""


def _integrate_rows(config: SimConfig, targets, blend, state, t0: float, h: float, n_steps: int, record: bool, scene=None):
    """:func:`_integrate` of a small batch (n, 9 + 2L) robot by robot on floats: (the states,
    [the record's rows (S, record_rows, n) or None]). A robot that blows up gets NaN rows, as in a batch."""
    out = np.empty_like(state)
    rows = []
    # A source's own ``robot(i)`` gives one robot's targets on floats; any other is indexed at every evaluation.
    one_robot = getattr(targets, "robot", None) or (lambda i: _RowOf(targets, i))
    for i in range(len(state)):
        try:
            y, recorder = _integrate(config, one_robot(i), _blend_row(blend, i),
                                     state[i].tolist(), t0, h, n_steps, record, _scene_row(scene, i))  # fmt: skip
            out[i] = y
            rows.append(None if recorder is None else recorder.rows)
        except (OverflowError, ValueError, ZeroDivisionError):  # math.* on inf/NaN floats
            out[i] = np.nan
            rows.append(np.full((n_steps, compiled.record_rows(config.robot.num_legs)), np.nan) if record else None)
    return out, np.stack(rows, axis=2) if record else None


def _blend_row(blend, i):
    """Robot i's part of a kinematic blend (t0, one set of coefficients a leg), on floats."""
    if blend is None:
        return None
    t_blend, coeffs = blend
    return t_blend, tuple(tuple(float(_take(v, i)) for v in c) for c in coeffs)


def _integrate_batch(config: SimConfig, targets, blend, state, t0: float, h: float, n_steps: int, record: bool, scene=None):
    """:func:`_integrate` on a batch (n, 9 + 2L) as (n,) arrays: (the states, the record's rows
    (S, record_rows, n) or None)."""
    with np.errstate(all="ignore"):  # a blow-up is reported by advance, by name, not as warnings
        y, recorder = _integrate(config, targets, blend, list(np.array(state.T)), t0, h, n_steps, record, scene)
    return np.stack(y, axis=1), (None if recorder is None else recorder.rows)


def _take(value, i):
    """``value[i]`` for a per-robot array, ``value`` itself for a number shared by all robots."""
    return value[i] if isinstance(value, np.ndarray) and value.ndim else value


class _RowOf:
    """A leg-target source as seen by robot i of a batch, on Python floats."""

    def __init__(self, targets, i):
        self._targets, self._i = targets, i

    def leg_targets(self, t):
        return tuple(tuple(float(_take(v, self._i)) for v in triple) for triple in self._targets.leg_targets(t))


@dataclass(frozen=True)
class Trajectory:
    """Sampled states of one robot or a batch: ``times`` (T,) s, ``states`` (T, 9 + 2L) or (T, N, 9 + 2L)."""

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
        """phi_1 .. phi_L, rad."""
        return self.states[..., self.config.fields.leg_angles]

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


MAX_SAMPLES = 10**8
"""The most samples :func:`simulate` and :func:`simulate_reference` keep (``duration / sample_dt``):
13 float64s each for the paper's robot, 10.4 GB for one robot."""


def _sample_times(duration: float, sample_dt: float):
    duration, sample_dt = real_number("duration", duration), real_number("sample_dt", sample_dt)
    if duration <= 0.0:
        raise ValueError(f"duration must be a positive finite number of seconds, got {duration}")
    if sample_dt <= 0.0:
        raise ValueError(f"sample_dt must be a positive finite number of seconds, got {sample_dt}")
    ratio = duration / sample_dt
    if not ratio <= MAX_SAMPLES:  # (before round(): an infinite ratio has no integer)
        raise ValueError(
            f"duration {duration:g} s sampled every {sample_dt:g} s is {ratio:.3g} samples, more than {MAX_SAMPLES:.0e}: "
            "a longer sample_dt or a shorter duration"
        )
    return np.linspace(0.0, duration, max(1, round(ratio)) + 1)


def _kinematic_path(config: SimConfig, targets, state):
    """With kinematic legs, a scripted run's legs follow the targets blended in from the start state."""
    if config.legs != "kinematic":
        return targets
    fields = config.fields
    legs, rates = state[..., fields.leg_angles], state[..., fields.leg_rates]
    return SmoothStart(targets, [legs[..., m] for m in range(legs.shape[-1])], [rates[..., m] for m in range(rates.shape[-1])])


def simulate(config: SimConfig, targets, duration: float, *, state=None, sample_dt: float = 0.01):
    """Run the fixed-step integrator and sample the state every ``sample_dt`` seconds.

    ``state`` defaults to :func:`initial_state` (one robot). Time starts at 0. With
    kinematic legs the legs follow :class:`SmoothStart` from the start state into the targets.
    """
    legs = config.robot.num_legs
    state = check_state(initial_state(num_legs=legs) if state is None else state, legs)
    check_targets(targets, state)
    targets = _kinematic_path(config, targets, state)
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

    legs = config.robot.num_legs
    state = check_state(initial_state(num_legs=legs) if state is None else state, legs)
    check_targets(targets, state)
    rtol, atol = real_number("rtol", rtol), real_number("atol", atol)
    if rtol <= 0.0 or atol < 0.0:
        raise ValueError(f"rtol must be positive and atol non-negative, got rtol={rtol!r}, atol={atol!r}")
    times = _sample_times(duration, sample_dt)
    shape = state.shape
    f = _derivative_fn(config, _kinematic_path(config, targets, state))
    if state.ndim == 1:
        fun = f
    else:

        def fun(t, flat):
            return f(t, flat.reshape(config.fields.size, -1)).ravel()

    sol = solve_ivp(fun, (0.0, times[-1]), state.T.ravel(), method=method, t_eval=times, rtol=rtol, atol=atol)
    if not sol.success:
        raise NumericalFailure(f"reference integration failed: {sol.message}")
    out = sol.y.reshape(config.fields.size, *shape[:-1], len(times))
    out = np.moveaxis(out, 0, -1)
    out = np.moveaxis(out, -2, 0) if out.ndim == 3 else out
    out = np.ascontiguousarray(out)
    out[..., dynamics.QUAT] /= np.linalg.norm(out[..., dynamics.QUAT], axis=-1, keepdims=True)
    return Trajectory(times, out, config)
