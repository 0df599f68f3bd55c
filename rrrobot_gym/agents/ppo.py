"""Loading a trained policy, with its observation normalisation, as an agent: PPO's, or any
algorithm's ``train.py --algo`` trains (its run's ``args.json`` names it).

A model whose actions need more than its network (a mirrored or a residual run) names a policy
class in its zip that SB3's ``PPO.load`` refuses to build (:class:`~.mirror.MirroredPolicy`,
:class:`~.residual.ResidualPolicy`); :func:`load_ppo_agent` reads it as the network it is and adds
the rest. Loading a Stable-Baselines3 model unpickles it (``PPO.load`` and the VecNormalize
statistics both use pickle): load only files you trust.
"""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import numpy as np

from .mirror import MIRROR_FILE, MirroredAgent, MirroredPolicy, is_mirrored
from .residual import RESIDUAL_FILE, ResidualAgent, ResidualPolicy, load_base, run_directory

RUN_FILE_OF = {MirroredPolicy: MIRROR_FILE, ResidualPolicy: RESIDUAL_FILE}
"""The policy classes that refuse ``PPO.load``, and the run file whose agent each model needs."""


SCENE_KEYWORDS = ("model", "target_direction", "reset_noise_scale", "randomize")
"""Env keywords whoever runs a policy chooses (the scene, and whether its robot is drawn at random);
:attr:`PPOAgent.env_kwargs` leaves them out."""


class PPOAgent:
    """A PPO policy that normalises raw env observations with saved statistics.

    ``obs_mean``, ``obs_var``, ``clip_obs`` and ``epsilon`` are SB3's ``VecNormalize``'s at the
    end of training (None: raw observations). ``env_config`` holds the training env's keywords
    (``gymnasium.make("RRRobot-v0", **agent.env_config)`` rebuilds it); ``env_kwargs`` the same
    without :data:`SCENE_KEYWORDS`, what an evaluation of its own scene keeps.
    """

    name = "ppo"
    closed_loop = True  # (it reads the observation: evaluate.py gives it no open-loop "own direction")

    def __init__(self, model, obs_mean=None, obs_var=None, clip_obs=10.0, epsilon=1e-8, env_config=None):
        self.model = model
        self.env_config = dict(env_config or {})
        self.env_kwargs = {key: value for key, value in self.env_config.items() if key not in SCENE_KEYWORDS}
        self.obs_mean = None if obs_mean is None else np.asarray(obs_mean, dtype=np.float64)
        self.obs_var = None if obs_var is None else np.asarray(obs_var, dtype=np.float64)
        self.clip_obs = float(clip_obs)
        self.epsilon = float(epsilon)

    def normalize(self, observation):
        observation = np.asarray(observation, dtype=np.float64)
        if self.obs_mean is None:
            return observation.astype(np.float32)
        scaled = (observation - self.obs_mean) / np.sqrt(self.obs_var + self.epsilon)
        return np.clip(scaled, -self.clip_obs, self.clip_obs).astype(np.float32)

    def check_observation(self, observation) -> np.ndarray:
        """``observation`` as an array, or a ValueError naming what is wrong: a size other than the
        policy's, or NaN/inf (:func:`rrrobot_gym.envs.task.check_observations`)."""
        from ..envs.task import check_observations

        return check_observations(observation, self.model.observation_space.shape[-1])

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        observation = self.check_observation(observation)
        actions, _ = self.model.predict(self.normalize(observation), deterministic=deterministic)
        return actions, state


def normalization_path(model_path) -> Path:
    """Where the VecNormalize statistics of a saved model live: ``best_model.zip`` ->
    ``vecnormalize.pkl``; ``final_model.zip`` -> ``final_vecnormalize.pkl``; a checkpoint
    ``ppo_<N>_steps.zip`` -> ``ppo_vecnormalize_<N>_steps.pkl``; ``<stem>.zip`` ->
    ``<stem>_vecnormalize.pkl``."""
    model_path = Path(model_path)
    stem = model_path.stem
    if stem == "best_model":
        name = "vecnormalize.pkl"
    elif stem == "final_model":
        name = "final_vecnormalize.pkl"
    elif stem.endswith("_steps") and "_" in stem[: -len("_steps")]:
        prefix, steps = stem[: -len("_steps")].rsplit("_", 1)
        name = f"{prefix}_vecnormalize_{steps}_steps.pkl"
    else:
        name = f"{stem}_vecnormalize.pkl"
    return model_path.with_name(name)


def saved_policy_class(model_path):
    """The policy class a model zip names, read as SB3 reads it (nothing else is loaded), or None if
    it names none that imports; a file that is not an SB3 model zip is a ValueError naming it."""
    import zipfile

    from stable_baselines3.common.save_util import json_to_data

    try:
        with zipfile.ZipFile(model_path) as archive:
            entry = json.loads(archive.read("data"))["policy_class"]
    except (zipfile.BadZipFile, KeyError, ValueError):
        raise ValueError(f"{model_path} is not a Stable-Baselines3 model zip") from None
    return json_to_data(json.dumps({"policy_class": entry})).get("policy_class")


