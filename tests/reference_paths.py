"""Stored reference paths: every Table II gait on both models, 50 s from the paper's start, by
``simulate_reference`` (scipy's DOP853 at rtol = atol = 1e-10).

The six adaptive solves take about as long as the rest of the paper tests together, and they
change only when the equations of motion, the parameters or the start change. So they are
computed once, stored in ``tests/data/table2_reference_paths.npz`` with the configuration that
made them, and checked against a fresh solve of their first seconds on every test run
(``tests/test_paper_results.py``): a change in the dynamics fails that check, and the file is
then remade with

    python tests/reference_paths.py
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from rrrobot_gym.control import table2_gait
from rrrobot_gym.simulation import SimConfig, simulate_reference

PATH = Path(__file__).resolve().parent / "data" / "table2_reference_paths.npz"
DURATION = 50.0  # s
SAMPLE_DT = 0.05  # s
CASES = [(model, gait) for model in ("plane", "pivot") for gait in (1, 2, 3)]
SOLVER = {"method": "DOP853", "rtol": 1e-10, "atol": 1e-10}


def key(model: str, gait: int) -> str:
    return f"{model}_gait{gait}"


def describe(model: str) -> str:
    """What a stored path depends on: the model's whole configuration and the solver's settings."""
    return json.dumps({"config": repr(SimConfig(model=model)), "solver": SOLVER, "sample_dt": SAMPLE_DT})


def solve(model: str, gait: int, duration: float = DURATION) -> np.ndarray:
    """Contact path (x, y), m, shape (T, 2), sampled every SAMPLE_DT from t = 0."""
    traj = simulate_reference(SimConfig(model=model), table2_gait(gait), duration, sample_dt=SAMPLE_DT, **SOLVER)
    return np.column_stack([traj.x, traj.y])


def load() -> tuple[dict, dict]:
    """({(model, gait): path (T, 2)}, {model: description}), as stored."""
    with np.load(PATH) as data:
        paths = {(m, g): data[key(m, g)] for m, g in CASES}
        described = {m: str(data[f"{m}_described"]) for m in ("plane", "pivot")}
    return paths, described


def main() -> None:
    PATH.parent.mkdir(parents=True, exist_ok=True)
    arrays = {key(m, g): solve(m, g) for m, g in CASES}
    arrays.update({f"{m}_described": np.array(describe(m)) for m in ("plane", "pivot")})
    np.savez_compressed(PATH, **arrays)
    print(f"wrote {PATH}")


if __name__ == "__main__":
    main()
