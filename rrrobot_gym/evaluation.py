"""Score a learned PPO policy and the paper's gaits on the same RRRobot-v0 evaluation.

Every agent runs episodes of ``--duration`` (default 50 s) from the paper's start (no noise) on
each model, along the 8 compass headings and each gait's own direction of travel, through one
loop over the batched env and the same ``predict`` interface (:mod:`rrrobot_gym.agents`).

    python evaluate.py                                  # the shipped policy
    python evaluate.py --policy runs/RUN/best_model.zip --json results.json --plots docs/evaluation
    python evaluate.py --gaits agents/searched/plane_own.json        # searched gaits too
    python evaluate.py --turn-then-run agents/searched/turn_then_run.json \
        --turn-then-run agents/searched/turn_then_run_pivot.json   # the closed-loop baseline, plane and pivot
    python evaluate.py --also-policy residual=agents/pretrained_residual/best_model.zip   # a second policy beside
    python evaluate.py --gaits agents/searched/plane_own.json --randomize 16   # and over 16 drawn robots per heading

A policy is scored on the model it was trained on (its run's ``env_kwargs.json``; ``--cross-model``
scores it on every model of ``--models``), in rows labelled with its file. Every agent runs the
nominal robot, whatever a policy was trained on; ``--randomize N`` also scores every agent over N
robots per compass heading drawn with the env's domain randomization.
Writes Markdown tables to stdout (``--markdown FILE`` too), records with ``--json FILE`` (keys:
agent, model, heading_deg, speed_mps, lateral_drift_m, effort_rms_torque_nm, ...; the randomized
robots under "randomized") and plots with ``--plots DIR``. Loading a policy unpickles it: load
only files you trust.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path

import numpy as np
from gymnasium.utils import seeding

from .agents import GAIT_AGENT_NAMES, gait_agent, load_gait_agents, load_ppo_agent
from .agents.turn_then_run import load_turn_then_run_agent
from .cli import UsageError, check_output_path, keyword_value
from .envs.task import RANDOMIZATIONS, action_to_leg_targets, control_steps, make_task_config
from .envs.vector import RRRobotVectorEnv

PHYSICS_KEYWORDS = ("torque_limit", "leg_rate_limit", "leg_accel_limit", "kp", "kd", "robot", "damping", "legs", "timestep", "integrator",
                    "frame_skip", "friction_coefficient", "max_slip_velocity", "max_liftoff_time",
                    "contact_quadrature", "action_hold", "num_legs", "shell_axes")  # fmt: skip
"""Env keywords that change what any agent can do: a policy's apply to every agent on its model."""
SERVO_KEYWORDS = ("torque_limit", "leg_rate_limit", "leg_accel_limit")
"""The servo's keywords: every record names them, default or not."""
COMPASS_DEG = tuple(range(0, 360, 45))
EFFORT_KEYS = ("torque_rms", "torque_peak", "leg_rate_peak", "liftoff_fraction")
"""The step record's summaries (env info keys) the evaluation keeps."""


def shared_env_kwargs(agents, **env_kwargs) -> dict:
    """The keywords of one env for all ``agents``: each agent's training keywords (the first
    agent's where two differ; gaits have none) under ``env_kwargs``."""
    for agent in agents.values():  # (the observation a learned policy was trained with)
        env_kwargs = {**getattr(agent, "env_kwargs", {}), **env_kwargs}
    return env_kwargs


def run_episodes(agents, model: str, headings_deg, duration: float = 50.0, seed: int = 0, info_keys=EFFORT_KEYS,
                 randomize=None, robot_seeds=None, start_noise: float = 0.0, **env_kwargs):
    """Run every agent (``agents``: {name: agent}) once along each heading (degrees), all in one
    batched env, from the paper's start (``start_noise`` > 0: a start drawn with that reset noise,
    the env's ``reset_noise_scale``), on the nominal robot unless ``randomize`` (the env keyword; a
    policy's own is not used) draws one per episode.

    ``seed`` seeds the env: sub-env i gets ``seed + i``, unless ``robot_seeds`` (one per heading,
    the same for every agent) seeds heading i's robot; the env's own generator (observation noise)
    gets ``seed`` either way. Returns {name: run}, each run a dict of arrays: ``times`` (T+1,) s,
    ``xy`` (T+1, H, 2) contact path (m), ``leg_angles`` (T+1, H, L) and ``leg_targets`` (T, H, L)
    rad, ``terminated`` (H,), ``draws`` ({name: (H,)}, the randomized robots of the reset info) and
    per control step (T, H) the env info's step summaries named by ``info_keys``. After a robot's
    episode ends its path holds its last position, then NaN (and its summaries NaN).
    """
    names = list(agents)
    n_head = len(headings_deg)
    env_kwargs = {**shared_env_kwargs(agents, **env_kwargs), "randomize": randomize}
    headings = np.tile(np.radians(np.asarray(headings_deg, dtype=float)), len(names))
    env = RRRobotVectorEnv(
        num_envs=len(headings), max_episode_steps=None, model=model, reset_noise_scale=start_noise, **env_kwargs
    )
    try:  # (the nearest whole number of control steps: score divides by their time)
        steps = control_steps("duration", duration, env.dt)
        if robot_seeds is not None and len(robot_seeds) != n_head:
            raise ValueError(f"robot_seeds: expected one per heading ({n_head}), got {len(robot_seeds)}")
    except ValueError:
        env.close()
        raise
    if robot_seeds is not None:  # (a seed list leaves the env's own generator unseeded: seed it here)
        env.np_random = seeding.np_random(seed)[0]
    obs, reset_info = env.reset(seed=seed if robot_seeds is None else list(robot_seeds) * len(names),
                                options={"target_direction": headings})
    draws = {key[len("randomized_"):]: reset_info[key] for key in reset_info if key.startswith("randomized_")}
    leg_columns = env.config.sim.fields.leg_angles
    xy, legs, targets = [env.states[:, 0:2].copy()], [env.states[:, leg_columns].copy()], []
    effort = {key: [] for key in info_keys}
    agent_states = {name: None for name in names}
    episode_start = np.ones(n_head, dtype=bool)
    ended = np.zeros(len(headings), dtype=bool)
    for _ in range(steps):
        actions = np.empty((len(headings), env.config.num_robot_legs), dtype=np.float32)
        for a, name in enumerate(names):
            rows = slice(a * n_head, (a + 1) * n_head)
            actions[rows], agent_states[name] = agents[name].predict(
                obs[rows], state=agent_states[name], episode_start=episode_start, deterministic=True
            )
        episode_start = np.zeros(n_head, dtype=bool)
        obs, _, terminated, _, info = env.step(actions)
        leg_target = action_to_leg_targets(np.clip(actions, -1, 1))
        current = env.states.copy()
        step_effort = {key: np.array(info[key], dtype=float) for key in info_keys}
        ended_before = ended.copy()
        if np.any(terminated):
            # SAME_STEP autoreset has already restarted a finished robot: its last step is in final_info.
            final = info["final_info"]
            for i in np.flatnonzero(terminated & ~ended):
                current[i, :] = np.nan
                current[i, 0:2] = final["x_position"][i], final["y_position"][i]
                for key in info_keys:
                    step_effort[key][i] = final[key][i]
            ended |= terminated
        # Ended at an earlier step: NaN, even when its autoreset episode terminates again now.
        gone = ended & ~(terminated & ~ended_before)
        current[gone] = np.nan
        targets.append(leg_target)
        xy.append(current[:, 0:2])
        legs.append(current[:, leg_columns])
        for key in info_keys:
            step_effort[key][gone] = np.nan
            effort[key].append(step_effort[key])
    env.close()
    arrays = {"xy": np.array(xy), "leg_angles": np.array(legs), "leg_targets": np.array(targets)}
    arrays.update({key: np.array(values) for key, values in effort.items()})
    runs = {}
    for a, name in enumerate(names):
        rows = slice(a * n_head, (a + 1) * n_head)
        runs[name] = {key: value[:, rows] for key, value in arrays.items()}
        runs[name]["times"] = np.arange(steps + 1) * env.dt
        runs[name]["terminated"] = ended[rows]
        runs[name]["draws"] = {key: values[rows] for key, values in draws.items()}
    return runs


