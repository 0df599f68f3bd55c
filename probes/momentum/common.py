"""Probe: pivot policy windows, candidate steppers (numpy). Throwaway."""
import math, pickle, sys, time
from pathlib import Path
import numpy as np
sys.path.insert(0, "/work/main")
from dataclasses import replace
from benchmarks import scene_accuracy as sa
from benchmarks._common import contact_error
from rrrobot_gym import dynamics
from rrrobot_gym.control import RampTargets
from rrrobot_gym import simulation

CACHE = Path("/tmp/mprobe/windows_pivot.pkl")

def load(model="pivot", actions="policy"):
    path = Path(f"/tmp/mprobe/windows_{model}_{actions}.pkl")
    if path.exists():
        return pickle.loads(path.read_bytes())
    states, rs, re, ended, dt, sim = sa.rollout(model, actions, 45.0)
    start, ws, we, picked = sa.windows(states, rs, re, ended, dt, sa.WINDOW_STARTS_S)
    ref = sa.cached_reference(sim, start, ws, we, dt)
    out = dict(start=start, ws=ws, we=we, picked=picked, ref=ref, dt=dt, sim=sim)
    path.write_bytes(pickle.dumps(out))
    return out

def run(d, stepper, n=15):
    """stepper(f, first, t0, y(list of arrays), h, n, targets, sim) -> y"""
    sim, dt = d["sim"], d["dt"]
    state = d["start"].copy()
    out = [state.copy()]
    h = dt / n
    for i in range(d["ws"].shape[1]):
        targets = Lin(d["ws"][:, i], d["we"][:, i], dt)
        f, first = simulation._stage_fns(sim, targets)
        g = lambda t, c: f(t, c)
        with np.errstate(all="ignore"):
            y = stepper(f, g, 0.0, list(np.array(state.T)), h, n, targets, sim)
        state = np.stack(y, axis=1)
        out.append(state.copy())
    return np.array(out)

def report(name, d, path, t0=None):
    err = contact_error(path, d["ref"]).max(axis=0)
    per = sa.per_window(err, d["picked"], sa.WINDOW_STARTS_S)
    print(f"{name:30s} max {err.max()*1e3:8.3f} mm  per start {[round(v*1e3,3) for v in per]}" + (f" ({time.time()-t0:.0f} s)" if t0 else ""), flush=True)
    return err.max()

class Lin:
    """A ramp within its control step, at float or per-robot times."""
    def __init__(self, a, b, dt):
        self.a, self.slope = a.T, (b.T - a.T) / dt
        self.zero = tuple(0.0 * s for s in self.slope)
    def leg_targets(self, t):
        return tuple(a + s * t for a, s in zip(self.a, self.slope)), tuple(self.slope), self.zero
