import sys, time, numpy as np
from rrrobot_gym.simulation import SimConfig, advance, initial_state
from rrrobot_gym.control import RampTargets
N = int(sys.argv[1]); model = sys.argv[2] if len(sys.argv) > 2 else "plane"
cfg = SimConfig(model=model, backend="numba", torque_limit=0.5, leg_rate_limit=10.0)
rng = np.random.default_rng(0)
s = initial_state(N)
s[..., 6:8] += rng.uniform(-0.3, 0.3, s[..., 6:8].shape)
tgt = RampTargets(s[..., 6:8], s[..., 6:8] + 0.2, 0.0, 0.05)
advance(cfg, s, 0.0, 0.05, tgt, record=bool(int(__import__("os").environ.get("REC","1"))), check=False)
reps = max(1, 40000 // N)
ts = []
for r in range(7):
    t = time.perf_counter()
    for _ in range(reps):
        advance(cfg, s, 0.0, 0.05, tgt, record=bool(int(__import__("os").environ.get("REC","1"))), check=False)
    ts.append((time.perf_counter() - t) / reps)
print(N / np.median(ts))