def score(run, headings_deg, duration=None):
    """Per heading: speed along it (m/s), lateral drift (m), the RMS and peak leg torque applied
    (N m), the peak leg rate (rad/s) and the share of time without ground contact. Speeds are over
    the time the run simulated, ``run["times"][-1]``; ``duration``, if given, must be that time."""
    simulated = float(run["times"][-1])
    if duration is not None and abs(duration - simulated) > 1e-9 * max(1.0, simulated):
        raise ValueError(f"the run simulated {simulated!r} s (whole control steps), not {duration!r} s")
    duration = simulated
    records = []
    for i, heading in enumerate(headings_deg):
        direction = np.array([math.cos(math.radians(heading)), math.sin(math.radians(heading))])
        path = run["xy"][:, i]
        valid = np.all(np.isfinite(path), axis=1)
        end = path[valid][-1] - path[0]
        along = float(end @ direction)
        lateral = float(direction[0] * end[1] - direction[1] * end[0])
        records.append({
            "heading_deg": float(heading),
            "speed_mps": along / duration,
            "lateral_drift_m": lateral,
            "displacement_m": [float(end[0]), float(end[1])],
            # (every step has as many samples: the root of the mean of the steps' mean squares)
            "effort_rms_torque_nm": float(np.sqrt(np.nanmean(run["torque_rms"][:, i] ** 2))),
            "peak_torque_nm": float(np.nanmax(run["torque_peak"][:, i])),
            "peak_leg_rate_radps": float(np.nanmax(run["leg_rate_peak"][:, i])),
            "liftoff_fraction": float(np.nanmean(run["liftoff_fraction"][:, i])),
            "terminated": bool(run["terminated"][i]),
        })
    return records


def physics_of(agents) -> dict:
    """The :data:`PHYSICS_KEYWORDS` the agents were trained under (their ``env_kwargs``); agents
    that disagree are an error, whether or not one of them has the env's default."""
    chosen = {}
    for name, agent in agents.items():
        for key, value in getattr(agent, "env_kwargs", {}).items():
            if key == "shell_axes" and value is not None:
                value = tuple(float(v) for v in value)  # (a list from JSON, a tuple from Python)
            if key in PHYSICS_KEYWORDS:
                if key in chosen and chosen[key][1] != value:
                    raise ValueError(f"agents {chosen[key][0]!r} and {name!r} were trained with different {key}: "
                                     f"{chosen[key][1]!r} and {value!r}; score them in separate evaluations")  # fmt: skip
                chosen.setdefault(key, (name, value))
    return {key: value for key, (_, value) in chosen.items()}


def physics_on(model: str, agents: dict, physics=None) -> dict:
    """The physics keywords every agent on ``model`` runs under: the ones its policies were
    trained with (:func:`physics_of`) and ``physics`` ({keyword: value}; one that contradicts a
    policy's is an error)."""
    trained = physics_of(agents)
    clash = sorted(key for key, value in (physics or {}).items() if key in trained and trained[key] != value)
    if clash:
        raise ValueError(f"--physics sets {', '.join(f'{k}={physics[k]!r}' for k in clash)} on the {model} model, "
                         f"where a policy was trained with {', '.join(f'{k}={trained[k]!r}' for k in clash)}")
    return {**trained, **(physics or {})}


def physics_shown(imposed: dict) -> dict:
    """What a record says its agents ran under: the servo (:data:`SERVO_KEYWORDS`) and the other
    ``imposed`` keywords that differ from the env's defaults."""
    defaults = make_task_config().to_kwargs()
    effective = {**{key: defaults[key] for key in SERVO_KEYWORDS}, **imposed}
    return {key: dataclasses.asdict(value) if key == "robot" else value for key, value in effective.items()
            if key in SERVO_KEYWORDS or value != defaults[key]}


def parse_physics(specs) -> dict:
    """``--physics`` KEY=VALUE specs (keys of :data:`PHYSICS_KEYWORDS` but ``robot``) as {key: value},
    checked together by the env, or a ValueError naming the bad spec."""
    chosen = {}
    allowed = ", ".join(k for k in PHYSICS_KEYWORDS if k != "robot")
    for spec in specs:
        try:
            key, value = keyword_value(spec)
        except ValueError as exc:
            raise ValueError(f"--physics {spec!r}: {exc}") from None
        if key not in PHYSICS_KEYWORDS or key == "robot":
            raise ValueError(f"--physics {spec!r}: expected KEY=VALUE with KEY one of {allowed}")
        if key in chosen:  # (the last one won, silently)
            raise ValueError(f"--physics {spec!r}: {key} is given twice")
        chosen[key] = value
    try:  # together: some keywords need others (a leg-rate limit needs a torque limit)
        make_task_config(**chosen)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"--physics {' '.join(specs)}: {exc}") from None
    return chosen


def agents_on(model: str, agents: dict, per_model=None) -> dict:
    """The agents scored on ``model``: ``agents`` with ``per_model[model]``'s in place of same-named ones,
    "ppo" first."""
    merged = {**agents, **(per_model or {}).get(model, {})}
    return dict(sorted(merged.items(), key=lambda item: item[0] != "ppo"))  # (stable: the rest as given)


def gait_legs(agent):
    """The leg count of an open-loop gait agent's gait (None for any other agent)."""
    gait = getattr(agent, "gait", None)
    return None if gait is None else int(np.shape(gait.angles(np.zeros(1)))[-1])


