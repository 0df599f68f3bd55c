import sys, time, pickle
import numpy as np
sys.path.insert(0, "probes")
from kinks import *
from windows import err
model, method = sys.argv[1], sys.argv[2]
n = int(sys.argv[3]) if len(sys.argv) > 3 else 15
d = pickle.load(open(f"/tmp/acc_{model}.pkl", "rb"))
states, starts, ends, dt, sim = d["roll"]
start, s, e, ref = d["start"], d["s"], d["e"], d["ref"]
keep = np.arange(len(start)).reshape(5, 8)[:, :5].ravel()  # headings 0..180 (the rest mirror them)
start, s, e, ref = start[keep], s[keep], e[keep], ref[:, keep]
t0 = time.time()
kw = eval("dict(" + (sys.argv[4] if len(sys.argv) > 4 else "") + ")")
eps = kw.pop("eps", None)
if eps is not None:
    import os
    kw["law"] = law_smooth(eps)
    path = f"/tmp/ref_{model}_smooth{eps}.pkl"
    if os.path.exists(path):
        ref = pickle.load(open(path, "rb"))
    else:
        ref = reference(sim, start, s, e, dt, kw["law"])
        pickle.dump(ref, open(path, "wb"))
    kref = err(ref, d["ref"][:, keep]).max(axis=0)
    print(f"smooth law eps {eps}: its reference from the clip's: max {kref.max() * 1e3:.3g} mm over the windows")
p, cost = run(sim, start, s, e, dt, n, method, **kw)
er = err(p, ref).max(axis=0).reshape(5, 5)
print(f"{model} {method} n={n}: max {er.max() * 1e3:.3g} mm, evals/env step mean {cost.mean():.2f} max {cost.max():.0f} "
      f"({time.time() - t0:.0f} s)")
print((er * 1e3).round(3))
