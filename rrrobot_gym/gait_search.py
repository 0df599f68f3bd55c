"""Gait search: CMA-ES over open-loop per-leg sinusoids, scored in one batched env.

The gait family is phi_k(t) = o_k + a_k sin(w t + beta_k), beta_1 = 0, for each of the robot's L
legs: 3L numbers (:class:`SinusoidGait`, :func:`parameter_names`), six for the paper's robot, whose
beta_2 is the phase gap. A population runs as ONE
:class:`rrrobot_gym.envs.vector.RRRobotVectorEnv` with the env's own envelope, so a searched gait
is scored exactly as the env would score it.

    from rrrobot_gym.gait_search import search
    search(model="plane", objective="own", budget_seconds=600, seed=0).write_json("best_gaits.json")

or ``rrrobot gait-search``. Needs the ``search`` extra (``cma``, ``tqdm``); ``ray_address`` needs
``distributed`` (``ray``).

Glossary
--------
parameters      (P, 3L) float, one row a gait, columns :func:`parameter_names` (L)
unit box        the search's coordinates: each parameter mapped affinely from its
                :func:`bounds` interval onto [0, 1], so one CMA step size suits them all
start seeds     the env's reset seeds of the starts a gait is scored from (start noise
                ``reset_noise_scale``); every gait of a search sees the same starts
objective       "own": speed along the gait's own net displacement; "heading": speed
                along a commanded heading (deg from +X towards +Y) from the paper's start
fitness         what CMA-ES maximises (m/s): the objective's speed, penalised for leaving
                the model (:func:`fitness_from_runs`)

Output JSON (:meth:`SearchResult.to_json`, schema ``rrrobot_gym.gait_search/1``)
---------------------------------------------------------------------------------
- ``schema``, ``family`` ("sinusoid"), ``parameter_names``, ``bounds`` ({name: [lo, hi]})
- ``num_legs`` (the robot's L; absent means 2), ``model``, ``objective``, ``heading_deg`` (null for "own"), ``env_kwargs`` (the env
  keywords besides ``model`` and ``reset_noise_scale``, every servo keyword among them:
  :func:`rrrobot_gym.envs.task.with_servo`), ``reset_noise_scale``, ``ramp_s``
  (s, :func:`ramp_factor`; absent means 0), ``duration_s`` (episode length scored), ``start_seeds``
- ``seed``, ``budget`` ({"evaluations", "seconds"}, null if not limited),
  ``used`` ({"evaluations", "seconds", "generations", "restarts"}), ``popsize``,
  ``screen`` (random gaits tried first), ``command``, ``history`` (per population scored:
  evaluations so far, seconds, best fitness and speed so far, the population's median fitness)
- ``robust_pool``: how many of the fittest distinct gaits were re-scored on new starts (null: none)
- ``gaits``: best first, each ``{"name", "parameters": {name: value}, "fitness",
  "speed_mps", "direction_deg", "terminated_starts", "search_rank", "robust",
  "robustness"}``; ``search_rank`` is the gait's place by fitness (1: the fittest), ``robust``
  whether it stayed in the model on every start it was scored from (null if not re-scored);
  ``robustness`` (if re-scored) is :func:`robustness`'s report on start seeds the search never
  used. With a re-score, the best gait is the fittest robust one (:func:`rank_robust_first`).
One evaluation = one gait scored from all its start seeds.
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import dynamics
from .analysis import json_safe
from .envs.task import (LEG_TARGET_MAX, LEG_TARGET_MIN, control_steps, leg_targets_to_action, upright_contact_points,
                         with_servo)
from .control import TARGETS_SINUSOID, sinusoid_targets
from .params import MAX_LEGS, leg_count, real_number, whole_number

SCHEMA = "rrrobot_gym.gait_search/1"
OBJECTIVES = ("own", "heading")


def parameter_names(num_legs: int = 2) -> tuple:
    """The names of an L-leg sinusoid's 3L numbers, in the order of its parameter arrays:
    ``amplitude_1..L``, ``offset_1..L``, ``frequency``, then the phases of legs 2..L after leg 1's
    (leg 1's is 0): ``phase_gap`` for the paper's two legs, ``phase_2 .. phase_L`` otherwise."""
    legs = range(1, leg_count("num_legs", num_legs) + 1)
    phases = ("phase_gap",) if num_legs == 2 else tuple(f"phase_{k}" for k in legs if k > 1)
    return (*(f"amplitude_{k}" for k in legs), *(f"offset_{k}" for k in legs), "frequency", *phases)


def bounds(num_legs: int = 2) -> dict:
    """The search box of an L-leg sinusoid, per parameter (:func:`parameter_names`; rad, rad/s)."""
    box = {"amplitude": (0.0, 1.5), "offset": (LEG_TARGET_MIN, LEG_TARGET_MAX), "frequency": (1.0, 15.0),
           "phase": (-math.pi, math.pi)}  # fmt: skip
    return {name: box[name.split("_")[0]] for name in parameter_names(num_legs)}


def legs_of_parameters(size: int) -> int:
    """L of a sinusoid given as ``size`` numbers (3L), or a ValueError naming the sizes allowed."""
    if size % 3 or not 1 <= size // 3 <= MAX_LEGS:
        raise ValueError(f"a sinusoid gait has 3 numbers a leg (amplitudes, offsets, a frequency and the phases of "
                         f"legs 2..L), 3 to {3 * MAX_LEGS} in all; got {size}")
    return size // 3


PARAMETER_NAMES = parameter_names(2)
"""The paper's robot's six: ``amplitude_1, amplitude_2, offset_1, offset_2, frequency, phase_gap``."""
BOUNDS = bounds(2)
"""The search box, per parameter (rad, rad, rad, rad, rad/s, rad); :func:`bounds` for L legs. Offsets
span the whole action range; amplitudes are repaired to keep o_k +- a_k inside it (:func:`repair`), so
the targets are a true sinusoid, never one flattened by the action clip. Frequencies: from three
periods in a 20 s episode to about 8 control steps a period (the paper's gaits run at 8 rad/s). The
phase gap's sign picks the direction of travel (the paper's swapped phases).
"""


TERMINATION_PENALTY = 1.0
"""m/s, L in :func:`fitness_from_runs`: a speed no sinusoid reaches here (the best
found without the envelope is ~0.17 m/s)."""


def _lows_highs(num_legs: int = 2):
    box = bounds(num_legs)
    return np.array([low for low, _ in box.values()]), np.array([high for _, high in box.values()])


def repair(parameters) -> np.ndarray:
    """Parameters (P, 3L) or (3L,) clipped to :func:`bounds`, amplitudes shrunk so that
    o_k +- a_k stays inside the action range (see :data:`BOUNDS`)."""
    params = np.array(parameters, dtype=float)
    try:
        legs = legs_of_parameters(params.shape[-1]) if params.ndim in (1, 2) else None
    except ValueError:
        legs = None
    if legs is None or not np.all(np.isfinite(params)):
        raise ValueError(f"gait parameters must be finite, shape (3L,) or (P, 3L) for L legs "
                         f"({', '.join(PARAMETER_NAMES)} for two), got {parameters!r}")  # fmt: skip
    lows, highs = _lows_highs(legs)
    params = np.clip(params, lows, highs)
    for a in range(legs):
        o = legs + a
        room = np.minimum(params[..., o] - LEG_TARGET_MIN, LEG_TARGET_MAX - params[..., o])
        params[..., a] = np.minimum(params[..., a], room)
    return params


DEFAULT_RAMP_S = 2.0
"""s, how long a search's gaits take to grow their swing from nothing (:func:`ramp_factor`): without
a ramp the fastest plane gaits leave the model on some starts and not others
(``docs/notes/gait_search.md``)."""


def ramp_factor(times, ramp_s: float) -> np.ndarray:
    """The share of the amplitude at ``times`` (s): 3 u^2 - 2 u^3 with u = t / ramp_s while
    t < ramp_s (its rate starts and ends at zero), 1 after; 1 throughout for ``ramp_s`` 0."""
    t = np.asarray(times, dtype=float)
    ramp_s = _check_ramp(ramp_s)
    if ramp_s <= 0.0:
        return np.ones_like(t)
    u = np.clip(t / ramp_s, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def sinusoid_angles(parameters, times, ramp_s: float = 0.0) -> np.ndarray:
    """Leg target angles (..., L), rad, of L-leg gaits ``parameters`` (..., 3L) at ``times`` (s,
    broadcast against the leading axes): phi_k = o_k + r(t) a_k sin(w t + beta_k), beta_1 = 0, r the
    amplitude's ramp over the first ``ramp_s`` s (:func:`ramp_factor`; none by default)."""
    p = np.asarray(parameters, dtype=float)
    t = np.asarray(times, dtype=float)
    legs = legs_of_parameters(p.shape[-1])
    arg = p[..., 2 * legs] * t
    r = ramp_factor(t, ramp_s) if ramp_s > 0.0 else None
    angles = []
    for k in range(legs):
        swing = p[..., k] * np.sin(arg if k == 0 else arg + p[..., 2 * legs + k])
        angles.append(p[..., legs + k] + (swing if r is None else r * swing))
    return np.stack(np.broadcast_arrays(*angles), axis=-1)


def _check_ramp(ramp_s) -> float:
    if real_number("ramp_s", ramp_s) < 0.0:
        raise ValueError(f"ramp_s must be a number of seconds >= 0, got {ramp_s!r}")
    return float(ramp_s)


def positive_seconds(label: str, value) -> float:
    """``float(value)`` for a finite number of seconds > 0, else a ValueError naming ``label``."""
    if isinstance(value, (bool, str)) or not isinstance(value, (int, float, np.integer, np.floating)) or not (
        math.isfinite(value) and value > 0
    ):
        raise ValueError(f"{label} must be a positive number of seconds, got {value!r}")
    return float(value)


class SinusoidGait:
    """phi_k(t) = offset_k + amplitude_k sin(frequency t + beta_k), beta_1 = 0, for L legs.

    Made from the 3L numbers in :func:`parameter_names` order, positionally or by name
    (``SinusoidGait(a1, a2, o1, o2, w, gap)`` for the paper's robot; :meth:`from_dict`), each
    readable as an attribute (``gait.amplitude_1``). The paper's Table II gaits are the case
    amplitude_1 = amplitude_2 = 0.3 rad, frequency 8 rad/s, phase_gap pi/2, both offsets gamma. Has
    the ``angles(times)`` and ``leg_targets(t)`` of :class:`rrrobot_gym.control.Gait`, so it drives
    :class:`rrrobot_gym.agents.GaitAgent` and :func:`rrrobot_gym.simulation.simulate` alike.
    ``ramp_s`` > 0 grows the swing in over that many seconds (:func:`ramp_factor`; not a
    searched parameter but a setting of the search that found the gait).
    """

    def __init__(self, *values, ramp_s: float = 0.0, name: str = "sinusoid", **named):
        if values and named:
            raise ValueError("give a SinusoidGait's parameters by position or by name, not both")
        if named:
            legs = sum(key.startswith("amplitude_") for key in named)
            names = parameter_names(legs) if 1 <= legs <= MAX_LEGS else ()
            if set(named) != set(names):
                raise ValueError(f"sinusoid gait parameters must be exactly {', '.join(names or PARAMETER_NAMES)}; "
                                 f"got {', '.join(map(str, named))}")  # fmt: skip
            values = tuple(named[key] for key in names)
        legs = legs_of_parameters(len(values))
        names = parameter_names(legs)
        values = tuple(real_number(f"SinusoidGait.{key}", value) for key, value in zip(names, values))
        for key, value in zip(names[:legs], values):
            if value < 0.0:
                raise ValueError(f"SinusoidGait.{key} must be >= 0 rad, got {value}")
        object.__setattr__(self, "_values", values)
        object.__setattr__(self, "num_legs", legs)
        object.__setattr__(self, "ramp_s", _check_ramp(ramp_s))
        object.__setattr__(self, "name", str(name))

    def __getattr__(self, key):
        values = self.__dict__.get("_values")
        names = parameter_names(self.__dict__["num_legs"]) if values is not None else ()
        if key in names:
            return values[names.index(key)]
        raise AttributeError(f"{type(self).__name__} has no attribute {key!r}")

    def __setattr__(self, key, value):
        raise AttributeError(f"a SinusoidGait is frozen: cannot set {key}")

    def _key(self):
        return self._values, self.ramp_s, self.name

    def __eq__(self, other):
        return isinstance(other, SinusoidGait) and self._key() == other._key()

    def __hash__(self):
        return hash(self._key())

    def __repr__(self):
        items = ", ".join(f"{k}={v!r}" for k, v in self.parameters().items())
        return f"SinusoidGait({items}, ramp_s={self.ramp_s!r}, name={self.name!r})"

    def replace(self, **changes) -> "SinusoidGait":
        """A copy with some parameters (by name), ``ramp_s`` or ``name`` changed."""
        values = {**self.parameters(), "ramp_s": self.ramp_s, "name": self.name, **changes}
        return SinusoidGait(**values)

    @classmethod
    def from_dict(cls, values: dict, name: str = "sinusoid", ramp_s: float = 0.0) -> "SinusoidGait":
        return cls(**values, ramp_s=ramp_s, name=name)

    def as_array(self) -> np.ndarray:
        return np.array(self._values)

    def parameters(self) -> dict:
        return dict(zip(parameter_names(self.num_legs), self._values))

    @property
    def period(self) -> float:
        """s, one leg cycle; inf for a gait that does not oscillate."""
        return 2.0 * math.pi / abs(self.frequency) if self.frequency else math.inf

    def angles(self, times) -> np.ndarray:
        """Target leg angles at an array of times, shape (T, L), rad."""
        return sinusoid_angles(self.as_array(), np.asarray(times, dtype=float), self.ramp_s)

    def _legs(self):
        """(amplitudes, phases, offsets), a tuple a leg each."""
        L, v = self.num_legs, self._values
        return v[:L], (0.0, *v[2 * L + 1:]), v[L:2 * L]

    def compiled_targets(self):
        """(kind, per-robot parameters, shared parameters) for :mod:`rrrobot_gym.compiled`; None
        with a ramp, which the compiled stepper does not know (the numpy path runs it)."""
        if self.ramp_s > 0.0:
            return None
        amplitudes, phases, offsets = self._legs()
        return TARGETS_SINUSOID, (*amplitudes, self.frequency, *phases, *offsets), ()

    def leg_targets(self, t):
        """(angles, rates, accelerations) of every leg at time t, the ramp's own rate included."""
        amplitudes, phases, offsets = self._legs()
        w = self.frequency
        if t >= self.ramp_s:
            return sinusoid_targets(t, amplitudes, w, phases, offsets)
        # phi = o + r a sin(w t + b): the ramp r's rate r' and curvature r'' enter by the product rule
        u = max(t, 0.0) / self.ramp_s
        r, dr, ddr = u * u * (3.0 - 2.0 * u), 6.0 * u * (1.0 - u) / self.ramp_s, (6.0 - 12.0 * u) / self.ramp_s**2
        s, d, dd = sinusoid_targets(t, amplitudes, w, phases, (0.0,) * self.num_legs)
        return (
            tuple(o + r * sk for o, sk in zip(offsets, s)),
            tuple(dr * sk + r * dk for sk, dk in zip(s, d)),
            tuple(ddr * sk + 2.0 * dr * dk + r * ddk for sk, dk, ddk in zip(s, d, dd)),
        )


# ---------------------------------------------------------------- scoring a population


def body_yaw(states) -> np.ndarray:
    """rad (N,): the heading of the body's x axis, atan2(R10, R00) of its rotation."""
    qw, qx, qy, qz = np.asarray(states)[:, dynamics.QUAT].T
    return np.arctan2(2.0 * (qx * qy + qw * qz), 1.0 - 2.0 * (qy * qy + qz * qz))


def rollout(act, n, duration, reset, *, model, env_kwargs, record=False) -> dict:
    """Run ``n`` robots in ONE env for ``duration`` s, each until its first termination (the env's
    envelope), after ``env.reset(**reset)``; ``act(k, observations, dt)`` gives control step k's actions (n, 2).

    Returns a dict: ``displacement`` (n, 2) m of the contact point up to the end, ``end_time`` (n,) s,
    ``terminated`` (n,), ``torque_peak`` N m and ``leg_rate_peak`` rad/s (n,) while the run lasted,
    ``dt`` and ``duration`` (s, whole control steps); with ``record`` also ``upright`` (T + 1, n, 2) m,
    the upright contact point (below the centre: free of the contact point's swing with the tilt),
    and ``yaw`` (T + 1, n) rad, the body's yaw unwrapped, both held at their last value inside the model.
    """
    from .envs.vector import RRRobotVectorEnv

    env = RRRobotVectorEnv(num_envs=n, max_episode_steps=None, model=model, **env_kwargs)
    try:
        steps = control_steps("duration", duration, env.dt)
        obs, _ = env.reset(**reset)
        first = last = env.states[:, 0:2].copy()
        up, yaw = [upright_contact_points(env.states, env.config)], [body_yaw(env.states)]
        end_step, alive = np.full(n, steps), np.ones(n, dtype=bool)
        torque_peak, rate_peak = np.zeros(n), np.zeros(n)
        for k in range(steps):
            actions = np.clip(np.asarray(act(k, obs, env.dt), dtype=np.float64), -1.0, 1.0).astype(np.float32)
            obs, _, terminated, _, info = env.step(actions)
            ending, running = terminated & alive, alive & ~terminated
            last = np.where(alive[:, None], env.states[:, 0:2], last)
            torque_peak[running] = np.maximum(torque_peak[running], info["torque_peak"][running])
            rate_peak[running] = np.maximum(rate_peak[running], info["leg_rate_peak"][running])
            if ending.any():  # (SAME_STEP autoreset restarted these robots: their last step is in final_info)
                final = info["final_info"]
                last[ending, 0], last[ending, 1] = final["x_position"][ending], final["y_position"][ending]
                torque_peak[ending] = np.maximum(torque_peak[ending], final["torque_peak"][ending])
                rate_peak[ending] = np.maximum(rate_peak[ending], final["leg_rate_peak"][ending])
                end_step[ending] = k + 1
            alive = running
            if record:
                upright = np.where(alive[:, None], upright_contact_points(env.states, env.config), up[-1])
                if ending.any():
                    upright[ending, 0], upright[ending, 1] = final["x_upright"][ending], final["y_upright"][ending]
                up.append(upright)
                yaw.append(np.where(alive, body_yaw(env.states), yaw[-1]))
            elif not alive.any():
                break
        out = {"displacement": last - first, "end_time": end_step * env.dt, "terminated": ~alive,
               "torque_peak": torque_peak, "leg_rate_peak": rate_peak, "dt": env.dt, "duration": steps * env.dt}
        if record:
            out["upright"], out["yaw"] = np.array(up), np.unwrap(np.array(yaw), axis=0)
        return out
    finally:
        env.close()


RUN_FIELDS = ("displacement", "end_time", "terminated", "torque_peak", "leg_rate_peak")


@dataclass
class PopulationRuns:
    """What one batched rollout measured, per gait p and start s (arrays (P, S) unless noted):
    the :data:`RUN_FIELDS` of :func:`rollout`, ``displacement`` (P, S, 2)."""

    displacement: np.ndarray
    end_time: np.ndarray
    terminated: np.ndarray
    torque_peak: np.ndarray
    leg_rate_peak: np.ndarray
    duration: float

    @classmethod
    def concatenate(cls, parts) -> "PopulationRuns":
        """The runs of chunks of one population, in order."""
        fields = {k: np.concatenate([getattr(p, k) for p in parts]) for k in RUN_FIELDS}
        return cls(duration=parts[0].duration, **fields)


def robot_legs(**env_kwargs) -> int:
    """How many legs the robot of these env keywords has (the env's own reading of them)."""
    from .envs.task import make_task_config

    return make_task_config(**env_kwargs).num_robot_legs


def _check_population(parameters, num_legs: int | None = None) -> np.ndarray:
    """Gaits (P, 3L), P >= 1, finite; with ``num_legs``, L must be it (the robot's leg count)."""
    params = np.asarray(parameters, dtype=float)
    try:
        legs = legs_of_parameters(params.shape[1]) if params.ndim == 2 and len(params) else None
    except ValueError:
        legs = None
    if legs is None:
        raise ValueError(f"parameters must have shape (P, 3L) with P >= 1 for L legs ((P, {len(PARAMETER_NAMES)}) "
                         f"for two), got {params.shape}")  # fmt: skip
    if num_legs is not None and params.shape[1] != 3 * num_legs:
        raise ValueError(f"the robot has {num_legs} legs, so a gait has {3 * num_legs} parameters "
                         f"({', '.join(parameter_names(num_legs))}); got {params.shape[1]}")  # fmt: skip
    if not np.all(np.isfinite(params)):
        raise ValueError("parameters contain NaN or inf")
    return params


def rollout_population(parameters, *, model="plane", duration=20.0, start_seeds=(0, 1), reset_noise_scale=0.01,
                       ramp_s=0.0, **env_kwargs) -> PopulationRuns:  # fmt: skip
    """Run every gait (rows of ``parameters``, used as given) from every start, in ONE env.

    Robot ``p * S + s`` is gait p from start seed ``start_seeds[s]``: the start a gait sees depends
    only on its seed, not on its row, so chunks of a population (:func:`evaluate_population` on
    Ray) give the same numbers. The targets are commanded at the end of each control step, as
    :class:`rrrobot_gym.agents.GaitAgent` does, the swing ramped in over ``ramp_s`` s.
    """
    ramp_s = _check_ramp(ramp_s)
    params = _check_population(parameters, robot_legs(model=model, **env_kwargs))
    seeds = [int(s) for s in start_seeds]
    if not seeds:
        raise ValueError("start_seeds must name at least one start")
    rows = np.repeat(params, len(seeds), axis=0)
    runs = rollout(lambda k, obs, dt: leg_targets_to_action(sinusoid_angles(rows, (k + 1) * dt, ramp_s)), len(rows),
                   positive_seconds("duration", duration), {"seed": seeds * len(params)}, model=model,
                   env_kwargs={"reset_noise_scale": reset_noise_scale, **env_kwargs})  # fmt: skip
    shape = (len(params), len(seeds))
    fields = {k: runs[k].reshape(shape + runs[k].shape[1:]) for k in RUN_FIELDS}
    return PopulationRuns(duration=runs["duration"], **fields)


@dataclass
class PopulationScores:
    """Per gait (arrays (P,)): ``fitness`` (m/s, maximised), ``speed_mps`` (mean over
    starts along the objective's direction), ``direction_deg`` (that direction, from +X
    towards +Y), ``terminated_starts`` (how many starts left the model), and the
    per-start ``runs``."""

    fitness: np.ndarray
    speed_mps: np.ndarray
    direction_deg: np.ndarray
    terminated_starts: np.ndarray
    runs: PopulationRuns


def objective_directions(runs: PopulationRuns, objective: str, heading_deg=None) -> np.ndarray:
    """Unit vectors (P, 2): "own", each gait's mean net displacement over its starts (+X if
    it did not move); "heading", the commanded heading."""
    if objective == "heading":
        h = math.radians(heading_deg)
        return np.tile([math.cos(h), math.sin(h)], (runs.displacement.shape[0], 1))
    mean = runs.displacement.mean(axis=1)
    norm = np.linalg.norm(mean, axis=1, keepdims=True)
    return np.where(norm > 0, mean / np.where(norm > 0, norm, 1.0), [1.0, 0.0])


def fitness_from_runs(runs: PopulationRuns, objective: str = "own", heading_deg=None) -> PopulationScores:
    """Score runs, penalising a gait that leaves the model on any start.

    v_s is start s's travel along the objective's direction up to its episode's end, divided by
    the FULL episode duration T (so stopping early already costs travel); L = :data:`TERMINATION_PENALTY`.

    - No start terminated: fitness = max(mean_s v_s, -L/2).
    - Some start terminated: fitness = -L + clip(mean_s v_s, -L/4, L/4) + (L/4) mean_s(t_end,s / T),
      always below -L/2: such a gait loses to every gait that stays in, and among them the longer
      and further they get the better, which keeps a slope for CMA-ES where everything fails.
    """
    _check_objective(objective, heading_deg)
    units = objective_directions(runs, objective, heading_deg)
    along = np.einsum("psk,pk->ps", runs.displacement, units) / runs.duration
    mean_speed = along.mean(axis=1)
    return PopulationScores(
        fitness=penalised_fitness(mean_speed, runs.end_time / runs.duration, runs.terminated),
        speed_mps=mean_speed,
        direction_deg=np.degrees(np.arctan2(units[:, 1], units[:, 0])) % 360.0,
        terminated_starts=runs.terminated.sum(axis=1),
        runs=runs,
    )


def penalised_fitness(mean_speed, survived_share, terminated) -> np.ndarray:
    """Fitness (P,) of :func:`fitness_from_runs` from each candidate's mean speed (P,) m/s, the
    share of the episode each of its runs lasted (P, S) and whether each left the model (P, S)."""
    survived_share = np.asarray(survived_share, dtype=float).mean(axis=1)
    failed = np.asarray(terminated, dtype=bool).any(axis=1)
    L = TERMINATION_PENALTY
    return np.where(
        failed,
        -L + np.clip(mean_speed, -L / 4, L / 4) + (L / 4) * survived_share,
        np.maximum(mean_speed, -L / 2),
    )


def _check_objective(objective, heading_deg):
    if objective not in OBJECTIVES:
        raise ValueError(f"unknown objective {objective!r}: expected one of {', '.join(OBJECTIVES)}")
    if objective == "heading":
        if heading_deg is None or isinstance(heading_deg, bool) or not math.isfinite(float(heading_deg)):
            raise ValueError(f"objective 'heading' needs a finite heading_deg, got {heading_deg!r}")
    elif heading_deg is not None:
        raise ValueError("heading_deg is only used with objective 'heading' (objective 'own' follows the gait)")


def ray_runtime_env() -> dict:
    """A Ray ``runtime_env`` that ships this copy of :mod:`rrrobot_gym` to the workers, so
    they run the driver's code whatever is installed on the cluster."""
    return {"py_modules": [str(Path(__file__).resolve().parent)]}


RAY_CONNECT_SECONDS = 10.0
"""How long :func:`check_ray_address` waits for a Ray head to answer."""

RAY_TOKEN_SOURCES = "RAY_AUTH_TOKEN, RAY_AUTH_TOKEN_PATH or ~/.ray/auth_token"
"""Where a Ray driver reads its token, in Ray's order of precedence, once RAY_AUTH_MODE is "token"."""


def check_ray_address(address: str) -> None:
    """Raise ConnectionError, in one line naming ``address`` and what to set, if nothing answers at
    host:port within :data:`RAY_CONNECT_SECONDS`, or the head refuses this driver's token or its lack
    of one (:func:`_ray_auth_problem`): ``ray.init`` would retry either with warnings for 20 s or
    more, then raise. "auto", "local" and no port are left to Ray."""
    import socket

    if not isinstance(address, str):
        raise TypeError(f"ray_address must be a string (host:port, ray://host:port, 'auto' or 'local'), got {address!r}")
    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if not sep or not port.isdigit():
        return
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=RAY_CONNECT_SECONDS).close()
    except OSError as exc:
        raise ConnectionError(
            f"ray_address {address!r}: nothing answers at {host}:{port} ({exc}); start a head there "
            "('ray start --head') or pass 'local' for a Ray on this machine"
        ) from None
    problem = None if address.startswith("ray://") else _ray_auth_problem(address)
    if problem:
        raise ConnectionError(f"ray_address {address!r}: {problem}")