def evaluate(agents: dict, models, duration: float = 50.0, seed: int = 0, per_model=None, physics=None):
    """Records for every agent, model and heading, plus the runs for plotting.

    Headings: the 8 compass directions and each open-loop gait's own direction (of its net
    displacement in a first episode). ``per_model`` ({model: {name: agent}}) adds or replaces
    agents on one model. On each model every agent runs the nominal robot (no randomization) under
    :func:`physics_on` (its policies' training physics and ``physics``); each record names them
    under ``physics`` (:func:`physics_shown`).
    """
    records, runs = [], {}
    for model in models:
        on_model = agents_on(model, agents, per_model)
        imposed = physics_on(model, on_model, physics)
        legs = make_task_config(model=model, **imposed).num_robot_legs
        other = [name for name, agent in on_model.items() if gait_legs(agent) not in (None, legs)]
        if other:  # (the Table II gaits beside a family member's policy or gaits)
            print(f"not scored on the {legs}-leg robot: {', '.join(other)} (gaits of another leg count)", file=sys.stderr)
            on_model = {name: agent for name, agent in on_model.items() if name not in other}
        # Open-loop gaits go one way: score them along it too (a closed-loop agent has no such direction).
        gaits = {name: agent for name, agent in on_model.items() if name != "ppo" and not getattr(agent, "closed_loop", False)}
        first = run_episodes(gaits, model, [0.0], duration, seed, **imposed) if gaits else {}
        own = {}
        for name, run in first.items():
            path = run["xy"][:, 0]  # NaN after an episode that left the model: use its last position
            end = path[np.all(np.isfinite(path), axis=1)][-1] - path[0]
            own[name] = round(math.degrees(math.atan2(end[1], end[0])) % 360.0, 3)
        headings = list(COMPASS_DEG) + list(own.values())
        for name, run in run_episodes(on_model, model, headings, duration, seed, **imposed).items():
            runs[(name, model)] = (headings, run)
            for record in score(run, headings):
                record.update(agent=name, model=model, compass=record["heading_deg"] in COMPASS_DEG,
                              physics=physics_shown(imposed), **policy_source(on_model[name]))
                record["own_direction_of"] = [g for g, h in own.items() if h == record["heading_deg"]]
                records.append(record)
    return records, runs


def policy_source(agent) -> dict:
    """What a record says of a policy loaded from a file (``agent.path``, set by
    :func:`rrrobot_gym.agents.load_ppo_agent`): ``policy_file`` (relative to the working directory
    where it lies inside it), ``algorithm`` (train.py's ``--algo``) and ``trained_on``, its training
    env's model; {} for other agents."""
    from .agents.ppo import trained_algorithm

    path = getattr(agent, "path", None)
    if path is None:
        return {}
    path = Path(path)
    try:
        shown = path.resolve().relative_to(Path.cwd().resolve())
    except ValueError:
        shown = path
    return {"policy_file": str(shown), "algorithm": trained_algorithm(path), "trained_on": agent.env_config.get("model", "plane")}


def row_label(name: str, source: dict, model: str) -> str:
    """A table row's agent: a policy's algorithm (PPO's row keeps its name) with its file, and the
    model it was trained on where that is not the table's (``source``: :func:`policy_source`'s)."""
    if "policy_file" not in source:
        return name
    algorithm = source.get("algorithm", "ppo")
    shown = name if algorithm == "ppo" or name != "ppo" else algorithm
    elsewhere = f", trained on {source['trained_on']}" if source["trained_on"] != model else ""
    return f"{shown} ({source['policy_file']}{elsewhere})"


def robot_seeds(seed: int, slot: int, n: int) -> list:
    """The seeds of the ``n`` randomized robots of heading slot ``slot`` (the compass headings in
    order, then the gaits' own directions), the same for every agent; other ``seed``s, other robots."""
    return [int(s) for s in np.random.SeedSequence([seed, slot]).generate_state(n)]


def rows_of(run: dict, rows) -> dict:
    """The paths and step summaries of a run (:func:`run_episodes`) of its robots ``rows``."""
    out = {key: value[:, rows] for key, value in run.items() if key not in ("times", "terminated", "draws")}
    return out | {"times": run["times"], "terminated": run["terminated"][rows]}


def spread(run, heading_deg: float) -> dict:
    """A run's robots (all along ``heading_deg``): their speeds along it (m/s), which ended early,
    the median, the 10th percentile (numpy's, linear interpolation) and the share that ended."""
    records = score(run, [heading_deg] * len(run["terminated"]))
    speeds = np.array([r["speed_mps"] for r in records])
    ended = [r["terminated"] for r in records]
    return {"heading_deg": float(heading_deg), "speeds_mps": speeds.tolist(), "ended": ended,
            "median_mps": float(np.median(speeds)), "p10_mps": float(np.percentile(speeds, 10)),
            "share_ended": float(np.mean(ended))}


def evaluate_randomized(agents: dict, models, n: int, duration: float = 50.0, seed: int = 0, per_model=None,
                        physics=None, ranges="default", own=None):
    """Every agent over ``n`` randomized robots per compass heading, on each model.

    The robots are drawn with the env's ``randomize=ranges`` (a name of ``task.RANDOMIZATIONS`` or
    {name: (low, high)}), robot j of a heading seeded by :func:`robot_seeds`: every agent meets
    the same robots and, run alone in an env seeded alike, the same observation noise. Each
    open-loop gait named in ``own`` ({model: {name: heading_deg}}, its nominal own direction)
    also runs ``n`` robots along it. Agents, ``per_model`` and ``physics`` as in :func:`evaluate`.
    Returns (one section per model: {"model", "robots_per_heading", "ranges", "seed",
    "duration_s", "physics", "robots": per heading its seeds and draws, "searched_gaits",
    "agents": {name: {"headings": [:func:`spread`...], "own_direction" (gaits), "worst_heading_deg"
    (lowest P10), "worst_median_mps", "worst_p10_mps", "share_ended"}}}, {(name, model): {heading
    "compass": run, "own_direction": run}}).
    """
    sections, runs = [], {}
    for model in models:
        on_model = agents_on(model, agents, per_model)
        imposed = physics_on(model, on_model, physics)
        legs = make_task_config(model=model, **imposed).num_robot_legs
        other = [name for name, agent in on_model.items() if gait_legs(agent) not in (None, legs)]
        if other:  # (the Table II gaits beside a family member's policy or gaits)
            print(f"not scored on the {legs}-leg robot: {', '.join(other)} (gaits of another leg count)", file=sys.stderr)
            on_model = {name: agent for name, agent in on_model.items() if name not in other}
        headings = [float(h) for h in COMPASS_DEG for _ in range(n)]
        seeds = [s for slot in range(len(COMPASS_DEG)) for s in robot_seeds(seed, slot, n)]
        own_here = {name: deg for name, deg in (own or {}).get(model, {}).items() if name in on_model}
        searched = [name for name, agent in on_model.items()
                    if name not in GAIT_AGENT_NAMES and name != "ppo" and not getattr(agent, "closed_loop", False)]
        section = {"model": model, "robots_per_heading": n, "ranges": ranges, "seed": seed,
                   "physics": physics_shown(imposed), "searched_gaits": searched, "robots": [], "agents": {}}
        for name, agent in on_model.items():
            run = run_episodes({name: agent}, model, headings, duration, seed, randomize=ranges, robot_seeds=seeds,
                               **imposed)[name]  # fmt: skip
            runs[(name, model)] = {"compass": run}
            rows = [slice(k * n, (k + 1) * n) for k in range(len(COMPASS_DEG))]
            per_heading = [spread(rows_of(run, r), h) for h, r in zip(COMPASS_DEG, rows)]
            worst = min(per_heading, key=lambda x: x["p10_mps"])
            summary = section["agents"][name] = {
                **policy_source(agent), "headings": per_heading, "worst_heading_deg": worst["heading_deg"],
                "worst_median_mps": worst["median_mps"], "worst_p10_mps": worst["p10_mps"],
                "share_ended": float(np.mean([e for x in per_heading for e in x["ended"]])),
            }
            if not section["robots"]:
                section["robots"] = [{"heading_deg": float(h), "seeds": seeds[r],
                                      "draws": {key: values[r].tolist() for key, values in run["draws"].items()}}
                                     for h, r in zip(COMPASS_DEG, rows)]  # fmt: skip
            if name in own_here:
                slot = len(COMPASS_DEG) + list(own_here).index(name)
                own_seeds = robot_seeds(seed, slot, n)
                own_run = run_episodes({name: agent}, model, [own_here[name]] * n, duration, seed, randomize=ranges,
                                       robot_seeds=own_seeds, **imposed)[name]  # fmt: skip
                runs[(name, model)]["own_direction"] = own_run
                summary["own_direction"] = spread(own_run, own_here[name]) | {
                    "seeds": own_seeds, "draws": {key: values.tolist() for key, values in own_run["draws"].items()}}
        section["duration_s"] = float(run["times"][-1]) if on_model else float(duration)
        sections.append(section)
    return sections, runs


