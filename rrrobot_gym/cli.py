"""Command line: reproduce the paper's Table I, gaits and Figs. 7-9.

    rrrobot table1 [--json]
    rrrobot simulate --model plane --gait 1 --out run.npz [--plot run.png]
    rrrobot figures --out DIR
    rrrobot gait-search --model plane --objective own --budget-seconds 600 --out best_gaits.json
    rrrobot turn-then-run-search --model plane --run-gaits GAITS.json --budget 900 --out AGENT.json
    rrrobot turn-then-run-steer --agent AGENT.json --gain 0.5 1 --limit 0.05 0.1 --out AGENT.json
    rrrobot export-onnx agents/pretrained/best_model.zip --out policy.onnx
    rrrobot video --policy agents/pretrained/best_model.zip --heading 90 --out robot.gif

(also ``python -m rrrobot_gym ...``). This module only parses arguments, calls
:mod:`rrrobot_gym.simulation`, :mod:`rrrobot_gym.analysis` and
:mod:`rrrobot_gym.plotting`, and writes files. A bad argument ends the program
with one line ``rrrobot: error: ...`` and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import asdict, fields
from fractions import Fraction
from pathlib import Path

import numpy as np

from . import analysis, dynamics, plotting
from .control import GAIT_OFFSETS, table2_gait
from .params import MODELS, PDGains, RobotParams
from .simulation import BACKENDS, DEFAULT_TIMESTEP, INTEGRATORS, NumericalFailure, SimConfig, simulate

PROG = "rrrobot"
PAPER_DURATION = 50.0
"""s, the length of the paper's simulated runs."""
FIGURE_FILE = "contact_paths.png"
MODEL_HELP = "plane: rolling on a plane; pivot: Pivoting Dynamics"
NPZ_CONTENTS = """arrays in the .npz file (N samples, every --sample-dt seconds from t = 0):
  t          (N,)    s       sample times
  x, y       (N,)    m       contact point on the ground
  theta      (N, 3)  rad     the paper's ZXY angles theta1..3, unwrapped along time
  phi        (N, 2)  rad     leg angles phi1, phi2 (0 horizontal along +X, pi/2 up)
  quat       (N, 4)  -       unit quaternion w, x, y, z, body to world
  body_rate  (N, 3)  rad/s   the body's angular velocity in the WORLD frame"""


class UsageError(Exception):
    """A user-facing problem: reported as one line, exit status 2."""


# ---------------------------------------------------------------- argument types


def _read_number(text: str) -> float:
    """``float(text)``, a fraction such as 1/300 included; ValueError if it is not a number."""
    try:
        return float(Fraction(text.strip())) if "/" in text else float(text)
    except ZeroDivisionError:
        raise ValueError(f"not a number: {text!r}") from None


def _number(text: str) -> float:
    """A finite real number; a fraction such as 1/300 is accepted too."""
    try:
        value = _read_number(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return value


def _positive_seconds(text: str) -> float:
    value = _number(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f"must be a positive number of seconds, got {text!r}")
    return value


def _nonnegative_seconds(text: str) -> float:
    value = _number(text)
    if value < 0.0:
        raise argparse.ArgumentTypeError(f"must be a number of seconds >= 0, got {text!r}")
    return value


def _timestep(text: str):
    """A positive number of seconds (1/300 is accepted), or "auto": the step SimConfig derives from the scene."""
    return "auto" if text.strip() == "auto" else _positive_seconds(text)


def _robot_param(text: str):
    """NAME=VALUE for a field of RobotParams (other than damping, which has its own option)."""
    names = [f.name for f in fields(RobotParams) if f.name != "damping"]
    name, sep, value = text.partition("=")
    if not sep:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    name = name.strip().replace("-", "_")
    if name == "damping":
        raise argparse.ArgumentTypeError("set damping with --damping")
    if name not in names:
        raise argparse.ArgumentTypeError(f"unknown robot parameter {name!r}: expected one of {', '.join(names)}")
    return name, _number(value)


ENV_KEYWORDS_WITH_OPTIONS = {"model": "--model", "reset_noise_scale": "--reset-noise-scale",
                             "num_envs": "--popsize", "max_episode_steps": "--duration"}
"""Env keywords ``gait-search --env`` refuses: each is set by its own option."""


def keyword_value(text: str):
    """(name, value) of a KEY=VALUE env keyword (dashes in KEY read as underscores); VALUE is read
    as JSON (1.5, true, null), None/none as None, else as a number if it is one (.5, +20,
    1/300), else as a string. Raises ValueError naming the
    problem: no KEY=VALUE, or a value that is not finite. Shared by ``gait-search --env`` and
    ``evaluate.py --physics``."""
    name, sep, raw = text.partition("=")
    name = name.strip().replace("-", "_")
    if not sep or not name.isidentifier():
        raise ValueError(f"expected KEY=VALUE (an env keyword), got {text!r}")
    raw = raw.strip()
    if raw in ("None", "none"):
        return name, None
    try:
        value = json.loads(raw)
    except json.JSONDecodeError:
        try:  # (numbers JSON does not read: .5, +20, 1., 1/300)
            value = _read_number(raw)
        except ValueError:
            value = raw
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"{name}: must be finite, got {raw!r}")
    return name, value


def env_keyword(text: str, options: dict):
    """(name, value) of a tool's ``--env`` KEY=VALUE (:func:`keyword_value`), refusing the env
    keywords the tool sets by options of its own, ``options`` ({keyword: option}). Raises
    ValueError naming the problem. Shared by ``gait-search --env`` and ``train.py --env``."""
    name, value = keyword_value(text)
    if name in options:
        raise ValueError(f"set {name} with {options[name]}, not --env")
    return name, value


def _env_keyword(text: str):
    """``gait-search --env`` KEY=VALUE (:func:`env_keyword`, its own options refused), for argparse."""
    try:
        return env_keyword(text, ENV_KEYWORDS_WITH_OPTIONS)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _numbers(text: str) -> tuple:
    """Comma-separated numbers."""
    return tuple(_number(part) for part in text.split(","))