RAY_TOKEN_PROBE_SECONDS = 3.0
"""How long :func:`check_ray_address` waits for the head's answer to its one request."""


def _ray_auth_problem(address: str) -> str | None:
    """What to set, in words, if the Ray head (its GCS) at ``address`` refuses one request sent as
    ``ray.init`` would send it: with the token Ray finds (:data:`RAY_TOKEN_SOURCES`) if
    RAY_AUTH_MODE is "token", else none (Ray sends none to an address it is given). None if it
    answers, if Ray is not installed, or on any other answer or none within
    :data:`RAY_TOKEN_PROBE_SECONDS` (``ray.init`` then reports what is wrong)."""
    try:
        import grpc
        from ray._raylet import AuthenticationTokenLoader
        from ray.core.generated import gcs_service_pb2, gcs_service_pb2_grpc
    except ImportError:
        return None
    token_mode = os.environ.get("RAY_AUTH_MODE", "").lower() == "token"
    header = {}
    if token_mode:
        loader = AuthenticationTokenLoader.instance()
        try:
            header = loader.get_token_for_http_header(ignore_auth_mode=True)
        except Exception as exc:  # noqa: BLE001 - Ray's AuthenticationError: e.g. RAY_AUTH_TOKEN_PATH unreadable
            return f"RAY_AUTH_MODE=token, but the token cannot be read: {str(exc).partition('. ')[0]}"
        if not header:
            return (f"RAY_AUTH_MODE=token, but no token is set here: give the cluster's (`ray get-auth-token` on "
                    f"its head) in {RAY_TOKEN_SOURCES}")
    try:
        with grpc.insecure_channel(address) as channel:
            gcs_service_pb2_grpc.NodeInfoGcsServiceStub(channel).GetClusterId(
                gcs_service_pb2.GetClusterIdRequest(), timeout=RAY_TOKEN_PROBE_SECONDS, metadata=tuple(header.items())
            )
        return None
    except grpc.RpcError as exc:
        if exc.code() != grpc.StatusCode.UNAUTHENTICATED:
            return None
    except Exception:  # noqa: BLE001 - not ours to diagnose: ray.init will
        return None
    if token_mode:
        return (f"the cluster refuses this driver's token (read from {_token_source()}): give the cluster's "
                f"(`ray get-auth-token` on its head) in {RAY_TOKEN_SOURCES}")
    return (f"the cluster uses token authentication: set RAY_AUTH_MODE=token (as `ray start --address` needs "
            f"too), with the cluster's token in {RAY_TOKEN_SOURCES}")