def gait_p10(summary: dict) -> float:
    """A gait's 10th-percentile speed under randomization, what PPO's must reach: the larger of
    its best compass heading's and its own direction's."""
    own = summary.get("own_direction", {}).get("p10_mps", -math.inf)
    return max([x["p10_mps"] for x in summary["headings"]] + [own])


def randomized_targets(section: dict, records) -> dict | None:
    """PPO's targets under randomization on ``section``'s model, computed from the numbers (None
    without a PPO agent): its P10 on its worst heading at least 0.8 x its nominal worst heading
    (``records``) and at least every searched gait's (:func:`gait_p10`; None without searched
    gaits), and at most 5 % of its episodes ended. ``qualifies``: at least 16 robots per heading
    and the default ranges, as the targets ask."""
    ppo = section["agents"].get("ppo")
    nominal = [r["speed_mps"] for r in records if r["compass"] and (r["model"], r["agent"]) == (section["model"], "ppo")]
    if ppo is None or not nominal:
        return None
    gaits = {name: gait_p10(section["agents"][name]) for name in section["searched_gaits"]}
    out = {"ppo_worst_p10_mps": ppo["worst_p10_mps"], "ppo_worst_heading_deg": ppo["worst_heading_deg"],
           "nominal_worst_mps": min(nominal),
           "searched_gait_p10_mps": gaits, "share_ended": ppo["share_ended"],
           "qualifies": section["robots_per_heading"] >= 16 and section["ranges"] == "default"}  # fmt: skip
    out["p10_at_least_0.8_nominal_worst"] = bool(ppo["worst_p10_mps"] >= 0.8 * min(nominal))
    out["p10_at_least_every_searched_gait"] = all(ppo["worst_p10_mps"] >= v for v in gaits.values()) if gaits else None
    out["share_ended_at_most_5pct"] = bool(ppo["share_ended"] <= 0.05)
    checks = [out["p10_at_least_0.8_nominal_worst"], out["p10_at_least_every_searched_gait"], out["share_ended_at_most_5pct"]]
    out["all_hold"] = None if None in checks else all(checks)
    return out


def randomized_markdown(sections, records) -> str:
    """The randomized evaluation's tables (mm/s), one per model, and PPO's targets."""
    lines = []
    for section in sections:
        model, n = section["model"], section["robots_per_heading"]
        ranges = section["ranges"] if isinstance(section["ranges"], str) else "custom"
        lines.append(f"### {model}, {n} randomized robots per heading: median / P10 of the speed along the commanded "
                     f"heading (mm/s), {seconds_text(section['duration_s'])} from rest\n")  # fmt: skip
        lines.append(f"Robots drawn with the {ranges!r} ranges of the env's domain randomization, robot j of a heading "
                     f"the same for every agent (seed {section['seed']}), {physics_text(section['physics'])}. "
                     "P10: the 10th percentile (numpy's, linear interpolation). Worst heading: the compass heading of "
                     "lowest P10. Own direction: an open-loop gait's nominal one, on robots of its own. Ended: the "
                     "share of the compass episodes that ended early (left the model or tipped over); such a robot "
                     "counts with its displacement up to then over the whole duration.\n")  # fmt: skip
        lines.append("| agent | " + " | ".join(f"{h} deg" for h in COMPASS_DEG) + " | worst heading | own direction | ended |")
        lines.append("|---" * (len(COMPASS_DEG) + 4) + "|")
        for name, summary in section["agents"].items():
            cells = [f"{x['median_mps'] * 1e3:.1f} / {x['p10_mps'] * 1e3:.1f}" for x in summary["headings"]]
            cells.append(f"{summary['worst_median_mps'] * 1e3:.1f} / {summary['worst_p10_mps'] * 1e3:.1f} at "
                         f"{summary['worst_heading_deg']:.0f} deg")  # fmt: skip
            own = summary.get("own_direction")
            cells.append(f"{own['median_mps'] * 1e3:.1f} / {own['p10_mps'] * 1e3:.1f} at {own['heading_deg']:.0f} deg"
                         if own else "")
            cells.append(f"{summary['share_ended']:.1%}")
            lines.append(f"| {row_label(name, summary, model)} | " + " | ".join(cells) + " |")
        lines.append("")
        target = randomized_targets(section, records)
        if target is not None:
            lines.append(targets_text(model, target))
            lines.append("")
    return "\n".join(lines)


def targets_text(model: str, target: dict) -> str:
    """:func:`randomized_targets` as a sentence."""
    def verdict(holds):
        return "not checked" if holds is None else "holds" if holds else "FAILS"

    gaits = target["searched_gait_p10_mps"]
    best = max(gaits, key=gaits.get) if gaits else None
    text = (f"PPO's targets under randomization, {model}: P10 on its worst heading ({target['ppo_worst_heading_deg']:.0f} deg) "
            f"{target['ppo_worst_p10_mps'] * 1e3:.1f} mm/s, at least 0.8 x its nominal worst heading's "
            f"{target['nominal_worst_mps'] * 1e3:.1f} ({0.8e3 * target['nominal_worst_mps']:.1f}): "
            f"{verdict(target['p10_at_least_0.8_nominal_worst'])}; "
            "at least every searched gait's P10 (a gait's: the larger of its best compass heading's and its own "
            f"direction's{f'; the highest {best}, {gaits[best] * 1e3:.1f}' if best else ', no searched gait scored'}): "
            f"{verdict(target['p10_at_least_every_searched_gait'])}; episodes ended {target['share_ended']:.1%} <= 5 %: "
            f"{verdict(target['share_ended_at_most_5pct'])}.")  # fmt: skip
    if not target["qualifies"]:
        text += " Not the targets' run: they ask for at least 16 robots per heading and the default ranges."
    return text


ACCURACY_REFINE = 10
"""``--check-accuracy`` runs each policy again at a step this many times finer (the same control step)."""
ACCURACY_TOLERANCE = 1e-3
"""The largest relative change of a heading's mean speed at the finer step that ``--check-accuracy`` takes
for the integrator's error alone: 0.1 %."""
ACCURACY_STARTS = 128
"""``--check-accuracy``'s starts per compass heading, drawn with the env's reset noise. The shipped pivot
policy's closed loop is chaotic: starts 1e-12 rad apart move its 50 s speeds by up to 1.1 %, so one
run's change with the step measures that, not the step; the mean of many starts does not. With 128
its means' standard errors stay under 0.07 % (with 32, up to 0.15 %: too wide to judge 0.1 %)."""