def _counts(text: str) -> tuple:
    """Comma-separated whole numbers."""
    return tuple(_positive_int(part) for part in text.split(","))


def _seed_list(text: str) -> tuple:
    """Comma-separated seeds (whole numbers >= 0)."""
    return tuple(_count(part) for part in text.split(","))


def _gait_name(text: str) -> str:
    """A name for searched gaits: letters, digits, '-', '_' and '.' (agent names in tables and on the command line)."""
    if not text or not all(c.isalnum() or c in "-_." for c in text):
        raise argparse.ArgumentTypeError(f"must be letters, digits, '-', '_' or '.', got {text!r}")
    return text


def _positive_int(text: str, minimum: int = 1) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < minimum:
        wanted = "a positive integer" if minimum == 1 else f"an integer >= {minimum}"
        raise argparse.ArgumentTypeError(f"must be {wanted}, got {text!r}")
    return value


def _count(text: str) -> int:
    return _positive_int(text, 0)


def _positive_number(text: str) -> float:
    value = _number(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}")
    return value


def _heading_deg(text: str) -> float:
    """A heading in degrees, in [-360, 360]."""
    value = _number(text)
    if not -360.0 <= value <= 360.0:
        raise argparse.ArgumentTypeError(f"must be a heading in degrees, in [-360, 360], got {text!r}")
    return value


def _palette_size(text: str) -> int:
    value = _positive_int(text)
    if not 2 <= value <= 256:
        raise argparse.ArgumentTypeError(f"must be 2 to 256 colours (a GIF's palette), got {text!r}")
    return value