def _token_source() -> str:
    """Which of :data:`RAY_TOKEN_SOURCES` Ray reads the token from, by its precedence."""
    if os.environ.get("RAY_AUTH_TOKEN"):
        return "RAY_AUTH_TOKEN"
    if os.environ.get("RAY_AUTH_TOKEN_PATH"):
        return f"RAY_AUTH_TOKEN_PATH, {os.environ['RAY_AUTH_TOKEN_PATH']}"
    return "~/.ray/auth_token"


def ray_map(function, rows, settings, ray_address=None, ray_chunks=None) -> list:
    """The results of ``function(chunk, settings)`` on chunks of ``rows`` (a sequence), in order:
    without ``ray_address`` one chunk, run here; with it, ``ray_chunks`` chunks (default: the
    cluster's CPUs), each a Ray task. Connects to ``ray_address`` first unless this process already
    runs a Ray session (:func:`check_ray_address`, then ``ray.init`` shipping this package)."""
    if ray_address is None:
        return [function(rows, settings)]
    try:
        import ray
    except ImportError:  # pragma: no cover - depends on the install
        raise ImportError("ray_address needs Ray: pip install 'rrrobot_gym[distributed]'") from None
    if ray_chunks is not None:
        ray_chunks = whole_number("ray_chunks", ray_chunks)
    if not ray.is_initialized():
        check_ray_address(ray_address)
        ray.init(address=ray_address, runtime_env=ray_runtime_env(), include_dashboard=False, log_to_driver=False)
    if ray_chunks is None:
        ray_chunks = max(1, int(ray.cluster_resources().get("CPU", 1)))
    chunks = [c for c in np.array_split(np.arange(len(rows)), min(ray_chunks, len(rows))) if len(c)]
    task = ray.remote(num_cpus=1)(function)
    return ray.get([task.remote(rows[c[0]:c[-1] + 1], settings) for c in chunks])


