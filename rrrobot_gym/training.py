"""Train a policy for directional locomotion on RRRobot-v0 (Stable-Baselines3, CPU): PPO by default.

Reads top to bottom: arguments, environments, model, callbacks, learn, save.

    python train.py                       # goal-conditioned: any commanded heading
    python train.py --direction-deg 45    # a specialist for one heading (degrees from +X towards +Y)
    python train.py --algo sac            # SAC (or td3, tqc), with its defaults from rrrobot_gym.hyperparams
    python train.py --resume runs/RUN/checkpoints/ppo_500000_steps.zip

Runs go to ``runs/RRRobot-v0__<exp_name>__<seed>__<unix time>/``: TensorBoard logs,
``evaluations.npz``, ``best_model.zip`` (the best evaluation by ``--select-by``, every
``--eval-freq`` steps; a run too short for any is given a copy of the final model),
checkpoints, ``final_model.zip`` (also on Ctrl-C), each model's VecNormalize statistics beside
it, ``env_kwargs.json`` (every env keyword, from which ``rrrobot_gym.agents.load_ppo_agent``
rebuilds the env), ``args.json`` and ``command.txt``. The models of a mirrored (the default) or
residual run name a policy class SB3's ``load`` refuses, naming ``load_ppo_agent``, the loader
that runs them right (:mod:`rrrobot_gym.agents.ppo`). ``--total-timesteps`` is rounded up to
whole rollouts of ``num_envs x n_steps`` (off-policy: ``num_envs x train_freq``). Loading a model
unpickles it: trusted files only.

``evaluations.npz`` holds SB3's ``timesteps``, ``results`` (each evaluation's returns) and
``ep_lengths``, plus ``wall_time_s`` (s from ``main()``'s start to each evaluation's end) and
``heading_speeds_mm_s`` (evaluations x headings: speed along each heading in
``speed_headings_deg``, scored by :func:`rrrobot_gym.evaluation.score`: the nominal robot from the
paper's start, over ``--episode-steps``; a mirrored policy's headings towards -Y are its +Y
headings' mirror images, the same episodes) and ``train_episode_steps`` (the mean length, in
control steps, of the last 100 training episodes that ended before each evaluation; NaN if none).

``--seeds K`` runs K such runs instead (seeds ``--seed`` ... ``--seed`` + K - 1) into one folder
and summarises them (:mod:`rrrobot_gym.seeds`); with several algorithms, ``--algo ppo,sac,td3,tqc``,
K runs of each, side by side (:mod:`rrrobot_gym.algorithms`).

Every algorithm runs the same env, evaluations and selection: the training robots with the slip
margin, the mirror for a goal-conditioned policy, the evaluations on the nominal robot and
best_model.zip by the worst heading. Each takes the settings ``rrrobot_gym.hyperparams.SETTINGS``
gives it (another algorithm's setting is refused), with its defaults from that module.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import random
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .agents.mirror import MIRROR_FILE, MirroredPolicy, has_mirror, is_mirrored, make_mirrored_vec_env, save_mirror
from .agents.ppo import load_sb3_model, normalization_path, policy_class_to_save, saved_policy_class
from .agents.residual import FEATURES, RESIDUAL_FILE, check_scale, load_base, make_residual_vec_env, run_directory, save_residual
from .agents.turn_then_run import load_turn_then_run_agent
from .cli import env_keyword
from .envs.task import SERVO, config_to_json, make_task_config
from . import hyperparams as hp
from .simulation import BACKENDS

ENV_ID = "RRRobot-v0"


def _option(default, help_text):
    """An :class:`Args` field: a command-line option with its default and its --help text."""
    return field(default=default, metadata={"help": help_text})


@dataclass
class Args:
    exp_name: str | None = _option(None, "name of this experiment (part of the run name); default: the --algo")
    algo: str = _option(
        "ppo", f"the learning algorithm: {', '.join(hp.ALGORITHMS)} (rrrobot_gym.hyperparams.ALGORITHMS); with --seeds, "
        "several joined by commas run side by side (rrrobot_gym/algorithms.py)")
    seed: int = _option(1, "seed of every RNG: python, numpy, torch, the envs")
    total_timesteps: int = _option(
        hp.TOTAL_TIMESTEPS, "env steps (control steps) to train for, rounded up to whole rollouts of num_envs x n_steps")
    model: str = _option("plane", "dynamic model: plane or pivot")
    direction_deg: float | None = _option(
        None, "commanded heading in degrees (from +X towards +Y) for a specialist; default: any heading")
    num_envs: int = _option(hp.NUM_ENVS, "robots simulated together in the batched env")
    n_steps: int = _option(hp.N_STEPS, "PPO rollout length per env")
    batch_size: int = _option(hp.MAX_BATCH_SIZE, "minibatch size")
    n_epochs: int = _option(hp.N_EPOCHS, "PPO epochs per rollout")
    learning_rate: float = _option(hp.LEARNING_RATE, "Adam learning rate (at the start, with --learning-rate-final)")
    learning_rate_final: float | None = _option(
        hp.LEARNING_RATE_FINAL,
        "Adam learning rate at the run's end, reached linearly from --learning-rate; none: constant")
    gamma: float = _option(hp.GAMMA, "discount factor (per 0.05 s control step)")
    gae_lambda: float = _option(hp.GAE_LAMBDA, "GAE lambda")
    clip_range: float = _option(hp.CLIP_RANGE, "PPO clip range")
    ent_coef: float | str = _option(
        hp.ENT_COEF, "entropy bonus coefficient; SAC and TQC: also auto (learned) or auto_X (learned from X)")
    log_std_init: float = _option(
        hp.LOG_STD_INIT, "initial log std of the Gaussian policy (SAC, TQC: of gSDE's noise, with --use-sde)")
    buffer_size: int = _option(hp.BUFFER_SIZE, "off-policy (SAC, TD3, TQC): transitions the replay buffer holds")
    learning_starts: int = _option(
        hp.LEARNING_STARTS, "off-policy: env steps of uniformly random actions (gSDE's with --use-sde) before the first "
        "update")
    train_freq: int = _option(hp.TRAIN_FREQ, "off-policy: batched env steps (each --num-envs transitions) between updates")
    gradient_steps: int = _option(hp.GRADIENT_STEPS, "off-policy: gradient steps an update (-1: one a transition)")
    tau: float = _option(hp.TAU, "off-policy: soft-update rate of the target networks")
    action_noise: float | None = _option(
        hp.ACTION_NOISE, "TD3: std of its Gaussian exploration noise (action units); none: no noise")
    use_sde: bool = _option(hp.USE_SDE, "SAC, TQC: explore with gSDE, state-dependent noise of scale --log-std-init")
    net_arch: str = _option(",".join(map(str, hp.NET_ARCH)), "hidden layer sizes of policy and value nets")
    activation: str = _option(hp.ACTIVATION, f"their activation: {', '.join(hp.ACTIVATIONS)}")
    healthy_reward: float = _option(1.0, "env reward per step that stays inside the model (survival first, then speed)")
    clock_frequency: float | None = _option(
        None, "rad/s of a gait clock for the policy to observe (e.g. 8, the paper's); default none")
    torque_limit: float | None = _option(
        SERVO.torque_limit, "N m, the leg motors' stall torque (the env's torque_limit); none: unlimited")
    leg_rate_limit: float | None = _option(
        SERVO.leg_rate_limit, "rad/s, the leg motors' no-load speed (the env's leg_rate_limit, needs --torque-limit); "
        "none: unlimited")
    leg_accel_limit: float | None = _option(
        SERVO.leg_accel_limit, "rad/s^2, the servo's motion profile (the env's leg_accel_limit); none: no profile")
    randomize: str | None = _option(
        "default", "domain randomization of the training robots (the env's randomize: a new robot each episode; "
        "evaluations run the nominal robot); none: off")
    slip_margin: float = _option(
        hp.SLIP_MARGIN, "m/s: the training robots leave the model at the env's max_slip_velocity less this, a margin "
        "from the hop (plane model; the evaluations, env_kwargs.json and evaluate.py keep the robot's envelope); 0: none")
    backend: str = _option(
        "auto", "simulator backend (the env's backend): auto (numba where installed), numba or numpy")
    env: list[str] | None = _option(
        None, "another env keyword as KEY=VALUE, e.g. contact_quadrature=trapezoid (repeatable, as gait-search's; not "
        "those with options of their own; saved in env_kwargs.json, so evaluate.py holds the agents compared to them)")
    episode_steps: int = _option(1000, "control steps per training episode (1000 = 50 s)")
    eval_freq: int = _option(250_000, "evaluate every this many env steps")
    max_minutes: float | None = _option(
        None, "end training after this many minutes of wall time (from the start), saving as at its end; none: no "
        "limit (the learning rate still falls over --total-timesteps)")
    stop_at_speed: float | None = _option(
        None, "mm/s: end training at the first evaluation whose worst heading reaches this speed (a sweep's trials "
        "stop at the bar); none: train on")
    checkpoint_freq: int = _option(1_000_000, "save a checkpoint every this many env steps")
    resume: str | None = _option(None, "a model zip to continue from (its vecnormalize.pkl beside it)")
    runs_dir: str = _option("runs", "where runs are written")
    progress_bar: bool = _option(True, "show a progress bar (needs tqdm and rich)")
    residual_on: str | None = _option(
        None, "a turn-then-run JSON (agents/searched/turn_then_run.json): learn a residual on that agent's actions")
    residual_scale: float = _option(0.05, "with --residual-on: the largest change of the base's action (action units)")
    mirror: bool | None = _option(
        None, "run headings towards -Y as mirror images of those towards +Y (rrrobot_gym/agents/mirror.py): the policy "
        "learns half the compass; default: on for a goal-conditioned policy of a robot with that symmetry, off for a "
        "--direction-deg specialist or a --residual-on policy, and as the --resume run was")
    select_by: str = _option(
        "worst", "which evaluation picks best_model.zip: mean (the headings' mean return) or worst (the worst "
        "heading's return)")
    torch_threads: int = _option(
        2, "torch CPU threads for the updates; the model's construction, the rollouts and the evaluations run on one "
        "(the env steps between updates, so its core is free then)")
    seeds: int | None = _option(
        None, "run this many runs (seeds --seed, --seed + 1, ...; every other option as given) into one folder and "
        "write summary.json and summary.md there (rrrobot_gym/seeds.py); each run on --torch-threads 1 unless given")
    bar: float | None = _option(
        None, "with --seeds: mm/s, the worst heading's speed a run must reach (its time to the bar)")
    bar_from: str | None = _option(
        None, "with --seeds, instead of --bar: a gait-search JSON (rrrobot gait-search) searched under this run's "
        "servo; the bar is its best gait's speed along its own direction from the paper's start")
    ray_address: str | None = _option(
        None, "with --seeds: run each run as a Ray task on this cluster (host:port, or local), its files gathered here")
    bootstrap_reps: int = _option(50_000, "with --seeds: bootstrap replications of the IQM's confidence interval")
    summary_dir: str | None = _option(
        None, "with --seeds: also write the summary (summary.json, summary.md; with several --algo the learning curves, "
        "learning_curves.png) into this folder, e.g. docs/training/algorithms")
    sweep: int | None = _option(
        None, "run this many trials of an optuna sweep of the PPO settings for the wall time to --bar (or --bar-from), "
        "each ending there or after --max-minutes (rrrobot_gym/sweep.py); summary.json and summary.md in its folder")


SEEDS_OPTIONS = ("seeds", "bar", "bar_from", "ray_address", "bootstrap_reps", "summary_dir")
"""The options of ``--seeds`` (:mod:`rrrobot_gym.seeds`), which its runs are not given."""

RESUME_SETTINGS = ("learning_rate", "learning_rate_final", "n_steps", "batch_size", "n_epochs", "gae_lambda", "clip_range", "ent_coef")
"""PPO settings a resumed run takes from the command line when given there (else the model's own)."""
FIXED_ON_RESUME = ("net_arch", "activation", "log_std_init", "gamma")
"""PPO settings a resumed model keeps: the networks' shape and activation, the initial noise, and
the discount its value function and return normalisation were trained with."""


def _parser(given_only=False):
    """The command line of :class:`Args`; with ``given_only`` the namespace holds only the flags given."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     argument_default=argparse.SUPPRESS if given_only else None)
    for f in dataclasses.fields(Args):
        flag = "--" + f.name.replace("_", "-")
        per_model = "".join(f"; --model {model}: {values[f.name]}" for model, values in hp.MODEL_DEFAULTS.items()
                            if f.name in values)
        per_algo = "".join(f"; --algo {algo}: {values[f.name]}" for algo, values in hp.ALGO_DEFAULTS.items()
                           if f.name in values)
        help_text = f"{f.metadata['help']} (default: {f.default}{per_model}{per_algo})"
        default = {} if given_only else {"default": f.default}
        if f.type in ("bool", "bool | None"):
            parser.add_argument(flag, action=argparse.BooleanOptionalAction, help=help_text, **default)
        elif f.type == "list[str] | None":  # repeatable
            parser.add_argument(flag, action="append", metavar="KEY=VALUE", help=help_text, **default)
        else:  # "float", "float | None", ...: the field's annotation names the type
            kind = {"int": int, "float": float, "str": str, "float | str": _number_or_word}[f.type.removesuffix(" | None")]
            if f.type.endswith(" | None"):
                kind = _or_none(kind)
            parser.add_argument(flag, type=kind, help=help_text, **default)
    return parser


def _or_none(kind):
    """An argparse type that also takes "none" (an optional setting left unset)."""

    def parse(text):
        return None if text.strip().lower() == "none" else kind(text)

    parse.__name__ = kind.__name__  # (argparse names the type in its error messages)
    return parse


def _number_or_word(text):
    """An argparse type: a number as a float, else the text (``--ent-coef auto``; checked later)."""
    try:
        return float(text)
    except ValueError:
        return text.strip()


def given_flags(argv=None) -> set:
    """The :class:`Args` fields set on the command line ``argv`` (default: sys.argv)."""
    return set(vars(_parser(given_only=True).parse_args(argv)))


def resume_overrides(args: Args, argv=None) -> dict:
    """The :data:`RESUME_SETTINGS` given on the command line: what a resumed model changes (the
    learning rate as SB3's setting: a number, or with --learning-rate-final its schedule)."""
    given = given_flags(argv)
    overrides = {name: getattr(args, name) for name in RESUME_SETTINGS if name in given}
    if "learning_rate_final" in overrides or "learning_rate" in overrides:
        overrides.pop("learning_rate_final", None)
        overrides["learning_rate"] = learning_rate(args)
    return overrides


def learning_rate(args: Args):
    """SB3's learning_rate: --learning-rate, falling linearly to --learning-rate-final if given."""
    return hp.learning_rate_schedule(args.learning_rate, args.learning_rate_final)


ALGORITHM_SETTINGS = tuple(dict.fromkeys(name for names in hp.SETTINGS.values() for name in names))
"""The options that are some algorithm's settings (rrrobot_gym.hyperparams.SETTINGS)."""


def parse_args(argv=None) -> Args:
    parser = _parser()
    args = Args(**vars(parser.parse_args(argv)))
    if args.model not in hp.MODEL_DEFAULTS:
        parser.error(f"--model must be one of {', '.join(hp.MODEL_DEFAULTS)}, got {args.model!r}")
    given = given_flags(argv)
    algos = args.algo.split(",")
    for algo in algos:
        if algo not in hp.ALGORITHMS:
            parser.error(f"--algo must be one of {', '.join(hp.ALGORITHMS)} (or several joined by commas, with "
                         f"--seeds), got {algo!r}")
    if len(algos) > 1:
        return _side_by_side_args(parser, args, algos, argv)
    if args.exp_name is None:
        args.exp_name = args.algo
    defaults = {**hp.ALGO_DEFAULTS[args.algo], **(hp.MODEL_DEFAULTS[args.model] if args.algo == "ppo" else {})}
    for name, value in defaults.items():  # (the algorithm's and the model's own defaults, where not given)
        if name not in given:
            setattr(args, name, value)
    _check_algorithm_settings(parser, args, given)
    if args.select_by not in ("mean", "worst"):
        parser.error(f"--select-by must be mean or worst, got {args.select_by!r}")
    resumed_mirrored = args.resume is not None and resumes_mirrored(args.resume)
    try:
        symmetric = has_mirror(make_task_config(**env_kwargs(args)))
    except (TypeError, ValueError) as error:
        parser.error(f"--env: {error}")
    if args.mirror is None:  # auto: a goal-conditioned policy of a symmetric robot, or as the resumed run was
        if args.direction_deg is not None or args.residual_on is not None:
            args.mirror = False
        else:
            args.mirror = resumed_mirrored if args.resume is not None else symmetric
    if args.mirror and not symmetric:
        parser.error("--mirror needs a robot with mirror symmetry in its x-z plane (legs in mirrored pairs, "
                     "rrrobot_gym.dynamics.mirror_legs); this one has none")
    if args.mirror and args.residual_on is not None:
        parser.error("--mirror and --residual-on cannot be combined (the base agent is not mirrored)")
    if args.mirror and args.direction_deg is not None:
        parser.error("--mirror is for the goal-conditioned policy (any heading), not a --direction-deg specialist")
    if args.backend not in BACKENDS:
        parser.error(f"--backend must be one of {', '.join(BACKENDS)}, got {args.backend!r}")
    if args.direction_deg is not None and not math.isfinite(args.direction_deg):
        parser.error("--direction-deg must be a finite number of degrees")
    if args.clock_frequency is not None and not (math.isfinite(args.clock_frequency) and args.clock_frequency > 0):
        parser.error("--clock-frequency must be a positive number of rad/s")
    if args.max_minutes is not None and not (math.isfinite(args.max_minutes) and args.max_minutes > 0):
        parser.error(f"--max-minutes must be a positive number, got {args.max_minutes}")
    if args.stop_at_speed is not None and not math.isfinite(args.stop_at_speed):
        parser.error(f"--stop-at-speed must be a finite speed in mm/s, got {args.stop_at_speed}")
    for name in ("learning_rate", "learning_rate_final"):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and value >= 0):
            parser.error(f"--{name.replace('_', '-')} must be a number >= 0, got {value}")
    for name in ("torque_limit", "leg_rate_limit", "leg_accel_limit"):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and value > 0):
            parser.error(f"--{name.replace('_', '-')} must be a positive number, got {value}")
    if args.leg_rate_limit is not None and args.torque_limit is None:
        parser.error("--leg-rate-limit needs --torque-limit (a motor's speed limit is where its torque reaches zero)")
    try:  # the env's own checks, on every keyword together (a step past the servo's stability limit, ...)
        config = make_task_config(**env_kwargs(args))
    except (TypeError, ValueError) as exc:
        parser.error(f"--env {' '.join(args.env)}: {exc}" if args.env else str(exc))
    if not (math.isfinite(args.slip_margin) and 0 <= args.slip_margin < config.max_slip_velocity):
        parser.error(f"--slip-margin must be >= 0 and under the env's max_slip_velocity ({config.max_slip_velocity} "
                     f"m/s), got {args.slip_margin}")
    for name in ("total_timesteps", "num_envs", "n_steps", "batch_size", "n_epochs", "episode_steps", "eval_freq",
                 "checkpoint_freq", "torch_threads"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be a positive integer, got {getattr(args, name)}")
    _check_ppo_settings(parser, args)
    try:
        check_scale(args.residual_scale)
    except ValueError as exc:
        parser.error(f"--residual-scale: {exc}")
    if args.residual_on is not None:
        try:
            base = load_turn_then_run_agent(args.residual_on)
        except ValueError as exc:
            parser.error(f"--residual-on: {exc}")
        if base.model != args.model:
            parser.error(f"--residual-on: {args.residual_on} was made for the {base.model} model, not {args.model}")
    if args.resume is not None:
        if not Path(args.resume).is_file():
            parser.error(f"--resume: no model file at {args.resume}")
        fixed = sorted(given & set(FIXED_ON_RESUME))
        if fixed:
            parser.error(f"--resume keeps the model's {', '.join('--' + n.replace('_', '-') for n in fixed)}: "
                         "leave it out")
        _check_resumed_residual(parser, args)
        if resumed_mirrored and not args.mirror:
            parser.error(f"--resume: {args.resume} was trained mirrored (its run's {MIRROR_FILE}, or the policy class "
                         "its zip names): give --mirror")
        _check_resumed_model(parser, args)
    if args.sweep is not None:
        if args.seeds is not None:
            parser.error("--sweep and --seeds cannot be combined (a sweep's trials run on --seed)")
        if args.sweep < 1:
            parser.error(f"--sweep must be a positive integer, got {args.sweep}")
        if args.max_minutes is None:
            parser.error("--sweep needs --max-minutes: each trial's wall-time budget")
    if args.seeds is None and args.sweep is None:
        seeds_options = sorted(given & set(SEEDS_OPTIONS))
        if seeds_options:
            parser.error(f"--{seeds_options[0].replace('_', '-')} is an option of --seeds and --sweep")
    else:
        from .seeds import check_seeds_args

        try:
            check_seeds_args(args, env_config(args))
        except ValueError as exc:
            parser.error(str(exc))
    return args


def resumes_mirrored(model_path) -> bool:
    """Whether the --resume model was trained mirrored: its run holds mirror.json, or its zip names
    :class:`~rrrobot_gym.agents.mirror.MirroredPolicy` (a file that is no model zip: no; the resume's
    checks name it)."""
    if is_mirrored(run_directory(model_path)):
        return True
    try:
        return saved_policy_class(model_path) is MirroredPolicy
    except (OSError, ValueError):
        return False


def _side_by_side_args(parser, args: Args, algos: list, argv) -> Args:
    """``--algo A,B,...`` (rrrobot_gym/algorithms.py): needs --seeds, and each algorithm's run's
    command line is checked as that run will check it, before any run starts."""
    if len(set(algos)) < len(algos):
        parser.error(f"--algo names an algorithm twice: {args.algo}")
    if args.seeds is None:
        parser.error(f"--algo {args.algo}: several algorithms run side by side with --seeds (K runs of each)")
    if args.max_minutes is None:
        parser.error(f"--algo {args.algo} needs --max-minutes: the wall-clock budget the algorithms share")
    for option in ("resume", "sweep"):
        if getattr(args, option) is not None:
            parser.error(f"--{option} takes one --algo, not {args.algo}")
    if args.exp_name is None:
        args.exp_name = "-".join(algos)
    argv = sys.argv[1:] if argv is None else list(argv)
    for algo in algos:
        parse_args(seed_argv(argv, args.seed, {"algo": algo}))
    from .seeds import check_seeds_args

    try:
        check_seeds_args(args, env_config(args))
    except ValueError as exc:
        parser.error(str(exc))
    return args


def _is_auto(text: str) -> bool:
    """SAC's learned entropy coefficient: "auto", or "auto_X", learned from X > 0."""
    try:
        return text == "auto" or (text.startswith("auto_") and float(text.removeprefix("auto_")) > 0)
    except ValueError:
        return False


def _check_algorithm_settings(parser, args: Args, given: set) -> None:
    """The settings of --algo only, and the off-policy ones in range."""
    others = [name for name in ALGORITHM_SETTINGS if name in given and name not in hp.SETTINGS[args.algo]]
    if others:
        parser.error(f"--{others[0].replace('_', '-')} is not a setting of --algo {args.algo} (its settings: "
                     f"{', '.join('--' + n.replace('_', '-') for n in hp.SETTINGS[args.algo])})")
    learned = args.algo in ("sac", "tqc")  # (their entropy coefficient may be learned)
    if isinstance(args.ent_coef, str) and not (learned and _is_auto(args.ent_coef)):
        parser.error(f"--ent-coef must be a number >= 0{' or auto (auto_X: learned from X > 0)' if learned else ''}, "
                     f"got {args.ent_coef!r}")
    for name, low in (("buffer_size", 1), ("learning_starts", 0), ("train_freq", 1)):
        if getattr(args, name) < low:
            parser.error(f"--{name.replace('_', '-')} must be an integer >= {low}, got {getattr(args, name)}")
    if args.gradient_steps < 1 and args.gradient_steps != -1:
        parser.error(f"--gradient-steps must be a positive integer or -1 (one a transition), got {args.gradient_steps}")
    if not (math.isfinite(args.tau) and 0 < args.tau <= 1):
        parser.error(f"--tau must be in (0, 1], got {args.tau}")
    if args.action_noise is not None and not (math.isfinite(args.action_noise) and args.action_noise >= 0):
        parser.error(f"--action-noise must be a number >= 0 (action units) or none, got {args.action_noise}")
    if args.algo in ("sac", "tqc") and "log_std_init" in given and not args.use_sde:
        parser.error(f"--log-std-init is the scale of gSDE's noise for --algo {args.algo}: give --use-sde too")
    if args.algo != "ppo" and args.resume is not None:
        parser.error(f"--resume continues PPO runs only: an --algo {args.algo} run does not save its replay buffer")
    if args.algo != "ppo" and args.sweep is not None:
        parser.error(f"--sweep tunes PPO's settings: it takes --algo ppo, not {args.algo}")


LOG_STD_INIT_RANGE = (-20.0, 5.0)
"""--log-std-init's range: e^-20 is no noise, e^5 = 148 action units spans [-1, 1] many times."""


def _check_ppo_settings(parser, args):
    """The PPO settings SB3 and torch would take and fail on later, or train on without meaning."""
    for name in ("gamma", "gae_lambda"):
        value = getattr(args, name)
        if not 0.0 <= value <= 1.0:
            parser.error(f"--{name.replace('_', '-')} must be in [0, 1], got {value}")
    if not (math.isfinite(args.clip_range) and args.clip_range > 0):
        parser.error(f"--clip-range must be a positive number, got {args.clip_range}")
    if not isinstance(args.ent_coef, str) and not (math.isfinite(args.ent_coef) and args.ent_coef >= 0):
        parser.error(f"--ent-coef must be a number >= 0, got {args.ent_coef}")
    low, high = LOG_STD_INIT_RANGE
    if not low <= args.log_std_init <= high:
        parser.error(f"--log-std-init must be in [{low:g}, {high:g}], got {args.log_std_init}")
    try:
        hp.check_activation(args.activation)
    except ValueError as exc:
        parser.error(f"--{exc}")
    sizes = args.net_arch.split(",")
    if not all(size.strip().isascii() and size.strip().isdigit() and int(size) > 0 for size in sizes):
        parser.error(f"--net-arch must be positive layer sizes joined by commas, e.g. 128,128, got {args.net_arch!r}")
    if args.batch_size < 2:  # (SB3 normalises each minibatch's advantages)
        parser.error(f"--batch-size must be at least 2, got {args.batch_size}")
    if not 0 <= args.seed < 2**32 - 100_000:  # (numpy's seeds end at 2**32; the envs' are seed + 10,000 + i)
        parser.error(f"--seed must be in [0, 2**32 - 100000), got {args.seed}")
    if Path(args.runs_dir).exists() and not Path(args.runs_dir).is_dir():
        parser.error(f"--runs-dir: {args.runs_dir} is a file, not a directory")


def _check_resumed_model(parser, args):
    """The --resume zip is an SB3 model with its normalisation statistics beside it, observing as
    many numbers as this run's env gives."""
    import zipfile

    data = None
    if zipfile.is_zipfile(args.resume):
        with zipfile.ZipFile(args.resume) as archive:
            data = archive.read("data") if "data" in archive.namelist() else None
    if data is None:
        parser.error(f"--resume: {args.resume} is not a Stable-Baselines3 model zip")
    stats = normalization_path(args.resume)
    if not stats.exists():
        parser.error(f"--resume needs the normalisation statistics {stats}")
    try:
        shape = json.loads(data)["observation_space"]["_shape"]
    except (KeyError, TypeError, ValueError):
        return  # (no readable shape: SB3 checks it when it loads)
    # (a residual policy, which _check_resumed_residual has matched to --residual-on, observes its base too)
    size = make_task_config(**env_kwargs(args)).observation_size + (len(FEATURES) if args.residual_on is not None else 0)
    if list(shape) != [size]:
        parser.error(f"--resume: the model observes {shape[0] if len(shape) == 1 else shape} numbers, this run's env "
                     f"{size}: an option that changes the observation (--clock-frequency, "
                     "--env exclude_current_positions_from_observation=...) differs from the model's run "
                     "(its env_kwargs.json)")


def _check_resumed_residual(parser, args):
    """A residual policy (residual.json in its run directory) resumes only as one, on the same
    scale; a plain one never does."""
    run_dir = run_directory(args.resume)
    try:
        saved = load_base(run_dir)
    except ValueError as exc:
        parser.error(f"--resume: {exc}")
    if saved is None:
        if args.residual_on is not None:
            parser.error(f"--residual-on: the --resume model {args.resume} is not a residual policy "
                         f"(no {run_dir / RESIDUAL_FILE})")
        return
    scale = saved[1]
    if args.residual_on is None:
        parser.error(f"--resume: {args.resume} is a residual policy ({run_dir / RESIDUAL_FILE}): give --residual-on "
                     f"(its base is copied in {run_dir / 'residual_base'}) and --residual-scale {scale} as it was trained")
    if args.residual_scale != scale:
        parser.error(f"--residual-scale: the --resume model was trained with scale {scale}, not {args.residual_scale}")


ENV_OPTIONS = {"model": "--model", "target_direction": "--direction-deg", "healthy_reward": "--healthy-reward",
               "clock_frequency": "--clock-frequency", "torque_limit": "--torque-limit",
               "leg_rate_limit": "--leg-rate-limit", "leg_accel_limit": "--leg-accel-limit", "randomize": "--randomize",
               "backend": "--backend"}  # fmt: skip
"""The env keywords train.py sets by options of their own (``--env`` refuses them)."""


def extra_env_kwargs(specs) -> dict:
    """The ``--env`` KEY=VALUE specs as {key: value} (:func:`rrrobot_gym.cli.env_keyword`). Raises
    ValueError naming a bad or repeated spec, or a keyword with an option of its own."""
    chosen = {}
    for spec in specs or ():
        name, value = env_keyword(spec, ENV_OPTIONS)
        if name in chosen:
            raise ValueError(f"{name} given twice")
        chosen[name] = value
    return chosen


def env_kwargs(args: Args) -> dict:
    """The training env's keywords (the env's heading keyword is in radians)."""
    direction = None if args.direction_deg is None else math.radians(args.direction_deg)
    return {"model": args.model, "target_direction": direction, "healthy_reward": args.healthy_reward,
            "clock_frequency": args.clock_frequency, "torque_limit": args.torque_limit,
            "leg_rate_limit": args.leg_rate_limit, "leg_accel_limit": args.leg_accel_limit,
            "randomize": args.randomize, "backend": args.backend, **extra_env_kwargs(args.env)}


def train_env_kwargs(args: Args) -> dict:
    """The training robots' keywords: :func:`env_kwargs` with the slip tolerance less --slip-margin."""
    kwargs = env_kwargs(args)
    if args.slip_margin > 0:
        kwargs["max_slip_velocity"] = make_task_config(**kwargs).max_slip_velocity - args.slip_margin
    return kwargs


def env_config(args: Args) -> dict:
    """Every env keyword of the training env, defaults included, as JSON (saved as env_kwargs.json)."""
    return config_to_json(make_task_config(**env_kwargs(args)))


def algorithm_default(algo: str, name: str):
    """train.py's default of option ``name`` for ``algo``: its ALGO_DEFAULTS entry, else the Args field's."""
    return hp.ALGO_DEFAULTS[algo].get(name, next(f.default for f in dataclasses.fields(Args) if f.name == name))


def algorithm_kwargs(args: Args) -> dict:
    """The --algo's keywords for a new model: :func:`rrrobot_gym.hyperparams.algorithm_kwargs` with
    this run's settings."""
    return hp.algorithm_kwargs(args.algo, args.num_envs, **{name: getattr(args, name) for name in hp.SETTINGS[args.algo]})


def rollout_steps(args: Args) -> int:
    """Env steps between updates: PPO's rollout, num_envs x n_steps; off-policy, num_envs x train_freq."""
    return args.num_envs * (args.n_steps if args.algo == "ppo" else args.train_freq)


def rounded_timesteps(args: Args) -> int:
    """--total-timesteps rounded up to whole rollouts (:func:`rollout_steps`): what the algorithm will run."""
    rollout = rollout_steps(args)
    return -(-args.total_timesteps // rollout) * rollout


def make_env(args: Args, num_envs: int, seed: int):
    """The batched env behind SB3's VecEnv API, with episode statistics."""
    from .envs.sb3 import RRRobotSB3VecEnv

    venv = RRRobotSB3VecEnv(num_envs=num_envs, max_episode_steps=args.episode_steps, **train_env_kwargs(args))
    return _as_policy_sees(args, venv, seed)


def _as_policy_sees(args: Args, venv, seed: int):
    """``venv`` seeded, with episode statistics, as the policy sees it (--residual-on, --mirror)."""
    from stable_baselines3.common.vec_env import VecMonitor

    venv.seed(seed)
    return mirrored(args, on_base(args, VecMonitor(venv)))


def on_base(args: Args, venv):
    """With --residual-on, the policy's actions become residuals on the base agent's (rrrobot_gym/agents/residual.py)."""
    if args.residual_on is None:
        return venv
    return make_residual_vec_env(venv, load_turn_then_run_agent(args.residual_on), args.residual_scale)


def mirrored(args: Args, venv):
    """With --mirror, the env as a mirrored policy sees it (rrrobot_gym/agents/mirror.py)."""
    if not args.mirror:
        return venv
    return make_mirrored_vec_env(venv, make_task_config(**env_kwargs(args)))


def eval_headings(args: Args):
    """rad, the fixed evaluation headings: the 8 compass directions (or the specialist's one)."""
    if args.direction_deg is not None:
        return np.array([math.radians(args.direction_deg)])
    if args.mirror:  # the others are these headings' mirror images: the same episodes
        return np.radians(np.arange(0, 181, 45, dtype=float))
    return np.radians(np.arange(0, 360, 45, dtype=float))


def make_eval_env(args: Args, seed: int):
    """One env per evaluation heading, from the paper's start (no noise); otherwise the training
    env's keywords (the same reward) and episode length. Its ``unwrapped.run()`` is the last
    evaluation's first episodes as :func:`rrrobot_gym.evaluation.run_episodes` returns a run."""
    from .envs.sb3 import RRRobotSB3VecEnv
    from .evaluation import EFFORT_KEYS

    headings = eval_headings(args)

    class _FixedHeadings(RRRobotSB3VecEnv):
        def reset(self):
            self.set_options({"target_direction": headings})
            observations = super().reset()
            self._path = [[(info["x_position"], info["y_position"]) for info in self.reset_infos]]
            self._effort = {key: [] for key in EFFORT_KEYS}
            self._ended = np.zeros(self.num_envs, dtype=bool)
            self._left = np.zeros(self.num_envs, dtype=bool)  # (terminated: left the model)
            return observations

        def step_wait(self):
            observations, rewards, dones, infos = super().step_wait()
            live = ~self._ended  # (each robot's first episode is recorded)
            self._path.append([(info["x_position"], info["y_position"]) if on else (np.nan, np.nan)
                               for info, on in zip(infos, live)])
            for key, values in self._effort.items():
                values.append([info[key] if on else np.nan for info, on in zip(infos, live)])
            self._left |= live & dones & ~np.array([info["TimeLimit.truncated"] for info in infos])
            self._ended |= dones
            return observations, rewards, dones, infos

        def run(self) -> dict:
            steps = args.episode_steps  # (speeds are over the whole episode, as evaluate.py's)
            xy = np.full((steps + 1, self.num_envs, 2), np.nan)
            xy[:len(self._path)] = self._path
            effort = {key: np.full((steps, self.num_envs), np.nan) for key in self._effort}
            for key, values in self._effort.items():
                effort[key][:len(values)] = values
            return {"times": np.arange(steps + 1) * self.vector_env.dt, "xy": xy, "terminated": self._left.copy(),
                    **effort}

    venv = _FixedHeadings(
        num_envs=len(headings), max_episode_steps=args.episode_steps,
        **{**env_kwargs(args), "reset_noise_scale": 0.0, "randomize": None},
    )
    return _as_policy_sees(args, venv, seed)


def heading_speeds(args: Args, run: dict) -> tuple:
    """The evaluation headings (deg) and the speeds along them (mm/s) of an evaluation's ``run``
    (:func:`make_eval_env`), scored by :func:`rrrobot_gym.evaluation.score`; a mirrored policy's
    headings towards -Y are added as its +Y headings' mirror images (the same episodes)."""
    from .evaluation import score

    degrees = np.degrees(eval_headings(args))
    speeds = np.array([record["speed_mps"] * 1e3 for record in score(run, degrees)])
    if args.mirror:  # 0, 45, ..., 180: 225, 270 and 315 mirror 135, 90 and 45
        degrees, speeds = np.concatenate([degrees, 360 - degrees[-2:0:-1]]), np.concatenate([speeds, speeds[-2:0:-1]])
    return degrees, speeds


def seed_argv(argv, seed: int, settings: dict | None = None) -> list:
    """The command line of --seeds' run of ``seed`` (:mod:`rrrobot_gym.seeds`), or of a --sweep
    trial with its ``settings`` ({option: value}, :mod:`rrrobot_gym.sweep`): the options given in
    ``argv`` but those of --seeds, --sweep and --runs-dir, on one torch thread unless given,
    without a progress bar; the files it reads by absolute path."""
    given = {name: value for name, value in vars(_parser(given_only=True).parse_args(argv)).items()
             if name not in (*SEEDS_OPTIONS, "sweep", "seed", "runs_dir", "progress_bar")}
    for name in ("resume", "residual_on"):
        if given.get(name) is not None:
            given[name] = str(Path(given[name]).resolve())
    given = {"torch_threads": 1, **given, **(settings or {}), "seed": seed, "progress_bar": False}
    out = []
    for name, value in given.items():
        flag = "--" + name.replace("_", "-")
        if isinstance(value, bool):
            out.append(flag if value else "--no-" + flag[2:])
        elif isinstance(value, list):  # (a repeatable option)
            out += [part for item in value for part in (flag, item)]
        else:
            out += [flag, "none" if value is None else str(value)]
    return out


def stop_after(deadline: float | None):
    """A callback that ends training at the first env step after ``deadline`` (time.monotonic()
    seconds; None: never)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class StopAfter(BaseCallback):
        def _on_step(self) -> bool:
            if deadline is not None and time.monotonic() >= deadline:
                print(f"--max-minutes reached at {self.num_timesteps:,} steps: ending training", flush=True)
                return False
            return True

    return StopAfter()


def stop_on_ctrl_c():
    """A callback that ends training at the next env step after Ctrl-C, so the interrupt never
    lands inside a checkpoint's save (a broken zip, no final model); main() then saves. A second
    Ctrl-C interrupts at once."""
    import contextlib
    import signal
    import threading

    from stable_baselines3.common.callbacks import BaseCallback

    class Stop(BaseCallback):
        requested = False

        def _on_step(self) -> bool:
            return not self.requested

        def _request(self, signum, frame):
            self.requested = True
            print("interrupted: saving the model before exiting", flush=True)
            signal.signal(signal.SIGINT, signal.default_int_handler)

        @contextlib.contextmanager
        def handling_ctrl_c(self):
            if threading.current_thread() is not threading.main_thread():
                yield  # signal handlers belong to the main thread: plain KeyboardInterrupt there
                return
            previous = signal.signal(signal.SIGINT, self._request)
            try:
                yield
            finally:
                signal.signal(signal.SIGINT, previous)

    return Stop()


def threads_for_updates(threads: int):
    """An SB3 callback that runs torch on ``threads`` CPU threads while the model updates (the env's
    core is idle then; docs/benchmarks.md) and on one while it collects a rollout (64-row forward
    passes, which a second thread only slows). The model is built on one thread too: its initial
    weights' bits depend on the thread count."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback

    class ThreadsForUpdates(BaseCallback):
        def _on_rollout_start(self) -> None:
            torch.set_num_threads(1)

        def _on_rollout_end(self) -> None:
            torch.set_num_threads(threads)

        def _on_step(self) -> bool:
            return True

    return ThreadsForUpdates()


def first_update_notice(started: float):
    """An SB3 callback that prints, once, when PPO's first update has ended (the second rollout
    starts): s since ``started`` (time.monotonic()) and the unix time, the run's start-up cost."""
    from stable_baselines3.common.callbacks import BaseCallback

    class FirstUpdate(BaseCallback):
        told = False

        def _on_rollout_start(self) -> None:
            if self.n_calls > 0 and not self.told:  # (a rollout of this learn() and its update are done)
                self.told = True
                print(f"first PPO update done {time.monotonic() - started:.1f} s into the run "
                      f"(unix time {time.time():.3f})", flush=True)

        def _on_step(self) -> bool:
            return True

    return FirstUpdate()


def best_model_line(args: Args, run_dir: Path, best) -> str:
    """The run's last line: what best_model.zip is (``best``: (steps, heading speeds in mm/s) of its
    evaluation, None if none ran) and where it and the final model are saved."""
    files = f"{run_dir / 'best_model.zip'} (final model: {run_dir / 'final_model.zip'})"
    if best is None:
        return f"no evaluation ran (shorter than --eval-freq): best_model.zip is a copy of the final model: {files}"
    steps, speeds = best
    return (f"best model: heading speeds {speeds.min():.1f} mm/s worst, {speeds.mean():.1f} mean, the evaluation at "
            f"{steps:,} steps of highest {args.select_by} heading return; saved as {files}")


def run_name(args: Args) -> str:
    return f"{ENV_ID}__{args.exp_name}__{args.seed}__{int(time.time())}"


def main(argv=None) -> Path:
    started = time.monotonic()
    args = parse_args(argv)
    if args.sweep is not None:
        from .sweep import run_sweep

        return run_sweep(args, sys.argv[1:] if argv is None else list(argv), seed_argv, ENV_ID, env_config(args))
    if args.seeds is not None:
        argv = sys.argv[1:] if argv is None else list(argv)
        if "," in args.algo:
            from .algorithms import run_algorithms

            given = given_flags(argv)
            rows = [(algo, seed, seed_argv(argv, seed, {"algo": algo, "exp_name": algo, **(
                        {} if "torch_threads" in given else {"torch_threads": algorithm_default(algo, "torch_threads")})}))
                    for seed in range(args.seed, args.seed + args.seeds) for algo in args.algo.split(",")]
            return run_algorithms(args, rows, ENV_ID, env_config(args))
        from .seeds import run_seeds

        rows = [(seed, seed_argv(argv, seed)) for seed in range(args.seed, args.seed + args.seeds)]
        return run_seeds(args, rows, f"{ENV_ID}__{args.exp_name}__", env_config(args))
    import torch
    from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback, EvalCallback
    from stable_baselines3.common.utils import set_random_seed
    from stable_baselines3.common.vec_env import VecNormalize

    from .seeds import selection_score

    torch.set_num_threads(1)  # (until the first update: ThreadsForUpdates)
    random.seed(args.seed)
    np.random.seed(args.seed)
    set_random_seed(args.seed)

    run_dir = Path(args.runs_dir) / run_name(args)
    run_dir.mkdir(parents=True, exist_ok=False)
    (run_dir / "args.json").write_text(json.dumps(dataclasses.asdict(args), indent=2))
    (run_dir / "command.txt").write_text(" ".join([sys.executable, *sys.argv]) + "\n")
    (run_dir / "env_kwargs.json").write_text(json.dumps(env_config(args), indent=2))
    if args.residual_on is not None:
        save_residual(run_dir, args.residual_on, args.residual_scale)
    if args.mirror:
        save_mirror(run_dir)

    algorithm = hp.algorithm_class(args.algo)
    train_env = make_env(args, args.num_envs, args.seed)
    eval_env = make_eval_env(args, args.seed + 10_000)
    if args.resume:
        train_env = VecNormalize.load(str(normalization_path(args.resume)), train_env)  # (parse_args found it)
        train_env.training = True
        overrides = resume_overrides(args, argv)
        model = load_sb3_model(args.resume, env=train_env, tensorboard_log=str(run_dir), **overrides)
        if overrides:
            print("resumed with " + ", ".join(f"{name} {value}" for name, value in overrides.items()), flush=True)
    else:
        train_env = VecNormalize(train_env, **hp.vecnormalize_kwargs(gamma=args.gamma))
        model = algorithm("MlpPolicy", train_env, **algorithm_kwargs(args), tensorboard_log=str(run_dir), seed=args.seed,
                          verbose=0)
    saved_class = policy_class_to_save(run_dir)
    if saved_class is not None:  # (SB3 builds its policy once, above: this is only what every save names)
        model.policy_class = saved_class  # a mirrored or residual model that load refuses, naming load_ppo_agent
    eval_env = VecNormalize(eval_env, training=False, norm_reward=False, gamma=args.gamma)

    class SaveBest(EvalCallback):
        """Saves best_model.zip and its statistics at the best evaluation by --select-by, adds each
        evaluation's wall time, heading speeds and the training episodes' mean length to
        evaluations.npz, and prints one line an evaluation (SB3's own lines are off: its "best" is
        the mean return's, not --select-by's)."""

        best_score = -math.inf
        best = None  # (steps, heading speeds) of the evaluation saved as best_model.zip
        wall_times, speeds, episode_steps = [], [], []

        def _on_step(self) -> bool:
            done = len(self.evaluations_results)
            result = super()._on_step()
            if len(self.evaluations_results) > done:
                self.wall_times.append(time.monotonic() - started)
                degrees, speeds = heading_speeds(args, self.eval_env.unwrapped.run())
                self.speeds.append(speeds)
                ended = [episode["l"] for episode in self.model.ep_info_buffer]  # (the last 100 training episodes)
                self.episode_steps.append(np.mean(ended) if ended else np.nan)
                with np.load(self.log_path + ".npz") as saved:  # (SB3's keys, as it just wrote them)
                    np.savez(self.log_path, **saved, wall_time_s=self.wall_times, heading_speeds_mm_s=self.speeds,
                             speed_headings_deg=degrees, train_episode_steps=self.episode_steps)
                score = selection_score(self.evaluations_results[-1], args.select_by)  # (as the seeds' summary)
                saved = score > self.best_score
                if saved:
                    self.best_score, self.best = score, (self.num_timesteps, speeds)
                    self.model.save(run_dir / "best_model.zip")
                    train_env.save(str(run_dir / "vecnormalize.pkl"))
                print(f"evaluation at {self.num_timesteps:,} steps: heading speeds {speeds.min():.1f} mm/s worst, "
                      f"{speeds.mean():.1f} mean; {args.select_by} heading return {score:,.0f}"
                      + (", the best yet: saved as best_model.zip" if saved else ""), flush=True)
                if args.stop_at_speed is not None and speeds.min() >= args.stop_at_speed:
                    print(f"worst heading {speeds.min():.1f} mm/s reached --stop-at-speed {args.stop_at_speed:g}: "
                          "ending training", flush=True)
                    return False
            return result

    evaluation = SaveBest(eval_env, n_eval_episodes=len(eval_headings(args)), deterministic=True,
                          eval_freq=max(1, args.eval_freq // args.num_envs), log_path=str(run_dir), verbose=0)
    checkpoints = CheckpointCallback(save_freq=max(1, args.checkpoint_freq // args.num_envs),
                                     save_path=str(run_dir / "checkpoints"), name_prefix=args.algo, save_vecnormalize=True)
    print(f"run: {run_dir}", flush=True)
    total_timesteps = rounded_timesteps(args)
    if total_timesteps != args.total_timesteps:
        print(f"training for {total_timesteps:,} env steps: --total-timesteps {args.total_timesteps:,} rounded up to "
              f"whole rollouts of --num-envs x {'--n-steps' if args.algo == 'ppo' else '--train-freq'} = "
              f"{rollout_steps(args):,}", flush=True)
    stop = stop_on_ctrl_c()
    deadline = None if args.max_minutes is None else started + 60 * args.max_minutes
    try:
        with stop.handling_ctrl_c():
            model.learn(total_timesteps=total_timesteps, progress_bar=args.progress_bar, tb_log_name="tb",
                        callback=CallbackList([stop, stop_after(deadline), evaluation, checkpoints,
                                               threads_for_updates(args.torch_threads),
                                               *([first_update_notice(started)] if args.algo == "ppo" else [])]),
                        reset_num_timesteps=args.resume is None)
    except KeyboardInterrupt:  # a second Ctrl-C: stop at once
        stop.requested = True
        print("interrupted again: saving the model before exiting", flush=True)
    interrupted = stop.requested
    model.save(run_dir / "final_model.zip")
    train_env.save(str(run_dir / "final_vecnormalize.pkl"))
    if not (run_dir / "best_model.zip").exists():
        # No evaluation ran (a run shorter than --eval-freq): the final model stands in, chosen by nothing.
        shutil.copy(run_dir / "final_model.zip", run_dir / "best_model.zip")
        shutil.copy(run_dir / "final_vecnormalize.pkl", run_dir / "vecnormalize.pkl")
    print(best_model_line(args, run_dir, evaluation.best), flush=True)
    train_env.close()
    eval_env.close()
    if interrupted:
        raise SystemExit(130)
    return run_dir


if __name__ == "__main__":
    main()
