import pickle, sys
from dataclasses import replace
import numpy as np
sys.path.insert(0, "probes")
from windows import replay, err
model = sys.argv[1]
d = pickle.load(open(f"/tmp/acc_{model}.pkl", "rb"))
states, starts, ends, dt, sim = d["roll"]
start, s, e, ref = d["start"], d["s"], d["e"], d["ref"]
cfg = replace(sim, timestep=1/3000)
base = replay(cfg, start, s, e, dt)
for comp, delta in ((11, 1e-6), (6, 1e-7), (8, 1e-7)):
    p = start.copy(); p[:, comp] += delta
    dev = err(replay(cfg, p, s, e, dt), base)
    print(f"component {comp} + {delta:g}: contact deviation (m per unit) max over windows at 1,2,3,4,5 s:",
          [f"{dev[k].max() / delta:.3g}" for k in (20, 40, 60, 80, 100)])