# ---------------------------------------------------------------- the parser


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Simulate the RRRobot of 'Legless Locomotion' and reproduce the paper's Table I and Figs. 7-9.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    table = sub.add_parser("table1", help="Table I: small-oscillation periods, computed beside the paper's")
    table.add_argument("--json", action="store_true", help="print the records as JSON (NaN as null)")
    table.set_defaults(run=run_table1)

    sim = sub.add_parser(
        "simulate",
        help="simulate one Table II gait and write the trajectory to an .npz file",
        description="Simulate one Table II gait from rest and write the sampled trajectory to an .npz file.",
        epilog=NPZ_CONTENTS,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sim.add_argument("--model", choices=MODELS, required=True, help=MODEL_HELP)
    sim.add_argument("--gait", type=int, choices=sorted(GAIT_OFFSETS), required=True, help="Table II gait")
    sim.add_argument("--swap-phase", action="store_true", help="exchange the legs' phases (the mirrored gait)")
    sim.add_argument("--out", type=Path, required=True, metavar="FILE.npz", help="where to write the arrays")
    sim.add_argument("--plot", type=Path, metavar="FILE.png", help="also draw the contact path (Figs. 7-9 style)")
    _add_run_options(sim)
    sim.set_defaults(run=run_simulate)

    figs = sub.add_parser("figures", help="all gaits on both models: the Figs. 7-9 panels and a travel summary")
    figs.add_argument("--out", type=Path, required=True, metavar="DIR", help="directory for the PNG and summary files")
    _add_run_options(figs)
    figs.set_defaults(run=run_figures)

    search = sub.add_parser(
        "gait-search",
        help="search open-loop per-leg sinusoid gaits with CMA-ES (needs rrrobot_gym[search])",
        description="Search phi_k(t) = o_k + a_k sin(w t + beta_k) with a random screen and CMA-ES, "
        "scoring whole populations in one batched RRRobot-v0 env (its envelope included), and write "
        "the best gaits as JSON (schema: rrrobot_gym.gait_search). Without a budget: --budget-seconds 600.",
    )
    _add_search_options(search, seed="the screen and CMA-ES", budget=("--budget-seconds", None, "wall-clock budget, s"),
                        env_help="an RRRobot-v0 env keyword, e.g. max_slip_velocity=0.05 (repeatable)",
                        ray_help=RAY_ADDRESS_HELP, progress_help="no progress bar",
                        out_help="where to write the best gaits")
    search.add_argument("--objective", choices=("own", "heading"), default="own",
                        help="own: speed along the gait's own direction; heading: along --heading-deg (default: own)")
    search.add_argument("--heading-deg", type=_number, help="commanded heading, deg from +X towards +Y (objective heading)")
    search.add_argument("--evaluations", type=_positive_int, help="budget in gaits scored")
    search.add_argument("--popsize", type=_positive_int, default=64, help="CMA-ES population (default: %(default)s)")
    search.add_argument("--screen", type=_count, help="random gaits tried first (default: 2 x popsize)")
    search.add_argument("--duration", type=_positive_seconds, default=20.0, help="episode length scored, s (default: %(default)g)")
    search.add_argument("--starts", type=_positive_int, default=2,
                        help="start-noise seeds each gait is scored from (seeds 0..N-1; default: %(default)s)")
    search.add_argument("--ramp-s", type=_nonnegative_seconds,
                        help="every gait grows its swing in over this many seconds from the start at rest, 0: none "
                             "(default: gait_search.DEFAULT_RAMP_S, 2 s)")
    search.add_argument("--keep", type=_positive_int, default=3, help="best gaits written (default: %(default)s)")
    search.add_argument("--name", type=_gait_name,
                        help="the gaits' names, NAME-1, NAME-2, ... (default: searched-MODEL-OBJECTIVE); files "
                             "evaluate.py compares need distinct names")
    search.add_argument("--robustness-seeds", type=_count, default=8,
                        help="fresh start seeds the best gaits are re-scored on, 0: none (default: %(default)s)")
    search.add_argument("--robustness-duration", type=_positive_seconds, default=50.0,
                        help="episode length of the re-score, s (default: %(default)g, the paper's)")
    search.add_argument("--robust-pool", type=_positive_int, default=32,
                        help="the fittest gaits re-scored on the new starts; those that stay in the model on every "
                             "start are written first (default: %(default)s)")
    search.set_defaults(run=run_gait_search)
    study = sub.add_parser(
        "shape-study",
        help="what the shell's shape and the leg count do to speed: one gait search a family member (needs "
             "rrrobot_gym[search] and matplotlib)",
        description="Search gaits (rrrobot gait-search, objective own, plane, default servo) for shells of "
        "semi-axes (0.12, 0.12, 0.12 c/a) with two legs and for the sphere with each leg count, the same number of "
        "gaits scored and seed each, and write summary.json, each member's gaits and speed.png into --out-dir "
        "(rrrobot_gym/shape_study.py).",
    )
    study.add_argument("--out-dir", type=Path, required=True, metavar="DIR", help="where the study is written")
    study.add_argument("--evaluations", type=_positive_int, default=8000,
                       help="gaits each member's search scores (default: %(default)s)")
    study.add_argument("--ratios", type=_numbers, metavar="R,R,...",
                       help="shell ratios c/a (default: 0.6,0.7,0.8,0.9,1,1.1,1.2,1.4)")
    study.add_argument("--legs", type=_counts, metavar="N,N,...", help="leg counts on the sphere (default: 2,3,4)")
    study.add_argument("--seeds", type=_seed_list, default=(0, 1),
                       help="each member is searched once per seed; its best search counts (default: 0,1)")
    study.add_argument("--no-progress", action="store_true", help="print nothing until the end")
    study.set_defaults(run=run_shape_study)
    _add_turn_then_run_parsers(sub)
    return parser


RAY_ADDRESS_HELP = ("evaluate populations as Ray tasks on the cluster at ADDR (host:port, ray://host:port); 'local' "
                    "starts a Ray on this machine, which costs about 60 s of start-up on two cores, so it pays only "
                    "with many cores")


def _add_search_options(parser, *, env_help, progress_help, out_help, seed=None, budget=None, ray_help=None):
    """The options the search commands share: --env, --no-progress and --out; with ``seed`` (what it
    seeds) --model, --seed and --reset-noise-scale; a ``budget`` ((flag, default, help)) in seconds;
    --ray-address with ``ray_help``."""
    if seed is not None:
        parser.add_argument("--model", choices=MODELS, required=True, help=MODEL_HELP)
        parser.add_argument("--seed", type=_count, default=0, help=f"seed of {seed} (default: %(default)s)")
        parser.add_argument("--reset-noise-scale", type=_number, default=0.01,
                            help="start noise (default: %(default)g, the env's)")
    if budget is not None:
        flag, default, text = budget
        parser.add_argument(flag, type=_positive_seconds, default=default, help=text)
    parser.add_argument("--env", type=_env_keyword, action="append", default=[], metavar="KEY=VALUE", help=env_help)
    if ray_help is not None:
        parser.add_argument("--ray-address", metavar="ADDR", help=ray_help)
    parser.add_argument("--no-progress", action="store_true", help=progress_help)
    parser.add_argument("--out", type=Path, required=True, metavar="FILE.json", help=out_help)


def _add_turn_then_run_parsers(sub):
    ttr = sub.add_parser(
        "turn-then-run-search",
        help="search the turn-then-run agent's turning gait, switch lead and blend for a running gait (needs rrrobot_gym[search])",
        description="Make a turn-then-run agent file for the best gait of a gait-search file: measure the gait's "
        "direction of travel against the body's yaw, search the sinusoid that turns the body fastest inside the "
        "model, then search the turning gait, the switch's lead and the blend together, scored through the agent "
        "on the headings from the paper's start and noisy starts (random screen + CMA-ES, one batched env a "
        "population). The heading correction is tuned after, by turn-then-run-steer.",
    )
    _add_search_options(ttr, seed="the screens and CMA-ES",
                        budget=("--budget", 900.0, "wall-clock budget of the two searches, s (default: %(default)g)"),
                        env_help="an RRRobot-v0 env keyword, e.g. torque_limit=0.5 (repeatable); the running gait "
                                 "file's env_kwargs apply unless overridden",
                        ray_help=RAY_ADDRESS_HELP.replace("populations", "populations of maneuvers"),
                        progress_help="print nothing while searching", out_help="where to write the agent file")
    ttr.add_argument("--run-gaits", type=Path, required=True, metavar="GAITS.json",
                     help="gait-search file of the running gait (its best gait unless --run-gait)")
    ttr.add_argument("--run-gait", metavar="NAME", help="the running gait by name, e.g. searched-plane-own-2")
    ttr.add_argument("--evaluations", type=_positive_int,
                     help="also end the two searches after this many candidates scored in all, shared as the "
                          "budget: a search that repeats itself on any machine")
    ttr.add_argument("--turning-share", type=_number, default=0.5,
                     help="share of the budget for the turning gait's search (default: %(default)g)")
    ttr.add_argument("--popsize", type=_positive_int, default=64,
                     help="the turning gait's CMA-ES population, its screen 8x that; the maneuver's half of it, "
                          "its screen 1x (default: %(default)s)")
    ttr.add_argument("--headings", type=_number, nargs="+", metavar="DEG",
                     help="headings the maneuver is scored on, deg from +X towards +Y (default: 0 45 135 180)")
    ttr.add_argument("--starts", type=_positive_int, default=2,
                     help="starts each maneuver is scored from: the paper's and N - 1 noisy ones (default: %(default)s)")
    ttr.add_argument("--duration", type=_positive_seconds,
                     help="episode length a maneuver is scored over, s (default: 20, or 30 for a running gait with a swing ramp)")
    ttr.add_argument("--warm-start", type=Path, metavar="AGENT.json", help="a turn-then-run file whose maneuver joins the screen")
    ttr.add_argument("--run-at-once-below-deg", type=_number, default=10.0,
                     help="a start needing a smaller turn runs the gait at once (default: %(default)g)")
    ttr.set_defaults(run=run_turn_then_run_search)

    steer = sub.add_parser(
        "turn-then-run-steer",
        help="tune a turn-then-run agent's heading correction on a grid",
        description="Run a turn-then-run agent file without its heading correction and with every combination "
        "of the values given, each 50 s along the 8 compass headings from the paper's start and noisy starts, "
        "and write the file with the combination whose runs end least, then with the best worst heading, then "
        "the best mean (the grid's rows recorded under steer_tune). Values not given keep the file's.",
    )
    _add_search_options(steer, env_help="an RRRobot-v0 env keyword (repeatable); the agent file's env_kwargs apply "
                                        "unless overridden",
                        progress_help="print nothing while running", out_help="where to write the tuned agent file")
    steer.add_argument("--agent", type=Path, required=True, metavar="AGENT.json", help="the turn-then-run file to tune")
    steer.add_argument("--param", choices=("offset", "amplitude"), nargs="+", help="what the correction changes")
    steer.add_argument("--gain", type=_number, nargs="+", help="proportional gains, rad per rad of heading error")
    steer.add_argument("--integral", type=_number, nargs="+", help="integral gains, rad per rad s")
    steer.add_argument("--limit", type=_steer_limit, nargs="+", metavar="LIMIT",
                       help="limits of the change, rad: one number for +-LIMIT or LOW:HIGH")
    steer.add_argument("--after", type=_nonnegative_seconds, nargs="+", help="s into the episode the correction sets in")
    steer.add_argument("--starts", type=_positive_int, default=3,
                       help="starts: the paper's and N - 1 noisy ones (default: %(default)s)")
    steer.add_argument("--duration", type=_positive_seconds, default=PAPER_DURATION, help="s (default: %(default)g)")
    steer.set_defaults(run=run_turn_then_run_steer)

    export = sub.add_parser(
        "export-onnx",
        help="write a trained PPO policy as one ONNX network (observation normalisation and mirror folded in)",
        description="Write the PPO policy MODEL.zip (with the files train.py writes beside it) as ONNX: input "
        "'observation' (N, observation size) float32, the env's raw observations; output 'action' (N, 2), what "
        "the policy's deterministic predict gives. The VecNormalize statistics and, for a mirrored policy, the "
        "mirror are folded in. A residual policy is refused. Needs rrrobot_gym[train] and onnx.",
    )
    export.add_argument("model", type=Path, metavar="MODEL.zip", help="the SB3 PPO model (e.g. a run's best_model.zip)")
    export.add_argument("--out", type=Path, required=True, metavar="FILE.onnx", help="where to write the network")
    export.set_defaults(run=run_export_onnx)

    video = sub.add_parser(
        "video",
        help="write an animation (GIF or MP4) of a trained policy or a Table II gait (needs rrrobot_gym[video])",
        description="Run one episode of a trained policy (any train.py run's model, with the files beside it) "
        "or a Table II gait from the paper's start on the nominal robot, and write the env's rgb_array frames "
        "(a top view with the path and the heading, a side view along the heading) as a GIF or an MP4. A "
        "policy runs under the env keywords it was trained with. Loading a policy unpickles it: trusted "
        "files only.",
    )
    source = video.add_mutually_exclusive_group(required=True)
    source.add_argument("--policy", type=Path, metavar="MODEL.zip", help="a train.py model, e.g. a run's best_model.zip")
    source.add_argument("--gait", type=int, choices=sorted(GAIT_OFFSETS), help="a Table II gait (open loop)")
    video.add_argument("--heading", type=_heading_deg, default=90.0, metavar="DEG",
                       help="commanded heading, deg from +X towards +Y; a gait ignores it, but the side view "
                            "looks along it (default: %(default)g)")
    video.add_argument("--model", choices=MODELS,
                       help="the gait's model (default: plane); a policy runs on the model it was trained on")
    video.add_argument("--seconds", type=_positive_seconds, default=10.0, help="s of the episode (default: %(default)g)")
    video.add_argument("--every", type=_positive_int, default=1,
                       help="a frame every this many control steps of 0.05 s (default: %(default)s)")
    video.add_argument("--speed", type=_positive_number, default=1.0,
                       help="playback speed, times real time (default: %(default)g)")
    video.add_argument("--width", type=_positive_int, default=480, help="frame width, pixels (default: %(default)s)")
    video.add_argument("--height", type=_positive_int, default=240, help="frame height, pixels (default: %(default)s)")
    video.add_argument("--colors", type=_palette_size, default=32,
                       help="a GIF's palette, 2-256 colours shared by all frames (default: %(default)s)")
    video.add_argument("--out", type=Path, required=True, metavar="FILE", help="the animation: FILE.gif or FILE.mp4")
    video.set_defaults(run=run_video)


def _steer_limit(text: str):
    """A heading correction's limit: a number (+-it) or LOW:HIGH."""
    low, sep, high = text.partition(":")
    return [_number(low), _number(high)] if sep else _number(text)


def _add_run_options(parser):
    gains, robot = PDGains(), RobotParams()
    parser.add_argument("--duration", type=_positive_seconds, default=PAPER_DURATION, help="s (default: %(default)g, the paper's)")
    parser.add_argument("--kp", type=_number, default=gains.kp, help="leg servo gain, N m/rad (default: %(default)g)")
    parser.add_argument("--kd", type=_number, default=gains.kd, help="leg servo gain, N m s/rad (default: %(default)g)")
    parser.add_argument(
        "--damping", type=_number, default=robot.damping, help="k, torque k w on the body, N m s/rad (default: %(default)g)"
    )
    parser.add_argument(
        "--param",
        type=_robot_param,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a robot parameter in SI units, e.g. mass_tip=0.06 (repeatable)",
    )
    parser.add_argument("--sample-dt", type=_positive_seconds, default=0.01, help="s between samples (default: %(default)g)")
    parser.add_argument(
        "--timestep",
        type=_timestep,
        default=DEFAULT_TIMESTEP,
        help="s, the integration step, or 'auto': derived from the gains, masses and model (default: 1/300)",
    )
    parser.add_argument(
        "--integrator",
        choices=INTEGRATORS,
        default="rk4",
        help="the fixed-step integrator, a name of rrrobot_gym.integrators.INTEGRATORS (default: %(default)s)",
    )
    parser.add_argument(
        "--backend",
        choices=BACKENDS,
        default="auto",
        help="'numba': the compiled stepper; 'numpy'; 'auto': numba where installed (default: %(default)s)",
    )


def sim_config(args, model: str) -> SimConfig:
    """The SimConfig the options describe; a bad value raises UsageError naming it."""
    try:
        robot = RobotParams(**{**dict(args.param), "damping": args.damping})
        gains = PDGains(kp=args.kp, kd=args.kd)
        return SimConfig(model=model, robot=robot, gains=gains, timestep=args.timestep, integrator=args.integrator,
                         backend=args.backend)  # fmt: skip
    except (TypeError, ValueError, ImportError) as exc:
        raise UsageError(str(exc)) from None


# ---------------------------------------------------------------- table1


def format_table1(records) -> str:
    """Table I as aligned text, with a footnote on the paper's single-axis formulas."""
    header = ("model", "axis", "code (s)", "paper (s)", "diff", "compound (s)", "eq. 5/6 (s)", "rho (m)")
    rows = []
    for rec in records:
        literal = rec["paper_formula_s"]
        rows.append(
            (
                rec["model"],
                rec["axis"].upper(),
                f"{rec['period_s']:.4f}",
                f"{rec['paper_s']:.2f}",
                f"{100 * rec['relative_difference']:+.2f} %",
                f"{rec['compound_formula_s']:.4f}",
                f"{literal:.4f}" if math.isfinite(literal) else "n/a *",
                f"{rec['radius_of_gyration_m']:.4f}",
            )
        )
    out = ["Table I: small-oscillation periods about rest, legs held vertical", *_aligned(header, rows)]
    out += ["", *_table1_footnotes(records)]
    return "\n".join(out)


def _aligned(header, rows) -> list:
    """The lines of a text table: the header, a rule and the rows, the first two columns to the left."""
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]

    def line(cells):
        return "  ".join(c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths)))

    return [line(header), line(["-" * w for w in widths]), *(line(r) for r in rows)]


