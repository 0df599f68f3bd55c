"""Physical and control parameters of the RRRobot, as frozen dataclasses.

Values are the paper's (Section III, Table I) unless noted; see ``shared/MODEL.md``.
Every field carries its unit. Construction validates values, so a bad parameter is
reported where it is made, not as a NaN deep inside the integrator.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

MODELS = ("plane", "pivot")
"""The two dynamic models: rolling on a plane, and the Pivoting Dynamics model."""


def real_number(label: str, value) -> float:
    """``float(value)``, or an error naming ``label``: TypeError if it is not a real number (a
    bool, a string of digits or a complex number is not one, though ``float`` takes each),
    ValueError if it is NaN or infinite."""
    if isinstance(value, (bool, np.bool_, str, bytes, np.complexfloating)) or (
        isinstance(value, np.ndarray) and value.dtype.kind in "bcUSO"
    ):  # (float() takes each of these, the complex ones dropping their imaginary part)
        raise TypeError(f"{label} must be a real number, got {value!r}")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise TypeError(f"{label} must be a real number, got {value!r}") from None
    if not math.isfinite(number):
        raise ValueError(f"{label} must be finite, got {value!r}")
    return number


def whole_number(label: str, value, minimum: int = 1) -> int:
    """``int(value)`` for an integer (not a bool) of at least ``minimum``, or a ValueError naming ``label``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        wanted = "a positive integer" if minimum == 1 else "a non-negative integer" if minimum == 0 else f"an integer >= {minimum}"
        raise ValueError(f"{label} must be {wanted}, got {value!r}")
    return int(value)


def _require_finite(obj, names):
    """Make each named field of a frozen dataclass a finite float, or raise naming it."""
    for name in names:
        object.__setattr__(obj, name, real_number(f"{type(obj).__name__}.{name}", getattr(obj, name)))


MAX_LEGS = 6
"""The most legs a robot of the family has."""


def leg_count(label: str, value, fewest: int = 1, why: str = "") -> int:
    """``int(value)`` for a whole number of legs from ``fewest`` to :data:`MAX_LEGS`, or one ValueError
    naming ``label`` (and ``why``, in parentheses, where a caller allows fewer than the family)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not fewest <= value <= MAX_LEGS:
        reason = f" ({why})" if why else ""
        raise ValueError(f"{label} must be a whole number from {fewest} to {MAX_LEGS}{reason}, got {value!r}")
    return int(value)


def _vector(label: str, value) -> tuple:
    """``value`` as three finite floats, or an error naming ``label``."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{label} must be three numbers (x, y, z), got {value!r}") from None
    if array.shape != (3,):
        raise ValueError(f"{label} must be three numbers (x, y, z), got shape {array.shape}")
    return tuple(real_number(f"{label}[{i}]", v) for i, v in enumerate(array.tolist()))


@dataclass(frozen=True)
class Leg:
    """One leg of the family: a massless rod hinged on the shell, with a point mass at its pin and
    one at its tip. The tip is at ``hinge + length (cos phi zero + sin phi up)``: it swings in the
    plane of the orthonormal ``zero`` (phi = 0) and ``up`` (phi = pi/2) about the hinge axis
    zero x up. ``length``, ``mass_pin`` and ``mass_tip`` None take the robot's (``RobotParams``);
    a per-robot draw of those (domain randomization) scales a leg's own value alike."""

    hinge: tuple  # m, body frame: the pin, on the shell
    zero: tuple  # unit vector, body frame: the leg's direction at phi = 0
    up: tuple  # unit vector, body frame, orthogonal to zero: the leg's direction at phi = pi/2
    length: float | None = None  # m, pin to tip mass; None: RobotParams.leg_length
    mass_pin: float | None = None  # kg; None: RobotParams.mass_pin
    mass_tip: float | None = None  # kg; None: RobotParams.mass_tip

    def __post_init__(self):
        for name in ("hinge", "zero", "up"):
            object.__setattr__(self, name, _vector(f"Leg.{name}", getattr(self, name)))
        for name, unit in (("zero", self.zero), ("up", self.up)):
            if abs(math.hypot(*unit) - 1.0) > 1e-9:
                raise ValueError(f"Leg.{name} must be a unit vector, got {unit} (length {math.hypot(*unit):.6g})")
        if abs(sum(a * b for a, b in zip(self.zero, self.up))) > 1e-9:
            raise ValueError(f"Leg.zero and Leg.up must be orthogonal, got {self.zero} and {self.up}")
        for name in ("length", "mass_pin", "mass_tip"):
            value = getattr(self, name)
            if value is not None:
                value = real_number(f"Leg.{name}", value)
                if value < 0.0 or (value == 0.0 and name != "mass_pin"):
                    raise ValueError(f"Leg.{name} must be {'positive' if name != 'mass_pin' else '>= 0'}, got {value}")
                object.__setattr__(self, name, value)


