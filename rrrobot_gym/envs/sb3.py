"""A Stable-Baselines3 ``VecEnv`` over the native batched env, so SB3 trains on it directly.

SB3 cannot take a Gymnasium ``VectorEnv``, but its ``VecEnv`` resets a finished env within the
step, as Gymnasium's SAME_STEP autoreset does, so this adapter only reshapes the results
(``info["terminal_observation"]``, ``info["TimeLimit.truncated"]``). ``rrrobot_gym.envs``
imports this module, and so SB3, only when ``RRRobotSB3VecEnv`` is first used.
"""

from __future__ import annotations

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from stable_baselines3.common.vec_env import VecEnv

from ..params import real_number
from .vector import RRRobotVectorEnv

NOISE_STREAM = 0x6E6F697365
"""Mixed into :func:`noise_seed`'s entropy: the batch's stream is none of its sub-envs'."""


def noise_seed(seeds) -> int:
    """The int seed of a batch's own generator (its observation noise) from SB3's per-env ``seeds``
    (None where not given): every (index, seed) given, through a SeedSequence. Without it, SB3's
    ``seed()`` seeded the robots but not their noise, and no two training runs were alike."""
    given = [value for i, s in enumerate(seeds) if s is not None for value in (i, int(s))]
    return int(np.random.SeedSequence([NOISE_STREAM, *given]).generate_state(1, np.uint64)[0])


