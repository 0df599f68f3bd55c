"""Stepper candidates of probes/candidates.py on one set of windows: the status quo's own (numpy)
rollout of benchmarks.scene_accuracy, so that every candidate meets the same paths and amplification.

    PYTHONPATH=. python probes/winfixed.py MODEL ACTIONS CANDIDATE ...
"""
import os, sys, time
import numpy as np
sys.path.insert(0, os.path.dirname(__file__))
import candidates as C  # noqa: E402  (numpy everywhere)
from dataclasses import replace  # noqa: E402
from benchmarks import scene_accuracy as sa  # noqa: E402
from benchmarks._common import contact_error  # noqa: E402

model, actions = sys.argv[1], sys.argv[2]
C.choose("clip/rk4")
states, rs, re_, ended, dt, sim = sa.rollout(model, actions, 45.0)
start, ws, we, picked = sa.windows(states, rs, re_, ended, dt, sa.WINDOW_STARTS_S)
ref = sa.cached_reference(sim, start, ws, we, dt)
for cand in sys.argv[3:]:
    n = C.choose(cand)
    for k in C.STATS:
        C.STATS[k] = 0
    t = time.time()
    path = sa.replay(replace(sim, timestep=0.05 / n), start, ws, we, dt)
    err = contact_error(path, ref).max(axis=0)
    per = sa.per_window(err, picked, sa.WINDOW_STARTS_S)
    extra = ""
    if C.STATS.get("robot_substeps"):
        q = C.STATS["split"] / C.STATS["robot_substeps"]
        extra = f"; switch substeps {100 * q:.2f} % of a robot's ({100 * (1 - (1 - q) ** 32):.0f} % of 32-lane blocks')"
    print(f"{model} {actions} {cand}: max {err.max() * 1e3:.3g} mm, per window {[round(v * 1e3, 3) for v in per]}{extra} "
          f"({time.time() - t:.0f} s)", flush=True)
