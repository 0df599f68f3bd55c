import pickle, sys
import numpy as np
sys.path.insert(0, "probes")
from kinks import Scene, STEPPERS
model = sys.argv[1]
d = pickle.load(open(f"/tmp/acc_{model}.pkl", "rb"))
states, starts, ends, dt, sim = d["roll"]
start, s, e, ref = d["start"], d["s"], d["e"], d["ref"]
keep = np.arange(len(start)).reshape(5, 8)[:, :5].ravel()
s, e, ref = s[keep], e[keep], ref[:, keep]
for arg in sys.argv[2:]:
    method, _, extra = arg.partition(":")
    kw = eval("dict(" + extra + ")")
    errs, costs = [], []
    for i in range(s.shape[1]):
        sc = Scene(sim, s[:, i], e[:, i], dt)
        y, c = STEPPERS[method](sc, list(ref[i].T.copy()), dt, 15, **kw)
        errs.append(np.array(y).T - ref[i + 1]); costs.append(c)
    errs = np.array(errs)
    rate = np.abs(errs[..., 8:13]).max(axis=-1)
    idx = np.unravel_index(np.argsort(rate.ravel())[-5:], rate.shape)
    print(method, kw, "rate err max", rate.max(), "p99", np.percentile(rate, 99), "median", np.median(rate), "evals", np.mean(costs),
          "worst at", list(zip(*idx)))
