"""Turn-then-run search: the parameters of the turn-then-run agent for a running gait.

The agent (:class:`rrrobot_gym.agents.turn_then_run.TurnThenRunAgent`) turns the body with a
turning sinusoid until a searched running gait points along the commanded heading, blends into
that gait and runs it. For a running gait of a gait-search file this module finds:

1. **direction**: the gait's direction of travel minus the body's yaw (``direction_offset_deg``),
   from the paper's start and two noisy starts, the gait and its mirror, to the whole degree;
2. **turning gait**: the sinusoid that turns the body fastest inside the model (sustained yaw rate);
3. **maneuver**: the turning gait, the switch's lead and the blend together, scored through the
   agent on ``headings_deg`` x starts: the mean speed along the heading, penalised for leaving the
   model as gait search penalises it (:func:`rrrobot_gym.gait_search.penalised_fitness`).

Steps 2 and 3 are a random screen then CMA-ES within a wall-clock budget, and within a number of
candidates scored if one is given (a search that repeats itself on any machine)
(:func:`rrrobot_gym.gait_search.maximise`), each population one batched env or chunks of it as Ray
tasks. :func:`tune_steering` then tunes the heading correction's gains on a grid through the agent.

    rrrobot turn-then-run-search --model plane --run-gaits agents/searched/plane_own.json \\
        --budget 900 --out agents/searched/turn_then_run.json
    rrrobot turn-then-run-steer --agent agents/searched/turn_then_run.json --gain 0.5 1 \\
        --limit 0.05 0.1 --out agents/searched/turn_then_run.json

Every env gets the running gait file's ``env_kwargs`` updated by ``env_kwargs``; the agent's
file records them as ``env_kwargs``, every servo keyword among them (:func:`rrrobot_gym.envs.task.with_servo`).
"""
from __future__ import annotations

import itertools
import json
import math
import os
import time
from pathlib import Path

import numpy as np

from .agents.turn_then_run import (
    TurnThenRunAgent,
    agent_from_spec,
    load_turn_then_run_agent,
    per_leg_angles,
    per_leg_gait,
    wrap_angle,
)
from .envs import task
from .gait_search import (
    PARAMETER_NAMES,
    budget,
    load_gaits,
    maximise,
    penalised_fitness,
    positive_seconds,
    ramp_factor,
    ray_map,
    repair,
    rollout,
    unit_box,
)
from .params import check_model, whole_number

COMPASS_DEG = tuple(range(0, 360, 45))
DEFAULT_HEADINGS_DEG = (0.0, 45.0, 135.0, 180.0)
"""Headings the maneuver is scored on: from the paper's start, for a gait travelling at yaw +-90 deg,
every turn the agent makes on the compass (a quarter turn, and 45 deg either way)."""
WINDOW_STEPS = 15
"""Control steps of the agent's yaw moving average (about one period of the gaits searched)."""
TURN_SECONDS, SETTLE_SECONDS = 10.0, 1.0
"""s, the turning gait's runs, and the start left out of its yaw rate's fit."""
TURN_SEEDS = [None, 11, 12]
"""Starts the turning gait is scored from: the paper's (None) and two noisy ones."""
DIRECTION_SECONDS, DIRECTION_SETTLE = 20.0, 2.0
"""s, the running gait's runs for its direction, and the start left out (its first period)."""
TURN_POPSIZE = 64
LEAD_MAX, BLEND_MAX, BLEND_MIN = 1.5, 2.0, 0.05
"""s, the bounds of the switch's lead and of the blend. A running gait with a swing ramp from rest
slips when blended into quickly after a turn: its blend may take up to five of its ramps and its
lead up to 3 s (:func:`maneuver_bounds`)."""


class SearchError(ValueError):
    """A bad input of the turn-then-run search, named."""


# ---------------------------------------------------------------- rollouts