def _rollout_chunk(parameters, settings):
    return rollout_population(parameters, **settings)


def evaluate_population(
    parameters,
    *,
    model: str = "plane",
    objective: str = "own",
    heading_deg: float | None = None,
    duration: float = 20.0,
    start_seeds=(0, 1),
    reset_noise_scale: float = 0.01,
    ramp_s: float = 0.0,
    ray_address: str | None = None,
    ray_chunks: int | None = None,
    **env_kwargs,
) -> PopulationScores:
    """Score gaits ``parameters`` (P, 3L), used as given (see :func:`repair`): one batched env, or
    with ``ray_address`` (or "local" to start a Ray here) chunks of rows as Ray tasks (:func:`ray_map`).
    Other keywords go to :class:`rrrobot_gym.envs.vector.RRRobotVectorEnv`."""
    _check_objective(objective, heading_deg)
    settings = dict(model=model, duration=duration, start_seeds=tuple(start_seeds), reset_noise_scale=reset_noise_scale,
                    ramp_s=ramp_s, **env_kwargs)  # fmt: skip
    parts = ray_map(_rollout_chunk, _check_population(parameters), settings, ray_address, ray_chunks)
    return fitness_from_runs(PopulationRuns.concatenate(parts), objective, heading_deg)


# ---------------------------------------------------------------- the search


