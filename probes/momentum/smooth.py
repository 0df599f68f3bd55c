"""momentum RK4 with a smooth motor law on its own closed-loop rollout (numpy)."""
import sys
eps = float(sys.argv[1]); MODEL = sys.argv[2] if len(sys.argv) > 2 else "pivot"; KIND = sys.argv[3] if len(sys.argv) > 3 else "hyp"
import rrrobot_gym.compiled as compiled
compiled.available = lambda: False
import rrrobot_gym.control as control
def smooth_motor(eps):
    def smin(a, b):
        d = a - b
        if KIND == "hyp":
            return 0.5 * (a + b - (d * d + eps * eps) ** 0.5)
        hh = np.maximum(eps - abs(d), 0.0) / eps
        if KIND == "cubic":
            return np.minimum(a, b) - hh * hh * hh * eps / 6.0
        return np.minimum(a, b) - hh * hh * eps / 4.0
    def motor_torque(tau, rate, torque_limit, rate_limit=None):
        drop = torque_limit * rate / rate_limit
        high = smin(torque_limit, torque_limit - drop)
        low = smin(torque_limit, torque_limit + drop)
        return smin(-smin(-tau, low), high)
    return motor_torque
control.motor_torque = smooth_motor(eps)
import pickle, time
from pathlib import Path
import numpy as np
sys.path.insert(0, "/tmp/mprobe")
from split import *
path = Path(f"/tmp/mprobe/smooth_{eps}_{MODEL}_{KIND}.pkl")
if path.exists():
    d = pickle.loads(path.read_bytes())
else:
    t0 = time.time()
    states, rs, re, ended, dt, sim = sa.rollout(MODEL, "policy", 45.0)
    start, ws, we, picked = sa.windows(states, rs, re, ended, dt, sa.WINDOW_STARTS_S)
    print("rollout", time.time() - t0, flush=True)
    ref = sa.replay(sim, start, ws, we, dt, reference=True)
    d = dict(start=start, ws=ws, we=we, picked=picked, ref=ref, dt=dt, sim=sim, states=states)
    path.write_bytes(pickle.dumps(d))
    print("reference", time.time() - t0, flush=True)
from rrrobot_gym.integrators import rk4
report(f"smooth {eps} rk4", d, run(d, lambda f, g, t, y, h, n, tg, sim: rk4.step(f, g, t, y, h, n)))
if MODEL == "pivot":
    report(f"smooth {eps} momentum", d, run(d, make(True, False)))
    report(f"smooth {eps} momentum n=30", d, run(d, make(True, False), 30))
else:
    report(f"smooth {eps} {MODEL} rk4 n=30", d, run(d, lambda f, g, t, y, h, n, tg, sim: rk4.step(f, g, t, y, h, n), 30))
