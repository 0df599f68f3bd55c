"""Arithmetic of one derivative evaluation with and without the locked rate, on numpy at N = 65536
(array operations dominate, so their count stands for the compiled lanes' work)."""
import os, sys, time
import numpy as np
sys.path.insert(0, os.path.dirname(__file__))
import candidates as C
from rrrobot_gym.simulation import SimConfig
from rrrobot_gym.control import RampTargets
from rrrobot_gym import dynamics
rng = np.random.default_rng(0)
N = 65536
for model in ("plane", "pivot"):
    cfg = SimConfig(model=model, torque_limit=0.5, leg_rate_limit=10.0, backend="numpy")
    y = np.zeros((N, 13)); q = rng.normal(size=(N, 4)) * 0.1; q[:, 0] = 1; q /= np.linalg.norm(q, axis=1, keepdims=True)
    y[:, 2:6] = q; y[:, 6:8] = rng.uniform(0, 3, (N, 2)); y[:, 8:11] = rng.normal(size=(N, 3)); y[:, 11:13] = rng.normal(size=(N, 2)) * 5
    targets = RampTargets(rng.uniform(0, 3, (N, 2)), rng.uniform(0, 3, (N, 2)), 0.0, 0.05)
    sc = C.Scene(cfg, targets, 0.0)
    c = list(y.T.copy())
    lf = C.locked(sc.f, sc.k)
    def best(fn, r=7):
        ts = []
        for _ in range(r):
            t = time.perf_counter(); fn(); ts.append(time.perf_counter() - t)
        return min(ts)
    plain = best(lambda: sc.f(0.01, c))
    lock = best(lambda: lf(0.01, c))
    kernel = best(lambda: dynamics.derivative_kernel(c, (c[11] * 0, c[12] * 0), sc.k))
    print(f"{model}: kernel {kernel * 1e3:.1f} ms, servo + kernel {plain * 1e3:.1f} ms, locked {lock * 1e3:.1f} ms: "
          f"locked / plain {lock / plain:.2f}")
