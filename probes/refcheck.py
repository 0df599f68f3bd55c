import pickle, sys, time
from dataclasses import replace
import numpy as np
sys.path.insert(0, "probes")
from windows import replay, err
model = sys.argv[1]
d = pickle.load(open(f"/tmp/acc_{model}.pkl", "rb"))
states, starts, ends, dt, sim = d["roll"]
start, s, e, ref = d["start"], d["s"], d["e"], d["ref"]
for h in (1/3000, 1/9000):
    t = time.time()
    p = replay(replace(sim, timestep=h), start, s, e, dt)
    er = err(p, ref).max(axis=0)
    print(f"1/{1/h:.0f}", time.time() - t, (er.reshape(5, -1) * 1e3).round(4))
