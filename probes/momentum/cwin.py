import sys, time, pickle
import numpy as np
from pathlib import Path
import rrrobot_gym, rrrobot_gym.simulation as simulation
print(rrrobot_gym.__file__)
sys.path.insert(0, "/tmp/mprobe")
d = pickle.loads(Path("/tmp/mprobe/windows_pivot_policy.pkl").read_bytes())
from benchmarks import scene_accuracy as sa
from benchmarks._common import contact_error
t0 = time.time()
path = sa.replay(d["sim"], d["start"], d["ws"], d["we"], d["dt"])
err = contact_error(path, d["ref"]).max(axis=0)
print("compiled", simulation.takes_compiled(d["sim"]), "max mm", err.max() * 1e3, [round(v * 1e3, 3) for v in sa.per_window(err, d["picked"], sa.WINDOW_STARTS_S)], time.time() - t0)