ROBUSTNESS_SEED_OFFSET = 100_000
"""Robustness starts use seeds ``ROBUSTNESS_SEED_OFFSET + i``: the search's start seeds
are small integers, so these are starts the search never saw."""


def write_json(path, data) -> None:
    """``data`` as the JSON files of the searches are written (NaN refused)."""
    Path(path).write_text(json.dumps(data, indent=1, allow_nan=False) + "\n")


@dataclass
class SearchResult:
    """A finished search; :meth:`to_json` is the file format (module docstring)."""

    gaits: list  # [{name, parameters, fitness, speed_mps, direction_deg, terminated_starts, robustness}], best first
    settings: dict
    used: dict
    history: list = field(default_factory=list)

    def to_json(self) -> dict:
        legs = self.settings.get("num_legs", 2)
        return json_safe({"schema": SCHEMA, "family": "sinusoid", "parameter_names": list(parameter_names(legs)),
                           "bounds": {k: list(v) for k, v in bounds(legs).items()}, **self.settings,
                           "used": self.used, "gaits": self.gaits, "history": self.history})

    def write_json(self, path) -> None:
        write_json(path, self.to_json())


def search(
    *,
    model: str = "plane",
    objective: str = "own",
    heading_deg: float | None = None,
    budget_evaluations: int | None = None,
    budget_seconds: float | None = None,
    seed: int = 0,
    popsize: int = 64,
    screen: int | None = None,
    start=None,
    sigma0: float = 0.25,
    duration: float = 20.0,
    start_seeds=(0, 1),
    reset_noise_scale: float = 0.01,
    ramp_s: float = DEFAULT_RAMP_S,
    keep: int = 3,
    name: str | None = None,
    robustness_seeds: int = 8,
    robustness_duration: float | None = 50.0,
    robust_pool: int = 32,
    progress: bool = True,
    ray_address: str | None = None,
    ray_chunks: int | None = None,
    command: str | None = None,
    **env_kwargs,
) -> SearchResult:
    """Search the sinusoid family with a random screen and then CMA-ES (:func:`maximise`); returns the best gaits.

    Budget: ``budget_evaluations`` gaits scored and/or ``budget_seconds`` of wall clock, checked
    between populations (a search may overrun by one population). The screen is ``screen``
    (default ``2 * popsize``) uniform random gaits plus ``start`` if given. Every candidate is
    repaired (:func:`repair`) before it is scored, so the gaits reported are the gaits simulated,
    and grows its swing in over ``ramp_s`` s. Populations are large by CMA-ES's standards (its
    own default for 6 parameters is 9) because the batched env steps 128 robots in about the time it steps 8.

    ``keep`` best gaits are returned, named ``name``-1, -2, ... (default
    ``searched-<model>-<objective>``; evaluate.py needs distinct names across the files it
    compares). With ``robustness_seeds``, the ``max(keep, robust_pool)`` fittest distinct gaits
    (:func:`distinct_fittest`) are re-scored (:func:`robustness`) on that many new start seeds
    over ``robustness_duration`` s (None: ``duration``) and from the paper's start, and those that
    stayed in the model on every start come first (:func:`rank_robust_first`): the fastest gaits
    sit on the envelope's edge, where two starts can miss one that ends the episode.
    """
    _check_objective(objective, heading_deg)
    if budget_evaluations is None and budget_seconds is None:
        raise ValueError("give a budget: budget_evaluations (gaits scored) and/or budget_seconds (wall clock)")
    if budget_evaluations is not None:
        budget_evaluations = whole_number("budget_evaluations", budget_evaluations)
    if budget_seconds is not None:
        positive_seconds("budget_seconds", budget_seconds)
    whole_number("seed", seed, minimum=0)
    popsize = whole_number("popsize", popsize)
    if popsize < 2:
        raise ValueError(f"popsize must be at least 2 for CMA-ES, got {popsize}")
    screen = whole_number("screen", 2 * popsize if screen is None else screen, minimum=0)
    keep = whole_number("keep", keep)
    ramp_s = _check_ramp(ramp_s)
    robust_pool = whole_number("robust_pool", robust_pool)
    if not (isinstance(sigma0, (int, float)) and math.isfinite(sigma0) and 0 < sigma0 <= 1):
        raise ValueError(f"sigma0 must be in (0, 1] (a step in the unit box), got {sigma0!r}")
    if robustness_seeds is not None:
        whole_number("robustness_seeds", robustness_seeds, minimum=0)
    positive_seconds("duration", duration)
    if robustness_duration is not None:
        positive_seconds("robustness_duration", robustness_duration)
    start_seeds = tuple(int(s) for s in start_seeds)
    if any(s >= ROBUSTNESS_SEED_OFFSET for s in start_seeds):
        raise ValueError(f"start_seeds must be below {ROBUSTNESS_SEED_OFFSET} (the robustness seeds start there)")
    # Fail on a bad env keyword now, not after the first population.
    from .envs.vector import RRRobotVectorEnv

    probe = RRRobotVectorEnv(num_envs=1, model=model, reset_noise_scale=reset_noise_scale, **env_kwargs)
    probe.close()
    legs = probe.config.num_robot_legs
    if start is not None:
        start = start.as_array() if hasattr(start, "as_array") else np.asarray(start, dtype=float)
        if start.shape != (3 * legs,) or not np.all(np.isfinite(start)):
            raise ValueError(f"start must be a SinusoidGait or {3 * legs} finite parameters (the robot has {legs} "
                             f"legs), got {start!r}")  # fmt: skip
    scored = control_steps("duration", duration, probe.dt) * probe.dt  # (the time each run simulates)
    if robustness_duration is not None:
        control_steps("robustness_duration", robustness_duration, probe.dt)

    to_params, to_unit = unit_box(num_legs=legs)
    scoring = dict(model=model, objective=objective, heading_deg=heading_deg, duration=duration,
                   start_seeds=start_seeds, reset_noise_scale=reset_noise_scale, ramp_s=ramp_s,
                   ray_address=ray_address, ray_chunks=ray_chunks, **env_kwargs)
    began = time.perf_counter()
    history, evaluations, bar = [], 0, None
    if progress:
        from tqdm import tqdm

        by_count = budget_evaluations is not None
        bar = tqdm(total=budget_evaluations if by_count else round(budget_seconds), unit="gait" if by_count else "s",
                   desc="gait search", dynamic_ncols=True)  # fmt: skip

    def score(params):  # (fitness, speed, direction, terminated starts) a gait
        scores = evaluate_population(params, **scoring)
        return np.column_stack([scores.fitness, scores.speed_mps, scores.direction_deg, scores.terminated_starts])

    def report(archive, rows):
        nonlocal evaluations
        evaluations, best = len(archive.rows), archive.rows[archive.best]
        history.append({"evaluations": evaluations, "seconds": round(time.perf_counter() - began, 3),
                        "best_fitness": float(best[0]), "best_speed_mps": float(best[1]),
                        "median_fitness": float(np.median(rows[:, 0]))})  # fmt: skip
        if bar is not None:
            if budget_evaluations is not None:
                bar.update(min(len(rows), bar.total - bar.n))
            else:
                bar.update(max(0, min(bar.total, round(time.perf_counter() - began)) - bar.n))
            bar.set_postfix_str(f"best {1e3 * best[1]:.1f} mm/s")

    try:
        first = [] if start is None else [repair(start)]
        deadline = None if budget_seconds is None else began + budget_seconds
        archive = maximise(score, to_params, to_unit, dimension=3 * legs, first=first, screen=screen, popsize=popsize,
                           sigma0=sigma0, seed=seed, remaining=budget(deadline, budget_evaluations), report=report)
    finally:
        if bar is not None:
            bar.close()
    seconds = time.perf_counter() - began

    params, rows = np.array(archive.params), np.array(archive.rows)
    by_fitness = np.argsort(-rows[:, 0], kind="stable")
    if robustness_seeds:
        pool = max(keep, robust_pool)
        order = distinct_fittest(to_unit(params), by_fitness, pool, POOL_SPACING)
        ranks = np.empty(len(by_fitness), dtype=int)
        ranks[by_fitness] = np.arange(1, len(by_fitness) + 1)
        search_ranks = [int(ranks[i]) for i in order]
    else:
        pool, order = keep, by_fitness[:keep]
        search_ranks = list(range(1, len(order) + 1))
    gaits = [{
        "parameters": dict(zip(parameter_names(legs), map(float, params[i]))),
        "fitness": float(rows[i, 0]),
        "speed_mps": float(rows[i, 1]),
        "direction_deg": float(rows[i, 2]),
        "terminated_starts": int(rows[i, 3]),
        "search_rank": rank,
        "robust": None,
    } for rank, i in zip(search_ranks, order)]  # fmt: skip
    if robustness_seeds:
        reports = robustness(params[order], model=model, objective=objective, heading_deg=heading_deg,
                             directions_deg=[g["direction_deg"] for g in gaits], seeds=robustness_seeds,
                             duration=duration if robustness_duration is None else robustness_duration,
                             reset_noise_scale=reset_noise_scale, ramp_s=ramp_s, ray_address=ray_address,
                             ray_chunks=ray_chunks, **env_kwargs)  # fmt: skip
        for gait, report in zip(gaits, reports):
            gait["robustness"] = report
        gaits = rank_robust_first(gaits)
    label = name or f"searched-{model}-{objective}" + (f"{heading_deg:g}" if objective == "heading" else "")
    gaits = [{"name": f"{label}-{rank}", **gait} for rank, gait in enumerate(gaits[:keep], start=1)]
    settings = {
        "num_legs": legs, "model": model, "objective": objective, "heading_deg": heading_deg, "env_kwargs": with_servo(env_kwargs),
        "reset_noise_scale": reset_noise_scale, "ramp_s": ramp_s, "duration_s": float(scored),
        "start_seeds": list(start_seeds),
        "seed": int(seed), "budget": {"evaluations": budget_evaluations, "seconds": budget_seconds},
        "popsize": popsize, "screen": int(screen), "sigma0": float(sigma0), "command": command,
        "robust_pool": pool if robustness_seeds else None,
    }
    used = {"evaluations": evaluations, "seconds": round(seconds, 3), "generations": archive.generations,
            "restarts": archive.restarts}
    return SearchResult(gaits=gaits, settings=settings, used=used, history=history)


