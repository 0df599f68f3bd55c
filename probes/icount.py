import sys, numpy as np
from rrrobot_gym.simulation import SimConfig, advance, initial_state
from rrrobot_gym.control import RampTargets
N, K = int(sys.argv[1]), int(sys.argv[2])
cfg = SimConfig(backend="numba", torque_limit=0.5, leg_rate_limit=10.0)
rng = np.random.default_rng(0)
s = initial_state(N) if N > 1 else initial_state()
s[..., 6:8] += rng.uniform(-0.3, 0.3, s[..., 6:8].shape)
tgt = RampTargets(s[..., 6:8], s[..., 6:8] + 0.2, 0.0, 0.05)
for _ in range(K):
    out, rec = advance(cfg, s, 0.0, 0.05, tgt, record=True, check=False)
