"""A trained PPO policy as one ONNX network, for a robot's own computer.

:func:`export_onnx` writes what ``rrrobot_gym.agents.load_ppo_agent(model).predict(obs,
deterministic=True)`` computes as one graph: input ``observation`` (N, observation size) float32,
the env's raw observations; output ``action`` (N, legs) float32, the legs' targets in [-1, 1]. Folded
in are the VecNormalize statistics (as constants), the actor's mean action clipped to the action
space as SB3 does, and for a policy trained mirrored the mirror: rows whose heading points to -Y go
in mirrored and come out mirrored back. A residual policy (on a scripted agent) is
not one network and is refused. Needs ``rrrobot_gym[train]`` and ``onnx``; loading the model
unpickles it: trusted files only.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from .agents.mirror import SIN_TOLERANCE, MirroredAgent, sin_index
from .agents.residual import RESIDUAL_FILE, run_directory
from .envs.task import mirror_actions, mirror_observations

OPSET = 17


def mirror_map(mirror, size: int):
    """(permutation, signs, offsets): ``mirror(x) == x[..., permutation] * signs + offsets`` for a
    mirror of vectors of ``size`` entries that moves, flips and shifts entries (each output one
    input's, +-, plus a constant: a flipped leg's angle is pi - angle), found from the images of
    zero and of the unit vectors."""
    offsets = np.asarray(mirror(np.zeros((1, size), dtype=np.float32)), dtype=np.float32)[0]
    images = np.asarray(mirror(np.eye(size, dtype=np.float32)), dtype=np.float32) - offsets  # row j: e_j's image
    permutation = np.abs(images).argmax(axis=0)
    signs = images[permutation, np.arange(size)]
    if not ((np.abs(images).sum(axis=0) == 1).all() and (np.abs(signs) == 1).all()):
        raise ValueError("the mirror is not a signed permutation of entries: it cannot be exported")
    return permutation, signs.astype(np.float32), offsets


def policy_module(agent):
    """A torch module computing ``agent.predict(obs, deterministic=True)`` for a batch of raw
    observations: ``agent`` a :class:`~rrrobot_gym.agents.ppo.PPOAgent` or a
    :class:`~rrrobot_gym.agents.mirror.MirroredAgent` around one."""
    import torch

    mirrored = isinstance(agent, MirroredAgent)
    ppo = agent.policy if mirrored else agent
    policy = ppo.model.policy
    low, high = ppo.model.action_space.low, ppo.model.action_space.high
    if mirrored:
        config, legs = agent.config, agent.config.num_robot_legs
        permutation, signs, offsets = mirror_map(lambda x: mirror_observations(x, config), config.observation_size)
        swap, swap_signs, _ = mirror_map(lambda x: mirror_actions(x, config.sim.robot), legs)
        sin_at = sin_index(config)
    mean, scale = ppo.obs_mean, np.sqrt(ppo.obs_var + ppo.epsilon)  # load_ppo_agent refuses a run without them

    class Policy(torch.nn.Module):
        def __init__(self):
            super().__init__()
            self.extractor, self.mlp, self.action_net = (policy.pi_features_extractor, policy.mlp_extractor,
                                                         policy.action_net)
            for name, value, dtype in (("mean", mean, torch.float64), ("scale", scale, torch.float64),
                                       ("low", low, torch.float32), ("high", high, torch.float32)):
                self.register_buffer(name, torch.as_tensor(np.asarray(value), dtype=dtype))
            if mirrored:
                self.register_buffer("permutation", torch.as_tensor(permutation, dtype=torch.int64))
                self.register_buffer("signs", torch.as_tensor(signs))
                self.register_buffer("offsets", torch.as_tensor(offsets))
                self.register_buffer("swap", torch.as_tensor(swap, dtype=torch.int64))
                self.register_buffer("swap_signs", torch.as_tensor(swap_signs))

        def forward(self, observation):
            if mirrored:  # MirroredAgent.predict: rows with sin(heading) < 0 as their mirror images
                flip = (observation[:, sin_at] < -SIN_TOLERANCE).unsqueeze(1)
                observation = torch.where(flip, observation[:, self.permutation] * self.signs + self.offsets, observation)
            # PPOAgent.normalize: in float64, as it computes, then float32
            scaled = ((observation.double() - self.mean) / self.scale).clamp(-ppo.clip_obs, ppo.clip_obs).float()
            action = self.action_net(self.mlp.forward_actor(self.extractor(scaled)))
            action = torch.maximum(torch.minimum(action, self.high), self.low)  # SB3's predict on a Box space
            return torch.where(flip, action[:, self.swap] * self.swap_signs, action) if mirrored else action

    return Policy().eval()


def export_onnx(model_path, out_path) -> Path:
    """Write the policy of ``model_path`` (an SB3 PPO zip with the files ``train.py`` writes beside
    it) to ``out_path`` as ONNX (see the module's docstring). FileNotFoundError names a missing
    file; ValueError refuses a residual policy."""
    import torch

    from .agents.ppo import load_ppo_agent, trained_algorithm

    model_path = Path(model_path)
    if not model_path.exists():
        raise FileNotFoundError(f"no PPO model at {model_path}")
    if (run_directory(model_path) / RESIDUAL_FILE).exists():
        raise ValueError(f"{model_path} is a residual policy (its run has {RESIDUAL_FILE}): its action adds a "
                         "scripted agent's, so it is not one network and cannot be exported as ONNX")
    algo = trained_algorithm(model_path)
    if algo != "ppo":
        raise ValueError(f"{model_path} is a {algo} model (its run's args.json): export-onnx writes PPO policies")
    agent = load_ppo_agent(model_path)
    module = policy_module(agent)
    size = agent.model.observation_space.shape[-1]
    out_path = Path(out_path)
    with torch.no_grad(), warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # (the TorchScript exporter: no onnxscript needed)
        torch.onnx.export(module, (torch.zeros(2, size),), str(out_path), input_names=["observation"],
                          output_names=["action"], dynamic_axes={"observation": {0: "batch"}, "action": {0: "batch"}},
                          opset_version=OPSET, dynamo=False)
    return out_path