def start_states(seeds, reset_noise_scale: float) -> np.ndarray:
    """States (N, 13): None is the paper's start; a seed s the env's start after ``reset(seed=s)``
    with that ``reset_noise_scale``."""
    from gymnasium.utils import seeding

    noise = np.zeros((len(seeds), 10))
    for i, seed in enumerate(seeds):
        if seed is not None:
            noise[i] = task.draw_noise(seeding.np_random(int(seed))[0], reset_noise_scale)
    return task.start_states(noise)


def yaw_rate(yaw, dt, after: float) -> np.ndarray:
    """rad/s (N,): the least-squares slope of yaw (T + 1, N) against time from ``after`` s on
    (the fit removes the wobble within a gait period)."""
    t = np.arange(len(yaw)) * dt
    fit = t >= after
    tt = t[fit] - t[fit].mean()
    return (tt[:, None] * (yaw[fit] - yaw[fit].mean(axis=0))).sum(axis=0) / (tt**2).sum()


def mirror_gait(parameters) -> np.ndarray:
    """The six numbers of a sinusoid's leg-exchanged mirror image, up to a phase: it turns, or
    travels, the other way."""
    a1, a2, o1, o2, w, gap = np.asarray(parameters, dtype=float)
    return np.array([a2, a1, o2, o1, w, -gap])


def _sinusoids(rows, ramp_s=0.0, mirror=None):
    """``act`` for :func:`rollout`: each robot runs its sinusoid (rows (N, 6)), or where ``mirror``
    (N,) its leg-exchanged mirror image (the same legs' motions, exchanged), the swing ramped in
    over ``ramp_s`` s; targets commanded at the end of each step as the gait agents do."""
    rows = np.asarray(rows, dtype=float)
    mirror = np.zeros(len(rows), dtype=bool) if mirror is None else np.asarray(mirror, dtype=bool)
    per_leg = np.array([per_leg_gait(g, m) for g, m in zip(rows, mirror)])

    def act(k, obs, dt):
        t = (k + 1) * dt
        g = per_leg.copy()
        g[:, :2] *= ramp_factor(t, ramp_s)
        return task.leg_targets_to_action(per_leg_angles(g, g[:, 4] * t))

    return act


# ---------------------------------------------------------------- step 1: direction


def measure_direction(run_gait, *, model, env_kwargs, reset_noise_scale=0.01, seeds=(None, 1, 2)) -> dict:
    """The running gait's direction of travel minus the body's mean yaw (deg), after the first
    :data:`DIRECTION_SETTLE` s of :data:`DIRECTION_SECONDS`, from each start of ``seeds`` (None:
    the paper's), for the gait and its mirror (whose offset is the gait's negated). Returns
    {"direction_offset_deg": the mean in the gait's sense, "offsets_deg", "ended"}."""
    seeds = list(seeds)
    rows = np.array([run_gait.as_array()] * (2 * len(seeds)))
    mirror = np.arange(len(rows)) >= len(seeds)
    runs = _rollout(_sinusoids(rows, run_gait.ramp_s, mirror), start_states(seeds * 2, reset_noise_scale),
                    np.zeros(len(rows)), DIRECTION_SECONDS, model=model, env_kwargs=env_kwargs, record=True)
    k0 = int(round(DIRECTION_SETTLE / runs["dt"]))
    travel = runs["upright"][-1] - runs["upright"][k0]
    yaw = runs["yaw"][k0:].mean(axis=0)
    offsets = np.degrees(wrap_angle(np.arctan2(travel[:, 1], travel[:, 0]) - yaw))
    kept = ~runs["terminated"]
    if not kept.any():
        raise SearchError(f"the running gait {run_gait.name} left the model on every start: it has no direction")
    signed = np.where(mirror, -offsets, offsets)
    return {"direction_offset_deg": float(signed[kept].mean()), "offsets_deg": offsets.tolist(),
            "ended": runs["terminated"].tolist()}  # fmt: skip


