"""Shared helpers for the yaw study (reuses rrrobot_gym.gait_search / envs.task helpers)."""
import json, math, time
from pathlib import Path
import numpy as np
from rrrobot_gym.envs.vector import RRRobotVectorEnv
from rrrobot_gym.envs import task
from rrrobot_gym.gait_search import sinusoid_angles, repair, PARAMETER_NAMES, BOUNDS, load_gaits, ramp_factor
from rrrobot_gym import dynamics

ROOT = Path(__file__).resolve().parents[2]
import sys
sys.path.insert(0, str(ROOT))  # this checkout's rrrobot_gym


def _model_from_argv(argv):
    """`--model plane|pivot` anywhere on the command line (default plane), removed from argv so
    each script's positional arguments (budget, duration, file) keep their places."""
    model = "plane"
    if "--model" in argv:
        i = argv.index("--model")
        model = argv[i + 1] if i + 1 < len(argv) else ""
        del argv[i:i + 2]
    if model not in ("plane", "pivot"):
        raise SystemExit(f"--model must be plane or pivot, got {model!r}")
    return model


def _pivot_physics():
    """The keywords evaluate.py runs every agent under on the pivot model: evaluate.physics_of
    applied to the shipped pivot policy's training env keywords (its env_kwargs.json, read as
    load_ppo_agent reads it, without unpickling the policy) -> torque_limit 0.5 N m,
    leg_rate_limit 10 rad/s."""
    from types import SimpleNamespace
    from rrrobot_gym.agents.ppo import SCENE_KEYWORDS
    from rrrobot_gym.envs.task import kwargs_from_json
    from rrrobot_gym.evaluation import physics_of
    trained = kwargs_from_json(json.loads((ROOT / "agents" / "pretrained_pivot" / "env_kwargs.json").read_text()))
    return physics_of({"ppo": SimpleNamespace(env_kwargs={k: v for k, v in trained.items() if k not in SCENE_KEYWORDS})})


def _run_gait_from_argv(argv):
    """`--run-gait FILE` anywhere on the command line (a file of agents/searched/, its best gait is
    the running gait), removed from argv like --model; None: the model's default file."""
    if "--run-gait" not in argv:
        return None
    i = argv.index("--run-gait")
    name = argv[i + 1] if i + 1 < len(argv) else ""
    del argv[i:i + 2]
    if not (ROOT / "agents" / "searched" / name).is_file():
        raise SystemExit(f"--run-gait must name a file of agents/searched/, got {name!r}")
    return name


MODEL = _model_from_argv(sys.argv)
RUN_GAIT = _run_gait_from_argv(sys.argv)
PHYSICS = _pivot_physics() if MODEL == "pivot" else {}   # env keywords every run on MODEL gets
OWN_FILE = RUN_GAIT or {"plane": "plane_own.json", "pivot": "pivot_own_limited.json"}[MODEL]
OWN_JSON = ROOT / "agents" / "searched" / OWN_FILE
SUFFIX = "" if MODEL == "plane" else "_" + MODEL   # plane keeps its file names; pivot: yaw_search_pivot.json, ...
# With --run-gait, every output that depends on the running gait also carries the file's stem
# (direction_plane_own_robust.json, ...); the turning-gait search (yaw_search) does not.
GAIT_SUFFIX = SUFFIX + ("" if RUN_GAIT is None else "_" + Path(RUN_GAIT).stem)


# The agent's file (agents/searched/): turn_then_run.json (plane), turn_then_run_pivot.json, and with
# --run-gait plane_own_robust.json turn_then_run_robust.json (write_agent.py writes it).
AGENT_FILE = ROOT / "agents" / "searched" / ("turn_then_run" + SUFFIX + (
    "" if RUN_GAIT is None else "_" + Path(RUN_GAIT).stem.replace(f"{MODEL}_own_", "")) + ".json")


def out_name(stem, gait=True):
    """This model's (and running gait's) file name for an output (or input) JSON of these scripts:
    yaw_search.json on the plane, yaw_search_pivot.json on the pivot, final_eval_plane_own_robust.json
    with --run-gait plane_own_robust.json; gait=False leaves the running gait out of the name."""
    return f"{stem}{GAIT_SUFFIX if gait else SUFFIX}.json"


def own_gait():
    return load_gaits(OWN_JSON)[0]


def ramped(g, t):
    """Per-leg gaits g (n, 7) with their swings scaled by the running gait's own ramp-in at time t
    (s; rrrobot_gym.gait_search.ramp_factor): the running gait as its file runs it from rest. No
    change for a gait without a ramp (plane_own.json, pivot_own_limited.json)."""
    g = np.array(g, float)
    g[:, :2] *= ramp_factor(t, own_gait().ramp_s)
    return g


