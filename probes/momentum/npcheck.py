import sys, time, pickle
import numpy as np
from pathlib import Path
import rrrobot_gym.compiled as compiled
if "np" in sys.argv: compiled.available = lambda: False
import rrrobot_gym, rrrobot_gym.simulation as simulation
d = pickle.loads(Path(sys.argv[1]).read_bytes())
from benchmarks import scene_accuracy as sa
from benchmarks._common import contact_error
t0 = time.time()
path = sa.replay(d["sim"], d["start"], d["ws"], d["we"], d["dt"])
err = contact_error(path, d["ref"]).max(axis=0)
print("compiled", simulation.takes_compiled(d["sim"]), "max mm", err.max() * 1e3, [round(v * 1e3, 3) for v in sa.per_window(err, d["picked"], sa.WINDOW_STARTS_S)], time.time() - t0)