def accuracy_check(agent, model: str, duration: float, seed: int = 0, refine: int = ACCURACY_REFINE,
                   starts: int = ACCURACY_STARTS):
    """The agent's speed along the compass headings at its own integration step (its env keywords';
    RRRobot-v0's default is 1/300 s) and at a ``refine`` times finer one with the same control step:
    a speed that depends on the step is the integrator's artefact. Per heading: the run from the
    paper's start at both steps (m/s), the steps (s) and its relative change, coarse / fine - 1;
    with ``starts`` > 1 also the mean over that many starts drawn with the env's reset noise (the
    same starts at both steps, seeded from ``seed``), its relative change and that change's
    standard error (of the paired differences), over the starts whose episodes ran to the end at
    both steps (``starts_used``)."""
    config = make_task_config(**{**getattr(agent, "env_kwargs", {}), "model": model})
    step, frame_skip = config.sim.step, config.frame_skip
    fine_step = {"timestep": step / refine, "frame_skip": frame_skip * refine}
    records = []
    for settings in ({}, fine_step):
        runs = [run_episodes({"agent": agent}, model, COMPASS_DEG, duration, seed, **settings)["agent"]]
        if starts > 1:
            runs.append(run_episodes({"agent": agent}, model, [h for h in COMPASS_DEG for _ in range(starts)], duration,
                                     seed, start_noise=make_task_config().reset_noise_scale, **settings)["agent"])  # fmt: skip
        records.append([score(run, [h for h in COMPASS_DEG for _ in range(len(run["terminated"]) // len(COMPASS_DEG))])
                        for run in runs])  # fmt: skip
    (coarse, *coarse_starts), (fine, *fine_starts) = records
    out = []
    for i, (c, f) in enumerate(zip(coarse, fine)):
        record = {"heading_deg": c["heading_deg"], "speed_mps": c["speed_mps"], "fine_step_speed_mps": f["speed_mps"],
                  "step_s": step, "fine_step_s": step / refine, "relative_change": c["speed_mps"] / f["speed_mps"] - 1.0}
        if starts > 1:
            mine = slice(i * starts, (i + 1) * starts)
            pairs = [(a["speed_mps"], b["speed_mps"]) for a, b in zip(coarse_starts[0][mine], fine_starts[0][mine])
                     if not (a["terminated"] or b["terminated"])]
            a, b = np.array(pairs).T if pairs else (np.full(0, np.nan), np.full(0, np.nan))
            mean_a, mean_b = float(np.mean(a)) if pairs else math.nan, float(np.mean(b)) if pairs else math.nan
            spread = float(np.std(a - b, ddof=1) / math.sqrt(len(a))) if len(a) > 1 else math.nan
            record.update(starts=starts, starts_used=len(pairs), mean_speed_mps=mean_a, fine_step_mean_speed_mps=mean_b,
                          mean_relative_change=mean_a / mean_b - 1.0, mean_relative_change_se=spread / abs(mean_b),
                          speed_range_mps=[float(np.min(a)), float(np.max(a))] if pairs else [math.nan, math.nan])
        out.append(record)  # fmt: skip
    return out


def step_text(step: float) -> str:
    """An integration step as the tables name it: 1/300 s, or 0.0125 s where 1/step is no whole number."""
    per_second = 1.0 / step
    return f"1/{per_second:.0f} s" if abs(per_second - round(per_second)) < 1e-6 * per_second else f"{step:.4g} s"


def accuracy_markdown(model: str, checked) -> str:
    """The table of :func:`accuracy_check`'s records on ``model``, headed by the largest change of a
    mean speed (of a run from the paper's start where it ran no ensemble) and whether it is within
    :data:`ACCURACY_TOLERANCE`: a mean's change beyond it by more than two standard errors is the
    step's; one within two standard errors of it may be the starts' noise."""
    coarse, fine = step_text(checked[0]["step_s"]), step_text(checked[0]["fine_step_s"])
    single = max(abs(a["relative_change"]) for a in checked)
    tolerance = f"{ACCURACY_TOLERANCE * 100:g} %"
    if "mean_relative_change" in checked[0]:
        worst = max(abs(a["mean_relative_change"]) for a in checked)
        over = [a for a in checked if abs(a["mean_relative_change"]) > ACCURACY_TOLERANCE]
        beyond = [f"{a['heading_deg']:g} deg" for a in over
                  if abs(a["mean_relative_change"]) - 2.0 * a["mean_relative_change_se"] > ACCURACY_TOLERANCE]
        if not over:
            verdict = f"within {tolerance}"
        elif beyond:
            verdict = f"NOT within {tolerance} (by more than two standard errors at {', '.join(beyond)})"
        else:
            verdict = (f"within {tolerance} up to the starts' noise (each change beyond it within two standard "
                       f"errors of it; more starts, --accuracy-starts, narrow them)")
        starts, used = checked[0]["starts"], min(a["starts_used"] for a in checked)
        se = max(a["mean_relative_change_se"] for a in checked)
        head = (f"means over {starts} starts a heading (the env's reset noise{'' if used == starts else f'; {used} ran to the end'}) "
                f"change by at most {worst * 100:.3f} % (standard error up to {se * 100:.3f} %), {verdict}; the run "
                f"from the paper's start alone by {single * 100:.3f} %")
    else:
        head = f"the run from the paper's start changes by at most {single * 100:.3f} %, " + (
            f"within {tolerance}" if single <= ACCURACY_TOLERANCE else f"NOT within {tolerance}")
    lines = [
        f"PPO speed (mm/s) at its step, {coarse}, and at a {ACCURACY_REFINE}x finer one, {fine} ({model}): {head}",
        "",
        "| heading | " + " | ".join(f"{a['heading_deg']:g} deg" for a in checked) + " |",
        "|---" * (len(checked) + 1) + "|",
        f"| paper's start, {coarse} | " + " | ".join(f"{a['speed_mps'] * 1e3:.2f}" for a in checked) + " |",
        f"| paper's start, {fine} | " + " | ".join(f"{a['fine_step_speed_mps'] * 1e3:.2f}" for a in checked) + " |",
        "| change | " + " | ".join(f"{a['relative_change'] * 100:+.3f} %" for a in checked) + " |",
    ]
    if "mean_relative_change" in checked[0]:
        lines += [
            f"| mean, {coarse} | " + " | ".join(f"{a['mean_speed_mps'] * 1e3:.2f}" for a in checked) + " |",
            f"| mean, {fine} | " + " | ".join(f"{a['fine_step_mean_speed_mps'] * 1e3:.2f}" for a in checked) + " |",
            "| change of the mean | " + " | ".join(
                f"{a['mean_relative_change'] * 100:+.3f} +- {a['mean_relative_change_se'] * 100:.3f} %" for a in checked) + " |",
            f"| range of runs, {coarse} | " + " | ".join(
                f"{a['speed_range_mps'][0] * 1e3:.2f} to {a['speed_range_mps'][1] * 1e3:.2f}" for a in checked) + " |",
        ]  # fmt: skip
    return "\n".join(lines) + "\n"


def ratios(records, model="plane"):
    """PPO's speed over gait 1's (along its own axis) on every compass heading, and over each
    gait's along that gait's own direction."""
    by = {(r["agent"], r["heading_deg"]): r for r in records if r["model"] == model}
    gait1_own = [r for r in records if r["model"] == model and r["agent"] == "gait1" and "gait1" in r["own_direction_of"]]
    out = {"model": model}
    if ("ppo", 0.0) in by and gait1_own:
        reference = gait1_own[0]["speed_mps"]
        out["gait1_own_speed_mps"] = reference
        out["ppo_over_gait1_by_heading"] = {
            int(h): by[("ppo", float(h))]["speed_mps"] / reference for h in COMPASS_DEG
        }
        out["ppo_over_gait_on_its_own_direction"] = {}
        for r in records:
            if r["model"] == model and r["agent"] != "ppo" and r["agent"] in r["own_direction_of"]:
                ppo = by[("ppo", r["heading_deg"])]["speed_mps"]
                out["ppo_over_gait_on_its_own_direction"][r["agent"]] = {
                    "heading_deg": r["heading_deg"],
                    "gait_speed_mps": r["speed_mps"],
                    "ppo_speed_mps": ppo,
                    "ratio": ppo / r["speed_mps"] if r["speed_mps"] > 0 else math.inf,
                }
    return out


TERMINATED_NOTE = ("(T): the episode ended early, the robot having left the model (the env's termination); "
                   "its speed is its displacement up to then over the whole duration.")


def seconds_text(seconds: float) -> str:
    """A duration for titles: 50 s as "50 s", 2.55 s as "2.55 s"."""
    return f"{round(float(seconds), 3):g} s"


def physics_text(physics: dict) -> str:
    """What a table's agents ran under (a record's ``physics``), as words."""
    return ("under " + ", ".join(f"{k} = {v}" for k, v in physics.items())
            + " (a policy's training keywords and --physics; the rest the env's defaults)")


def markdown(records, ratio_list, duration: float = 50.0):
    """The evaluation's Markdown tables; ``duration`` (s) is the episodes' simulated time."""
    lines = []
    for model in sorted({r["model"] for r in records}):
        lines.append(f"### {model}: mean speed along the commanded heading (mm/s), {seconds_text(duration)} from rest\n")
        physics = next(r["physics"] for r in records if r["model"] == model)
        lines.append(f"Every agent on the nominal robot, {physics_text(physics)}\n")
        agents = list(dict.fromkeys(r["agent"] for r in records if r["model"] == model))  # some score on one model only
        label = {r["agent"]: row_label(r["agent"], r, model) for r in records if r["model"] == model}
        lines.append("| agent | " + " | ".join(f"{h} deg" for h in COMPASS_DEG) + " | own direction |")
        lines.append("|---" * (len(COMPASS_DEG) + 2) + "|")
        for agent in agents:
            rows = {r["heading_deg"]: r for r in records if r["model"] == model and r["agent"] == agent}
            own = [r for r in rows.values() if agent in r["own_direction_of"]]
            own_text = f"{own[0]['speed_mps'] * 1e3:.2f} at {own[0]['heading_deg']:.0f} deg" if own else ""
            cells = []
            for h in COMPASS_DEG:
                r = rows[float(h)]
                cells.append(f"{r['speed_mps'] * 1e3:.2f}" + (" (T)" if r["terminated"] else ""))
            lines.append(f"| {label[agent]} | " + " | ".join(cells) + f" | {own_text} |")
        if any(r["terminated"] for r in records if r["model"] == model and r["compass"]):
            lines.append("\n" + TERMINATED_NOTE)
        lines.append("")
        lines.append(f"Lateral drift (m) and RMS leg torque applied (N m, from the step record), {model}:\n")
        lines.append("| agent | " + " | ".join(f"{h} deg" for h in COMPASS_DEG) + " |")
        lines.append("|---" * (len(COMPASS_DEG) + 1) + "|")
        for agent in agents:
            rows = {r["heading_deg"]: r for r in records if r["model"] == model and r["agent"] == agent}
            cells = [f"{rows[float(h)]['lateral_drift_m']:+.3f} / {rows[float(h)]['effort_rms_torque_nm']:.3f}" for h in COMPASS_DEG]
            lines.append(f"| {label[agent]} | " + " | ".join(cells) + " |")
        lines.append("")
        lines.append(f"Effort over the compass headings (worst heading), {model}:\n")
        lines.append("| agent | peak torque (N m) | peak leg rate (rad/s) | time without ground contact | episodes ended |")
        lines.append("|---|---|---|---|---|")
        for agent in agents:
            rows = [r for r in records if r["model"] == model and r["agent"] == agent and r["compass"]]
            lines.append(
                f"| {label[agent]} | {max(r['peak_torque_nm'] for r in rows):.3f} | {max(r['peak_leg_rate_radps'] for r in rows):.1f} | "
                f"{max(r['liftoff_fraction'] for r in rows):.2%} | {sum(r['terminated'] for r in rows)} of {len(rows)} |"
            )
        lines.append("")
    for ratio in ratio_list:
        if "ppo_over_gait1_by_heading" not in ratio:
            continue
        lines.append(
            f"PPO speed / gait 1's speed along its own axis ({ratio['gait1_own_speed_mps'] * 1e3:.2f} mm/s), {ratio['model']}: "
            + ", ".join(f"{h} deg {v:.2f}" for h, v in ratio["ppo_over_gait1_by_heading"].items())
        )
        lines.append("")
        lines.append(f"PPO / gait on the gait's own direction, {ratio['model']}: " + ", ".join(
            f"{g} ({v['heading_deg']:.0f} deg) {v['ratio']:.2f}" for g, v in ratio["ppo_over_gait_on_its_own_direction"].items()))
        lines.append("")
    return "\n".join(lines)


def plot(runs, out_dir: Path, models, duration: float = 50.0):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    names = list(dict.fromkeys(name for name, _ in runs))
    for model in models:
        fig, axes = plt.subplots(1, 2, figsize=(12, 6))
        ax = axes[0]
        if ("ppo", model) in runs:
            headings, run = runs[("ppo", model)]
            for i, h in enumerate(headings[: len(COMPASS_DEG)]):
                ax.plot(run["xy"][:, i, 0], run["xy"][:, i, 1], lw=1.0, label=f"{h} deg")
                d = np.radians(h)
                ax.annotate("", xy=(0.8 * math.cos(d) * _reach(run), 0.8 * math.sin(d) * _reach(run)), xytext=(0, 0),
                            arrowprops={"arrowstyle": "->", "color": "0.7", "lw": 0.8})
            ax.set_title(f"PPO, commanded along the 8 compass headings ({model})")
            ax.legend(fontsize=7, ncol=2)
        ax.set_ylabel("y (m)")
        ax = axes[1]
        for name in names:
            if name == "ppo" or (name, model) not in runs:
                continue
            headings, run = runs[(name, model)]
            ax.plot(run["xy"][:, 0, 0], run["xy"][:, 0, 1], lw=1.0, label=name)
        for ax in axes:  # (after the paths: drawn over them)
            ax.plot(0, 0, "ko")
            ax.set_aspect("equal")
            ax.set_xlabel("x (m)")
            ax.grid(alpha=0.3)
        axes[1].set_title(f"Table II gaits, {seconds_text(duration)} ({model})")
        axes[1].legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(out_dir / f"paths_{model}.png", dpi=90)
        plt.close(fig)
    if ("ppo", "plane") in runs:
        headings, run = runs[("ppo", "plane")]
        fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
        window = run["times"] <= 5.0
        for ax, i in zip(axes, (0, 2)):
            for leg in range(2):
                ax.plot(run["times"][window], run["leg_angles"][window, i, leg], label=f"leg {leg + 1} angle")
            ax.set_ylabel("rad")
            ax.set_title(f"PPO leg angles, first 5 s, heading {headings[i]} deg (plane)")
            ax.legend(fontsize=8)
            ax.grid(alpha=0.3)
        axes[-1].set_xlabel("t (s)")
        fig.tight_layout()
        fig.savefig(out_dir / "ppo_leg_angles.png", dpi=90)
        plt.close(fig)


def _reach(run):
    finite = run["xy"][np.isfinite(run["xy"]).all(axis=-1)]
    return float(np.max(np.abs(finite))) if len(finite) else 1.0


def build_parser() -> argparse.ArgumentParser:
    """evaluate.py's command line."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--policy", type=Path, default=None,
                        help="PPO model zip, scored as 'ppo' on the model it was trained on (its run's env_kwargs.json) "
                             "(default: the shipped plane and pivot policies, each on its model)")
    parser.add_argument("--pivot-policy", type=Path, default=None,
                        help="PPO model zip scored as 'ppo' on the pivot model beside a plane --policy")
    parser.add_argument("--cross-model", action="store_true",
                        help="score every policy on every model of --models, not only on the one it was trained on "
                             "(--pivot-policy still takes the pivot)")
    parser.add_argument("--no-policy", action="store_true", help="score only the gaits")
    parser.add_argument("--physics", action="append", default=[], metavar="KEY=VALUE",
                        help="hold every agent on every model to this env keyword too, e.g. torque_limit=0.5 (motors, "
                             "the model checks, the step; repeatable; a policy's own must agree). Without a policy, "
                             "the way to score gaits under motor limits")
    parser.add_argument("--models", nargs="+", default=["plane", "pivot"], choices=["plane", "pivot"],
                        help="the dynamic models to evaluate on (default: both)")
    parser.add_argument("--duration", type=float, default=50.0, help="episode length in s (default 50, the paper's)")
    parser.add_argument("--seed", type=int, default=0,
                        help="seed of the envs' reset and of the --randomize robots (default 0; every episode "
                             "starts from the paper's start, without noise)")
    parser.add_argument("--json", type=Path, help="write the records (ratios, randomized robots) as JSON here")
    parser.add_argument("--markdown", type=Path, help="write the Markdown tables here too")
    parser.add_argument("--plots", type=Path, help="write path and leg-angle plots into this directory")
    parser.add_argument("--gaits", type=Path, action="append", default=[], metavar="FILE",
                        help="also score the gaits of a gait-search JSON file (rrrobot gait-search; repeatable; "
                             "a gait named like one already scored is named FILESTEM/NAME)")
    parser.add_argument("--turn-then-run", type=Path, action="append", default=[], metavar="FILE",
                        help="also score the scripted turn-then-run baseline of this file, as 'turn-then-run', on "
                             "the model its JSON names ('model', default plane): agents/searched/turn_then_run.json "
                             "(plane), agents/searched/turn_then_run_pivot.json (pivot); repeatable (a second file for a "
                             "model is scored as 'FILESTEM/turn-then-run')")
    parser.add_argument("--also-policy", action="append", default=[], metavar="NAME=FILE",
                        help="also score the PPO model zip FILE as agent NAME, on the model it was trained on "
                             "(its env_kwargs.json; default plane; --cross-model: every model); repeatable")
    parser.add_argument("--randomize", type=int, default=0, metavar="N",
                        help="also score every agent over N robots per compass heading drawn with the env's domain "
                             "randomization, e.g. python evaluate.py --gaits agents/searched/plane_own.json --randomize "
                             "16: the same N robots for every agent (seeded by --seed; open-loop gaits also along their "
                             "own direction), per heading the median and 10th-percentile (P10) speed and the share of "
                             "episodes that ended, and whether PPO's targets hold: P10 on its worst heading at least "
                             "0.8 x its nominal worst heading and at least every searched gait's P10 (the larger of "
                             "the gait's best compass heading's and its own direction's), at most 5 %% of its "
                             "episodes ended (default 0: off)")
    parser.add_argument("--randomize-ranges", default="default", choices=sorted(RANDOMIZATIONS),
                        help="the named set of ranges --randomize draws from (the env docstring's Domain "
                             "Randomization table; default: default)")
    parser.add_argument("--check-accuracy", action="store_true",
                        help="also run the policy of each model of --models (by default both: the shipped plane and "
                             "pivot policies) with a 10x finer integration step, the same control step, and compare "
                             "its speeds along the compass headings, from the paper's start and as the mean over "
                             "--accuracy-starts starts a heading (within 0.1 %%: the integrator's error is small)")
    parser.add_argument("--accuracy-starts", type=int, default=ACCURACY_STARTS, metavar="K",
                        help=f"--check-accuracy's starts per compass heading, drawn with the env's reset noise, the same "
                             f"at both steps (default {ACCURACY_STARTS}; 1: the paper's start only). A chaotic closed loop "
                             f"(the shipped pivot policy's) moves one run's speed by up to 1 %% with any change; the mean "
                             f"of many starts measures the step")
    return parser


def load_policy(parser, flag: str, path):
    """:func:`rrrobot_gym.agents.load_ppo_agent`, a missing file or a refusal as the command line's error."""
    if not Path(path).is_file():
        parser.error(f"{flag}: no model file at {path}")
    try:
        return load_ppo_agent(path)
    except (FileNotFoundError, ValueError) as exc:
        parser.error(f"{flag}: {exc}")


def trained_on(policy) -> str:
    """The model a loaded policy was trained on (its run's env_kwargs.json; plane if it names none)."""
    return policy.env_config.get("model", "plane")


def place_policy(parser, args, flag: str, name: str, policy, agents: dict, per_model: dict, required: bool):
    """Put ``policy`` as agent ``name`` on the model it was trained on (``per_model``), or with
    --cross-model on every model (``agents``). A policy given on the command line (``required``)
    whose model --models leaves out is the command line's error; a default one is left out."""
    model = trained_on(policy)
    if args.cross_model:
        agents[name] = policy
    elif model in args.models:
        per_model.setdefault(model, {})[name] = policy
    elif required:
        parser.error(f"{flag}: {policy.path} was trained on the {model} model, which --models leaves out: add it to "
                     "--models, or give --cross-model to score it on the others")


def place_pivot_policy(parser, args, policy, per_model: dict):
    """Put --pivot-policy ``policy`` as 'ppo' on the pivot model: refused if it was trained on another
    model (unless --cross-model) or if --policy was trained on the pivot (it is scored there)."""
    flag = "--pivot-policy"
    if trained_on(policy) != "pivot" and not args.cross_model:
        parser.error(f"{flag}: {policy.path} was trained on the {trained_on(policy)} model, not the pivot: give "
                     "--cross-model to score it on the pivot")
    if "ppo" in per_model.get("pivot", {}):
        parser.error(f"--policy {per_model['pivot']['ppo'].path} was trained on the pivot model, where {flag} is "
                     "scored: give one of them")
    if "pivot" in args.models:
        per_model.setdefault("pivot", {})["ppo"] = policy
    elif args.pivot_policy is not None:
        parser.error(f"{flag}: --models leaves out the pivot model")


def main(argv=None, default_policy=None, default_pivot_policy=None):
    """Run evaluate.py's command line ``argv`` (default: sys.argv). ``default_policy`` is the model
    zip scored without ``--policy`` (None: ``--policy`` or ``--no-policy`` is needed), and
    ``default_pivot_policy`` the one scored on the pivot model with it."""
    parser = build_parser()
    default_policy = None if default_policy is None else Path(default_policy)
    default_pivot_policy = None if default_pivot_policy is None else Path(default_pivot_policy)
    args = parser.parse_args(argv)
    if not (math.isfinite(args.duration) and args.duration > 0):
        parser.error(f"--duration must be a positive number of seconds, got {args.duration}")
    for flag, path in (("--json", args.json), ("--markdown", args.markdown)):  # before the runs, not after them
        if path is not None:
            try:
                check_output_path(flag, path)
            except UsageError as exc:
                parser.error(str(exc))
    if args.plots is not None and args.plots.exists() and not args.plots.is_dir():
        parser.error(f"--plots: {args.plots} is a file, not a directory")
    if args.seed < 0:
        parser.error(f"--seed must be >= 0, got {args.seed}")
    if args.accuracy_starts < 1:
        parser.error(f"--accuracy-starts must be a number of starts >= 1, got {args.accuracy_starts}")
    if args.randomize < 0:
        parser.error(f"--randomize must be a number of robots >= 0, got {args.randomize}")
    if len(set(args.models)) < len(args.models):  # (each was evaluated, and reported, as often as named)
        parser.error(f"--models names a model twice: {' '.join(args.models)}")
    try:
        physics = parse_physics(args.physics)
    except ValueError as exc:
        parser.error(str(exc))
    agents, per_model = {}, {}
    if args.no_policy:
        given = [flag for flag, value in (("--policy", args.policy), ("--pivot-policy", args.pivot_policy)) if value]
        if given:
            parser.error(f"--no-policy scores only the gaits: leave out {' and '.join(given)}")
    else:
        policy = args.policy if args.policy is not None else default_policy
        if policy is None:
            parser.error("--policy: give a PPO model zip (this installation has no default), or --no-policy")
        given = args.policy is not None
        loaded = load_policy(parser, "--policy", policy)
        place_policy(parser, args, "--policy", "ppo", loaded, agents, per_model, required=given)
        pivot_policy = args.pivot_policy
        if (pivot_policy is None and not given and default_pivot_policy is not None
                and default_pivot_policy.is_file()):
            pivot_policy = default_pivot_policy
        if pivot_policy is not None:
            place_pivot_policy(parser, args, load_policy(parser, "--pivot-policy", pivot_policy), per_model)
        bare = [model for model in args.models if "ppo" not in agents_on(model, agents, per_model)]
        if given and bare:  # (a user who asked for a policy is told where it was not scored)
            print(f"--policy: {loaded.path} was trained on the {trained_on(loaded)} model: not scored on "
                  f"{' and '.join(bare)} (--cross-model scores it there)", file=sys.stderr)
    for name in GAIT_AGENT_NAMES:
        agents[name] = gait_agent(name)
    for path in args.gaits:
        try:
            searched = load_gait_agents(path)
        except ValueError as exc:
            parser.error(f"--gaits: {exc}")
        if set(searched) & set(agents):
            # Two searches of one model and objective name their gaits alike: tell them apart by file.
            searched = {f"{path.stem}/{name}": agent for name, agent in searched.items()}
            for name, agent in searched.items():
                agent.name = name
        clash = sorted(set(searched) & set(agents))
        if clash:
            parser.error(f"--gaits {path}: agent names already taken: {', '.join(clash)}")
        agents.update(searched)
    baseline_files = set()
    for path in args.turn_then_run:
        try:
            baseline = load_turn_then_run_agent(path)
        except ValueError as exc:
            parser.error(f"--turn-then-run: {exc}")
        if path.resolve() in baseline_files:
            parser.error(f"--turn-then-run {path}: given twice")
        baseline_files.add(path.resolve())
        on_model = per_model.setdefault(baseline.model, {})
        if baseline.name in on_model:  # a second baseline for this model: tell them apart by file
            baseline.name = f"{path.stem}/{baseline.name}"
            if baseline.name in on_model:
                parser.error(f"--turn-then-run {path}: agent name {baseline.name!r} already taken")
        on_model[baseline.name] = baseline
    for spec in args.also_policy:
        name, sep, path = spec.partition("=")
        name = name.strip()
        if not sep or not name or not path:
            parser.error(f"--also-policy: expected NAME=FILE, got {spec!r}")
        taken = set(agents) | {"ppo"} | {n for on_model in per_model.values() for n in on_model}
        if name in taken:
            parser.error(f"--also-policy {spec}: agent name {name!r} already taken")
        flag = f"--also-policy {spec}"
        place_policy(parser, args, flag, name, load_policy(parser, flag, path), agents, per_model, required=True)
    try:
        records, runs = evaluate(agents, args.models, args.duration, args.seed, per_model, physics)
    except ValueError as exc:
        parser.error(str(exc))
    ratio_list = [ratios(records, model) for model in args.models]
    simulated = float(next(iter(runs.values()))[1]["times"][-1])  # (whole control steps: what was scored)
    text = markdown(records, ratio_list, simulated)
    accuracy = {}
    for model in args.models if args.check_accuracy else ():
        policy = agents_on(model, agents, per_model).get("ppo")
        if policy is None:
            continue
        checked = accuracy[model] = accuracy_check(policy, model, args.duration, args.seed, starts=args.accuracy_starts)
        text += "\n" + accuracy_markdown(model, checked)
    randomized = []
    if args.randomize:
        own = {}
        for r in records:
            for name in r["own_direction_of"]:
                own.setdefault(r["model"], {})[name] = r["heading_deg"]
        try:
            randomized, _ = evaluate_randomized(agents, args.models, args.randomize, args.duration, args.seed, per_model,
                                                physics, args.randomize_ranges, own)  # fmt: skip
        except ValueError as exc:
            parser.error(str(exc))
        text += "\n" + randomized_markdown(randomized, records)
        for section in randomized:
            section["targets"] = randomized_targets(section, records)
    print(text)
    if args.markdown:
        args.markdown.write_text(text + "\n")
    if args.json:
        payload = {"records": records, "ratios": ratio_list, "accuracy_check": accuracy, "randomized": randomized,
                   "command": " ".join(sys.argv)}
        args.json.write_text(json.dumps(payload, indent=1))
    if args.plots:
        plot(runs, args.plots, args.models, simulated)
    return records


if __name__ == "__main__":
    main()