def unit_box(extra_bounds=(), num_legs: int = 2):
    """(to_params, to_unit): the affine maps from the unit box onto an L-leg sinusoid's 3L numbers
    (:func:`bounds`, repaired: :func:`repair`) and then ``extra_bounds`` ((low, high) each), and back."""
    lows, highs = _lows_highs(num_legs)
    size = len(lows)
    lows = np.r_[lows, [low for low, _ in extra_bounds]]
    highs = np.r_[highs, [high for _, high in extra_bounds]]

    def to_params(unit):
        params = lows + np.clip(unit, 0.0, 1.0) * (highs - lows)
        params[:size] = repair(params[:size])
        return params

    return to_params, lambda params: (np.asarray(params) - lows) / (highs - lows)


@dataclass
class Archive:
    """Every candidate :func:`maximise` scored (``params``) and its score row (``rows``, column 0 the
    fitness), in order; ``best`` indexes the first of the fittest."""

    params: list = field(default_factory=list)
    rows: list = field(default_factory=list)
    best: int | None = None
    generations: int = 0
    restarts: int = 0

    def add(self, params, rows) -> None:
        i = int(np.argmax(rows[:, 0]))
        if self.best is None or rows[i, 0] > self.rows[self.best][0]:
            self.best = len(self.rows) + i
        self.params += list(np.asarray(params, dtype=float))
        self.rows += list(rows)


