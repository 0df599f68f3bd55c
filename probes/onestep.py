"""One control step's error from the reference's own states: by component, kinked or not."""
import pickle, sys
import numpy as np
sys.path.insert(0, "probes")
from kinks import Scene, step_plain, step_refine, law_clip
model = sys.argv[1]
d = pickle.load(open(f"/tmp/acc_{model}.pkl", "rb"))
states, starts, ends, dt, sim = d["roll"]
start, s, e, ref = d["start"], d["s"], d["e"], d["ref"]
keep = np.arange(len(start)).reshape(5, 8)[:, :5].ravel()
s, e, ref = s[keep], e[keep], ref[:, keep]
res = {}
for n in (15, 30, 60):
    errs, kinked = [], []
    for i in range(s.shape[1]):
        sc = Scene(sim, s[:, i], e[:, i], dt)
        y0 = list(ref[i].T.copy())
        y, _ = step_plain(sc, y0, dt, n)
        y = np.array(y).T
        errs.append(y - ref[i + 1])
        # kinked: pieces differ at the 16 sample points
        h = dt / 15
        pcs = []
        yy = list(ref[i].T.copy())
        for j in range(15):
            pcs.append(sc.pieces(j * h, yy))
            yy, _ = step_plain(Scene(sim, s[:, i], e[:, i], dt), yy, h, 1) if False else (yy, None)
        kinked.append(None)
    errs = np.array(errs)  # (100, R, 13)
    res[n] = errs
    legrate = np.abs(errs[..., 11:13]).max(axis=-1)
    body = np.linalg.norm(errs[..., 8:11], axis=-1)
    pos = np.hypot(errs[..., 0], errs[..., 1])
    print(f"n={n}: leg rate err max {legrate.max():.3g} median {np.median(legrate):.3g}; body rate max {body.max():.3g} "
          f"median {np.median(body):.3g}; contact max {pos.max():.3g}")
for a, b in ((15, 30), (30, 60)):
    r = np.abs(res[a][..., 8:13]).max(axis=-1) / np.maximum(np.abs(res[b][..., 8:13]).max(axis=-1), 1e-30)
    print(a, b, "ratio of rate errors: median", np.median(r), "10%", np.percentile(r, 10), "90%", np.percentile(r, 90))