def _table1_footnotes(records):
    notes = [
        "code: linearisation of the equations of motion (rrrobot_gym.analysis.small_oscillation_periods);",
        "diff: code / paper - 1. compound: a rigid body rocking about one axis, 2 pi sqrt(I / (M g d)),",
        "with I about the contact point (plane) or the centre (pivot), d the centre of mass's depth.",
    ]
    defined = [r for r in records if math.isfinite(r["paper_formula_s"])]
    undefined = [r for r in records if not math.isfinite(r["paper_formula_s"])]
    notes.append("eq. 5/6: the paper's eq. (5) (plane) and eq. (6) (pivot) taken literally, with")
    notes.append("rho = sqrt(I / M) the radius of gyration about the same axis.")
    for rec in undefined:
        notes.append(
            f"* {rec['model']} {rec['axis'].upper()}: rho = {rec['radius_of_gyration_m']:.3f} m >= r, "
            f"so {rec['paper_formula']} has no real value."
        )
    if defined:
        diffs = [100 * (r["paper_formula_s"] / r["paper_s"] - 1.0) for r in defined]
        close = [r for r, d in zip(defined, diffs) if abs(d) <= 2.0]
        notes.append(f"Where defined they differ from the paper's values by {min(diffs):+.0f} % to {max(diffs):+.0f} %:")
        notes.append(
            "taken literally they do not reproduce the paper's Table I;\n"
            "the compound form equals the code's linearisation."
            if not close
            else f"{len(close)} of {len(records)} entries are within 2 % of the paper's."
        )
    return notes