class RRRobotSB3VecEnv(VecEnv):
    """SB3 view of a batched Gymnasium vector env with SAME_STEP autoreset.

    ``vector_env``: an :class:`RRRobotVectorEnv` (``gymnasium.make_vec("RRRobot-v0", num_envs=N)``) or
    any Gymnasium ``VectorEnv`` with SAME_STEP autoreset; None builds an :class:`RRRobotVectorEnv`
    from ``num_envs`` and ``env_kwargs``.

    ``infos[i]`` is env i's step info; for a finished episode, the last step's info plus
    ``terminal_observation`` and ``TimeLimit.truncated``, while the returned observation starts
    the next episode, whose reset info goes to ``reset_infos[i]``. Seeds from ``seed()`` and
    options from ``set_options()`` apply at the next ``reset()``; per-env options must be equal.

    The sub-envs share one batched env, so, one entry per requested index:

    - ``get_attr``: row i of a per-env attribute (``per_env_attributes``, a copy), else the value.
    - ``set_attr``: writes row i of a settable per-env attribute (``per_env_settable``:
      ``episode_target_directions``, in effect from the next step); the other per-env arrays are
      the simulation's state (set them with ``reset`` options); any other attribute is shared, so
      only indices None (or every index) may set it. The rest raise ``ValueError``.
    - ``env_method``: a ``per_env_methods`` method (``render``) is called once and env i's result
      returned; any other acts on every env, so only indices None (or every index) may call it.
    """

    def __init__(self, vector_env: VectorEnv | None = None, *, num_envs: int | None = None, **env_kwargs):
        if vector_env is None:
            vector_env = RRRobotVectorEnv(num_envs=1 if num_envs is None else num_envs, **env_kwargs)
        elif num_envs is not None or env_kwargs:
            raise TypeError("pass either a vector_env or num_envs and env keywords, not both")
        if not isinstance(vector_env, VectorEnv):
            raise TypeError(f"vector_env must be a gymnasium VectorEnv, got {type(vector_env).__name__}")
        mode = vector_env.metadata.get("autoreset_mode")
        if mode != AutoresetMode.SAME_STEP:
            raise ValueError(
                f"the SB3 adapter needs a vector env with AutoresetMode.SAME_STEP (SB3's convention), got {mode!r}"
            )
        self.vector_env = vector_env
        super().__init__(vector_env.num_envs, vector_env.single_observation_space, vector_env.single_action_space)
        self._actions = None

    def reset(self):
        seeds = None if all(seed is None for seed in self._seeds) else list(self._seeds)
        options = self._options
        if any(options) and any(option != options[0] for option in options):
            raise ValueError("per-env reset options differ; the batched env takes one options dict for all envs")
        if seeds is not None:  # (a list leaves the batch's own generator, its observation noise, as it is)
            self.vector_env.np_random = seeding.np_random(noise_seed(seeds))[0]
        observations, info = self.vector_env.reset(seed=seeds, options=options[0] if any(options) else None)
        self.reset_infos = _info_list(info, self.num_envs)
        self._reset_seeds()
        self._reset_options()
        return observations

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        observations, rewards, terminated, truncated, info = self.vector_env.step(self._actions)
        self._actions = None
        dones = terminated | truncated
        # (the envs that go on get dicts filled when read; each gets a key below, so none is an empty
        # dict underneath: json's C encoder reads that size)
        infos = _info_list(info, self.num_envs, exclude=("final_obs", "final_info"), lazy=~dones)
        if dones.any():
            rows = np.flatnonzero(dones).tolist()
            final_infos = _info_rows(info["final_info"], rows)
            for i in rows:
                self.reset_infos[i] = infos[i]
                infos[i] = final_infos[i]
                infos[i]["terminal_observation"] = info["final_obs"][i]
                infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
        for i in np.flatnonzero(~dones).tolist():
            infos[i]["TimeLimit.truncated"] = False
        return observations, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        self.vector_env.close()

    def get_images(self):
        frames = self.vector_env.render()
        return [None] * self.num_envs if frames is None else list(frames)

    def get_attr(self, attr_name, indices=None):
        value = getattr(self.vector_env, attr_name)
        indices = self._get_indices(indices)
        if attr_name in self._per_env("per_env_attributes"):
            return [np.copy(value[i]) for i in indices]
        return [value for _ in indices]

    def set_attr(self, attr_name, value, indices=None):
        indices = list(self._get_indices(indices))
        if attr_name in self._per_env("per_env_attributes"):
            if attr_name not in self._per_env("per_env_settable"):
                raise ValueError(
                    f"{attr_name} is the batched env's simulation state, not a setting: start from a "
                    "state with set_options({'state': ...}) and reset()"
                )
            rows = getattr(self.vector_env, attr_name)
            if rows.dtype.kind == "f":  # (a heading: a finite number, named if not)
                value = real_number(attr_name, value)
            for i in indices:
                rows[i] = value
            return
        if attr_name == "num_envs":
            raise ValueError("num_envs is fixed when the batched env is made: make a new one for another batch size")
        self._require_all(indices, f"set_attr({attr_name!r})")
        setattr(self.vector_env, attr_name, value)

    def env_method(self, method_name, *method_args, indices=None, **method_kwargs):
        indices = list(self._get_indices(indices))
        if method_name not in self._per_env("per_env_methods"):
            self._require_all(indices, f"env_method({method_name!r})")
        result = getattr(self.vector_env, method_name)(*method_args, **method_kwargs)
        if method_name in self._per_env("per_env_methods"):
            return [None if result is None else result[i] for i in indices]
        return [result for _ in indices]

    def env_is_wrapped(self, wrapper_class, indices=None):
        return [False for _ in self._get_indices(indices)]

    def _get_indices(self, indices):
        """SB3's indices (None: every env; an int; an iterable), each checked to be an env's."""
        indices = list(super()._get_indices(indices))
        bad = [i for i in indices if isinstance(i, bool) or not isinstance(i, (int, np.integer))
               or not -self.num_envs <= i < self.num_envs]  # fmt: skip
        if bad:
            raise IndexError(f"env indices {bad} are not among the {self.num_envs} envs (0 to {self.num_envs - 1})")
        return [int(i) % self.num_envs for i in indices]  # (-1 is the last env, as in a list)

    def _per_env(self, kind):
        return getattr(self.vector_env, kind, ())

    def _require_all(self, indices, what):
        if sorted(indices) != list(range(self.num_envs)):
            raise ValueError(
                f"{what} acts on all {self.num_envs} envs at once (they share one batched env), "
                f"so it cannot act on indices {indices} only; pass indices=None"
            )


