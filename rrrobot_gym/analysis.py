"""Quantities the paper reports, computed from the dynamics: Table I and travel.

Table I (small-oscillation periods) comes from linearising
:func:`rrrobot_gym.dynamics.state_derivative` itself about rest, legs held vertical;
travel is measured on the contact path averaged over each gait period, because
the raw contact point wiggles at the gait frequency (see ``shared/MODEL.md``).
"""

from __future__ import annotations

import math

import numpy as np

from . import dynamics
from .params import MODELS, RobotParams
from .simulation import initial_state

PAPER_TABLE1 = {("plane", "x"): 1.29, ("plane", "y"): 1.07, ("pivot", "x"): 1.19, ("pivot", "y"): 0.96}
"""s, the paper's Table I: small-oscillation periods, legs vertical."""


def _locked_leg_body_accel(params: RobotParams, model: str, rotation_vector):
    """Omega' at rest, tilted by a body-frame rotation vector, legs vertical and held (phi'' = 0)."""
    legs = params.num_legs
    state = initial_state(num_legs=legs)
    angle = float(np.linalg.norm(rotation_vector))
    axis = np.asarray(rotation_vector) / angle if angle else np.zeros(3)
    state[dynamics.QUAT] = np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * axis])
    deriv = dynamics.state_derivative(state.tolist(), (0.0,) * legs, params, model, kinematic=True)
    return np.array(deriv[6 + legs : 9 + legs])


def small_oscillation_periods(model: str, params: RobotParams | None = None, eps: float = 1e-6):
    """Periods (s) of the X and Y rocking modes about rest with the legs held vertical.

    Linearises the equations of motion (damping off) about the upright rest state:
    Omega' = -K delta with delta a small body-frame rotation vector, K from central
    differences. Its eigenvalues are the squared angular frequencies; the Z mode has
    none (gravity exerts no torque about the vertical). Returns {"x": T_x, "y": T_y}.
    """
    params = _params(params)
    if not (math.isfinite(eps) and eps > 0):
        raise ValueError(f"eps must be a small positive rotation (rad) for the central differences, got {eps!r}")
    params = RobotParams(**{**params.__dict__, "damping": 0.0})
    stiffness = np.empty((3, 3))
    for j in range(3):
        dv = np.zeros(3)
        dv[j] = eps
        stiffness[:, j] = -(
            _locked_leg_body_accel(params, model, dv) - _locked_leg_body_accel(params, model, -dv)
        ) / (2 * eps)
    eigval, eigvec = np.linalg.eig(stiffness)
    periods = {}
    for axis, index in (("x", 0), ("y", 1)):
        mode = int(np.argmax(np.abs(eigvec[index])))
        omega_sq = float(np.real(eigval[mode]))
        periods[axis] = 2.0 * math.pi / math.sqrt(omega_sq) if omega_sq > 0 else math.inf
    return periods


def single_axis_formulas(model: str, params: RobotParams | None = None):
    """The paper's single-axis period models for rotations about X and Y, in s.

    ``compound``: a rigid body rocking about one axis through the contact point (plane)
    or the centre (pivot), T = 2 pi sqrt(I / (M g d)) with I the inertia about that
    axis and d the depth of the centre of mass below the centre.
    ``paper_eq``: eq. (5) (plane) or eq. (6) (pivot) taken literally, with rho the radius of
    gyration about that axis, sqrt(I / M). These model the robot as one lumped mass;
    NaN where the formula has no real value (eq. 5 needs rho < r).
    """
    params = _params(params)
    state = initial_state()
    inertia = dynamics.mass_matrix(state, params, model)[:3, :3]
    mass, g, r = params.total_mass, params.gravity, params.radius
    com_depth = -(2 * params.mass_tip * params.leg_length - params.mass_bottom * r) / mass
    out = {}
    for axis, index in (("x", 0), ("y", 1)):
        i_axis = inertia[index, index]
        rho = math.sqrt(i_axis / mass)
        compound = 2 * math.pi * math.sqrt(i_axis / (mass * g * com_depth)) if com_depth > 0 else math.inf
        if model == "plane":
            paper_eq = 2 * math.pi * math.sqrt(rho**2 / (g * (r - rho))) if rho < r else math.nan
        else:
            paper_eq = 2 * math.pi * math.sqrt(rho / g)
        out[axis] = {"compound": compound, "paper_eq": paper_eq, "rho": rho}
    return out


def _params(params) -> RobotParams:
    """``params`` (None: the paper's), checked: a RobotParams with gravity, or an error naming the problem."""
    params = RobotParams() if params is None else params
    if not isinstance(params, RobotParams):
        raise TypeError(f"params must be a rrrobot_gym.params.RobotParams, got {type(params).__name__}")
    if params.gravity <= 0.0:
        raise ValueError(f"the rocking periods need gravity > 0 (without it nothing rocks back), got {params.gravity}")
    return params


