import sys, os, time, numpy as np
sys.path.insert(0, "/tmp/sched")
import reorder
from rrrobot_gym import specialise
orig = specialise.kernel_source
VAR = os.environ.get("VAR", "base")
specialise.kernel_source = lambda robot, model: reorder.variant(orig(robot, model), VAR)
from rrrobot_gym.simulation import SimConfig, advance, initial_state
from rrrobot_gym.control import RampTargets
N = int(sys.argv[1]); model = sys.argv[2] if len(sys.argv) > 2 else "plane"
cfg = SimConfig(model=model, backend="numba", torque_limit=0.5, leg_rate_limit=10.0)
rng = np.random.default_rng(0)
s = initial_state(N)
s[..., 6:8] += rng.uniform(-0.3, 0.3, s[..., 6:8].shape)
tgt = RampTargets(s[..., 6:8], s[..., 6:8] + 0.2, 0.0, 0.05)
advance(cfg, s, 0.0, 0.05, tgt, record=True, check=False)
if os.environ.get("CHECK"):
    np.save(f"/tmp/sched/state_{VAR}_{model}.npy", s); sys.exit()
reps = max(1, 40000 // N)
ts = []
for r in range(7):
    t = time.perf_counter()
    for _ in range(reps):
        advance(cfg, s, 0.0, 0.05, tgt, record=True, check=False)
    ts.append((time.perf_counter() - t) / reps)
print(N / np.median(ts))