def _quarter_exact(angle_deg: float) -> tuple:
    """(cos, sin) of an angle in degrees, exact at multiples of 90 degrees."""
    quarter = angle_deg / 90.0
    if quarter == round(quarter):
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[int(round(quarter)) % 4]
    return math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))


def default_legs(num_legs: int, shell_axes) -> tuple:
    """The family's default placement of ``num_legs`` legs (lengths and masses the robot's): hinges
    on the rim (z = 0) at -90 deg + k 360 deg / num_legs from +x, each swinging in the plane of the
    rim's tangent and the body z axis, phi = 0 along the tangent pointing forward (+x; +y where the
    tangent is along y), phi = pi/2 straight up. Two legs are the paper's robot: at (0, -r, 0)
    (leg 1) and (0, +r, 0), both with phi = 0 along +x."""
    a, b, _ = shell_axes
    legs = []
    for k in range(num_legs):
        cos_t, sin_t = _quarter_exact(-90.0 + 360.0 * k / num_legs)
        tx, ty = -a * sin_t, b * cos_t  # the rim's tangent, (a cos t, b sin t)'
        norm = math.hypot(tx, ty)
        tx, ty = tx / norm, ty / norm
        if tx < 0.0 or (tx == 0.0 and ty < 0.0):
            tx, ty = -tx, -ty
        legs.append(Leg(hinge=(a * cos_t, b * sin_t, 0.0), zero=(tx + 0.0, ty + 0.0, 0.0), up=(0.0, 0.0, 1.0)))
    return tuple(legs)