def _rollout(act, starts, headings_rad, duration, *, model, env_kwargs, record=False):
    """:func:`rrrobot_gym.gait_search.rollout` of robots from ``starts`` (N, 13) along ``headings_rad`` (N,)."""
    reset = {"seed": 0, "options": {"state": starts, "target_direction": headings_rad}}
    return rollout(act, len(starts), duration, reset, model=model, env_kwargs={**env_kwargs, "reset_noise_scale": 0.0},
                   record=record)


# ---------------------------------------------------------------- step 2: the turning gait


def score_turning(params, settings) -> np.ndarray:
    """Turning gaits (P, 6) -> (P, 2 + S): fitness, mean yaw rate (rad/s) and each start's yaw rate.
    Fitness: |mean yaw rate| when no start left the model, else below -0.5 (as gait search
    penalises, the yaw rate in place of the speed)."""
    params = np.asarray(params, dtype=float)
    seeds = settings["seeds"]
    s = len(seeds)
    starts = np.tile(start_states(seeds, settings["reset_noise_scale"]), (len(params), 1))
    runs = _rollout(_sinusoids(np.repeat(params, s, axis=0)), starts, np.zeros(len(params) * s), TURN_SECONDS,
                    model=settings["model"], env_kwargs=settings["env_kwargs"], record=True)  # fmt: skip
    rates = yaw_rate(runs["yaw"], runs["dt"], SETTLE_SECONDS).reshape(len(params), s)
    mean = rates.mean(axis=1)
    fitness = penalised_fitness(np.abs(mean), (runs["end_time"] / runs["duration"]).reshape(len(params), s),
                                runs["terminated"].reshape(len(params), s))  # fmt: skip
    return np.column_stack([fitness, mean, rates])


# ---------------------------------------------------------------- step 3: the maneuver


def maneuver_bounds(run_gait):
    """(lead max, blend max) in s for a running gait (:data:`LEAD_MAX`)."""
    if run_gait.ramp_s > 0.0:
        return 3.0, max(BLEND_MAX, 5.0 * run_gait.ramp_s)
    return LEAD_MAX, BLEND_MAX


def make_agent(maneuver, settings):
    """The agent of a maneuver (turning gait's six numbers, lead s, blend s) for ``settings``' running gait."""
    m = np.asarray(maneuver, dtype=float)
    return TurnThenRunAgent(m[:6], settings["run_gait"], dt=settings["dt"], lead=float(m[6]), ramp=float(m[7]),
                            direction_offset=math.radians(settings["direction_offset_deg"]), window=WINDOW_STEPS,
                            run_ramp=settings["run_ramp"], run_at_once_below=settings["run_at_once_below_deg"],
                            **settings.get("steer", {}))  # fmt: skip


def run_agents(agents, headings_deg, seeds, duration, *, model, env_kwargs, reset_noise_scale, record=False):
    """Each agent on every (heading, start) case, all in ONE env: speeds (A, K) m/s along the
    heading (contact point displacement / duration), terminated (A, K), end_time (A, K), with K =
    len(headings_deg) x len(seeds), headings varying fastest; with ``record`` the rollout too."""
    cases = [(h, s) for s in seeds for h in headings_deg]
    k_cases, n = len(cases), len(agents) * len(cases)
    heads = np.radians([h for h, _ in cases] * len(agents))
    starts = np.tile(start_states([s for _, s in cases], reset_noise_scale), (len(agents), 1))
    memory = [None] * len(agents)

    def act(k, obs, dt):
        actions = np.empty((n, 2), dtype=np.float32)
        for a, agent in enumerate(agents):
            rows = slice(a * k_cases, (a + 1) * k_cases)
            actions[rows], memory[a] = agent.predict(obs[rows], state=memory[a], episode_start=np.full(k_cases, k == 0))
        return actions

    runs = _rollout(act, starts, heads, duration, model=model, env_kwargs=env_kwargs, record=record)
    speed = (runs["displacement"][:, 0] * np.cos(heads) + runs["displacement"][:, 1] * np.sin(heads)) / runs["duration"]
    shape = (len(agents), k_cases)
    return speed.reshape(shape), runs["terminated"].reshape(shape), runs["end_time"].reshape(shape), runs