def policy_class_to_save(run_dir):
    """The policy class the models of the train.py run in ``run_dir`` name when saved: the one of
    :data:`RUN_FILE_OF` whose file the run holds, or None (SB3's own: ``PPO.load`` runs them as trained)."""
    return next((cls for cls, name in RUN_FILE_OF.items() if (Path(run_dir) / name).exists()), None)


def load_sb3_model(model_path, device="cpu", **kwargs):
    """The SB3 model of ``model_path`` (its algorithm's ``load``, with ``kwargs``; the algorithm its
    run names, :func:`trained_algorithm`): the network alone, without its observation statistics,
    mirror or base agent. A zip naming a class of :data:`RUN_FILE_OF` loads as the algorithm's
    ``MlpPolicy`` it was trained as."""
    from ..hyperparams import algorithm_class

    algorithm = algorithm_class(trained_algorithm(model_path))
    custom = {"policy_class": algorithm.policy_aliases["MlpPolicy"]} if saved_policy_class(model_path) in RUN_FILE_OF else None
    return algorithm.load(model_path, device=device, custom_objects=custom, **kwargs)


def check_run_files(model_path, vecnormalize_path=None) -> None:
    """Raise FileNotFoundError naming the first file ``train.py`` writes with a model that is
    missing: its observation statistics, ``env_kwargs.json``, and ``mirror.json`` or
    ``residual.json`` if ``args.json`` or the zip's policy class (:data:`RUN_FILE_OF`) names them.
    Without them the policy's speeds mean nothing."""
    model_path = Path(model_path)
    run_dir = run_directory(model_path)
    needed = [(Path(vecnormalize_path) if vecnormalize_path is not None else normalization_path(model_path),
               "its observation statistics"),
              (run_dir / "env_kwargs.json", "its training env's keywords")]
    args_path = run_dir / "args.json"
    trained = json.loads(args_path.read_text()) if args_path.exists() else {}
    if trained.get("mirror"):
        needed.append((run_dir / MIRROR_FILE, "its args.json says it was trained mirrored"))
    if trained.get("residual_on"):
        needed.append((run_dir / RESIDUAL_FILE, "its args.json says it was trained as a residual policy"))
    policy_class = saved_policy_class(model_path)
    if policy_class in RUN_FILE_OF:
        needed.append((run_dir / RUN_FILE_OF[policy_class], f"the zip names {policy_class.__name__} as its policy"))
    for path, why in needed:
        if not path.exists():
            raise FileNotFoundError(f"{model_path}: {path} is missing ({why}; train.py writes it with the model): "
                                    "without it the policy's speeds mean nothing")


def trained_algorithm(model_path) -> str:
    """The algorithm of a model train.py saved (a key of :data:`rrrobot_gym.hyperparams.ALGORITHMS`):
    its run's ``args.json``'s ``algo``; PPO for a run without one (train.py before --algo)."""
    args_path = run_directory(model_path) / "args.json"
    return json.loads(args_path.read_text()).get("algo", "ppo") if args_path.exists() else "ppo"


def load_ppo_agent(model_path, vecnormalize_path=None, device="cpu") -> PPOAgent:
    """Load ``model_path`` (an SB3 model zip: PPO, or the algorithm its run's ``args.json`` names,
    :func:`trained_algorithm`), its VecNormalize statistics (``vecnormalize_path``, or
    :func:`normalization_path`) and its run's ``env_kwargs.json``; a run missing a file it needs
    is refused (:func:`check_run_files`). A run with ``residual.json`` gives a
    :class:`~rrrobot_gym.agents.residual.ResidualAgent`, one with ``mirror.json`` a
    :class:`~rrrobot_gym.agents.mirror.MirroredAgent`; each with ``path``, the model file (what
    evaluate.py labels its rows with). Unpickles the files: trusted files only.
    """
    from ..envs.task import kwargs_from_json

    model_path = Path(model_path)
    if not model_path.exists():
        raise FileNotFoundError(f"no PPO model at {model_path}")
    run_dir = run_directory(model_path)  # (a checkpoint's run is one directory up)
    check_run_files(model_path, vecnormalize_path)
    model = load_sb3_model(model_path, device=device)
    vecnormalize_path = normalization_path(model_path) if vecnormalize_path is None else vecnormalize_path
    env_config = kwargs_from_json(json.loads((run_dir / "env_kwargs.json").read_text()))
    with open(vecnormalize_path, "rb") as handle:
        stats = pickle.load(handle)
    agent = PPOAgent(model, stats.obs_rms.mean, stats.obs_rms.var, stats.clip_obs, stats.epsilon, env_config)
    if is_mirrored(run_dir):  # train.py --mirror: -Y headings run as mirror images
        agent = MirroredAgent(agent)
    else:
        base = load_base(run_dir)  # a residual policy (train.py --residual-on): its base agent
        agent = agent if base is None else ResidualAgent(agent, *base)
    agent.path = model_path
    return agent
