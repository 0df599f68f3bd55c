import re, sys, numpy as np
from rrrobot_gym import compiled
from rrrobot_gym.simulation import SimConfig, advance, initial_state
from rrrobot_gym.control import HeldTargets
cfg = SimConfig(model="plane", backend="numba")
N=64
s0 = np.repeat(initial_state()[None], N, axis=0)
tg = HeldTargets(np.pi/2 + 0.3*np.random.default_rng(0).uniform(-1,1,(N,2)))
advance(cfg, s0, 0.0, 0.05, tg)
step = compiled._stepper(False, None, 2)
g = step.py_func.__globals__["_lanes"].py_func.__globals__
f = g["_block_stage"]
for i,(sig, asm) in enumerate(f.inspect_asm().items()):
    open(f"/tmp/{sys.argv[1]}_{i}.s","w").write(asm)
