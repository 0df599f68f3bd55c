import time, sys, numpy as np
from rrrobot_gym.control import HeldTargets
from rrrobot_gym.simulation import SimConfig, advance, initial_state
cfg = SimConfig(model="plane", backend="numba")
N = int(sys.argv[1])
s0 = np.repeat(initial_state()[None], N, axis=0)
rng = np.random.default_rng(0)
tg = HeldTargets(np.pi/2 + 0.3*rng.uniform(-1,1,(N,2)))
out = advance(cfg, s0, 0.0, 0.05, tg)
ts=[]
for r in range(7):
    t=time.perf_counter()
    for _ in range(5):
        out = advance(cfg, s0, 0.0, 0.05, tg)
    ts.append((time.perf_counter()-t)/5)
print(sys.argv[1], "env steps/s %.0f" % (N/np.median(ts)))