def budget(deadline: float | None, evaluations: int | None):
    """``remaining`` for :func:`maximise`: none once the wall clock passes ``deadline``
    (perf_counter s; None: no clock), else ``evaluations`` less those scored (None: unbounded)."""

    def remaining(scored: int):
        if deadline is not None and time.perf_counter() >= deadline:
            return 0
        return math.inf if evaluations is None else max(0, evaluations - scored)

    return remaining


def maximise(score, to_params, to_unit, *, dimension, first=(), screen=0, popsize=64, sigma0=0.25, seed=0, remaining,
             report=None) -> Archive:  # fmt: skip
    """A random screen, then CMA-ES with restarts, maximising the fitness of ``score`` within a budget.

    ``score(params)`` takes candidates (n, D), D = ``dimension``, and returns their score rows (n, K),
    column 0 the fitness; ``report(archive, rows)``, if given, sees each population's. ``to_params``
    maps a point of the unit box [0, 1]^D to a candidate, ``to_unit`` back. The screen scores
    ``first`` (a list of candidates) and ``screen`` uniform random points (fewer if the budget is
    smaller), drawn from ``seed``; CMA-ES starts from the fittest candidate so far (the box's centre
    if none) with step ``sigma0``, bounded to the box, and restarts from the fittest with a fresh
    seed when it converges. ``remaining(scored)`` is how many more candidates the budget allows after
    ``scored`` (checked before each population; a population is cut to it): :func:`budget`. Returns
    the :class:`Archive`.
    """
    try:
        import cma
    except ImportError:  # pragma: no cover - depends on the install
        raise ImportError("the search needs cma: pip install 'rrrobot_gym[search]'") from None
    rng = np.random.default_rng(seed)
    archive = Archive()

    def scored(params):
        rows = np.asarray(score(params), dtype=float)
        archive.add(params, rows)
        if report is not None:
            report(archive, rows)
        return rows[:, 0]

    first = list(first)
    n_screen = int(min(screen, remaining(0) - len(first))) if screen else 0
    candidates = first + [to_params(u) for u in rng.uniform(size=(max(0, n_screen), dimension))]
    if candidates:
        scored(np.array(candidates))
    mean = to_unit(archive.params[archive.best]) if archive.rows else np.full(dimension, 0.5)
    while remaining(len(archive.rows)) >= 1:
        # cma treats seed 0 as "seed from the clock": shift by one to stay repeatable.
        es = cma.CMAEvolutionStrategy(
            np.clip(mean, 1e-6, 1 - 1e-6), sigma0,
            {"bounds": [0.0, 1.0], "popsize": popsize, "seed": seed * 1000 + archive.restarts + 1, "verbose": -9},
        )
        while remaining(len(archive.rows)) >= 1 and not es.stop():
            units = es.ask()
            n = int(min(len(units), remaining(len(archive.rows))))
            fitness = scored(np.array([to_params(u) for u in units[:n]]))
            archive.generations += 1
            if n < len(units):
                break
            es.tell(units, (-fitness).tolist())  # cma minimises
        if es.stop():
            archive.restarts += 1
        mean = to_unit(archive.params[archive.best])
    return archive