def run_table1(args) -> None:
    records = analysis.table1()
    if args.json:
        print(json.dumps(analysis.json_safe(records), indent=2, allow_nan=False))
    else:
        print(format_table1(records))


# ---------------------------------------------------------------- simulate


def trajectory_arrays(traj) -> dict:
    """The arrays ``rrrobot simulate`` writes (described in :data:`NPZ_CONTENTS`)."""
    return {
        "t": traj.times,  # s
        "x": traj.x,  # m, contact point
        "y": traj.y,  # m
        "theta": traj.theta,  # rad, paper's theta1..3 (ZXY), unwrapped
        "phi": traj.leg_angles,  # rad, phi1, phi2
        "quat": traj.quat,  # w, x, y, z, body to world
        "body_rate": traj.body_rate_world,  # rad/s, world frame
    }


def _run_gait(config: SimConfig, gait, args):
    try:
        traj = simulate(config, gait, args.duration, sample_dt=args.sample_dt)
    except (NumericalFailure, ValueError) as exc:  # (a ValueError: --duration / --sample-dt, too many samples)
        raise UsageError(str(exc)) from None
    _warn_if_tipped(traj, f"{gait.name}, {config.model}")
    return traj


def _warn_if_tipped(traj, label: str) -> None:
    """Say so when the body tilted past the hemisphere's rim: the model ends there."""
    tilt = dynamics.tilt(traj.states)
    beyond = np.flatnonzero(tilt >= dynamics.TILT_LIMIT)
    if beyond.size:
        print(
            f"{PROG}: warning: {label}: the body tilted past {math.degrees(dynamics.TILT_LIMIT):.0f} deg at "
            f"t = {traj.times[beyond[0]]:.2f} s; the shell's rim would touch the ground, so the motion "
            "after that is outside the model (a smaller --timestep or other gains may help)",
            file=sys.stderr,
        )


