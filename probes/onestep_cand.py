"""One control step from the reference's own states under a candidate stepper: its local errors."""
import os, pickle, sys
import numpy as np
sys.path.insert(0, os.path.dirname(__file__))
import candidates as C
from rrrobot_gym.control import RampTargets
model = sys.argv[1]
d = pickle.load(open(f"/tmp/acc_{model}.pkl", "rb"))
states, starts, ends, dt, sim = d["roll"]
start, s, e, ref = d["start"], d["s"], d["e"], d["ref"]
keep = np.arange(len(start)).reshape(5, 8)[:, :5].ravel()
s, e, ref = s[keep], e[keep], ref[:, keep]
for cand in sys.argv[2:]:
    n = C.choose(cand)
    errs = []
    for i in range(s.shape[1]):
        targets = RampTargets(s[:, i], e[:, i], 0.0, dt)
        y, _ = C.simulation._integrate(sim, targets, None, list(ref[i].T.copy()), 0.0, dt / n, n, False)
        errs.append(np.array(y).T - ref[i + 1])
    errs = np.array(errs)
    body = np.abs(errs[..., 8:11]).max(-1)
    legs = np.abs(errs[..., 11:13]).max(-1)
    print(f"{cand}: body rate err max {body.max():.3g} p99 {np.percentile(body, 99):.3g} median {np.median(body):.3g}; "
          f"leg rate err max {legs.max():.3g} p99 {np.percentile(legs, 99):.3g} median {np.median(legs):.3g}")
