"""Helpers shared by the benchmarks: machine description, cached references, errors, output."""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import pickle
import platform
import statistics
import time
from pathlib import Path

import numpy as np

from rrrobot_gym import dynamics
from rrrobot_gym.simulation import SimConfig, simulate_reference

ROOT = Path(__file__).resolve().parent.parent
POLICIES = {"plane": ROOT / "agents" / "pretrained" / "best_model.zip",
            "pivot": ROOT / "agents" / "pretrained_pivot" / "best_model.zip"}
"""The shipped PPO policies, one a model."""

CACHE_DIR = Path(os.environ.get("RRROBOT_BENCH_CACHE", Path(__file__).resolve().parent / ".cache"))
"""Reference trajectories are slow (seconds each) and deterministic: kept here between runs."""


def machine() -> dict:
    """What the numbers were measured on."""
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "cpu": cpu,
        "nproc": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "load_average_1min": os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
    }


def gentle_actions(rng, shape, steps):
    """(steps, *shape) smooth leg targets near vertical, from random phases: every robot stays
    inside the model, so no resets muddle a timing."""
    phase = rng.uniform(0, 2 * np.pi, shape)
    k = np.arange(steps)[:, None, None] if len(shape) == 2 else np.arange(steps)[:, None]
    return (0.05 * np.sin(0.4 * k + phase)).astype(np.float32)


def parser(description: str, markdown: bool = False) -> argparse.ArgumentParser:
    """The options every benchmark takes (--quick, --json), and --markdown for those that write
    Markdown tables (``markdown``)."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--quick", action="store_true", help="fewer, shorter runs")
    p.add_argument("--json", metavar="FILE", help="write the results as JSON")
    if markdown:
        p.add_argument("--markdown", metavar="FILE", help="write the tables as Markdown")
    return p


def write_json(path: str | None, payload: dict):
    if path:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Path(path).write_text(json.dumps(payload, indent=2, default=float))
        print(f"wrote {path}")


def reference(config: SimConfig, targets, duration: float, sample_dt: float, state=None) -> np.ndarray:
    """States of :func:`simulate_reference` (rtol = atol = 1e-10), cached on disk by their inputs."""
    key = repr((config.model, config.robot, config.gains, config.legs, repr(targets.__dict__), duration, sample_dt,
                None if state is None else np.asarray(state).tobytes().hex()))  # fmt: skip
    path = CACHE_DIR / f"ref-{hashlib.sha256(key.encode()).hexdigest()[:20]}.pkl"
    if path.exists():
        return pickle.loads(path.read_bytes())
    states = simulate_reference(config, targets, duration, sample_dt=sample_dt, state=state).states
    CACHE_DIR.mkdir(parents=True, exist_ok=True)
    path.write_bytes(pickle.dumps(states))
    return states


def contact_error(states, ref) -> np.ndarray:
    """m, distance between contact points, per sample."""
    return np.hypot(states[..., 0] - ref[..., 0], states[..., 1] - ref[..., 1])


def attitude_error(states, ref) -> np.ndarray:
    """rad, angle of R_ref^T R, per sample (from the quaternion q_ref^* q)."""
    q, p = states[..., dynamics.QUAT], ref[..., dynamics.QUAT]
    w = np.abs(np.sum(q * p, axis=-1))
    return 2.0 * np.arccos(np.clip(w, 0.0, 1.0))


def median_time(fn, repeats: int = 5) -> float:
    """s, median wall time of fn() over ``repeats`` runs (the machine is shared: medians, not means)."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def fmt(value: float, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "nan"
    if value == 0:
        return "0"
    return f"{value:.{digits}g}"


def markdown_table(header: list[str], rows: list[list]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)