def score_maneuvers(params, settings) -> np.ndarray:
    """Maneuvers (P, 8) -> (P, 1 + K): fitness (mean speed along the heading over the cases,
    penalised for leaving the model) and each case's speed."""
    params = np.asarray(params, dtype=float)
    agents = [make_agent(m, settings) for m in params]
    speed, ended, end_time, runs = run_agents(agents, settings["headings_deg"], settings["seeds"], settings["duration"],
                                              model=settings["model"], env_kwargs=settings["env_kwargs"],
                                              reset_noise_scale=settings["reset_noise_scale"])  # fmt: skip
    fitness = penalised_fitness(speed.mean(axis=1), end_time / runs["duration"], ended)
    return np.column_stack([fitness, speed])


# ---------------------------------------------------------------- the search


def load_run_gait(path, name=None):
    """(gait, file's JSON) of the running gait: the file's best gait, or the one named ``name``."""
    gaits = load_gaits(path)  # (a ValueError naming the problem)
    if name is None:
        gait = gaits[0]
    else:
        found = [g for g in gaits if g.name == name]
        if not found:
            raise SearchError(f"gait file {path} has no gait {name!r} (it has {', '.join(g.name for g in gaits)})")
        gait = found[0]
    return gait, json.loads(Path(path).read_text())


