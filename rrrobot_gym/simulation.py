"""Integrating the RRRobot: fixed-step RK4 (or RK3) for stepping, solve_ivp as the reference.

Both paths evaluate :func:`rrrobot_gym.dynamics.derivative_kernel` (the one
implementation behind ``state_derivative``); the leg servo is evaluated inside
every derivative call (a continuous-time PD controller), so a scripted gait's
targets are tracked between steps, not sampled once per step.

Options that skip work a scene does not need (``SimConfig``): ``legs="kinematic"``
(the legs follow a smooth path exactly; the stiff servo leaves the integration) and
``timestep="auto"`` (a step derived from the gains, masses and model). A step beyond
the servo's stability limit is refused at construction.

States are arrays shaped (13,) for one robot or (N, 13) for a batch (layout in
:data:`rrrobot_gym.dynamics.STATE_FIELDS`). Internally a batch is integrated
component-first, (13, N), so each component is a contiguous array; one robot is
integrated on Python floats, which is several times faster than numpy at N = 1.
"""

from __future__ import annotations

import cmath
import ctypes
import functools
import math
import threading
from dataclasses import dataclass, field, replace

import numpy as np

from . import compiled, dynamics
from .control import limit_torque, pd_torque
from .params import PDGains, RobotParams, check_model, real_number, rotation_point_depth, whole_number

INTEGRATORS = ("rk4", "rk3", "rosw", "etdrk4b", "rk4_locked")
"""Fixed-step integrators for stepping (``SimConfig.integrator``): "rk4", classical
Runge-Kutta (4 derivative evaluations a step); "rk3", Kutta's third-order method
(3 evaluations; a step ~12 % shorter gives the same error here, see the benchmark);
"rosw", the Rosenbrock-W method ROS34PW2 (4 evaluations and a 2x2 solve a step), linearly
implicit in the leg servo, so no servo stability limit: it pays for stiff servos (kd = 5,
kp = 200: within 0.1 mm at 1/3000 s, where RK4's auto step is 1/33,000 s), not for the default gains,
where accuracy, not stability, sets the step (``python -m benchmarks.work_precision``);
"etdrk4b", Krogstad's exponential Runge-Kutta method ETDRK4-B (4 evaluations a step), which
integrates the servo's linear part exactly (its phi-functions in closed form) and the rest
explicitly: no servo stability limit, and order 4 where the rest is smooth, as on a scripted
gait (within 0.4 mm after 50 s at 1/80 s, 16 evaluations an env step, from a fine first env
step); not on a policy's path, whose every new ramp kicks the servo (docs/benchmarks.md);
"rk4_locked", RK4's tableau on the body's locked rate (:func:`rrrobot_gym.dynamics.locked_share`)
in place of its rate: the same steps and stability limit as "rk4", and the leg torques act on
the legs' rows alone, so a new ramp's kick is followed far more closely (at 1/300 s ~100x closer
on the gaits and ~25x on a policy's path; ``python -m benchmarks.locked_rate``). Servo legs, a
fixed step."""

LOCKED_INTEGRATORS = ("etdrk4b", "rk4_locked")
"""The integrators that step the body's locked rate in rows 8-10 (:func:`rrrobot_gym.dynamics.locked_share`,
the body rows of the momentum, which the leg torques do not change): each advance converts the
state to it and back."""

SERVO_INTEGRATORS = {"rosw": "implicitly", "etdrk4b": "exactly"}
"""The integrators that treat the leg servo's stiff linear part implicitly or exactly: servo legs
only, a fixed step, no stability limit on it."""

LEG_MODES = ("servo", "kinematic")
"""How the legs move (``SimConfig.legs``): "servo" integrates the PD servo with the
body (the paper's model); "kinematic" makes the legs follow a smooth path to their
targets exactly, so the stiff servo leaves the integration (see :func:`advance`)."""