def table1(params: RobotParams | None = None):
    """Table I computed by the code, as a list of records (one per model and axis)."""
    records = []
    for model in MODELS:
        periods = small_oscillation_periods(model, params)
        formulas = single_axis_formulas(model, params)
        for axis in ("x", "y"):
            paper = PAPER_TABLE1[(model, axis)]
            records.append(
                {
                    "model": model,
                    "axis": axis,
                    "period_s": periods[axis],
                    "paper_s": paper,
                    "relative_difference": periods[axis] / paper - 1.0,
                    "compound_formula_s": formulas[axis]["compound"],
                    "paper_formula_s": formulas[axis]["paper_eq"],
                    "paper_formula": "eq. (5)" if model == "plane" else "eq. (6)",
                    "radius_of_gyration_m": formulas[axis]["rho"],
                }
            )
    return records


def period_average(times, values, period: float):
    """Moving average of ``values`` (T, ...) over one ``period`` (s), at the window centres.

    Returns (times, averages) for every full window; the gait-frequency wiggle of
    the contact point averages out, leaving the path the robot actually travels.
    """
    times = np.asarray(times, dtype=float)
    values = np.asarray(values, dtype=float)
    if not (math.isfinite(period) and period > 0):
        raise ValueError(f"period must be a positive number of seconds, got {period!r}")
    if times.ndim != 1 or len(times) < 2 or len(values) != len(times):
        raise ValueError(
            f"period_average needs two or more samples, times (T,) and values (T, ...), got {times.shape} and {values.shape}"
        )
    dt = float(np.median(np.diff(times)))
    width = max(1, int(round(period / dt)))
    if width >= len(times):
        raise ValueError(f"the trajectory ({times[-1] - times[0]:.3g} s) is shorter than one period ({period:.3g} s)")
    cumsum = np.cumsum(np.concatenate([np.zeros((1,) + values.shape[1:]), values]), axis=0)
    avg = (cumsum[width:] - cumsum[:-width]) / width
    centre = times[: len(avg)] + 0.5 * (width - 1) * dt
    return centre, avg


def travel_summary(times, x, y, period: float):
    """Net displacement, direction, path length and turning of the period-averaged path.

    Returns a dict: ``displacement_m`` (start to end of the averaged path),
    ``direction_deg`` (of that displacement, from +X counter-clockwise),
    ``path_length_m`` (length of the averaged path), ``turning_deg`` (total signed
    change of heading along the averaged path, counter-clockwise positive),
    ``signed_area_m2`` (enclosed area, > 0 when the path winds counter-clockwise),
    ``mean_speed_mps`` (path length over the averaged path's duration).
    """
    times = np.asarray(times, dtype=float)
    if len(times) < 2 or times[-1] - times[0] < 2.0 * period:
        span = times[-1] - times[0] if len(times) else 0.0
        raise ValueError(f"travel_summary needs at least two periods ({2 * period:.3g} s) of trajectory, got {span:.3g} s")
    t_avg, xy = period_average(times, np.stack([x, y], axis=-1), period)
    dt = float(np.median(np.diff(t_avg)))
    # One point per period: finer sampling follows the residual wiggle of the
    # start-up transient, whose heading flips back and forth.
    coarse = xy[:: max(1, int(round(period / dt)))]
    step = np.diff(coarse, axis=0)
    seg = np.linalg.norm(step, axis=-1)
    disp = xy[-1] - xy[0]
    moving = seg > 0.05 * max(float(np.median(seg)), 1e-15)
    heading = np.unwrap(np.arctan2(step[moving, 1], step[moving, 0]))
    turning = float(heading[-1] - heading[0]) if len(heading) > 1 else 0.0
    duration = t_avg[-1] - t_avg[0]
    # Shoelace area of the averaged path closed by a straight line: > 0 counter-clockwise.
    signed_area = 0.5 * float(np.sum(xy[:-1, 0] * xy[1:, 1] - xy[1:, 0] * xy[:-1, 1]) + xy[-1, 0] * xy[0, 1] - xy[0, 0] * xy[-1, 1])
    path_length = float(np.linalg.norm(np.diff(xy, axis=0), axis=-1).sum())
    return {
        "displacement_m": float(np.hypot(*disp)),
        "dx_m": float(disp[0]),
        "dy_m": float(disp[1]),
        "direction_deg": float(np.degrees(np.arctan2(disp[1], disp[0]))),
        "path_length_m": path_length,
        "turning_deg": float(np.degrees(turning)),
        "signed_area_m2": signed_area,
        "mean_speed_mps": float(path_length / duration) if duration > 0 else 0.0,
    }


def json_safe(value):
    """``value`` as JSON can hold it: numpy scalars and arrays become Python numbers and lists,
    mapping keys strings, and floats that are not finite None (JSON has no NaN)."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