MIN_SUMMARY_PERIODS = 3
"""Gait periods a run must last for a travel summary: the averaged path needs a few
period-spaced points before it has a heading that can turn."""


def _summary(traj, period):
    """analysis.travel_summary, or None for a run too short to summarise."""
    if traj.times[-1] - traj.times[0] < MIN_SUMMARY_PERIODS * period:
        return None
    return analysis.travel_summary(traj.times, traj.x, traj.y, period)


def format_travel(label: str, summary) -> str:
    if summary is None:
        return f"{label}: run shorter than {MIN_SUMMARY_PERIODS} gait periods, no travel summary"
    return (
        f"{label}: moved {summary['displacement_m']:.4f} m towards {summary['direction_deg']:+.1f} deg "
        f"(dx {summary['dx_m']:+.4f} m, dy {summary['dy_m']:+.4f} m), path {summary['path_length_m']:.4f} m, "
        f"turned {summary['turning_deg']:+.0f} deg, mean speed {1000 * summary['mean_speed_mps']:.2f} mm/s"
    )


def check_output_path(flag: str, path: Path) -> None:
    """A usage error, before a run, if ``path``'s directory does not exist or ``path`` is one
    (``flag`` names the option; evaluate.py's outputs too)."""
    if path.parent and not path.parent.is_dir():
        raise UsageError(f"cannot write {flag} {path}: no directory {path.parent}")
    if path.is_dir():
        raise UsageError(f"cannot write {flag} {path}: it is a directory")


def _write(path: Path, writer) -> None:
    try:
        writer(path)
    except OSError as exc:
        raise UsageError(f"cannot write {path}: {exc.strerror or exc}") from None


def run_simulate(args) -> None:
    if args.out.suffix != ".npz":
        raise UsageError(f"--out must name an .npz file, got {str(args.out)!r}")
    check_output_path("--out", args.out)
    config = sim_config(args, args.model)
    if args.plot:  # before the run, not after it
        try:
            plotting.check_figure_path(args.plot)
        except ValueError as exc:
            raise UsageError(f"--plot: {exc}") from None
        check_output_path("--plot", args.plot)
    gait = table2_gait(args.gait, swapped=args.swap_phase)
    traj = _run_gait(config, gait, args)
    arrays = trajectory_arrays(traj)
    _write(args.out, lambda p: np.savez(p, **arrays))
    label = f"{gait.name}, {args.model}, {args.duration:g} s"
    print(format_travel(label, _summary(traj, gait.period)))
    print(f"wrote {args.out}")
    if args.plot:
        title = f"Gait {args.gait}{' (phases swapped)' if args.swap_phase else ''}, {args.model}"
        _write(args.plot, lambda p: plotting.plot_contact_path(p, traj.times, traj.x, traj.y, gait.period, title))
        print(f"wrote {args.plot}")


# ---------------------------------------------------------------- figures


def run_figures(args) -> None:
    configs = {model: sim_config(args, model) for model in MODELS}
    plotting.require_matplotlib()
    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"cannot create {args.out}: {exc.strerror or exc}") from None
    runs, summaries = {}, []
    for number in sorted(GAIT_OFFSETS):
        gait = table2_gait(number)
        for model in MODELS:
            traj = _run_gait(configs[model], gait, args)
            runs[(number, model)] = {"times": traj.times, "x": traj.x, "y": traj.y, "period": gait.period}
            summary = _summary(traj, gait.period)
            summaries.append({"gait": number, "model": model, **(summary or {})})
            print(format_travel(f"gait {number}, {model}", summary))
    figure = args.out / FIGURE_FILE
    _write(figure, lambda p: plotting.plot_gait_panels(p, runs))
    table = analysis.table1()
    settings = {
        "command": args.command_line,
        "duration_s": args.duration,
        "sample_dt_s": args.sample_dt,
        "timestep_s": configs["plane"].step,
        "timestep_option": args.timestep,
        "gains": asdict(configs["plane"].gains),
        "robot": asdict(configs["plane"].robot),
    }
    report = {"settings": settings, "travel": summaries, "table1": table}
    _write(args.out / "summary.json", lambda p: p.write_text(json.dumps(analysis.json_safe(report), indent=2, allow_nan=False) + "\n"))
    _write(args.out / "summary.txt", lambda p: p.write_text(format_summary(settings, summaries, table) + "\n"))
    for name in (FIGURE_FILE, "summary.txt", "summary.json"):
        print(f"wrote {args.out / name}")


def format_summary(settings, summaries, table) -> str:
    header = ("gait", "model", "net (m)", "dx (m)", "dy (m)", "direction", "path (m)", "turning", "area (m^2)", "speed (mm/s)")
    rows = []
    for s in summaries:
        if "displacement_m" not in s:
            rows.append((str(s["gait"]), s["model"], *(["-"] * (len(header) - 2))))
            continue
        rows.append(
            (
                str(s["gait"]),
                s["model"],
                f"{s['displacement_m']:.4f}",
                f"{s['dx_m']:+.4f}",
                f"{s['dy_m']:+.4f}",
                f"{s['direction_deg']:+.1f} deg",
                f"{s['path_length_m']:.4f}",
                f"{s['turning_deg']:+.0f} deg",
                f"{s['signed_area_m2']:+.5f}",
                f"{1000 * s['mean_speed_mps']:.2f}",
            )
        )
    gains = settings["gains"]
    lines = [
        f"made by: {settings['command']}",
        f"Travel of the Table II gaits, {settings['duration_s']:g} s from rest "
        f"(RK4 step {settings['timestep_s']:.4g} s{' (auto, plane)' if settings['timestep_option'] == 'auto' else ''}, "
        f"Kp {gains['kp']:g}, Kd {gains['kd']:g}, "
        f"damping {settings['robot']['damping']:g})",
        "measured on the contact path averaged over each gait period (2 pi / 8 s);",
        "direction of the net displacement from +X, counter-clockwise; turning: signed change of heading, CCW +;",
        "area: signed area enclosed by the averaged path, > 0 counter-clockwise; speed: path length / time.",
        "",
        *_aligned(header, rows),
        "",
        format_table1(table),
    ]
    return "\n".join(lines)


