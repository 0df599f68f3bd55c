"""How often a motor changes branch within a substep (per robot, and per 32-lane block)."""
import pickle, sys
from dataclasses import replace
import numpy as np
sys.path.insert(0, "probes")
from windows import err
from rrrobot_gym.control import RampTargets, pd_torque, motor_torque
from rrrobot_gym.simulation import advance, _substeps

def branch(config, y, targets, t):
    rates = (y[:, 11], y[:, 12])
    tau = pd_torque(config.gains, (y[:, 6], y[:, 7]), rates, targets.leg_targets(t))
    out = []
    for tq, w in zip(tau, rates):
        g = motor_torque(tq, w, config.torque_limit, config.leg_rate_limit)
        b = np.where(g == tq, 0, np.where(g < tq, np.where(w > 0, 3, 1), np.where(w < 0, 4, 2)))
        out.append(b)
    return np.stack(out, 1)

model = sys.argv[1]
d = pickle.load(open(f"/tmp/acc_{model}.pkl", "rb"))
states, starts, ends, dt, sim = d["roll"]
start, s, e = d["start"], d["s"], d["e"]
n, h = _substeps(dt, sim.step)
y = start.copy()
changes = []
for i in range(s.shape[1]):
    targets = RampTargets(s[:, i], e[:, i], 0.0, dt)
    for j in range(n):
        b0 = branch(sim, y, targets, j * h)
        y1 = advance(sim, y, j * h, h, targets, check=False)
        b1 = branch(sim, y1, targets, (j + 1) * h)
        changes.append((b0 != b1).any(axis=1))
        y = y1
c = np.array(changes)  # (S, R)
print("robot-substeps with a branch change:", c.mean())
print("per robot:", c.mean(axis=0).round(3))
# blocks of 32 lanes: probability any of 32 random robots changes
p = c.mean(axis=0)
for L in (8, 16, 32):
    idx = np.random.default_rng(0).integers(0, c.shape[1], (200, L))
    print(L, "lanes: block substeps with a change", np.mean([c[:, k].any(axis=1).mean() for k in idx]))