def yaw_of(states):
    """Body yaw (N,) rad: body x axis in world, atan2(R10, R00)."""
    qw, qx, qy, qz = states[:, 2], states[:, 3], states[:, 4], states[:, 5]
    r00 = 1.0 - 2.0 * (qy * qy + qz * qz)
    r10 = 2.0 * (qx * qy + qw * qz)
    return np.arctan2(r10, r00)


def start_states(n_each, seeds, noise_scale=0.01):
    """Start states for each of seeds (None = paper's start, no noise), noise drawn as the env does."""
    rows = []
    for s in seeds:
        if s is None:
            rows.append(np.zeros(10))
        else:
            rng = np.random.default_rng(s)
            rows.append(rng.uniform(-noise_scale, noise_scale, size=10))
    return task.start_states(np.array(rows))


def run(controller, starts, steps, record_every=1, targets=0.0, **env_kwargs):
    """Run N robots from states `starts` (N, 13) in ONE vector env (no autoreset effect: we
    stop tracking a robot at its first termination). controller(k, states, alive) -> (N, 2)
    leg target angles (rad) commanded for the end of step k+1 (as GaitAgent does).
    Returns dict: yaw (T+1, N) unwrapped, up (T+1, N, 2) upright contact points (frozen after
    termination), terminated (N,), end_step (N,), reason dict, peaks."""
    n = len(starts)
    env = RRRobotVectorEnv(num_envs=n, max_episode_steps=None, model=MODEL, reset_noise_scale=0.0,
                           **{**PHYSICS, **env_kwargs})
    env.reset(seed=0, options={"state": starts, "target_direction": targets})
    reward_forward = np.zeros(n)
    radius = env.config.sim.robot.radius
    yaw = [yaw_of(env.states)]
    up = [task.upright_contact_points(env.states, radius)]
    alive = np.ones(n, dtype=bool)
    end_step = np.full(n, steps)
    why = np.array([""] * n, dtype=object)
    torque_peak = np.zeros(n); rate_peak = np.zeros(n); slip_max = np.zeros(n); clear_min = np.full(n, np.inf)
    for k in range(steps):
        angles = controller(k, env.states, alive)
        actions = np.clip(task.leg_targets_to_action(angles), -1.0, 1.0).astype(np.float32)
        _, _, terminated, _, info = env.step(actions)
        ending = terminated & alive
        st = env.states.copy()
        src = info
        if ending.any():
            fin = info["final_info"]
            for i in np.flatnonzero(ending):
                reasons = []
                if fin["leg_clearance"][i] <= 0: reasons.append("leg-on-floor")
                if fin["slip_velocity"][i] > env.config.max_slip_velocity: reasons.append("slip")
                if fin["liftoff_time"][i] > env.config.max_liftoff_time: reasons.append("liftoff")
                if fin["tilt"][i] >= dynamics.TILT_LIMIT: reasons.append("tilt")
                if fin["numerical_failure"][i]: reasons.append("numerical")
                why[i] = "+".join(reasons) or "?"
            end_step[ending] = k + 1
        rf = np.where(ending, info["final_info"]["reward_forward"] if ending.any() else 0.0, info["reward_forward"])
        reward_forward += np.where(alive, rf, 0.0)
        running = alive & ~terminated
        torque_peak[running] = np.maximum(torque_peak[running], info["torque_peak"][running])
        rate_peak[running] = np.maximum(rate_peak[running], info["leg_rate_peak"][running])
        slip_max[running] = np.maximum(slip_max[running], np.where(k * env.dt >= task.STARTUP_GRACE, info["slip_velocity"][running], 0))
        clear_min[running] = np.minimum(clear_min[running], info["leg_clearance"][running])
        y = yaw_of(st); u = task.upright_contact_points(st, radius)
        # freeze ended robots
        y = np.where(alive & ~terminated, y, yaw[-1] if True else y)
        u = np.where((alive & ~terminated)[:, None], u, up[-1])
        if ending.any():  # last in-model point: from final_info
            fin = info["final_info"]
            u[ending, 0] = fin["x_upright"][ending]; u[ending, 1] = fin["y_upright"][ending]
        alive = running
        yaw.append(y); up.append(u)
    env.close()
    yaw = np.unwrap(np.array(yaw), axis=0)
    return dict(reward_forward_sum=reward_forward, yaw=yaw, up=np.array(up), terminated=~alive, end_step=end_step, why=why, dt=env.dt,
                torque_peak=torque_peak, leg_rate_peak=rate_peak, slip_max=slip_max, clear_min=clear_min)


def sinusoid_controller(params, dt):
    params = np.asarray(params, float)
    return lambda k, states, alive: sinusoid_angles(params, (k + 1) * dt)


def mirror_gait(params):
    """The six-number form (a1, a2, o1, o2, w, gap) of a sinusoid's leg-exchanged mirror (the
    agent's per_leg_gait(params, mirror=True), up to a phase): it turns the other way."""
    a1, a2, o1, o2, w, gap = np.asarray(params, float)
    return np.array([a2, a1, o2, o1, w, -gap])