# ---------------------------------------------------------------- gait-search


def run_gait_search(args) -> None:
    from . import gait_search

    if args.objective == "heading" and args.heading_deg is None:
        raise UsageError("--objective heading needs --heading-deg")
    if args.objective == "own" and args.heading_deg is not None:
        raise UsageError("--heading-deg needs --objective heading (objective own follows the gait's own direction)")
    budget_seconds = 600.0 if args.budget_seconds is None and args.evaluations is None else args.budget_seconds
    result = _run_search(args, (("cma", "search"), ("tqdm", "search")), lambda: gait_search.search(
        model=args.model, objective=args.objective, heading_deg=args.heading_deg,
        budget_evaluations=args.evaluations, budget_seconds=budget_seconds, seed=args.seed,
        popsize=args.popsize, screen=args.screen, duration=args.duration,
        start_seeds=tuple(range(args.starts)), reset_noise_scale=args.reset_noise_scale,
        ramp_s=gait_search.DEFAULT_RAMP_S if args.ramp_s is None else args.ramp_s, keep=args.keep, name=args.name,
        robustness_seeds=args.robustness_seeds, robustness_duration=args.robustness_duration,
        robust_pool=args.robust_pool, progress=not args.no_progress, ray_address=args.ray_address,
        command=args.command_line, **dict(args.env),
    ))  # fmt: skip
    _write(args.out, result.write_json)
    print(format_search(result))
    print(f"wrote {args.out}")


def require(command: str, modules) -> None:
    """A usage error naming the extra to install if one of ``modules`` ((module, extra) pairs) is missing."""
    for module, extra in modules:
        try:
            __import__(module)
        except ImportError:
            raise UsageError(f"{command} needs {module}: pip install 'rrrobot_gym[{extra}]'") from None


def _run_search(args, modules, search):
    """``search()``, after the checks the search commands share before any work: a .json ``--out``,
    the ``modules`` ((module, extra) pairs; Ray's with ``--ray-address``) and a Ray head that
    answers (:func:`rrrobot_gym.gait_search.check_ray_address`); its errors as usage errors."""
    from .gait_search import check_ray_address

    if args.out.suffix != ".json":
        raise UsageError(f"--out must name a .json file, got {str(args.out)!r}")
    check_output_path("--out", args.out)
    ray_address = getattr(args, "ray_address", None)
    require(args.command, modules + ((("ray", "distributed"),) if ray_address else ()))
    try:
        if ray_address is not None:
            check_ray_address(ray_address)
        return search()
    except (TypeError, ValueError, ConnectionError) as exc:
        raise UsageError(str(exc)) from None


def format_search(result) -> str:
    used = result.used
    lines = [
        f"{used['evaluations']} gaits scored in {used['seconds']:.0f} s "
        f"({used['evaluations'] / max(used['seconds'], 1e-9):.1f} a second), {used['generations']} CMA-ES generations",
    ]
    for gait in result.gaits:
        p = gait["parameters"]
        legs = sum(key.startswith("amplitude_") for key in p)

        def each(kind):
            return "/".join(f"{p[f'{kind}_{k}']:.3f}" for k in range(1, legs + 1))

        later = "/".join(f"{p[name]:.3f}" for name in p if name.startswith("phase_") and name != "phase_gap")
        phases = f", gap {p['phase_gap']:.3f} rad" if legs == 2 else f", phases {later} rad" if later else ""
        line = (
            f"{gait['name']}: {1e3 * gait['speed_mps']:.1f} mm/s towards {gait['direction_deg']:.0f} deg; "
            f"a {each('amplitude')} rad, o {each('offset')} rad, w {p['frequency']:.3f} rad/s{phases}"
        )
        if gait["terminated_starts"]:
            line += f" (left the model on {gait['terminated_starts']} starts)"
        if gait.get("robust") is not None:
            line += f" [search rank {gait['search_rank']}{'' if gait['robust'] else ', NOT robust'}]"
        robust = gait.get("robustness")
        if robust:
            line += (
                f"\n  re-scored on {len(robust['seeds'])} new starts, {robust['duration_s']:g} s: mean "
                f"{1e3 * robust['mean_speed_mps']:.1f}, worst {1e3 * robust['min_speed_mps']:.1f} mm/s, "
                f"{sum(robust['terminated'])} left the model; from the paper's start "
                f"{1e3 * robust['paper_start_speed_mps']:.1f} mm/s"
            )
        lines.append(line)
    return "\n".join(lines)


# ---------------------------------------------------------------- turn-then-run


def _progress(args):
    return None if args.no_progress else (lambda line: print(line, file=sys.stderr, flush=True))


def run_turn_then_run_search(args) -> None:
    from . import turn_then_run_search
    from .gait_search import write_json

    spec = _run_search(args, (("cma", "search"),), lambda: turn_then_run_search.search(
        args.run_gaits, model=args.model, budget_seconds=args.budget, budget_evaluations=args.evaluations, seed=args.seed,
        run_gait=args.run_gait,
        headings_deg=args.headings or turn_then_run_search.DEFAULT_HEADINGS_DEG, starts=args.starts,
        duration=args.duration, turning_share=args.turning_share, warm_start=args.warm_start,
        run_at_once_below_deg=args.run_at_once_below_deg, popsize=args.popsize,
        reset_noise_scale=args.reset_noise_scale, ray_address=args.ray_address, progress=_progress(args), command=args.command_line, out_path=args.out,
        **dict(args.env),
    ))  # fmt: skip
    _write(args.out, lambda p: write_json(p, spec))
    found = spec["search"]["maneuver"]
    print(f"turning gait {np.round(spec['turn_gait'], 3).tolist()}, lead {spec['lead_s']:.2f} s, blend {spec['ramp_s']:.2f} s; "
          f"fitness {1e3 * found['fitness']:.1f} mm/s over {found['duration_s']:g} s on headings "
          f"{', '.join(f'{h:g}' for h in found['headings_deg'])} deg, {found['evaluations']} maneuvers scored")  # fmt: skip
    print(f"wrote {args.out}")