def _info_list(info, num_envs, exclude=(), lazy=None):
    """Gymnasium's vector info (dict of arrays with "_key" masks) as SB3's list of per-env dicts. The
    rows in the boolean mask ``lazy`` get :class:`EnvInfo` dicts, filled when read, if every one of
    them has the same keys (each column a number array) and those are all the keys it has; the
    other rows (or all, if not) are built at once."""
    rows = list(range(num_envs))
    infos = [None] * num_envs
    columns = _shared_columns(info, lazy, exclude) if lazy is not None and lazy.any() else None
    if columns is not None:
        for i in np.flatnonzero(lazy).tolist():
            infos[i] = EnvInfo(columns, i)
        rows = np.flatnonzero(~lazy).tolist()
    for i, row_info in _info_rows(info, rows, exclude).items():
        infos[i] = row_info
    return infos


def _shared_columns(info, rows, exclude):
    """The columns ``{key: (N,) array}`` every env in the boolean mask ``rows`` has, in the info's
    order, if those envs have no other keys and each column is a number array; else None."""
    columns = {}
    for key, values in info.items():
        if key.startswith("_") or key in exclude:
            continue
        if not (isinstance(values, np.ndarray) and values.dtype != object):
            return None
        mask = info.get("_" + key)
        present = rows if mask is None else mask[rows]
        if present.all():
            columns[key] = values
        elif present.any():  # (some of the rows have it, some not: built at once)
            return None
    return columns


def _info_rows(info, rows, exclude=()):
    """``{i: env i's info dict}`` for the env indices ``rows``, from a vector info; nested infos
    (``final_info``) as dicts of their own."""
    infos = {i: {} for i in rows}
    if not rows:
        return infos
    for key, values in info.items():
        if key.startswith("_") or key in exclude:
            continue
        mask = info.get("_" + key)
        keep = rows if mask is None else [i for i in rows if mask[i]]
        if isinstance(values, dict):
            for i, sub_info in _info_rows(values, keep).items():
                infos[i][key] = sub_info
        elif isinstance(values, np.ndarray) and values.dtype != object:
            for i, item in zip(keep, values[keep].tolist()):
                infos[i][key] = item
        else:
            for i in keep:
                infos[i][key] = values[i]
    return infos


class EnvInfo(dict):
    """One env's info in the SB3 adapter's ``infos``: a dict, filled from the batch's arrays when first
    read as a whole (copy, items, iteration, printing ...) or by one of their keys; a key the batch
    does not have (``get("episode")``, as SB3 asks of every env every step) is answered without
    filling it. Keys set before it is filled come after the batch's, as in a dict built eagerly."""

    __slots__ = ("_columns", "_row")

    def __init__(self, columns: dict, row: int):
        super().__init__()
        self._columns, self._row = columns, row  # {key: (N,) array}, shared by the batch's envs

    def _fill(self):
        columns = self._columns
        if columns is not None:
            self._columns = None
            later = dict.copy(self)
            dict.clear(self)
            row = self._row
            dict.update(self, {key: values[row].item() for key, values in columns.items()})
            dict.update(self, later)

    def __getitem__(self, key):
        if self._columns is not None and key in self._columns:
            self._fill()
        return dict.__getitem__(self, key)

    def get(self, key, default=None):
        if self._columns is not None and key in self._columns:
            self._fill()
        return dict.get(self, key, default)

    def __contains__(self, key):
        return dict.__contains__(self, key) or (self._columns is not None and key in self._columns)

    def __getstate__(self):  # (pickled and copied as the dict it stands for)
        self._fill()
        return None, {"_columns": None, "_row": self._row}


def _filling(name):
    method = getattr(dict, name)

    def call(self, *args, **kwargs):
        self._fill()
        return method(self, *args, **kwargs)

    call.__name__ = call.__qualname__ = name
    return call


for _name in ("keys", "values", "items", "__iter__", "__reversed__", "__len__", "__repr__", "__eq__", "__ne__", "copy",
              "pop", "popitem", "setdefault", "update", "__delitem__", "clear", "__or__", "__ror__", "__ior__",
              "__reduce__", "__reduce_ex__"):  # fmt: skip
    setattr(EnvInfo, _name, _filling(_name))