def search(run_gaits, *, model, budget_seconds=900.0, budget_evaluations=None, seed=0, run_gait=None,
           headings_deg=DEFAULT_HEADINGS_DEG, starts=2, duration=None, turning_share=0.5, warm_start=None,
           run_at_once_below_deg=10.0, popsize=TURN_POPSIZE, reset_noise_scale=0.01, ray_address=None, ray_chunks=None,
           progress=None, command=None, out_path=None, **env_kwargs) -> dict:  # fmt: skip
    """The module docstring's steps 1-3 for the running gait of ``run_gaits`` (a gait-search file;
    its best gait, or ``run_gait`` by name) within ``budget_seconds`` of wall clock, a ``turning_share``
    of it for step 2 (each step scores at least its screen's first candidates). With
    ``budget_evaluations`` the two steps also stop after that many candidates scored in all, the same
    share of them for step 2: the budget that ends first ends a step.

    The maneuver is scored on ``headings_deg`` from the paper's start and ``starts`` - 1 noisy starts
    (reset seeds 1, 2, ...) over ``duration`` s (default 20 s, 30 s for a running gait with a swing
    ramp). ``warm_start``: an agent file whose maneuver joins the screen. ``popsize``: the turning
    gait's CMA-ES population (screen 8 x that), the maneuver's half of it (screen 2 x that).
    ``progress``: None, or a callable given a line per stage and at most every 10 s.

    Returns the agent file's dict, ``run_gait_file`` relative to ``out_path``'s folder (the loader
    looks there), with the search's record under ``"search"``.
    """
    check_model(model)
    budget_seconds = positive_seconds("budget_seconds", budget_seconds)
    if budget_evaluations is not None:
        budget_evaluations = whole_number("budget_evaluations", budget_evaluations)
    whole_number("seed", seed, minimum=0)
    whole_number("starts", starts)
    popsize = whole_number("popsize", popsize, minimum=4)
    if not (isinstance(turning_share, (int, float)) and 0.0 < turning_share < 1.0):
        raise SearchError(f"turning_share must be a fraction in (0, 1), got {turning_share!r}")
    heads = [float(h) for h in headings_deg]
    if not heads or not all(math.isfinite(h) and -360.0 <= h <= 360.0 for h in heads):
        raise SearchError(f"headings_deg must be one or more finite headings in deg within +-360, got {headings_deg!r}")
    if not (isinstance(run_at_once_below_deg, (int, float)) and 0.0 <= run_at_once_below_deg <= 180.0):
        raise SearchError(f"run_at_once_below_deg must be a number of degrees in [0, 180], got {run_at_once_below_deg!r}")
    gait, gait_file = load_run_gait(run_gaits, run_gait)
    if gait_file.get("model", "plane") != model:
        raise SearchError(f"the running gait's file {run_gaits} was searched on the {gait_file.get('model')} model, not {model}")
    env_kwargs = {**(gait_file.get("env_kwargs") or {}), **env_kwargs}
    duration = positive_seconds("duration", duration) if duration is not None else (30.0 if gait.ramp_s > 0 else 20.0)
    warm = None
    if warm_start is not None:
        agent = load_turn_then_run_agent(warm_start)  # (a ValueError naming the problem)
        warm = np.r_[agent.turn_gait, agent.lead, agent.ramp]
    from .envs.vector import RRRobotVectorEnv

    probe = RRRobotVectorEnv(num_envs=1, model=model, **env_kwargs)  # (a bad keyword fails now, not after a stage)
    dt = probe.dt
    probe.close()
    say = progress or (lambda line: None)
    began = time.perf_counter()
    said = {"at": -math.inf}

    def reporter(stage, best):
        """``report`` for :func:`maximise`: a line at most every 10 s, ``best(row)`` the best so far."""

        def report(archive, rows):
            if time.perf_counter() - said["at"] >= 10.0:
                said["at"] = time.perf_counter()
                say(f"{stage}: {len(archive.rows)} scored, {time.perf_counter() - began:.0f} s, "
                    f"best {best(archive.rows[archive.best])}")

        return report

    def scorer(function, settings):
        return lambda params: np.concatenate(ray_map(function, np.asarray(params), settings, ray_address, ray_chunks))

    seeds = [None] + list(range(1, starts))

    # 1. direction
    direction = measure_direction(gait, model=model, env_kwargs=env_kwargs, reset_noise_scale=reset_noise_scale)
    offset = float(round(direction["direction_offset_deg"]))
    say(f"direction: {gait.name} travels at the body's yaw {direction['direction_offset_deg']:+.2f} deg (used: {offset:+.0f})")

    # 2. turning gait
    turning_settings = dict(model=model, env_kwargs=env_kwargs, seeds=TURN_SEEDS, reset_noise_scale=reset_noise_scale)
    guesses = [gait.as_array(), [1.5, 0.0, 1.57, 1.57, 8.6, 0.0], [0.0, 1.5, 1.57, 1.57, 8.6, 0.0],
               [1.5, 1.5, 1.57, 1.57, 8.6, 0.0], [1.5, 1.5, 1.57, 1.57, 8.6, math.pi]]  # fmt: skip
    to_params, to_unit = unit_box()
    turning_evaluations = None if budget_evaluations is None else round(turning_share * budget_evaluations)
    turning = maximise(scorer(score_turning, turning_settings), to_params, to_unit, dimension=6,
                       first=[repair(np.array(g)) for g in guesses], screen=8 * popsize, popsize=popsize, sigma0=0.2,
                       seed=seed, remaining=budget(began + turning_share * budget_seconds, turning_evaluations),
                       report=reporter("turning gait", lambda row: f"{row[1]:+.3f} rad/s"))  # fmt: skip
    turn = np.asarray(turning.params[turning.best])
    turn_rate = float(turning.rows[turning.best][1])
    if turn_rate > 0:  # the agent's turning gait turns clockwise (its mirror anticlockwise)
        turn = mirror_gait(turn)

    # 3. maneuver
    lead_max, blend_max = maneuver_bounds(gait)
    to_params, to_unit = unit_box([(0.0, lead_max), (BLEND_MIN, blend_max)])
    settings = dict(model=model, env_kwargs=env_kwargs, seeds=seeds, headings_deg=heads, duration=duration, dt=dt,
                    run_gait=gait.as_array(), run_ramp=gait.ramp_s, direction_offset_deg=offset,
                    run_at_once_below_deg=float(run_at_once_below_deg), reset_noise_scale=reset_noise_scale)  # fmt: skip
    first = [to_params(to_unit(np.r_[turn, 0.6, 1.0]))]
    for factor in (0.3, 0.5, 0.7):  # gentler copies of the fastest turn: a spin overshoots
        gentle = turn.copy()
        gentle[:2] *= factor
        first.append(to_params(to_unit(np.r_[gentle, 0.4, 1.0])))
    if warm is not None:
        first.append(to_params(to_unit(warm)))
        first += [to_params(to_unit(np.r_[warm[:7], b])) for b in (4.0, 6.0, 8.0) if b <= blend_max]
    maneuver_evaluations = None if budget_evaluations is None else budget_evaluations - len(turning.rows)
    maneuvers = maximise(scorer(score_maneuvers, settings), to_params, to_unit, dimension=8, first=first,
                         screen=popsize, popsize=popsize // 2, sigma0=0.2, seed=seed,
                         remaining=budget(began + budget_seconds, maneuver_evaluations),
                         report=reporter("maneuver", lambda row: f"fitness {1e3 * row[0]:.1f} mm/s"))  # fmt: skip
    maneuver, scores = np.asarray(maneuvers.params[maneuvers.best]), maneuvers.rows[maneuvers.best]
    seconds = time.perf_counter() - began
    spec = agent_spec(maneuver, gait, run_gaits, out_path, offset, dt, model, env_kwargs, run_at_once_below_deg, command)
    spec["search"] = {
        "seed": seed, "budget_seconds": budget_seconds, "budget_evaluations": budget_evaluations,
        "seconds": round(seconds, 1), "reset_noise_scale": reset_noise_scale,
        "direction": direction,
        "turning_gait": {"parameters": turning.params[turning.best].tolist(), "yaw_rate_radps": turn_rate,
                         "evaluations": len(turning.rows), "generations": turning.generations, "seeds": TURN_SEEDS,
                         "duration_s": TURN_SECONDS},
        "maneuver": {"headings_deg": heads, "seeds": seeds, "duration_s": duration, "fitness": float(scores[0]),
                     "speeds_mps": [float(v) for v in scores[1:]], "evaluations": len(maneuvers.rows),
                     "generations": maneuvers.generations, "lead_max_s": lead_max, "blend_max_s": blend_max,
                     "warm_start": None if warm_start is None else str(warm_start)},
    }  # fmt: skip
    return spec


