import sys, gc, numpy as np
from rrrobot_gym.simulation import SimConfig, advance, initial_state
from rrrobot_gym.control import RampTargets
cfg = SimConfig(model="plane", backend="numba", torque_limit=0.5, leg_rate_limit=10.0)
s = initial_state(64)
tgt = RampTargets(s[..., 6:8], s[..., 6:8] + 0.2, 0.0, 0.05)
advance(cfg, s, 0.0, 0.05, tgt, record=False, check=False)
from numba.core.registry import CPUDispatcher
n = 0
for obj in gc.get_objects():
    if isinstance(obj, CPUDispatcher) and obj.signatures and obj.py_func.__name__ in ("_block", "_block_substep", "_block_combine", "_lanes", "_lane_substep"):
        for sig, a in obj.inspect_asm().items():
            n += 1; print(n, obj.py_func.__qualname__, obj.py_func.__globals__.get("BLOCK", obj.py_func.__globals__.get("LANES")), len(a.splitlines()))
            open(f"{sys.argv[1]}_{n}.s", "w").write(a)