def run_turn_then_run_steer(args) -> None:
    from . import turn_then_run_search
    from .gait_search import write_json

    grid = {key: values for key, values in (("steer_param", args.param), ("steer_gain", args.gain),
                                            ("steer_integral", args.integral), ("steer_limit", args.limit),
                                            ("steer_after_s", args.after)) if values}  # fmt: skip
    if not grid:
        raise UsageError("give the values to try: one or more of --gain, --integral, --limit, --after, --param")
    spec = _run_search(args, (), lambda: turn_then_run_search.tune_steering(
        args.agent, grid, seeds=[None] + list(range(1, args.starts)), duration=args.duration,
        command=args.command_line, progress=_progress(args), out_path=args.out, **dict(args.env),
    ))  # fmt: skip
    _write(args.out, lambda p: write_json(p, spec))
    best = spec["steer_tune"]["rows"][0]
    print(f"kept {best['combo'] or 'no correction'}: {best['ended']} runs ended, worst {1e3 * best['worst_mps']:.1f}, "
          f"mean {1e3 * best['mean_mps']:.1f} mm/s")
    print(f"wrote {args.out}")


# ---------------------------------------------------------------- ONNX export


def run_export_onnx(args) -> None:
    if args.out.suffix != ".onnx":
        raise UsageError(f"--out must name a .onnx file, got {str(args.out)!r}")
    check_output_path("--out", args.out)
    require("export-onnx", [(module, "train") for module in ("torch", "stable_baselines3", "onnx")])
    from .export import export_onnx

    try:
        _write(args.out, lambda path: export_onnx(args.model, path))
    except (FileNotFoundError, ValueError) as exc:
        raise UsageError(str(exc)) from None
    print(f"wrote {args.out}")


# ---------------------------------------------------------------- video


def run_shape_study(args) -> None:
    from . import shape_study

    require("shape-study", (("cma", "search"), ("matplotlib", "plots")))
    if args.out_dir.exists() and not args.out_dir.is_dir():
        raise UsageError(f"cannot write --out-dir {args.out_dir}: it is a file")
    options = {"ratios": args.ratios or shape_study.DEFAULT_RATIOS, "leg_counts": args.legs or shape_study.DEFAULT_LEG_COUNTS}
    try:
        shape_study.members(**options)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    summary = shape_study.run(args.out_dir, evaluations=args.evaluations, seeds=args.seeds,
                              progress=None if args.no_progress else print, command=args.command_line, **options)
    print(f"wrote {args.out_dir / 'summary.json'} and {args.out_dir / 'speed.png'} in {summary['wall_seconds']:.0f} s")


def run_video(args) -> None:
    from .envs.render import check_frame_size
    from .video import FORMATS, record, write_animation

    suffix = args.out.suffix.lower()
    if suffix not in FORMATS:
        raise UsageError(f"--out must name a {' or '.join(FORMATS)} file, got {str(args.out)!r}")
    check_output_path("--out", args.out)
    try:
        check_frame_size(args.width, args.height)
    except ValueError as exc:
        raise UsageError(f"--{exc}") from None
    if suffix == ".mp4" and (args.width % 2 or args.height % 2):
        raise UsageError(f"an MP4 needs an even --width and --height (H.264's colour planes), got {args.width} x "
                         f"{args.height}")
    require("video", [(module, "video") for module in ("PIL", "imageio") + (("imageio_ffmpeg",) if suffix == ".mp4" else ())])
    if args.policy is not None:
        agent, model, env_kwargs = _video_policy(args)
    else:
        from .agents.gaits import gait_agent

        agent, model, env_kwargs = gait_agent(f"gait{args.gait}"), args.model or "plane", {}
    frames, frame_dt, ended_at = record(agent, args.heading, args.seconds, every=args.every, width=args.width,
                                        height=args.height, model=model, **env_kwargs)
    fps = args.speed / frame_dt
    _write(args.out, lambda path: write_animation(path, frames, fps, args.colors))
    if ended_at is not None:
        print(f"{PROG}: warning: the episode left the model at t = {ended_at:.2f} s: the animation ends there",
              file=sys.stderr)
    print(f"wrote {args.out}: {len(frames)} frames at {fps:.3g} frames/s, {args.out.stat().st_size / 1024:.0f} KB")


def _video_policy(args):
    """(agent, model, env keywords) of ``--policy``; its problems as usage errors."""
    if not args.policy.is_file():
        raise UsageError(f"--policy: no model file at {args.policy}")
    try:
        from .agents import load_ppo_agent

        agent = load_ppo_agent(args.policy)
    except ImportError as exc:
        raise UsageError(f"--policy needs Stable-Baselines3 ({exc}): pip install 'rrrobot_gym[train]'") from None
    except (FileNotFoundError, ValueError, KeyError) as exc:
        raise UsageError(f"--policy: {exc}") from None
    model = agent.env_config.get("model", "plane")
    if args.model is not None and args.model != model:
        raise UsageError(f"--model {args.model}: {args.policy} was trained on the {model} model")
    return agent, model, agent.env_kwargs


# ---------------------------------------------------------------- entry point


def main(argv=None) -> int:
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parser.parse_args(argv)
    args.command_line = " ".join([PROG, *argv])
    try:
        args.run(args)
    except UsageError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    except ImportError as exc:
        if "rrrobot_gym[plots]" not in str(exc):
            raise
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        # The reader went away (``rrrobot table1 | head``): not an error of ours.
        sys.stderr.close()
        return 0
    return 0
