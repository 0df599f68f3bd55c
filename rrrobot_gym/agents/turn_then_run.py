"""Turn, then run: a scripted closed-loop baseline for travel along any heading.

A gait's direction of travel is fixed relative to the body's yaw (the floor is isotropic), so
an open-loop gait goes one way. This agent first turns the body with a turning sinusoid (or its
leg-exchanged mirror, for the other sense) until a running gait's direction points along the
commanded heading, then blends into the running gait (or its mirror, whichever needs the
smaller turn) and runs it. It reads only the observation: the body's yaw relative to the
heading is atan2((n x h)_x, h_x), with n = ``up_in_body`` and h = ``heading_in_body``.

    from rrrobot_gym.agents.turn_then_run import load_turn_then_run_agent
    agent = load_turn_then_run_agent("agents/searched/turn_then_run.json")        # plane
    agent = load_turn_then_run_agent("agents/searched/turn_then_run_pivot.json")  # pivot
    agent.model                                                                   # the model its file was searched on

The switch: when the yaw's moving average over ``window`` control steps, projected ``lead``
seconds ahead at its current rate, reaches its target, the running gait's phase is shifted so
its leg targets match the turning gait's there, and the gait parameters are blended over
``ramp`` seconds with the phase kept continuous. The file's parameters come from
``rrrobot turn-then-run-search`` on the file's ``"model"`` (``"plane"`` if absent) under its
``"env_kwargs"`` (kept on the agent as ``search_env_kwargs``, not applied).

Heading correction (off unless the file sets ``"steer_gain"`` or ``"steer_integral"``): while
blending and running, the running gait is changed by d (in its own six-number frame; its mirror
gets the mirror image of the change),

    d = clip(sense * (steer_gain * e + steer_integral * integral of e dt), -steer_limit, +steer_limit)
    "offset":    o1 + d, o2 - d            "amplitude": a1 (1 + d), a2 (1 - d)

scaled by the blend weight while blending and by a weight rising linearly from 0 at
``steer_after_s`` s into the episode to 1 ``ramp`` s later (a gait on the edge of the envelope
slips when changed at its start); e is the wrapped error of the yaw's moving average from the
running gait's target yaw, sense +1 for the running gait, -1 for its mirror, and the integral
runs in mode RUN only (held while d saturates). A positive gain suits a gait that a positive d
turns clockwise (``docs/notes/turn_then_run.md``). ``steer_limit``: one number, or [low, high]
(low <= 0 <= high). ``"run_at_once_below_deg"`` (default 0): a start needing a smaller turn runs
at once, keeping the running gait's own swing ramp from rest (its file's ``ramp_s``).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..envs.task import OBSERVATION_FIELDS, leg_targets_to_action
from ..gait_search import load_gaits, positive_seconds, ramp_factor
from ..params import MODELS, whole_number

_FIELDS = {name: slice(start, stop) for name, start, stop in OBSERVATION_FIELDS}
TURN, BLEND, RUN = 0, 1, 2


def per_leg_gait(gait, mirror=False):
    """(a1, a2, o1, o2, w, beta1, beta2) of a six-number sinusoid (a1, a2, o1, o2, w, gap);
    ``mirror`` exchanges the legs (the gait's mirror image: it turns or travels the other way)."""
    a1, a2, o1, o2, w, gap = np.asarray(gait, dtype=float)
    return np.array([a2, a1, o2, o1, w, gap, 0.0] if mirror else [a1, a2, o1, o2, w, 0.0, gap])


def per_leg_angles(g, phase):
    """Leg targets (n, 2) of per-leg gaits g (n, 7) at gait phases (n,)."""
    return np.stack([g[:, 2] + g[:, 0] * np.sin(phase + g[:, 5]), g[:, 3] + g[:, 1] * np.sin(phase + g[:, 6])], axis=1)


def per_leg_rates(g, phase):
    return g[:, 4:5] * np.stack([g[:, 0] * np.cos(phase + g[:, 5]), g[:, 1] * np.cos(phase + g[:, 6])], axis=1)


def matching_phase_shift(g_from, g_to, phase, candidates=72):
    """Phase shift (n,) that makes ``g_to`` at phase + shift best match ``g_from`` at phase
    (leg targets, and their rates weighted 0.002 s^2), from a grid of ``candidates``."""
    shifts = np.linspace(-math.pi, math.pi, candidates, endpoint=False)
    angles, rates = per_leg_angles(g_from, phase), per_leg_rates(g_from, phase)
    cost = [
        ((per_leg_angles(g_to, phase + c) - angles) ** 2).sum(1) + 0.002 * ((per_leg_rates(g_to, phase + c) - rates) ** 2).sum(1)
        for c in shifts
    ]
    return shifts[np.argmin(np.array(cost), axis=0)]


def _number(label, value, wanted, low=-math.inf, high=math.inf, finite=True) -> float:
    """``float(value)`` for a real number (not a bool) in [low, high], finite unless ``finite`` is
    False, else a ValueError naming ``label`` and what it must be (``wanted``)."""
    number = not isinstance(value, bool) and isinstance(value, (int, float, np.integer, np.floating))
    if not (number and low <= value <= high and (math.isfinite(value) or not finite)):
        raise ValueError(f"{label} must be {wanted}, got {value!r}")
    return float(value)


def wrap_angle(angle):
    """rad, ``angle`` wrapped into [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def relative_yaw(observations):
    """rad (n,): the body's yaw (the heading of its x axis's horizontal part) minus the
    commanded heading, from RRRobot-v0 observations (n, size)."""
    n = observations[:, _FIELDS["up_in_body"]].astype(float)
    h = observations[:, _FIELDS["heading_in_body"]].astype(float)
    across = n[:, 1] * h[:, 2] - n[:, 2] * h[:, 1]  # (n x h)_x: body x along (up x heading)
    return np.arctan2(across, h[:, 0])


class TurnThenRunAgent:
    """Turn, then run (module docstring), with the ``predict`` interface of an SB3 policy.

    ``turn_gait`` and ``run_gait``: six numbers (a1, a2, o1, o2, w, gap) each, the turning
    gait turning clockwise; ``direction_offset`` (rad): the running gait's direction of travel
    minus the body's yaw; ``dt``: the env's control step; ``run_ramp`` (s): the running gait's
    swing ramp from rest, used by starts that run at once. The recurrent ``state`` is a dict of
    per-env arrays; ``episode_start`` restarts an env's controller.
    """

    closed_loop = True  # evaluate.py: no "own direction" to score it along
    model = "plane"  # the model its parameters were searched on (load_turn_then_run_agent: the file's)

    def __init__(self, turn_gait, run_gait, *, dt, lead, ramp, direction_offset=0.5 * math.pi, window=15,
                 name="turn-then-run", steer_gain=0.0, steer_integral=0.0, steer_limit=0.0,
                 steer_param="offset", steer_after=0.0, run_at_once_below=0.0, run_ramp=0.0):  # fmt: skip
        self.turn_gait, self.run_gait = np.asarray(turn_gait, dtype=float), np.asarray(run_gait, dtype=float)
        for label, gait in (("turn_gait", self.turn_gait), ("run_gait", self.run_gait)):
            if gait.shape != (6,) or not np.all(np.isfinite(gait)):
                raise ValueError(f"{label} must be 6 finite numbers (a1, a2, o1, o2, w, gap), got {gait.tolist()}")
        self.dt, self.ramp = positive_seconds("dt", dt), positive_seconds("ramp", ramp)
        # (a NaN lead never switches to running; a NaN offset gives NaN actions)
        self.lead = _number("lead", lead, "a number of seconds >= 0", low=0.0)
        self.direction_offset = _number("direction_offset", direction_offset, "a finite angle")
        self.window, self.name = whole_number("window", window), name
        self.steer_gain = _number("steer_gain", steer_gain, "a finite number")
        self.steer_integral = _number("steer_integral", steer_integral, "a finite number")
        limit = np.atleast_1d(np.asarray(steer_limit, dtype=object))
        if limit.ndim != 1 or len(limit) not in (1, 2) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in limit
        ):
            raise ValueError(f"steer_limit must be a number >= 0 or [low, high], got {steer_limit!r}")
        limit = limit.astype(float)
        low, high = (-abs(limit[0]), abs(limit[0])) if len(limit) == 1 else (limit[0], limit[1])
        if (len(limit) == 1 and limit[0] < 0) or not (low <= 0.0 <= high) or max(-low, high) > 0.5:
            raise ValueError(f"steer_limit must be a number in [0, 0.5] or [low, high] with -0.5 <= low <= 0 <= high "
                             f"<= 0.5, got {steer_limit!r}")  # fmt: skip
        self.steer_after = _number("steer_after_s", steer_after, "a number in [0, inf]", 0.0, math.inf, finite=False)
        below = _number("run_at_once_below_deg", run_at_once_below, "a number in [0, 180]", 0.0, 180.0)
        self.run_ramp = _number("run_ramp", run_ramp, "a number in [0, inf]", 0.0, math.inf, finite=False)
        if steer_param not in ("offset", "amplitude"):
            raise ValueError(f'steer_param must be "offset" or "amplitude", got {steer_param!r}')
        self.steer_limit, self.steer_param = (float(low), float(high)), steer_param
        self.steering = self.steer_gain != 0.0 or self.steer_integral != 0.0
        self.run_at_once_below = math.radians(below)

    def _start(self, memory, rows, yaw):
        """Choose each restarted env's turn and gaits from its relative yaw at the start."""
        turn_own = wrap_angle(-self.direction_offset - yaw)
        turn_mirror = wrap_angle(self.direction_offset - yaw)
        mirror = np.abs(turn_mirror) < np.abs(turn_own) - 1e-9
        turn = np.where(mirror, turn_mirror, turn_own)
        memory["target"][rows] = yaw + turn
        memory["sense"][rows] = np.where(turn > 0.0, 1.0, -1.0)
        memory["g_turn"][rows] = [per_leg_gait(self.turn_gait, t > 0.0) for t in turn]  # the mirror turns anticlockwise
        memory["g_run"][rows] = [per_leg_gait(self.run_gait, m) for m in mirror]
        memory["run_sense"][rows] = np.where(mirror, -1.0, 1.0)
        memory["integral"][rows] = 0.0
        memory["steer"][rows] = 0.0
        memory["mode"][rows] = np.where(np.abs(turn) < max(1e-6, self.run_at_once_below), RUN, TURN)
        memory["at_once"][rows] = memory["mode"][rows] == RUN
        memory["steps"][rows] = 0
        memory["phase"][rows] = 0.0
        memory["switched"][rows] = np.nan
        memory["history"][:, rows] = yaw
        memory["yaw"][rows] = yaw

    @staticmethod
    def state_rows(state, rows):
        """The part of a batch's ``state`` (what :meth:`predict` returned) for the envs ``rows``
        only: a state :meth:`predict` takes for those envs."""
        return {key: (value[:, rows] if key == "history" else value[rows]) for key, value in state.items()}

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        observation = np.asarray(observation)
        single = observation.ndim == 1
        obs = observation[None] if single else observation
        n = len(obs)
        if state is None:
            state = {
                "target": np.zeros(n), "sense": np.zeros(n), "g_turn": np.zeros((n, 7)), "g_run": np.zeros((n, 7)),
                "mode": np.zeros(n, dtype=int), "steps": np.zeros(n, dtype=int), "phase": np.zeros(n),
                "switched": np.zeros(n), "history": np.zeros((2 * self.window, n)), "yaw": np.zeros(n),
                "run_sense": np.ones(n), "integral": np.zeros(n), "steer": np.zeros(n), "at_once": np.zeros(n, dtype=bool),
            }  # fmt: skip
            starting = np.ones(n, dtype=bool)
        else:
            if not isinstance(state, dict) or np.shape(state.get("steps")) != (n,):
                raise ValueError(f"state must be this agent's state for {n} envs (the one predict returned)")
            state = {key: value.copy() for key, value in state.items()}
            starting = np.zeros(n, dtype=bool)
        if episode_start is not None:
            starting |= np.asarray(episode_start, dtype=bool).reshape(n)
        yaw = relative_yaw(obs)
        if starting.any():
            self._start(state, starting, yaw[starting])
        # Unwrap the yaw step by step and keep the last two windows of it.
        yaw = state["yaw"] + wrap_angle(yaw - state["yaw"])
        state["yaw"] = yaw
        state["history"] = np.roll(state["history"], -1, axis=0)
        state["history"][-1] = yaw
        steps, w = state["steps"] + 1, self.window
        recent = state["history"][-w:].mean(axis=0)
        rate = np.where(steps >= 2 * w, (recent - state["history"][:w].mean(axis=0)) / (w * self.dt), 0.0)
        projected = recent + rate * self.lead
        t = (steps - 1) * self.dt
        switch = (state["mode"] == TURN) & (state["sense"] * (state["target"] - projected) <= 0.0) & (steps >= w)
        if switch.any():
            state["mode"][switch] = BLEND
            state["switched"][switch] = t[switch]
            shift = matching_phase_shift(state["g_turn"][switch], state["g_run"][switch], state["phase"][switch])
            state["g_run"][switch, 5:7] += shift[:, None]
        blend = np.where(state["mode"] == TURN, 0.0, 1.0)
        blending = state["mode"] == BLEND
        if blending.any():
            blend[blending] = ramp_factor(t[blending] - state["switched"][blending], self.ramp)  # (the gaits' smoothstep)
            state["mode"][blending & (blend >= 1.0)] = RUN
        g = (1.0 - blend)[:, None] * state["g_turn"] + blend[:, None] * state["g_run"]
        if self.steering:
            g = self._steer(state, g, blend * np.clip((t - self.steer_after) / self.ramp, 0.0, 1.0), recent)
        if self.run_ramp > 0.0:  # the running gait's own ramp, at the time its targets are for (as the gait's agent)
            g = g.copy()
            g[:, 0:2] *= np.where(state["at_once"], ramp_factor(steps * self.dt, self.run_ramp), 1.0)[:, None]
        state["phase"] = state["phase"] + g[:, 4] * self.dt
        state["steps"] = steps
        actions = np.clip(leg_targets_to_action(per_leg_angles(g, state["phase"])), -1.0, 1.0).astype(np.float32)
        return (actions[0] if single else actions), state

    def _steer(self, state, g, weight, recent):
        """The heading correction (module docstring): g with the running gait's part changed by
        d x ``weight``; the integral grows only at full weight."""
        error = wrap_angle(recent - state["target"])
        running = (state["mode"] == RUN) & (weight >= 1.0)
        sense = state["run_sense"]
        low, high = self.steer_limit
        raw = sense * (self.steer_gain * error + self.steer_integral * state["integral"])
        d = np.clip(raw, low, high)
        # Integrate only while running and not pushing further into the saturation.
        grow = running & ~(((raw >= high) & (sense * error > 0)) | ((raw <= low) & (sense * error < 0)))
        state["integral"] = np.where(grow, state["integral"] + error * self.dt, state["integral"])
        c = sense * d * weight  # per leg: the mirror's legs are exchanged
        state["steer"] = d * weight
        g = g.copy()
        if self.steer_param == "offset":
            g[:, 2] += c
            g[:, 3] -= c
        else:
            g[:, 0] *= 1.0 + c
            g[:, 1] *= 1.0 - c
        return g