def agent_spec(maneuver, gait, run_gaits, out_path, offset_deg, dt, model, env_kwargs, run_at_once_below_deg, command):
    """The agent file's dict (the format :func:`rrrobot_gym.agents.turn_then_run.load_turn_then_run_agent`
    reads): the maneuver, the running gait by file and name, the direction offset, and how it was made."""
    run_gaits = Path(run_gaits)
    folder = Path(out_path).resolve().parent if out_path is not None else run_gaits.resolve().parent
    spec = {
        "turn_gait": [float(v) for v in maneuver[:6]], "lead_s": float(maneuver[6]), "ramp_s": float(maneuver[7]),
        "run_gait_file": os.path.relpath(run_gaits.resolve(), folder), "run_gait": gait.name,
        "direction_offset_deg": float(offset_deg), "window_steps": WINDOW_STEPS, "dt": float(dt), "model": model,
    }  # fmt: skip
    spec["env_kwargs"] = task.with_servo(env_kwargs)
    spec["run_at_once_below_deg"] = float(run_at_once_below_deg)
    spec["made_by"] = [command] if command else []
    spec["parameter_names"] = {"turn_gait": list(PARAMETER_NAMES)}
    return spec


# ---------------------------------------------------------------- the heading correction


STEER_KEYS = ("steer_param", "steer_gain", "steer_integral", "steer_limit", "steer_after_s")