BACKENDS = ("auto", "numpy", "numba")
"""How :func:`advance` integrates (``SimConfig.backend``): "numba", the compiled stepper of
:mod:`rrrobot_gym.compiled` (numba installed; servo legs, RK4, and the ramp, held or sinusoid
targets of :mod:`rrrobot_gym.control`); "numpy", the Python and numpy steppers here; "auto"
(default), the compiled stepper where numba is installed and it covers the scene and targets,
else numpy. Both integrate the same equations (:func:`rrrobot_gym.dynamics.derivative_kernel`)."""

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
    # Servo legs: the first start_halves substeps of every advance() call are taken as two half
    # steps each, where a control step's new targets kick the servo's fast mode (4 evaluations
    # more each with RK4; benchmarks.policy_replay). 0: uniform steps.
    start_halves: int = 0
    # "auto", "numpy" or "numba" (BACKENDS): how, not what, is integrated, so it is left out of the repr
    # (which describes the physics: tests/reference_paths.py keys its stored paths on it)
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
        object.__setattr__(self, "start_halves", whole_number("SimConfig.start_halves", self.start_halves, minimum=0))
        if self.legs == "kinematic" and self.start_halves:
            raise ValueError(
                "SimConfig.start_halves applies to servo legs (it refines where new targets kick the servo); "
                "kinematic legs have no servo"
            )
        if self.legs == "kinematic" and self.torque_limit is not None:
            raise ValueError("SimConfig.torque_limit applies to servo legs; kinematic legs follow their path whatever it takes")
        if self.integrator not in INTEGRATORS:
            raise ValueError(f"unknown integrator {self.integrator!r}: expected one of {', '.join(INTEGRATORS)}")
        if self.legs not in LEG_MODES:
            raise ValueError(f"unknown leg mode {self.legs!r}: expected one of {', '.join(LEG_MODES)}")
        if not isinstance(self.robot, RobotParams):
            raise TypeError(f"SimConfig.robot must be a RobotParams, got {type(self.robot).__name__}")
        if not isinstance(self.gains, PDGains):
            raise TypeError(f"SimConfig.gains must be a PDGains, got {type(self.gains).__name__}")
        if self.integrator in SERVO_INTEGRATORS and self.legs != "servo":
            raise ValueError(
                f"integrator {self.integrator!r} treats the leg servo {SERVO_INTEGRATORS[self.integrator]}; "
                f"kinematic legs have no servo: use 'rk4'"
            )
        if self.integrator in LOCKED_INTEGRATORS and self.legs != "servo":
            raise ValueError(
                f"integrator {self.integrator!r} steps the body's locked rate, the share of the momentum the leg "
                "servo's torques do not reach; kinematic legs have no servo: use 'rk4'"
            )
        if self.legs == "servo" and not math.isfinite(servo_fastest_rate(self.model, self.robot, self.gains)):
            raise ValueError(
                f"the leg servo's fastest pole overflows floating point (kp={self.gains.kp}, kd={self.gains.kd}, "
                f"{self.model} model, {self.robot}): no step can follow it"
            )
        if isinstance(self.timestep, str):
            if self.timestep != "auto":
                raise ValueError(f"SimConfig.timestep must be a number of seconds or 'auto', got {self.timestep!r}")
            if self.integrator not in AUTO_INTEGRATORS:
                raise ValueError(
                    f"SimConfig.timestep='auto' is calibrated for the explicit integrators ({', '.join(AUTO_INTEGRATORS)}); "
                    f"give integrator {self.integrator!r} a fixed step (see benchmarks.work_precision)"
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
        if self.legs == "servo" and self.integrator not in SERVO_INTEGRATORS:  # no servo stability limit
            limit = stable_step_limit(self.model, self.robot, self.gains, self.integrator)
            if step > limit:
                raise ValueError(
                    f"SimConfig.timestep {step:.4g} s is beyond the stability limit {limit:.4g} s of "
                    f"{self.integrator} for the leg servo (kp={self.gains.kp}, kd={self.gains.kd}, tip mass "
                    f"{self.robot.mass_tip} kg, model {self.model!r}; fastest servo pole "
                    f"{servo_fastest_rate(self.model, self.robot, self.gains):.4g} 1/s): the run would blow up. "
                    + ("Use a smaller timestep, timestep='auto', or legs='kinematic'" if self.integrator in AUTO_INTEGRATORS
                       else "Use a smaller timestep")
                )

    @property
    def step(self) -> float:
        """s, the step actually used: ``timestep``, or the scene-derived step when it is "auto"."""
        return self._step

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
    try:
        angles = np.array(leg_angles, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"leg_angles must be two numbers (rad), got {leg_angles!r}") from None
    if angles.shape != (2,):
        raise ValueError(f"leg_angles must be two numbers (rad), got shape {angles.shape}")
    if not np.all(np.isfinite(angles)):
        raise ValueError(f"leg_angles must be finite, got {leg_angles!r}")
    state = np.zeros(dynamics.STATE_SIZE)
    state[dynamics.QUAT] = (1.0, 0.0, 0.0, 0.0)
    state[dynamics.LEG_ANGLES] = angles
    if num_robots is None:
        return state
    return np.tile(state, (whole_number("num_robots", num_robots), 1))


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
    off = (norm < 0.5) | (norm > 2.0)
    if np.any(off):
        raise ValueError(f"state quaternion (entries 2:6) must be a unit quaternion, got norm {norm[off].flat[0]:.3g}")
    arr[..., dynamics.QUAT] /= norm[..., None]
    return arr


# ---------------------------------------------------------------------------
# The scene's time scales: a step derived from gains, masses and model.


def _regular(mass) -> np.ndarray:
    """(K,) bool: which of the finite mass matrices (K, 5, 5) are regular, their least eigenvalue
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
    tilts = np.linspace(0.0, dynamics.TILT_LIMIT, 7)
    phi1, phi2, tilt_angle, axis_angle = np.meshgrid(angles, angles, tilts, np.linspace(0, math.pi, 5), indexing="ij")
    states = np.zeros(phi1.shape + (dynamics.STATE_SIZE,))
    states[..., 2] = np.cos(0.5 * tilt_angle)
    states[..., 3] = np.sin(0.5 * tilt_angle) * np.cos(axis_angle)
    states[..., 4] = np.sin(0.5 * tilt_angle) * np.sin(axis_angle)
    states[..., 6], states[..., 7] = phi1, phi2
    with np.errstate(over="ignore", invalid="ignore"):
        mass = dynamics.mass_matrix(states.reshape(-1, dynamics.STATE_SIZE), robot, model)
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


def _amplification(integrator: str, z: complex) -> float:
    """|R(z)|, the integrator's growth factor per step on y' = lambda y, z = h lambda."""
    poly = 1.0 + z + z * z / 2.0 + z**3 / 6.0
    if integrator in ("rk4", "rk4_locked"):  # (the locked rate changes variables, not the servo's poles)
        poly += z**4 / 24.0
    return abs(poly)


def stable_step_limit(model: str, robot: RobotParams, gains: PDGains, integrator: str = "rk4") -> float:
    """s, the largest step at which ``integrator`` stays stable on the leg servo's fastest poles."""
    poles = [p for p in servo_poles(model, robot, gains) if p != 0]
    lo, hi = 0.0, 10.0 / max(abs(p) for p in poles)
    for _ in range(60):  # bisection on the first step where some pole is amplified
        mid = 0.5 * (lo + hi)
        if all(_amplification(integrator, mid * p) <= 1.0 + 1e-12 for p in poles):
            lo = mid
        else:
            hi = mid
    return lo


SERVO_STEP_FACTOR = {("rk4", "plane"): 1.28, ("rk4", "pivot"): 1.08, ("rk3", "plane"): 1.13, ("rk3", "pivot"): 0.95}
"""h |lambda_servo| of the auto step for servo legs, per integrator and model (RK4 is
stable up to 2.785 on the real axis, RK3 up to 2.513). Calibrated by
``benchmarks.work_precision`` to the cheapest step under 1 mm of contact error after
50 s on every gait: plane RK4 1/300 s, pivot RK4 1/140 s, plane RK3 1/340 s (pivot
RK3 is scaled from pivot RK4, not swept). The models differ: the same h |lambda|
costs the pivot model more contact error than the plane model."""

AUTO_INTEGRATORS = tuple(dict.fromkeys(integrator for integrator, _ in SERVO_STEP_FACTOR))
"""The integrators ``timestep="auto"`` is calibrated for (SERVO_STEP_FACTOR's); others take a fixed step."""

KINEMATIC_STEP = 1.0 / 40.0
"""s, the auto step with kinematic legs: the fastest remaining motion is the body
rocking (~7 rad/s) driven at the gait frequency (8 rad/s). At 1/40 s the contact error
after 50 s is ~0.03 mm (1/20 s: ~0.4 mm; ``benchmarks.work_precision``)."""


def scene_timestep(model: str, robot: RobotParams, gains: PDGains, legs: str = "servo", integrator: str = "rk4") -> float:
    """s, a step derived from the scene rather than one fixed number (``timestep="auto"``).

    Servo legs: the stiffest motion is the overdamped leg servo, |lambda| =
    :func:`servo_fastest_rate`; h = SERVO_STEP_FACTOR[integrator, model] / |lambda|, and never
    more than 0.8 of the stability limit (:func:`stable_step_limit`). Kinematic legs:
    the servo is gone and the body's rocking sets the step (:data:`KINEMATIC_STEP`).
    """
    if legs == "kinematic":
        return KINEMATIC_STEP
    return min(
        SERVO_STEP_FACTOR[integrator, model] / servo_fastest_rate(model, robot, gains),
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
        (a1, a2), (r1, r2), _ = targets.leg_targets(self.t_start)
        self._coeffs = (
            _blend_coefficients(leg_angles[0] - a1, leg_rates[0] - r1, blend_time),
            _blend_coefficients(leg_angles[1] - a2, leg_rates[1] - r2, blend_time),
        )

    def leg_targets(self, t):
        (a1, a2), (r1, r2), (c1, c2) = self.targets.leg_targets(t)
        s = t - self.t_start
        b1, v1, acc1 = _blend(self._coeffs[0], s)
        b2, v2, acc2 = _blend(self._coeffs[1], s)
        return (a1 + b1, a2 + b2), (r1 + v1, r2 + v2), (c1 + acc1, c2 + acc2)


# ---------------------------------------------------------------------------
# Fixed-step integration.

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # mallopt's options (glibc's malloc.h)
_MMAP_THRESHOLD_MAX = 32 << 20
"""bytes: the largest mmap threshold glibc's own dynamic tuning reaches on a 64-bit machine."""
_heap_kept_for = 0  # the trim threshold set so far (0: malloc untouched)


def _keep_freed_heap(num_robots: int):
    """Tune glibc's malloc for batches of ``num_robots``, once per process (raised, never lowered).

    A derivative evaluation on N robots allocates and frees ~250 temporary arrays of 8N
    bytes, and the step's record and measures arrays of up to 10 x 15 x 8N. With glibc's
    trim threshold at its default (128 KiB) the top of the heap goes back to the OS after
    every evaluation and is faulted back in page by page on the next; so the trim threshold is
    raised to the batch's working set (``python -m benchmarks.malloc_tuning``: at N = 4096 the
    env runs ~8 % faster than under glibc's untouched, self-adapting defaults, in as much memory).

    This is process-wide and left in place on purpose: glibc turns off its own dynamic mmap
    threshold the moment any threshold is set through mallopt, and nothing turns it back on.
    Putting the trim threshold back to 128 KiB after each integration (as an earlier version
    did) therefore left every later array of 128 KiB or more, ours or the caller's, mmapped
    and page-faulted afresh: elementwise operations on the (15, 4096) record 10-15x slower.
    So the mmap threshold is set to the ceiling glibc's dynamic tuning would itself reach
    (32 MiB), and freed heap up to the trim threshold stays with the process. Does nothing off glibc.
    """
    global _heap_kept_for
    mallopt = _mallopt()
    trim = min(max(64 << 20, 4096 * num_robots), 2**31 - 1)
    if mallopt is None or trim <= _heap_kept_for:
        return
    mallopt(_M_MMAP_THRESHOLD, ctypes.c_int(_MMAP_THRESHOLD_MAX))
    mallopt(_M_TRIM_THRESHOLD, ctypes.c_int(trim))
    _heap_kept_for = trim


@functools.lru_cache(maxsize=1)
def _mallopt():
    try:
        return ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # not glibc: nothing to tune
        return None


def _stage_fns(config: SimConfig, targets, blend=None, locked=False):
    """(f, first) for components c (floats or (N,) arrays): f(t, c) -> 13 derivative
    components; first(t, c, mobility_out=None, contact_out=None) -> (the same, the two leg
    torques applied), filling ``mobility_out`` (servo legs) and ``contact_out`` when asked
    (:func:`rrrobot_gym.dynamics.derivative_kernel`).

    The steppers call ``first`` at the start of every substep and ``f`` at the other stages,
    so the torques the integrator applied come from the evaluation it makes anyway. ``locked``
    (servo legs; the exponential step): rows 8-10 are the locked rate, not the body rate
    (``derivative_kernel(locked=True)``).
    ``blend`` = (t0, coeffs1, coeffs2) adds a transition path to the targets (kinematic legs).
    """
    k = dynamics.constants(config.robot, config.depth)
    kernel = dynamics.derivative_kernel
    leg_targets = targets.leg_targets
    if config.legs == "kinematic":
        if blend is None:

            def accel(t):
                return leg_targets(t)[2]

        else:
            t_blend, coeffs1, coeffs2 = blend

            def accel(t):
                acc1, acc2 = leg_targets(t)[2]
                s = t - t_blend
                return acc1 + _blend(coeffs1, s)[2], acc2 + _blend(coeffs2, s)[2]

        def f(t, c):
            return kernel(c, None, k, accel(t))

        def first(t, c, mobility_out=None, contact_out=None):
            torque = [0.0, 0.0]
            return kernel(c, None, k, accel(t), torque, contact_out=contact_out), tuple(torque)

        return f, first
    gains, torque_limit, rate_limit = config.gains, config.torque_limit, config.leg_rate_limit

    if torque_limit is None:

        def torque(t, c):
            return pd_torque(gains, (c[6], c[7]), (c[11], c[12]), leg_targets(t))

    else:

        def torque(t, c):
            rates = (c[11], c[12])
            return limit_torque(pd_torque(gains, (c[6], c[7]), rates, leg_targets(t)), rates, torque_limit, rate_limit)

    body = dynamics.derivative_and_mobility  # (derivative_kernel's own body: one Python call less an evaluation)

    def f(t, c):
        return body(c, torque(t, c), k, False, None, None, None, locked)[0]

    def first(t, c, mobility_out=None, contact_out=None):
        applied = torque(t, c)
        return kernel(c, applied, k, mobility_out=mobility_out, contact_out=contact_out, locked=locked), applied

    f.locked = first.locked = locked  # the variable of rows 8-10, which the locked steppers check
    f.constants = k  # (what they convert with)
    return f, first


def _derivative_fn(config: SimConfig, targets, kinematic_legs: bool = False):
    """f(t, y) for a component-first state y: shape (13,) (one robot) or (13, N), as an array."""
    if kinematic_legs and config.legs != "kinematic":
        config = replace(config, legs="kinematic")
    f, _ = _stage_fns(config, targets)

    def g(t, y):
        return np.array(f(t, y.tolist() if y.ndim == 1 else y))

    return g


def _normalize_quat_floats(y):
    """Scale the quaternion (entries 2:6) of a state as 13 rows (Python floats, or the (N,) arrays of
    the exponential step's batch rows) to unit length, in place."""
    norm2 = y[2] * y[2] + y[3] * y[3] + y[4] * y[4] + y[5] * y[5]
    inv = 1.0 / (math.sqrt(norm2) if isinstance(norm2, float) else np.sqrt(norm2))
    y[2] *= inv
    y[3] *= inv
    y[4] *= inv
    y[5] *= inv


def _rk4_floats(f, t, y, h, n_steps, first=None):
    """RK4 on one robot as a list of 13 Python floats (numpy costs more than it saves at N = 1).

    ``first``, if given, evaluates the derivative at the start of each substep (the
    recorder of :func:`advance`); every stepper takes it.
    """
    half, sixth = 0.5 * h, h / 6.0
    first = first or f
    for _ in range(n_steps):
        k1 = first(t, y)
        k2 = f(t + half, [a + half * b for a, b in zip(y, k1)])
        k3 = f(t + half, [a + half * b for a, b in zip(y, k2)])
        k4 = f(t + h, [a + h * b for a, b in zip(y, k3)])
        y = [a + sixth * (b1 + 2.0 * (b2 + b3) + b4) for a, b1, b2, b3, b4 in zip(y, k1, k2, k3, k4)]
        _normalize_quat_floats(y)
        t += h
    return y


def _load_slope(deriv, slope):
    """Copy the 13 derivative components into the (13, N) buffer ``slope``.

    Copy, not keep: the derivative's leg-angle rows are views of its input's leg-rate rows,
    which the next stage overwrites.
    """
    for i, v in enumerate(deriv):
        slope[i] = v


def _rk4_arrays(f, t, y, h, n_steps, first=None):
    """RK4 on a component-first batch y (13, N), in place, with preallocated stage buffers."""
    half, sixth = 0.5 * h, h / 6.0
    first = first or f
    slope = np.empty_like(y)
    total = np.empty_like(y)
    stage_a = np.empty_like(y)
    stage_b = np.empty_like(y)
    for _ in range(n_steps):
        _load_slope(first(t, y), slope)
        np.copyto(total, slope)
        np.multiply(slope, half, out=stage_a)
        stage_a += y
        _load_slope(f(t + half, stage_a), slope)
        total += 2.0 * slope
        np.multiply(slope, half, out=stage_b)
        stage_b += y
        _load_slope(f(t + half, stage_b), slope)
        total += 2.0 * slope
        np.multiply(slope, h, out=stage_a)
        stage_a += y
        _load_slope(f(t + h, stage_a), slope)
        total += slope
        total *= sixth
        y += total
        y[2:6] /= np.sqrt(y[2] * y[2] + y[3] * y[3] + y[4] * y[4] + y[5] * y[5])
        t += h
    return y


def _rk3_floats(f, t, y, h, n_steps, first=None):
    """Kutta's third-order method on one robot (list of 13 floats)."""
    half, sixth = 0.5 * h, h / 6.0
    first = first or f
    for _ in range(n_steps):
        k1 = first(t, y)
        k2 = f(t + half, [a + half * b for a, b in zip(y, k1)])
        k3 = f(t + h, [a + h * (2.0 * b2 - b1) for a, b1, b2 in zip(y, k1, k2)])
        y = [a + sixth * (b1 + 4.0 * b2 + b3) for a, b1, b2, b3 in zip(y, k1, k2, k3)]
        _normalize_quat_floats(y)
        t += h
    return y


def _rk3_arrays(f, t, y, h, n_steps, first=None):
    """Kutta's third-order method on a component-first batch y (13, N), in place."""
    half, sixth = 0.5 * h, h / 6.0
    first = first or f
    slope1 = np.empty_like(y)
    slope2 = np.empty_like(y)
    stage_a = np.empty_like(y)
    stage_b = np.empty_like(y)
    for _ in range(n_steps):
        _load_slope(first(t, y), slope1)
        np.multiply(slope1, half, out=stage_a)
        stage_a += y
        _load_slope(f(t + half, stage_a), slope2)
        np.multiply(slope2, 2.0 * h, out=stage_b)
        stage_b -= h * slope1
        stage_b += y
        slope1 += 4.0 * slope2
        _load_slope(f(t + h, stage_b), slope2)
        slope1 += slope2
        slope1 *= sixth
        y += slope1
        y[2:6] /= np.sqrt(y[2] * y[2] + y[3] * y[3] + y[4] * y[4] + y[5] * y[5])
        t += h
    return y


# ROS34PW2 of Rang and Angermann (BIT 45, 2005): a Rosenbrock-W method, 4 stages, order 3 for
# any approximate Jacobian, L-stable when it is exact, stiffly accurate. Stage i solves
#     (I - h gamma A) k_i = h f(t + c_i h, y + sum_j a_ij k_j) + h A sum_j g_ij k_j,
# and y_new = y + sum_i b_i k_i.
_ROSW_GAMMA = 4.3586652150845900e-01
_ROSW_A = ((), (8.7173304301691801e-01,), (8.4457060015369423e-01, -1.1299064236484185e-01), (0.0, 0.0, 1.0))
_ROSW_G = (
    (),
    (-8.7173304301691801e-01,),
    (-9.0338057013044082e-01, 5.4180672388095326e-02),
    (2.4212380706095346e-01, -1.2232505839045147e00, 5.4526025533510214e-01),
)
_ROSW_B = (2.4212380706095346e-01, -1.2232505839045147e00, 1.5452602553351020e00, 4.3586652150845900e-01)
_ROSW_C = tuple(sum(row) for row in _ROSW_A)


def _servo_response(g, p, kp, kd, w_phi1, w_phi2, w_v1, w_v2):
    """A w for the servo's linear part A (:class:`_ServoJacobian`) frozen at the legs' mobility G =
    (g11, g12, g22) and the body's rows P (six): (leg angle rows, leg rate rows, body rate rows)."""
    g11, g12, g22 = g
    u1 = kp * w_phi1 + kd * w_v1
    u2 = kp * w_phi2 + kd * w_v2
    return (
        (w_v1, w_v2),
        (-(g11 * u1 + g12 * u2), -(g12 * u1 + g22 * u2)),
        (-(p[0] * u1 + p[3] * u2), -(p[1] * u1 + p[4] * u2), -(p[2] * u1 + p[5] * u2)),
    )


class _ServoJacobian:
    """The stiff part of the dynamics that the Rosenbrock-W steps treat implicitly: the leg servo.

    A is the servo torque's part of the Jacobian, frozen at the substep's start: phi' = phidot,
    phidot' = -G (kp phi + kd phidot) and Omega' = -P (kp phi + kd phidot), with G and P the
    legs' columns of M^-1 (:func:`rrrobot_gym.dynamics.derivative_kernel`'s ``mobility_out``).
    The rest of the Jacobian is left out (a W-method keeps its order for any A). Without the
    body rows P the body's recoil from the fast servo mode is explicit and the steps lose most
    of their accuracy; the servo's fast pole (about -kd G, up to ~-400 1/s on a plane) is
    what the explicit steps had to resolve.
    """

    def __init__(self, gains, h):
        self.kp, self.kd = gains.kp, gains.kd
        self.hg = h * _ROSW_GAMMA
        self.s = self.hg * (self.kd + self.hg * self.kp)

    def set(self, g11, g12, g22, *body):
        """Freeze A at G (and P, the body's rows) and factor I - h gamma A for the substep."""
        self.g = (g11, g12, g22)
        self.p = body
        s = self.s
        a, b, d = 1.0 + s * g11, s * g12, 1.0 + s * g22
        inv_det = 1.0 / (a * d - b * b)
        self.inv = (d * inv_det, -b * inv_det, a * inv_det)

    def apply(self, w_phi1, w_phi2, w_v1, w_v2):
        """A w: (leg angle rows, leg rate rows, body rate rows)."""
        return _servo_response(self.g, self.p, self.kp, self.kd, w_phi1, w_phi2, w_v1, w_v2)

    def solve(self, r_phi1, r_phi2, r_v1, r_v2, r_o1, r_o2, r_o3):
        """(I - h gamma A)^-1 r on the leg and body rate rows (the other rows of I - h gamma A
        are the identity): legs first, then the body rows, which A couples to the legs only."""
        g11, g12, g22 = self.g
        hg = self.hg
        c = hg * self.kp
        u1, u2 = r_v1 - c * (g11 * r_phi1 + g12 * r_phi2), r_v2 - c * (g12 * r_phi1 + g22 * r_phi2)
        i11, i12, i22 = self.inv
        v1, v2 = i11 * u1 + i12 * u2, i12 * u1 + i22 * u2
        x1, x2 = r_phi1 + hg * v1, r_phi2 + hg * v2
        t1 = hg * (self.kp * x1 + self.kd * v1)
        t2 = hg * (self.kp * x2 + self.kd * v2)
        p = self.p
        return x1, x2, v1, v2, r_o1 - (p[0] * t1 + p[3] * t2), r_o2 - (p[1] * t1 + p[4] * t2), r_o3 - (p[2] * t1 + p[5] * t2)

    _ROWS = (6, 7, 11, 12, 8, 9, 10)  # leg angles, leg rates, body rates: where A acts

    def stage(self, k, h, g, previous):
        """Turn k = h f(stage point) into the stage's increment, in place (k: 13 rows):
        add h A sum_j g_j k_j over the ``previous`` stages, then solve with I - h gamma A."""
        rows = self._ROWS
        if previous:
            w = [sum(gj * kj[r] for gj, kj in zip(g, previous)) for r in rows[:4]]
            (a1, a2), (b1, b2), (o1, o2, o3) = self.apply(*w)
            for r, a in zip(rows, (a1, a2, b1, b2, o1, o2, o3)):
                k[r] += h * a
        solved = self.solve(*(k[r] for r in rows))
        for r, value in zip(rows, solved):
            k[r] = value


def _rosw_floats(f, t, y, h, n_steps, first, jacobian):
    """ROS34PW2 on one robot as a list of 13 Python floats."""
    mobility = [0.0] * 9
    for _ in range(n_steps):
        stages = []
        for i in range(4):
            if i == 0:
                derivative = first(t, y, mobility)
                jacobian.set(*mobility)
                point = y
            else:
                point = list(y)
                for a, kj in zip(_ROSW_A[i], stages):
                    if a:
                        point = [p + a * q for p, q in zip(point, kj)]
                derivative = f(t + _ROSW_C[i] * h, point)
            k = [h * d for d in derivative]
            jacobian.stage(k, h, _ROSW_G[i], stages)
            stages.append(k)
        y = [a + sum(b * kj[r] for b, kj in zip(_ROSW_B, stages)) for r, a in enumerate(y)]
        _normalize_quat_floats(y)
        t += h
    return y


def _rosw_arrays(f, t, y, h, n_steps, first, jacobian):
    """ROS34PW2 on a component-first batch y (13, N), in place."""
    mobility = [None] * 9
    stages = [np.empty_like(y) for _ in range(4)]
    point = np.empty_like(y)
    for _ in range(n_steps):
        for i in range(4):
            k = stages[i]
            if i == 0:
                derivative = first(t, y, mobility)
                jacobian.set(*mobility)
            else:
                np.copyto(point, y)
                for a, kj in zip(_ROSW_A[i], stages):
                    if a == 1.0:
                        point += kj
                    elif a:
                        point += a * kj
                derivative = f(t + _ROSW_C[i] * h, point)
            for r, d in enumerate(derivative):
                np.multiply(d, h, out=k[r])
            jacobian.stage(k, h, _ROSW_G[i], stages[:i])
        for b, kj in zip(_ROSW_B, stages):
            y += b * kj
        y[2:6] /= np.sqrt(y[2] * y[2] + y[3] * y[3] + y[4] * y[4] + y[5] * y[5])
        t += h
    return y


# ---------------------------------------------------------------------------
# The exponential step ("etdrk4b"): the servo's linear part integrated exactly.
#
# A is _ServoJacobian's matrix. Its non-zero columns are the leg angles and leg rates (S), so
# phi_j(cA) v = v / j! + c A[:, S] phi_{j+1}(c L) v_S, with L = A_SS = [[0, I], [-kp G, -kd G]] the
# legs' 4x4 block (G: the legs' 2x2 block of M^-1). L satisfies L^2 = -kd G L - kp G, and G^2 =
# tr(G) G - det(G) I, so every function of L is (a0 + a1 G) + (b0 + b1 G) L: four numbers, with
# no eigenvalues (the servo's two modes may be under- or overdamped, or on the edge between).


def _g_product(p, q, tg, dg):
    """(p0 + p1 G)(q0 + q1 G) with G^2 = tg G - dg."""
    s = p[1] * q[1]
    return p[0] * q[0] - dg * s, p[0] * q[1] + p[1] * q[0] + tg * s


def _l_product(x, y, tg, dg, xkp, xkd):
    """(A + B X)(C + D X) for X^2 = -xkd G X - xkp G, elements (A, B) of G-polynomials."""
    (a, b), (c, d) = x, y
    bd = _g_product(b, d, tg, dg)
    gbd = (-dg * bd[1], bd[0] + tg * bd[1])  # G (B D)
    ac, ad, bc = _g_product(a, c, tg, dg), _g_product(a, d, tg, dg), _g_product(b, c, tg, dg)
    return (ac[0] - xkp * gbd[0], ac[1] - xkp * gbd[1]), (ad[0] + bc[0] - xkd * gbd[0], ad[1] + bc[1] - xkd * gbd[1])


def _x_times(element, tg, dg, xkp, xkd):
    """(A + B X) X = -xkp G B + (A - xkd G B) X."""
    (a0, a1), (b0, b1) = element
    g0, g1 = -dg * b1, b0 + tg * b1
    return (-xkp * g0, -xkp * g1), (a0 - xkd * g0, a1 - xkd * g1)


def _phis_from_phi4(phi4, tg, dg, xkp, xkd):
    """[phi_0, ..., phi_4] from phi_4 by phi_k = X phi_{k+1} + 1/k!: exact, and accurate where
    ||X|| is small (the error of phi_0 grows like ||X||^3)."""
    (a0, a1), b = _x_times(phi4, tg, dg, xkp, xkd)
    phi3 = ((a0 + 1.0 / _FACTORIALS[3], a1), b)
    (a0, a1), b = _x_times(phi3, tg, dg, xkp, xkd)
    phi2 = ((a0 + 1.0 / _FACTORIALS[2], a1), b)
    (a0, a1), b = _x_times(phi2, tg, dg, xkp, xkd)
    phi1 = ((a0 + 1.0 / _FACTORIALS[1], a1), b)
    (a0, a1), b = _x_times(phi1, tg, dg, xkp, xkd)
    return ((a0 + 1.0 / _FACTORIALS[0], a1), b), phi1, phi2, phi3, phi4


_FACTORIALS = tuple(float(math.factorial(n)) for n in range(24))
_RECURRENCE_RADIUS = 8.0
"""A doubling whose result's argument has spectral radius up to this (by the bound) doubles
phi_4 alone and takes the lower phi-functions by recurrence; a stiffer one doubles all five."""


def _per_leg_block(elements, scale):
    """The five elements A + B X as A + (scale B) L, for X = scale L."""
    return (_per_l(elements[0], scale), _per_l(elements[1], scale), _per_l(elements[2], scale), _per_l(elements[3], scale),
            _per_l(elements[4], scale))  # fmt: skip


def _per_l(element, scale):
    (a0, a1), (b0, b1) = element
    return (a0, a1), (b0 * scale, b1 * scale)


def _doubled(phis, k, tg, dg, xkp, xkd):
    """phi_k(2X) = (e^X phi_k(X) + sum_{j=1..k} phi_j(X) / (k - j)!) / 2^k from phis = phi_0..phi_4 of X,
    as an element of 2X."""
    (a0, a1), (b0, b1) = _l_product(phis[0], phis[k], tg, dg, xkp, xkd)
    for j in range(1, k + 1):
        w = 1.0 / _FACTORIALS[k - j]
        (c0, c1), (d0, d1) = phis[j]
        a0, a1, b0, b1 = a0 + w * c0, a1 + w * c1, b0 + w * d0, b1 + w * d1
    w = 1.0 / 2.0**k
    return (w * a0, w * a1), (0.5 * w * b0, 0.5 * w * b1)  # B of X is B / 2 of 2X


def _servo_phi(tg, dg, kp, kd, h, levels, terms, radius):
    """phi_0 .. phi_4 of h L / 2 and of h L, each as (A, B) with the function = A + B L.

    phi_4 by Taylor's series (Horner) at X = h L / 2^levels, whose norm the caller keeps near 1/2
    or less, and the lower ones by recurrence; then ``levels`` (>= 1) doublings,
    phi_k(2X) = (e^X phi_k(X) + sum_{j=1..k} phi_j(X) / (k - j)!) / 2^k (Skaflestad and Wright's
    modified squaring, accurate for stiff arguments, where phi_{k+1} = (phi_k - 1/k!) / X would
    cancel). ``radius`` bounds the spectral radius of h L: a doubling to an argument within
    _RECURRENCE_RADIUS doubles phi_4 only (one product instead of five). Plain arithmetic on
    tuples, so floats, (N,) arrays and the compiled stepper (:mod:`rrrobot_gym.compiled`) share it;
    the compiled lane stepper runs the same pieces (_phi_scale, _phi_taylor, _phi_stiff,
    _phi_doubling) one loop over its robots each."""
    xkp, xkd = _phi_scale(kp, kd, h, levels)
    phis = _phi_taylor(tg, dg, xkp, xkd, terms)
    half = phis
    for level in range(levels):
        if level == levels - 1:  # the last doubling starts from h L / 2
            half = phis
        phis = _phi_doubling(phis, tg, dg, xkp, xkd, _phi_stiff(radius, levels, level))
        xkd, xkp = 2.0 * xkd, 4.0 * xkp
    return _per_leg_block(half, 0.5 * h), _per_leg_block(phis, h)


def _phi_scale(kp, kd, h, levels):
    """(xkp, xkd) of X = h L / 2^levels, where the doublings start: X^2 = -xkd G X - xkp G."""
    return kp * (h / 2.0**levels) ** 2, kd * h / 2.0**levels


def _phi_taylor(tg, dg, xkp, xkd, terms):
    """phi_0 .. phi_4 of X: phi_4 by ``terms`` terms of Taylor's series (Horner), the rest by recurrence."""
    zero = 0.0 * tg
    phi4 = ((1.0 / _FACTORIALS[terms + 3] + zero, zero), (zero, zero))
    for m in range(terms - 2, -1, -1):
        (a0, a1), b = _x_times(phi4, tg, dg, xkp, xkd)
        phi4 = ((a0 + 1.0 / _FACTORIALS[m + 4], a1), b)
    return _phis_from_phi4(phi4, tg, dg, xkp, xkd)


def _phi_stiff(radius, levels, level):
    """True if doubling ``level`` (of ``levels``) leads to an argument beyond _RECURRENCE_RADIUS."""
    return not radius / 2.0 ** (levels - 1 - level) <= _RECURRENCE_RADIUS


def _phi_doubling(phis, tg, dg, xkp, xkd, stiff):
    """phi_0 .. phi_4 of 2X from those of X: all five doubled where ``stiff``, else phi_4 alone and
    the others by recurrence."""
    if stiff:
        return (_doubled(phis, 0, tg, dg, xkp, xkd), _doubled(phis, 1, tg, dg, xkp, xkd), _doubled(phis, 2, tg, dg, xkp, xkd),
                _doubled(phis, 3, tg, dg, xkp, xkd), _doubled(phis, 4, tg, dg, xkp, xkd))  # fmt: skip
    phi4 = _doubled(phis, 4, tg, dg, xkp, xkd)
    return _phis_from_phi4(phi4, tg, dg, 4.0 * xkp, 2.0 * xkd)


def _servo_rows(g, p, kp, kd, w1, w2, w3, w4, scale):
    """scale A w for w = (leg angles, leg rates), as 13 rows (zeros where A has none)."""
    (x1, x2), (r1, r2), (o1, o2, o3) = _servo_response(g, p, kp, kd, w1, w2, w3, w4)
    return (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, scale * x1, scale * x2, scale * o1, scale * o2, scale * o3, scale * r1, scale * r2)


def _g_apply(c0, c1, g, z1, z2):
    """(c0 + c1 G) z for a leg pair z."""
    g11, g12, g22 = g
    return c0 * z1 + c1 * (g11 * z1 + g12 * z2), c0 * z2 + c1 * (g12 * z1 + g22 * z2)


def _leg_function(g, p, kp, kd, element, w1, w2, w3, w4):
    """(A + B L) w on the legs' four rows, for an element (A, B) of :func:`_servo_phi`."""
    (a0, a1), (b0, b1) = element
    (l1, l2), (l3, l4), _ = _servo_response(g, p, kp, kd, w1, w2, w3, w4)  # L w: the legs' rows of A w
    p1, p2 = _g_apply(a0, a1, g, w1, w2)
    r1, r2 = _g_apply(a0, a1, g, w3, w4)
    q1, q2 = _g_apply(b0, b1, g, l1, l2)
    s1, s2 = _g_apply(b0, b1, g, l3, l4)
    return p1 + q1, p2 + q2, r1 + s1, r2 + s2


def _etd_correction(g, p, kp, kd, c, element, w1, w2, w3, w4):
    """c A[:, S] f(cL) w as 13 rows, f = ``element``, w = the four leg rows of a vector v:
    phi_j(cA) v = v / j! + this with phi_{j+1}(cL)."""
    f1, f2, f3, f4 = _leg_function(g, p, kp, kd, element, w1, w2, w3, w4)
    return _servo_rows(g, p, kp, kd, f1, f2, f3, f4, c)


def _combine_rows(x, scale, y):
    """x + scale y for 13 rows."""
    return (x[0] + scale * y[0], x[1] + scale * y[1], x[2] + scale * y[2], x[3] + scale * y[3], x[4] + scale * y[4],
            x[5] + scale * y[5], x[6] + scale * y[6], x[7] + scale * y[7], x[8] + scale * y[8], x[9] + scale * y[9],
            x[10] + scale * y[10], x[11] + scale * y[11], x[12] + scale * y[12])  # fmt: skip


def _etd_setup(mobility, kp, kd, h, levels, terms, radius, rates, accels):
    """The servo's linear part A frozen at a step's start, as the exponential step uses it, from the
    first evaluation's ``mobility`` (nine: G's three, P's six) and the targets' rates and
    accelerations there: (G, P, the phi-elements (phi_2, phi_3 of hL/2; phi_2, phi_3, 2 phi_3 - 4 phi_4,
    4 phi_4 - phi_3 of hL), A's time column (13 rows), and the time column's part of phi_1(cA) f(u)
    for c = h/2 and h (13 rows each)).

    The time column is the servo torque's change through the targets, d tau / dt = kp phi_target' +
    kd phi_target'' (the map of -(phi, phidot)), so a servo following a ramp is linear in (state, t).
    With A~ = [[L, beta], [0, 0]] on (legs, t), phi_1(cA~) (f_S, 1) = (phi_1(cL) f_S + c phi_2(cL) beta, 1),
    so phi_1(cA) f(u) gains c A[:, S] c phi_3(cL) beta + c A_t / 2 beyond the correction of f_S."""
    g = (mobility[0], mobility[1], mobility[2])
    p = (mobility[3], mobility[4], mobility[5], mobility[6], mobility[7], mobility[8])
    g11, g12, g22 = g
    half, whole = _servo_phi(g11 + g22, g11 * g22 - g12 * g12, kp, kd, h, levels, terms, radius)
    return _etd_finish(g, p, half, whole, kp, kd, h, rates, accels)


def _etd_finish(g, p, half, whole, kp, kd, h, rates, accels):
    """:func:`_etd_setup` from the phi-elements of h L / 2 and h L (:func:`_servo_phi`)."""
    (c0, c1), (d0, d1) = whole[3]
    (e0, e1), (f0, f1) = whole[4]
    b23 = ((2.0 * c0 - 4.0 * e0, 2.0 * c1 - 4.0 * e1), (2.0 * d0 - 4.0 * f0, 2.0 * d1 - 4.0 * f1))
    b4 = ((4.0 * e0 - c0, 4.0 * e1 - c1), (4.0 * f0 - d0, 4.0 * f1 - d1))
    elements = (half[2], half[3], whole[2], whole[3], b23, b4)
    t = _servo_rows(g, p, kp, kd, rates[0], rates[1], accels[0], accels[1], -1.0)
    # (the leg-angle rows of A w are its leg-rate input, not a torque's: none in the time column)
    column = (t[0], t[1], t[2], t[3], t[4], t[5], 0.0, 0.0, t[8], t[9], t[10], t[11], t[12])
    c = 0.5 * h
    forcing_half = _combine_rows(_etd_correction(g, p, kp, kd, c * c, half[3], 0.0, 0.0, t[11], t[12]), 0.5 * c, column)
    forcing = _combine_rows(_etd_correction(g, p, kp, kd, h * h, whole[3], 0.0, 0.0, t[11], t[12]), 0.5 * h, column)
    return g, p, elements, column, forcing_half, forcing


class _ServoExponential:
    """The scene's constants of the exponential step: the gains, the step, and the number of
    doublings of :func:`_servo_phi`, fixed by the servo's fastest pole over all configurations,
    not by the state, so no robot's result depends on the batch it is in."""

    TERMS = compiled.TAYLOR_TERMS  # of Taylor's series at ||X|| <= 1/2: a remainder below 1e-15

    def __init__(self, config: SimConfig, h: float, targets):
        self.kp, self.kd, self.h = config.gains.kp, config.gains.kd, h
        self.leg_targets = targets.leg_targets
        self.radius, self.levels = _doublings(config, h)


def _doublings(config: SimConfig, h: float):
    """(bound on h |lambda| of the servo's poles, number of doublings) of the exponential step at h."""
    radius = h * servo_fastest_rate(config.model, config.robot, config.gains)
    return radius, max(1, math.ceil(math.log2(max(2.0 * radius, 1.0))))


def _etdrk4b_rows(f, t, y, h, n_steps, first, servo):
    """Krogstad's ETDRK4-B with A the servo's linear part (:func:`_etd_setup`), on y as 13 rows
    (floats, or the (N,) arrays of a batch). Stages at c = 0, 1/2, 1/2, 1; with
    D(U) = f(U) - f(u) - A (U - u): U2 = u + h/2 phi_1(hA/2) f(u), U3 = U2 + h phi_2(hA/2) D(U2),
    B = u + h phi_1(hA) f(u), U4 = B + 2 h phi_2(hA) D(U3), and the step
    u + = B + h ((2 phi_2 - 4 phi_3)(D(U2) + D(U3)) + (4 phi_3 - phi_2) D(U4)), phi_j of hA unless
    said. It integrates u' = A u + (f(u) - A u) with the second part explicit, so its order (4)
    needs that part smooth, not A exact. Classical RK4 (on the locked rate) when A = 0. Four
    evaluations a step.
    It follows the body's locked rate (:func:`rrrobot_gym.dynamics.locked_share`) in rows 8-10,
    converting y to it and back here: the leg torques do not act on it, so A's body rows are zero
    and a new ramp's torque step is in the legs' rows alone, where A has it exactly.
    :mod:`rrrobot_gym.compiled` repeats it operation for operation."""
    _check_locked(f, "etdrk4b")
    half_h, third, sixth = 0.5 * h, 1.0 / 3.0, 1.0 / 6.0
    kp, kd = servo.kp, servo.kd
    mobility = [0.0] * 9
    _to_locked(y, f.constants, 1.0)
    for _ in range(n_steps):
        fu = list(first(t, y, mobility))
        _, rates, accels = servo.leg_targets(t)
        g, p, elements, column, forcing_half, forcing = _etd_setup(
            mobility, kp, kd, h, servo.levels, servo.TERMS, servo.radius, rates, accels
        )
        p2h, p3h, p2, p3, b23, b4 = elements

        def change(point, time):
            """D = f(U) - f(u) - A (U - u), the time column included."""
            linear = _servo_rows(g, p, kp, kd, point[6] - y[6], point[7] - y[7], point[11] - y[11], point[12] - y[12], 1.0)
            dt = time - t
            return [d - (a + dt * e) - b for d, a, e, b in zip(f(time, point), linear, column, fu)]

        k = _etd_correction(g, p, kp, kd, half_h, p2h, fu[6], fu[7], fu[11], fu[12])
        u2 = [a + half_h * (b + c + e) for a, b, c, e in zip(y, fu, k, forcing_half)]
        d2 = change(u2, t + half_h)
        k = _etd_correction(g, p, kp, kd, half_h, p3h, d2[6], d2[7], d2[11], d2[12])
        u3 = [a + h * (0.5 * b + c) for a, b, c in zip(u2, d2, k)]
        d3 = change(u3, t + half_h)
        k = _etd_correction(g, p, kp, kd, h, p2, fu[6], fu[7], fu[11], fu[12])
        base = [a + h * (b + c + e) for a, b, c, e in zip(y, fu, k, forcing)]
        k = _etd_correction(g, p, kp, kd, h, p3, d3[6], d3[7], d3[11], d3[12])
        u4 = [a + 2.0 * h * (0.5 * b + c) for a, b, c in zip(base, d3, k)]
        d4 = change(u4, t + h)
        k23 = _etd_correction(g, p, kp, kd, h, b23, d2[6] + d3[6], d2[7] + d3[7], d2[11] + d3[11], d2[12] + d3[12])
        k4 = _etd_correction(g, p, kp, kd, h, b4, d4[6], d4[7], d4[11], d4[12])
        y = [a + h * (third * (p_ + q) + sixth * r + c + e) for a, p_, q, r, c, e in zip(base, d2, d3, d4, k23, k4)]
        _normalize_quat_floats(y)
        t += h
    _to_locked(y, f.constants, -1.0)
    return y


def _check_locked(f, integrator):
    """Refuse stage functions in the body rate for a stepper of LOCKED_INTEGRATORS (it converts y
    to the locked rate, so they would give a wrong path without a word)."""
    if not getattr(f, "locked", False):
        raise ValueError(
            f"integrator {integrator!r} integrates the locked rate in rows 8-10: its stage functions must be "
            "_stage_fns(..., locked=True) or derivative_kernel(locked=True) marked with f.locked = True"
        )


def _rk4_locked_floats(f, t, y, h, n_steps, first=None):
    """RK4 on one robot (13 floats) in the body's locked rate: y converted to it, stepped by
    :func:`_rk4_floats` on the locked stage functions, converted back."""
    _check_locked(f, "rk4_locked")
    _to_locked(y, f.constants, 1.0)
    y = _rk4_floats(f, t, y, h, n_steps, first)
    _to_locked(y, f.constants, -1.0)
    return y


def _rk4_locked_arrays(f, t, y, h, n_steps, first=None):
    """:func:`_rk4_locked_floats` on a component-first batch y (13, N), in place."""
    _check_locked(f, "rk4_locked")
    _to_locked(y, f.constants, 1.0)
    _rk4_arrays(f, t, y, h, n_steps, first)
    _to_locked(y, f.constants, -1.0)
    return y


def _to_locked(y, k, sign):
    """Rows 8-10 of y (13 rows) from the body rate Omega to the locked rate (sign 1) or back (-1),
    in place (:func:`rrrobot_gym.dynamics.locked_share`)."""
    s0, s1, s2 = dynamics.locked_share(y, k)
    y[8], y[9], y[10] = y[8] + sign * s0, y[9] + sign * s1, y[10] + sign * s2


def _etdrk4b_floats(f, t, y, h, n_steps, first, servo):
    """ETDRK4-B on one robot as a list of 13 Python floats."""
    return _etdrk4b_rows(f, t, y, h, n_steps, first, servo)


def _etdrk4b_arrays(f, t, y, h, n_steps, first, servo):
    """ETDRK4-B on a component-first batch y (13, N), in place."""
    rows = _etdrk4b_rows(f, t, list(y.copy()), h, n_steps, first, servo)
    for r, row in enumerate(rows):
        y[r] = row
    return y


_STEPPERS = {"rk4": (_rk4_floats, _rk4_arrays), "rk3": (_rk3_floats, _rk3_arrays), "rosw": (_rosw_floats, _rosw_arrays),
             "etdrk4b": (_etdrk4b_floats, _etdrk4b_arrays), "rk4_locked": (_rk4_locked_floats, _rk4_locked_arrays)}  # fmt: skip


def _leg_path_end(targets, blend, t_end):
    """Leg angles and rates of the kinematic path at t_end: where the legs must be."""
    (a1, a2), (r1, r2), _ = targets.leg_targets(t_end)
    if blend is not None:
        t_blend, coeffs1, coeffs2 = blend
        b1, v1, _ = _blend(coeffs1, t_end - t_blend)
        b2, v2, _ = _blend(coeffs2, t_end - t_blend)
        a1, a2, r1, r2 = a1 + b1, a2 + b2, r1 + v1, r2 + v2
    return a1, a2, r1, r2


@dataclass(frozen=True)
class StepRecord:
    """What an :func:`advance` did, sampled at the start of every integration substep.

    Made by the integrator from the derivative it evaluates there anyway (the first stage
    of each substep), so the torques are the ones it applied (the servo law on the targets
    and their rate, after any motor limit; with kinematic legs, the torques the prescribed
    motion took) and the force is Newton's for the motion it integrated
    (:func:`rrrobot_gym.dynamics.contact_kernel`). Nothing downstream rebuilds them.

    Shapes: S samples; one robot: (S,), (S, 2), (S, 3); a batch of N: (S, N), (S, N, 2), (S, N, 3).
    :meth:`summary` gives each robot's extremes over the samples (what the env's measures read).
    """

    times: np.ndarray  # (S,) s, the substep starts
    step: float  # s, the substep length: each sample stands for this much time
    torque: np.ndarray  # (S, [N,] 2) N m, leg torques applied (shell on leg)
    force: np.ndarray  # (S, [N,] 3) N, the ground's force on the shell, body frame (pivot: the joint's)
    normal: np.ndarray  # (S, [N]) N, its component along world up
    leg_clearance: np.ndarray  # (S, [N,] 2) m, each leg tip's height above the ground
    leg_rates: np.ndarray  # (S, [N,] 2) rad/s
    # the integrator's own tangential values (dynamics.contact_kernel's), where it made the record
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

        The compiled stepper makes it as it finishes each block of robots, in both threads; a
        record from the numpy steppers, or made or changed by hand, is summarised here, to the
        same numbers (a NaN wins a min or max; the squares are summed sample by sample).
        """
        if self._summary is not None:
            return dict(zip(SUMMARY_KEYS, self._summary))
        samples = self.normal.shape[0]
        if samples == 0:
            raise ValueError("a StepRecord of no samples has no summary (advance records at least one substep)")
        normal = self.normal.reshape(samples, -1)
        num_robots = normal.shape[1]
        torque = self.torque.reshape(samples, num_robots, 2)
        with np.errstate(divide="ignore", invalid="ignore"):  # (a normal force of 0: see SUMMARY_KEYS)
            ratio = self.tangential.reshape(samples, num_robots) / normal
        squares = torque[..., 0] * torque[..., 0] + torque[..., 1] * torque[..., 1]
        values = (
            normal.min(axis=0),
            ratio.max(axis=0),
            self.leg_clearance.reshape(samples, num_robots, 2).min(axis=(0, 2)),
            np.add.accumulate(squares, axis=0)[-1],  # (sample by sample: numpy's sum may pair them)
            _largest_magnitude(torque),
            _largest_magnitude(self.leg_rates.reshape(samples, num_robots, 2)),
        )
        shape = self.normal.shape[1:]
        return {key: value.reshape(shape) for key, value in zip(SUMMARY_KEYS, values)}


SUMMARY_KEYS = ("least_normal", "most_ratio", "least_clearance", "torque_squares", "peak_torque", "peak_leg_rate")
"""What :meth:`StepRecord.summary` reports of each robot, over the record's samples: the least
normal force (N); the greatest tangential / normal (the grip rolling needs, where every sample
pushes: a sample with normal <= 0 makes it inf or NaN); the least leg clearance (m, both legs);
the sum of both legs' squared torques (N^2 m^2); the peak |torque| (N m, both legs) and the peak
|leg rate| (rad/s, both legs)."""


def _largest_magnitude(values):
    """max |v| per robot over samples and legs of (S, N, 2) values, from a max and a min (no
    array of magnitudes: at N = 4096 the record's arrays are large)."""
    return np.maximum(values.max(axis=(0, 2)), -values.min(axis=(0, 2)))


_RECORD_ROWS = compiled.RECORD_ROWS  # torque (2), force (3), normal, tangential, clearance (2), leg rates (2): one layout for both backends


class _Recorder:
    """The steppers' ``first``: evaluates a substep's first stage and keeps what it applied."""

    def __init__(self, first, config: SimConfig, n_steps: int, num_robots: int | None):
        self._first = first
        self._contact = [None] * 7
        self._rows = [] if num_robots is None else np.empty((n_steps, _RECORD_ROWS, num_robots))
        self._i = 0

    def __call__(self, t, c, mobility_out=None):
        derivative, torque = self._first(t, c, mobility_out, self._contact)
        fx, fy, fz, normal, tangential, clear1, clear2 = self._contact
        row = (torque[0], torque[1], fx, fy, fz, normal, tangential, clear1, clear2, c[11], c[12])
        if isinstance(self._rows, list):
            self._rows.append(row)
        else:
            self._rows[self._i] = row
            self._i += 1
        return derivative

    @property
    def rows(self):
        """What was recorded: (S, 11) floats for one robot, (S, 11, N) for a batch."""
        return np.asarray(self._rows, dtype=float)

    @staticmethod
    def merge(blocks, t0: float, h: float, summary=None) -> StepRecord:
        """One :class:`StepRecord` of the recorded rows of a batch's blocks, in robot order (and
        the compiled stepper's summary of them, if it made one)."""
        return _Recorder._record_of(blocks[0] if len(blocks) == 1 else np.concatenate(blocks, axis=2), t0, h, summary)

    def record(self, t0: float, h: float) -> StepRecord:
        return self._record_of(self.rows, t0, h)

    @staticmethod
    def _record_of(rows, t0: float, h: float, summary=None) -> StepRecord:
        if rows.ndim == 3:  # (S, 11, N) -> fields with the robot axis before the vector axis
            rows = rows.transpose(0, 2, 1)
        record = StepRecord(
            times=t0 + h * np.arange(len(rows)),
            step=h,
            torque=rows[..., 0:2],
            force=rows[..., 2:5],
            normal=rows[..., 5],
            leg_clearance=rows[..., 7:9],
            leg_rates=rows[..., 9:11],
        )
        object.__setattr__(record, "_tangential", rows[..., 6])
        object.__setattr__(record, "_summary", summary)
        return record


AUTO_RATE_FACTOR = 0.3
"""With ``timestep="auto"``, h x (fastest rate at the start of an advance) stays below this:
the body's spin and the legs' rates (or, kinematic, the peak rate of their path) set
a limit of their own that gains and masses cannot predict (bang-bang kinematic
targets, a top-heavy robot falling over)."""


def _rate_limited_step(state, path_rate: float) -> float:
    body = float(np.max(np.linalg.norm(np.atleast_2d(state)[:, dynamics.BODY_RATE], axis=-1)))
    legs = float(np.max(np.abs(state[..., dynamics.LEG_RATES])))
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
    with np.errstate(all="ignore"):
        body_rate = float(np.max(np.linalg.norm(state[:, dynamics.BODY_RATE], axis=-1), initial=0.0))
        leg_rate = float(np.max(np.abs(state[:, dynamics.LEG_RATES]), initial=0.0))
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


def advance(
    config: SimConfig, state, t0: float, duration: float, targets, *, check=True, record=False, workers: int = 1
):
    """Integrate ``state`` from time t0 over ``duration`` seconds with fixed steps.

    The step is the largest that divides ``duration`` evenly and is no larger than
    ``config.step``; with ``config.start_halves`` the first substeps are taken in halves (the
    record still has one sample a substep). Returns the new state (same shape as ``state``), and with
    ``record=True`` also a :class:`StepRecord` of the torques applied and the ground force
    at the start of every substep: ``(state, record)``.

    With ``config.legs == "kinematic"`` the legs follow a path exactly: the targets'
    own path (their angles, rates and accelerations) when the legs are on it at t0,
    else a minimum-jerk quintic from the legs' current angles and rates onto that path
    over ``duration`` (for held targets: onto the held angles, at rest). The body
    reacts to whatever torque that takes; only the body's equations are integrated.

    ``workers`` > 1 splits a batch into that many blocks of robots: with numba, among that many
    of numba's threads (the compiled loop holds no GIL); on numpy, one block integrated here and
    the others in worker processes (threads do not pay there: numpy's per-call work holds the
    GIL), kept for later calls until :func:`close_workers`. The robots are independent and the
    step is chosen for the whole batch first, so the result is bit-identical to one worker.
    Worth it for large batches (``benchmarks.throughput``).

    ``check`` validates the state (:func:`check_state`) and the targets against it
    (:func:`check_targets`); callers that made both themselves, as the envs do, pass False.
    Raises :class:`NumericalFailure` if the result is not finite.
    """
    t0 = real_number("t0", t0)
    duration = real_number("duration", duration)
    if check:
        state = check_state(state)
        check_targets(targets, state, t0)
    workers = whole_number("workers", workers)
    if duration < 0.0:
        raise ValueError(f"duration must be a non-negative finite number of seconds, got {duration}")
    if duration == 0.0:
        if record:
            raise ValueError("advance(record=True) needs a positive duration: a record of no substeps is empty")
        return np.array(state)
    blend = None
    path_rate = 0.0
    if config.legs == "kinematic":
        (a1, a2), (r1, r2), _ = targets.leg_targets(t0)
        legs = state[..., dynamics.LEG_ANGLES]
        rates = state[..., dynamics.LEG_RATES]
        off = (legs[..., 0] - a1, legs[..., 1] - a2, rates[..., 0] - r1, rates[..., 1] - r2)
        if max(float(np.max(np.abs(v))) for v in off) > 1e-9:
            blend = (t0, _blend_coefficients(off[0], off[2], duration), _blend_coefficients(off[1], off[3], duration))
            # A minimum-jerk move of b0 in T peaks at 1.875 b0 / T.
            path_rate = float(np.max(np.abs(off[:2]))) * 1.875 / duration + float(np.max(np.abs(off[2:])))
        path_rate += float(np.max(np.abs(np.asarray([r1, r2], dtype=float))))
    step = config.step
    if config.timestep == "auto":
        step = min(step, _rate_limited_step(state, path_rate))
    n_steps, h = _substeps(duration, step)
    if config.start_halves:
        return _advance_graded(config, state, t0, duration, targets, record, workers, n_steps, h)
    out, records, summary = _advance_rows(config, state, t0, targets, blend, record, workers, n_steps, h)
    if config.legs == "kinematic":
        # The legs' path is known exactly: remove the integrator's tiny drift from it.
        a1, a2, r1, r2 = _leg_path_end(targets, blend, t0 + duration)
        out[..., 6], out[..., 7], out[..., 11], out[..., 12] = a1, a2, r1, r2
    if not np.isfinite(out).all():
        raise NumericalFailure(_diagnose(config, state, t0, duration, h))
    if record:
        return out, _Recorder.merge(records, t0, h, summary)
    return out


def check_targets(targets, state, t0: float = 0.0) -> None:
    """Raise naming the problem unless ``targets`` is a leg-target source for the robots of
    ``state`` ((13,) or (N, 13), checked): one with a ``leg_targets(t)`` method whose values at
    ``t0`` are numbers (every robot's) or (N,) arrays (one per robot)."""
    if not callable(getattr(targets, "leg_targets", None)):
        raise TypeError(
            "targets must be a leg-target source with a leg_targets(t) method (rrrobot_gym.control's Gait, "
            f"HeldTargets or RampTargets), got {type(targets).__name__}"
        )
    robots = 1 if state.ndim == 1 else state.shape[0]
    for value in (v for triple in targets.leg_targets(t0) for v in triple):
        shape = np.shape(value)
        if not shape:
            continue
        if state.ndim == 1:
            raise ValueError(f"one robot's state (13,) takes leg targets that are numbers, got arrays of shape {shape}")
        if len(shape) > 1:
            raise ValueError(f"leg targets must be numbers or (N,) arrays, one entry a robot, got shape {shape}")
        if shape[0] != robots:
            raise ValueError(f"the leg targets are for {shape[0]} robots, the state has {robots}")


def _substeps(duration: float, step: float):
    """(n, h): the fewest substeps of at most ``step`` that divide ``duration`` evenly."""
    n_steps = max(1, math.ceil(duration / step - 1e-9))
    return n_steps, duration / n_steps


def _advance_rows(config: SimConfig, state, t0, targets, blend, record, workers, n_steps, h):
    """The integration of :func:`advance`: (the states after n_steps of h, the record's row
    blocks (in robot order) or Nones, the compiled stepper's summary or None)."""
    summary = None
    described = _compiled_targets(config, targets)
    if described is not None:
        out, rows, summary = compiled.integrate(config, described, state, t0, h, n_steps, record, workers)
        records = [rows]
    elif state.ndim == 1:
        try:
            out, recorder = _integrate(config, targets, blend, state.tolist(), t0, h, n_steps, record)
            out = np.array(out)
        except (OverflowError, ValueError, ZeroDivisionError):  # math.* on inf/NaN floats
            raise NumericalFailure(_diagnose(config, state, t0, n_steps * h, h)) from None
        records = [None if recorder is None else recorder.rows]
    elif state.shape[0] <= ROW_BY_ROW_MAX:
        out, records = _integrate_rows(config, targets, blend, state, t0, h, n_steps, record)
    else:
        blocks = np.array_split(np.arange(state.shape[0]), min(workers, state.shape[0]))
        if len(blocks) == 1:
            results = [_integrate_block((config, targets, blend, state, t0, h, n_steps, record))]
        else:
            jobs = [_block_inputs(config, targets, blend, state, t0, h, n_steps, record, slice(b[0], b[-1] + 1))
                    for b in blocks]  # fmt: skip
            # This process integrates the first block itself while the workers do the others: one
            # block fewer to send and receive, and no process idles on a core while others work.
            with _POOLS_LOCK:  # (map submits every job at once: a close_workers elsewhere then waits for them)
                others = _process_pool(len(blocks) - 1).map(_integrate_block, jobs[1:])
            results = [_integrate_block(jobs[0]), *others]
        out = np.concatenate([block for block, _ in results]) if len(results) > 1 else results[0][0]
        records = [rows for _, rows in results]
    return out, records, summary


@functools.lru_cache(maxsize=64)
def _graded_configs(config: SimConfig, h: float):
    """(steps of h / 2, steps of h): the uniform configs of a graded advance, made once (a
    SimConfig's checks cost ~40 us, as much as a one-robot env step's task code)."""
    uniform = replace(config, start_halves=0, timestep=h)
    return replace(uniform, timestep=0.5 * h), uniform


def _advance_graded(config: SimConfig, state, t0, duration, targets, record, workers, n_steps, h):
    """:func:`advance` with ``config.start_halves``: the first k = min(start_halves, n_steps)
    substeps of h as 2k of h / 2, then the rest as usual. The record keeps the substeps' grid,
    t0 + i h: of the halves, the samples at their starts on it (every other one), and its
    summary is of those samples. The compiled stepper runs the schedule in one call; the numpy
    steppers run each part as one uniform integration and join the parts' records, whose
    summary :meth:`StepRecord.summary` then computes."""
    k = min(config.start_halves, n_steps)
    halves, uniform = _graded_configs(config, h)
    # (config, start, length, substeps, step) of each part: the halves, then the rest if any
    parts = [(halves, t0, k * h, *_substeps(k * h, halves.step))]
    if k < n_steps:
        parts.append((uniform, t0 + k * h, duration - k * h, *_substeps(duration - k * h, uniform.step)))
    described = _compiled_targets(config, targets)
    if described is not None:
        # The compiled stepper takes the whole schedule in one call, recording and summarising
        # the grid's samples itself: the same substeps as the two parts, to the bit.
        lead_steps, lead_h = parts[0][3:]
        rest_t0, _, rest_steps, rest_h = parts[1][1:] if len(parts) == 2 else (t0 + k * h, 0.0, 0, h)
        out, rows, summary = compiled.integrate(
            uniform, described, state, rest_t0, rest_h, rest_steps, record, workers, lead=(t0, lead_h, lead_steps)
        )
        if not np.isfinite(out).all():
            raise NumericalFailure(_diagnose(config, state, t0, duration, h))
        return (out, _Recorder.merge([rows], t0, h, summary)) if record else out
    blocks = []
    for part, start, length, part_steps, part_h in parts:
        before = state
        state, rows, _ = _advance_rows(part, state, start, targets, None, record, workers, part_steps, part_h)
        if not np.isfinite(state).all():
            raise NumericalFailure(_diagnose(part, before, start, length, part_h))
        blocks.append(rows)
    if not record:
        return state
    # Each part's row blocks split the robots alike; join them in time, the halves' on the grid.
    joined = [np.concatenate([first[::2], *rest]) for first, *rest in zip(*blocks)]
    return state, _Recorder.merge(joined, t0, h)


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


def _integrate(config: SimConfig, targets, blend, y, t0: float, h: float, n_steps: int, record: bool):
    """Run the configured stepper on components y (13 floats, or a (13, n) array, in place):
    (y after n_steps steps of h, the recorder or None)."""
    f, first = _stage_fns(config, targets, blend, locked=config.integrator in LOCKED_INTEGRATORS)
    recorder = _Recorder(first, config, n_steps, None if isinstance(y, list) else y.shape[1]) if record else None
    step_floats, step_arrays = _STEPPERS[config.integrator]
    stepper = step_floats if isinstance(y, list) else step_arrays
    if config.integrator in SERVO_INTEGRATORS:
        start = recorder if recorder is not None else (lambda t, c, mobility: first(t, c, mobility)[0])
        servo = _ServoJacobian(config.gains, h) if config.integrator == "rosw" else _ServoExponential(config, h, targets)
        return stepper(f, t0, y, h, n_steps, start, servo), recorder
    return stepper(f, t0, y, h, n_steps, recorder), recorder


ROW_BY_ROW_MAX = 20
"""A batch of at most this many robots is integrated one robot at a time on Python floats:
below it numpy's per-call overhead costs more than the loop (``python -m benchmarks.row_crossover``:
robot by robot takes 0.70x the batched time at 16 robots, 0.96x at 20, 1.14x at 24). The
choice depends on the batch size only, so ``workers`` never changes a result."""


def _integrate_rows(config: SimConfig, targets, blend, state, t0: float, h: float, n_steps: int, record: bool):
    """:func:`_integrate` of a small batch (n, 13) robot by robot on floats: (the states (n, 13),
    [the record's rows (S, 11, n) or None]). A robot that blows up gets NaN rows, as in a batch."""
    out = np.empty_like(state)
    rows = []
    # A target source may give one robot's targets on floats itself (``robot(i)``: the ramps and
    # gaits of :mod:`rrrobot_gym.control`); any other is indexed at every evaluation.
    one_robot = getattr(targets, "robot", None) or (lambda i: _RowsOf(targets, i, float))
    for i in range(len(state)):
        try:
            y, recorder = _integrate(config, one_robot(i), _blend_rows(blend, i, float),
                                     state[i].tolist(), t0, h, n_steps, record)  # fmt: skip
            out[i] = y
            rows.append(None if recorder is None else recorder.rows)
        except (OverflowError, ValueError, ZeroDivisionError):  # math.* on inf/NaN floats
            out[i] = np.nan
            rows.append(np.full((n_steps, _RECORD_ROWS), np.nan) if record else None)
    return out, [np.stack(rows, axis=2) if record else None]


def _block_inputs(config: SimConfig, targets, blend, state, t0, h, n_steps, record, rows):
    """The arguments of :func:`_integrate_block` for the robots ``rows`` (a slice) of a batch."""
    return config, _RowsOf(targets, rows), _blend_rows(blend, rows), state[rows], t0, h, n_steps, record


def _blend_rows(blend, rows, cast=None):
    """The part of a kinematic blend (t0, coeffs1, coeffs2) for the robots ``rows`` (a slice,
    or one robot's index with ``cast=float`` for the float steppers)."""
    if blend is None:
        return None
    t_blend, *coeffs = blend
    take = (lambda v: _take(v, rows)) if cast is None else (lambda v: cast(_take(v, rows)))
    return (t_blend, *(tuple(take(v) for v in c) for c in coeffs))


def _integrate_block(job):
    """:func:`_integrate` on a batch (n, 13), in this process or a worker of :func:`advance`:
    (the states (n, 13), the record's rows (S, 11, n) or None)."""
    config, targets, blend, state, t0, h, n_steps, record = job
    if len(state) >= 1024:
        _keep_freed_heap(len(state))
    with np.errstate(all="ignore"):  # a blow-up is reported by advance, by name, not as warnings
        y, recorder = _integrate(config, targets, blend, np.array(state.T, order="C"), t0, h, n_steps, record)
    return y.T.copy(), (None if recorder is None else recorder.rows)


def _take(value, rows):
    """``value[rows]`` for a per-robot array, ``value`` itself for a number shared by all robots."""
    return value[rows] if isinstance(value, np.ndarray) and value.ndim else value


class _RowsOf:
    """A leg-target source as seen by some of a batch's robots (a block of :func:`advance`'s workers),
    or by one of them (``rows`` an index, ``cast=float``: Python floats for the float steppers)."""

    def __init__(self, targets, rows, cast=None):
        self._targets, self._rows, self._cast = targets, rows, cast

    def leg_targets(self, t):
        triples = self._targets.leg_targets(t)
        if self._cast is None:
            return tuple(tuple(_take(v, self._rows) for v in triple) for triple in triples)
        return tuple(tuple(self._cast(_take(v, self._rows)) for v in triple) for triple in triples)


_POOLS = {}
"""{workers: ProcessPoolExecutor}: the numpy path's worker processes, made at first use and
kept (a fork costs more than a step) until :func:`close_workers`."""
_POOLS_LOCK = threading.Lock()
"""Held while a pool is made or given its jobs, and while :func:`close_workers` takes the pools
away: so a batch stepping in one thread never meets a pool another thread has shut down."""


def _process_pool(workers: int):
    """Worker processes for :func:`advance`'s blocks (forked where the platform allows)."""
    pool = _POOLS.get(workers)
    if pool is None:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
        pool = _POOLS[workers] = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context(method))
    return pool


def close_workers() -> None:
    """Stop the worker processes :func:`advance` started for ``workers`` > 1 on the numpy path
    (numba's threads need no stopping); a vector env made with workers calls it on close(). Jobs
    already given to them finish first, and a later call with workers starts new ones, so this
    is safe while other batches step, in this thread or another."""
    with _POOLS_LOCK:
        pools = list(_POOLS.values())
        _POOLS.clear()
    for pool in pools:
        pool.shutdown(wait=True)


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


MAX_SAMPLES = 10**8
"""The most samples :func:`simulate` and :func:`simulate_reference` keep (``duration / sample_dt``):
13 float64s each, 10.4 GB for one robot."""


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
    legs, rates = state[..., dynamics.LEG_ANGLES], state[..., dynamics.LEG_RATES]
    return SmoothStart(targets, (legs[..., 0], legs[..., 1]), (rates[..., 0], rates[..., 1]))


def simulate(config: SimConfig, targets, duration: float, *, state=None, sample_dt: float = 0.01):
    """Run the fixed-step integrator and sample the state every ``sample_dt`` seconds.

    ``state`` defaults to :func:`initial_state` (one robot). Time starts at 0. With
    kinematic legs the legs follow :class:`SmoothStart` from the start state into the targets.
    """
    state = check_state(initial_state() if state is None else state)
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

    state = check_state(initial_state() if state is None else state)
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