@dataclass(frozen=True)
class RobotParams:
    """Geometry, masses and environment of a robot of the family (the paper's by default, Section III).

    The shell (a half-ellipsoid, open side up) and the legs are massless; point masses carry all
    the mass: one at the bottom of the shell, one at each leg's pin and one at each leg's tip.
    """

    radius: float | None = None  # m, the shell's radius r, a sphere (None: 0.12, or shell_axes' if a sphere)
    leg_length: float = 0.1  # m, leg length l (pin to tip mass), every leg's unless its own
    mass_bottom: float = 0.3  # kg, Mb at the bottom of the shell, body (0, 0, -c)
    mass_pin: float = 0.053  # kg, Ms at each leg pin, every leg's unless its own
    mass_tip: float = 0.057  # kg, Ml at each leg tip, every leg's unless its own
    gravity: float = 9.81  # m/s^2
    damping: float = -0.01  # N m s/rad, k: torque k*w on the body (w: its angular velocity)
    shell_axes: tuple | None = None  # m, (a, b, c): the shell's semi-axes along body x, y, z; None: (r, r, r)
    num_legs: int = 2  # 1 to MAX_LEGS
    legs: tuple | None = None  # one Leg per leg; None: default_legs(num_legs, shell_axes)

    def __post_init__(self):
        put = functools.partial(object.__setattr__, self)
        if self.shell_axes is None:
            put("radius", 0.12 if self.radius is None else self.radius)
            put("radius", real_number("RobotParams.radius", self.radius))
            if self.radius <= 0.0:
                raise ValueError(f"RobotParams.radius must be positive, got {self.radius}")
            put("shell_axes", (self.radius,) * 3)
        else:
            axes = _vector("RobotParams.shell_axes", self.shell_axes)
            if not all(v > 0.0 for v in axes):
                raise ValueError(f"RobotParams.shell_axes must be three positive semi-axes (m), got {axes}")
            put("shell_axes", axes)
            sphere = axes[0] == axes[1] == axes[2]
            if self.radius is not None and not (sphere and real_number("RobotParams.radius", self.radius) == axes[0]):
                raise ValueError(f"RobotParams: give radius (a sphere) or shell_axes, not both: radius {self.radius!r}, "
                                 f"shell_axes {axes}")
            put("radius", axes[0] if sphere else None)
        _require_finite(self, ["leg_length", "mass_bottom", "mass_pin", "mass_tip", "gravity", "damping"])
        for name in ("leg_length", "mass_tip"):
            if getattr(self, name) <= 0.0:
                raise ValueError(f"RobotParams.{name} must be positive, got {getattr(self, name)}")
        for name in ("mass_bottom", "mass_pin", "gravity"):
            if getattr(self, name) < 0.0:
                raise ValueError(f"RobotParams.{name} must not be negative, got {getattr(self, name)}")
        if self.damping > 0.0:
            raise ValueError(
                f"RobotParams.damping must be <= 0 (the paper's sign: torque k*w with k < 0 dissipates), "
                f"got {self.damping}"
            )
        put("num_legs", leg_count("RobotParams.num_legs", self.num_legs))
        if self.legs is None:
            put("legs", default_legs(self.num_legs, self.shell_axes))
        else:
            legs = tuple(Leg(**leg) if isinstance(leg, dict) else leg for leg in self.legs)
            if not all(isinstance(leg, Leg) for leg in legs):
                raise TypeError("RobotParams.legs must be rrrobot_gym.params.Leg objects (or dicts of their fields)")
            if len(legs) != self.num_legs:
                raise ValueError(f"RobotParams.legs has {len(legs)} legs but num_legs is {self.num_legs}")
            put("legs", legs)

    @property
    def leg_lengths(self) -> tuple:
        """m, each leg's length."""
        return tuple(self.leg_length if leg.length is None else leg.length for leg in self.legs)

    @property
    def leg_masses(self) -> tuple:
        """kg, each leg's (pin, tip) masses."""
        return tuple((self.mass_pin if leg.mass_pin is None else leg.mass_pin,
                      self.mass_tip if leg.mass_tip is None else leg.mass_tip) for leg in self.legs)  # fmt: skip

    @property
    def total_mass(self) -> float:
        """kg, the sum of the point masses."""
        total = self.mass_bottom
        for pin, tip in self.leg_masses:  # (leg by leg, as dynamics.constants adds them)
            total = total + (pin + tip)
        return total

    @property
    def leg_inertia(self) -> float:
        """kg m^2, the lightest leg's inertia about its pin, Ml l^2."""
        return min(tip * length**2 for (_, tip), length in zip(self.leg_masses, self.leg_lengths))

    @property
    def is_sphere(self) -> bool:
        """True if the shell is a sphere (the paper's)."""
        a, b, c = self.shell_axes
        return a == b == c


@dataclass(frozen=True)
class PDGains:
    """The leg servo: tau = kp (phi_target - phi) + kd (phi_rate_target - phi_rate).

    The paper gives no gains. With the leg inertia Ml l^2 = 5.7e-4 kg m^2 the defaults
    give a natural frequency of about 59 rad/s, well above the gaits' 8 rad/s.
    """

    kp: float = 2.0  # N m/rad
    kd: float = 0.05  # N m s/rad

    def __post_init__(self):
        _require_finite(self, ("kp", "kd"))
        if self.kp <= 0.0:
            raise ValueError(f"PDGains.kp must be positive, got {self.kp}")
        if self.kd < 0.0:
            raise ValueError(f"PDGains.kd must not be negative, got {self.kd}")


def check_model(model: str) -> str:
    """Return ``model`` if it names one of :data:`MODELS`, else raise a ValueError."""
    if model not in MODELS:
        raise ValueError(f"unknown model {model!r}: expected one of {', '.join(MODELS)}")
    return model