POOL_SPACING = 0.02
"""The least distance (largest coordinate difference, in the search's unit box) between two gaits
re-scored for robustness: CMA-ES ends in a cloud of near-copies of one gait, which would all
fail or pass the new starts together."""


def distinct_fittest(units, by_fitness, count: int, spacing: float = POOL_SPACING) -> list:
    """Indices of up to ``count`` gaits, fittest first (``by_fitness``: indices best first), each
    at least ``spacing`` from every one taken before it in every coordinate's largest difference
    (``units`` (P, 3L), the gaits in the unit box)."""
    units = np.asarray(units, dtype=float)
    taken = []
    for i in by_fitness:
        if len(taken) == count:
            break
        if not taken or np.abs(units[taken] - units[i]).max(axis=1).min() >= spacing:
            taken.append(int(i))
    return taken


def rank_robust_first(gaits: list) -> list:
    """Gaits (dicts in the order of the search's fitness, each with its ``robustness`` report)
    with those that stayed in the model on every start first: the search's starts
    (``terminated_starts``), the re-score's new starts and the paper's. Each group keeps the
    search's order, so the best gait is the fittest robust one; sets each gait's ``robust``."""
    for gait in gaits:
        report = gait["robustness"]
        gait["robust"] = bool(
            gait["terminated_starts"] == 0 and not any(report["terminated"]) and not report["paper_start_terminated"]
        )
    return [g for g in gaits if g["robust"]] + [g for g in gaits if not g["robust"]]


def robustness(parameters, *, model="plane", objective="own", heading_deg=None, directions_deg=None, seeds=8,
               duration=50.0, reset_noise_scale=0.01, ramp_s=0.0, ray_address=None, ray_chunks=None,
               **env_kwargs) -> list:  # fmt: skip
    """Re-score gaits (P, 3L) on ``seeds`` start-noise seeds the search never used
    (``ROBUSTNESS_SEED_OFFSET + i``), and once from the paper's start (no noise).

    Speeds (m/s) are along the heading, or for "own" the gait's direction as the search measured it
    (``directions_deg``), so a gait knocked onto another course by a new start scores low. One report
    a gait: per-start speeds and terminations, their mean and worst, the paper's start's, and the peaks.
    """
    params = np.asarray(parameters, dtype=float)
    _check_objective(objective, heading_deg)
    if isinstance(seeds, bool) or not isinstance(seeds, (int, np.integer)) or seeds < 1:
        raise ValueError(f"seeds must be a positive whole number of starts, got {seeds!r}")
    if objective == "own":
        if directions_deg is None or len(directions_deg) != len(params):
            raise ValueError("objective 'own' needs the gaits' own directions (directions_deg) to re-score along")
        units = np.radians(np.asarray(directions_deg, dtype=float))
        if not np.all(np.isfinite(units)):
            raise ValueError(f"directions_deg must be finite, got {directions_deg!r}")
    else:
        units = np.full(len(params), math.radians(heading_deg))
    units = np.stack([np.cos(units), np.sin(units)], axis=1)
    settings = dict(model=model, duration=duration, ramp_s=ramp_s, ray_address=ray_address, ray_chunks=ray_chunks,
                    **env_kwargs)  # fmt: skip
    seed_list = [ROBUSTNESS_SEED_OFFSET + i for i in range(int(seeds))]
    noisy = evaluate_population(params, start_seeds=seed_list, reset_noise_scale=reset_noise_scale, **settings).runs
    paper = evaluate_population(params, start_seeds=(0,), reset_noise_scale=0.0, **settings).runs
    noisy_speed = np.einsum("psk,pk->ps", noisy.displacement, units) / noisy.duration
    paper_speed = np.einsum("psk,pk->ps", paper.displacement, units)[:, 0] / paper.duration
    return [
        {
            "seeds": seed_list,
            "duration_s": float(noisy.duration),
            "reset_noise_scale": float(reset_noise_scale),
            "speeds_mps": noisy_speed[p].tolist(),
            "terminated": noisy.terminated[p].tolist(),
            "mean_speed_mps": float(noisy_speed[p].mean()),
            "min_speed_mps": float(noisy_speed[p].min()),
            "paper_start_speed_mps": float(paper_speed[p]),
            "paper_start_terminated": bool(paper.terminated[p, 0]),
            "peak_torque_nm": float(max(noisy.torque_peak[p].max(), paper.torque_peak[p, 0])),
            "peak_leg_rate_radps": float(max(noisy.leg_rate_peak[p].max(), paper.leg_rate_peak[p, 0])),
        }
        for p in range(len(params))
    ]


def load_gaits(path) -> list:
    """The gaits of a search JSON file, best first, as :class:`SinusoidGait` (named as in the file).

    Raises ValueError naming the problem for a file that is not a gait-search result.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except OSError as exc:
        raise ValueError(f"cannot read gait file {path}: {exc.strerror or exc}") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"gait file {path} is not JSON: {exc}") from None
    if not isinstance(data, dict) or data.get("schema") != SCHEMA:
        raise ValueError(f"gait file {path} is not a gait-search result (expected schema {SCHEMA!r})")
    gaits = data.get("gaits")
    if not isinstance(gaits, list) or not gaits:
        raise ValueError(f"gait file {path} has no gaits")
    try:
        ramp_s = _check_ramp(data.get("ramp_s", 0.0))  # (files before the ramp have none)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"gait file {path}: {exc}") from None
    out = []
    for i, gait in enumerate(gaits):
        try:
            out.append(SinusoidGait.from_dict(gait["parameters"], name=str(gait.get("name", f"searched-{i + 1}")),
                                              ramp_s=ramp_s))  # fmt: skip
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"gait file {path}, gait {i + 1}: {exc}") from None
    names = [gait.name for gait in out]
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:  # (the agents are looked up by name: one would hide the others)
        raise ValueError(f"gait file {path} gives two or more gaits the name {', '.join(map(repr, repeated))}")
    return out
