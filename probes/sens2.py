import sys, pickle
import numpy as np
sys.path.insert(0, "probes")
from kinks import *
from windows import err
model = sys.argv[1]
d = pickle.load(open(f"/tmp/acc_{model}.pkl", "rb"))
states, starts, ends, dt, sim = d["roll"]
start, s, e = d["start"], d["s"], d["e"]
keep = np.arange(len(start)).reshape(5, 8)[:, :5].ravel()
start, s, e = start[keep], s[keep], e[keep]
for name, law in (("clip", law_clip), ("smooth 0.05", law_smooth(0.05)), ("smooth 0.2", law_smooth(0.2))):
    base, _ = run(sim, start, s, e, dt, 60, "plain", law=law)
    p = start.copy(); p[:, 11] += 1e-6
    pert, _ = run(sim, p, s, e, dt, 60, "plain", law=law)
    dev = err(pert, base) / 1e-6
    print(name, "m per rad/s at 1..5 s (max over windows):", [f"{dev[k].max():.3g}" for k in (20, 40, 60, 80, 100)],
          "median at 5 s", f"{np.median(dev[100]):.3g}")
