"""Physical and control parameters of the RRRobot, as frozen dataclasses.

Values are the paper's (Section III, Table I) unless noted; see ``shared/MODEL.md``.
Every field carries its unit. Construction validates values, so a bad parameter is
reported where it is made, not as a NaN deep inside the integrator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

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


@dataclass(frozen=True)
class RobotParams:
    """Geometry, masses and environment of the robot (paper Section III).

    The shell and legs are massless; five point masses carry all the mass.
    """

    radius: float = 0.12  # m, shell radius r
    leg_length: float = 0.1  # m, leg length l (pin to tip mass)
    mass_bottom: float = 0.3  # kg, Mb at the bottom of the shell, body (0, 0, -r)
    mass_pin: float = 0.053  # kg, Ms at each leg pin, body (0, -+r, 0)
    mass_tip: float = 0.057  # kg, Ml at each leg tip
    gravity: float = 9.81  # m/s^2
    damping: float = -0.01  # N m s/rad, k: torque k*w on the body (w: its angular velocity)

    def __post_init__(self):
        _require_finite(self, [f.name for f in fields(self)])
        for name in ("radius", "leg_length", "mass_tip"):
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

    @property
    def total_mass(self) -> float:
        """kg, sum of the five point masses."""
        return self.mass_bottom + 2.0 * self.mass_pin + 2.0 * self.mass_tip

    @property
    def leg_inertia(self) -> float:
        """kg m^2, a leg's inertia about its pin, Ml l^2."""
        return self.mass_tip * self.leg_length**2


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


def rotation_point_depth(model: str, params: RobotParams) -> float:
    """m, depth h below the centre of the point the body rotates about.

    On a plane the body rolls, so its instantaneous rotation is about the contact point
    (h = r); the Pivoting Dynamics model turns about a spherical joint at the centre (h = 0).
    """
    return params.radius if check_model(model) == "plane" else 0.0