def tune_steering(agent_file, grid: dict, *, seeds=(None, 1, 2), duration=50.0, headings_deg=COMPASS_DEG,
                  reset_noise_scale=0.01, command=None, progress=None, out_path=None, **env_kwargs) -> dict:  # fmt: skip
    """The heading correction's gains for an agent file, on a grid through the agent itself.

    ``grid`` maps some of :data:`STEER_KEYS` to lists of values; every combination (the file's own
    keys for the rest), and the file without any correction first, runs ``duration`` s along
    ``headings_deg`` from each start of ``seeds`` (None: the paper's). The combination whose runs
    end least, then with the best worst speed, then the best mean, is kept: the file's dict with
    it and the grid's record under ``"steer_tune"``, ``run_gait_file`` relative to ``out_path``'s folder.
    """
    agent_file = Path(agent_file)
    load_turn_then_run_agent(agent_file)  # (a ValueError naming the problem)
    spec = json.loads(agent_file.read_text())
    unknown = sorted(set(grid) - set(STEER_KEYS))
    if unknown:
        raise SearchError(f"unknown steering key(s) {', '.join(unknown)}: expected some of {', '.join(STEER_KEYS)}")
    if not grid or any(not isinstance(v, (list, tuple)) or not v for v in grid.values()):
        raise SearchError(f"give each steering key of the grid one or more values, got {grid!r}")
    duration = positive_seconds("duration", duration)
    base = {k: v for k, v in spec.items() if k not in STEER_KEYS}
    keys = list(grid)
    combos = [{}] + [dict(zip(keys, values)) for values in itertools.product(*(grid[k] for k in keys))]
    folder = agent_file.resolve().parent
    trials = [{**base, **({k: spec[k] for k in STEER_KEYS if k in spec} if combo else {}), **combo} for combo in combos]
    agents = [agent_from_spec(trial, folder) for trial in trials]  # (a bad value: a ValueError naming it)
    model = spec.get("model", "plane")
    env_kwargs = {**(spec.get("env_kwargs") or {}), **env_kwargs}
    seeds = list(seeds)
    say = progress or (lambda line: None)
    began = time.perf_counter()
    rows = []
    for i in range(0, len(agents), 12):  # (12 agents x 24 runs an env)
        speed, ended, end_time, _ = run_agents(agents[i:i + 12], headings_deg, seeds, duration, model=model,
                                               env_kwargs=env_kwargs, reset_noise_scale=reset_noise_scale)  # fmt: skip
        for j in range(len(speed)):
            rows.append({"combo": combos[i + j], "ended": int(ended[j].sum()), "worst_mps": float(speed[j].min()),
                         "mean_mps": float(speed[j].mean()), "speeds_mps": speed[j].tolist()})  # fmt: skip
        say(f"steering: {len(rows)} of {len(combos)} combinations, {time.perf_counter() - began:.0f} s")
    ranked = sorted(range(len(rows)), key=lambda r: (rows[r]["ended"], -rows[r]["worst_mps"], -rows[r]["mean_mps"]))
    out = dict(trials[ranked[0]])
    if out_path is not None:
        out["run_gait_file"] = os.path.relpath((folder / spec["run_gait_file"]).resolve(), Path(out_path).resolve().parent)
    out["env_kwargs"] = task.with_servo(env_kwargs)  # (what the runs ran under, --env included)
    out["made_by"] = list(spec.get("made_by") or []) + ([command] if command else [])
    out["steer_tune"] = {"grid": grid, "seeds": seeds, "headings_deg": list(headings_deg), "duration_s": duration,
                         "seconds": round(time.perf_counter() - began, 1), "rows": [rows[r] for r in ranked]}  # fmt: skip
    return out