def load_turn_then_run_agent(path, dt: float | None = None) -> TurnThenRunAgent:
    """The agent of a turn-then-run JSON file (``agents/searched/turn_then_run.json``): its turning
    gait, lead and ramp, and the running gait named from a gait-search file beside it. The
    agent's ``model`` is the file's ``"model"`` (``"plane"`` if absent): the model to score it on."""
    path = Path(path)
    try:
        return agent_from_spec(json.loads(path.read_text()), path.parent, dt)
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"turn-then-run file {path}: {type(exc).__name__}: {exc}") from None
    except ValueError as exc:
        raise ValueError(f"turn-then-run file {path}: {exc}") from None


def agent_from_spec(spec: dict, folder, dt: float | None = None) -> TurnThenRunAgent:
    """The agent of a turn-then-run file's dict whose ``run_gait_file`` is relative to ``folder``."""
    try:
        run = {gait.name: gait for gait in load_gaits(Path(folder) / spec["run_gait_file"])}[spec["run_gait"]]
        model = spec.get("model", "plane")
        if model not in MODELS:
            raise ValueError(f'"model" must be one of {", ".join(MODELS)}, got {model!r}')
        agent = TurnThenRunAgent(
            spec["turn_gait"], run.as_array(), dt=dt if dt is not None else spec["dt"], lead=spec["lead_s"],
            ramp=spec["ramp_s"], direction_offset=math.radians(spec["direction_offset_deg"]), window=spec["window_steps"],
            run_ramp=run.ramp_s,
            **{key: spec[key] for key in ("steer_gain", "steer_integral", "steer_limit", "steer_param") if key in spec},
            **{arg: spec[key] for arg, key in (("steer_after", "steer_after_s"), ("run_at_once_below", "run_at_once_below_deg"))
               if key in spec},
        )  # fmt: skip
    except (KeyError, TypeError) as exc:
        raise ValueError(f"{type(exc).__name__}: {exc}") from None
    agent.model, agent.search_env_kwargs = model, dict(spec.get("env_kwargs") or {})
    return agent
