import time, sys, os, numpy as np
if os.environ.get("RR_GEN"):
    import importlib.util
    from rrrobot_gym import dynamics
    spec = importlib.util.spec_from_file_location("genkernel", os.environ["RR_GEN"]); g = importlib.util.module_from_spec(spec); spec.loader.exec_module(g)
    dynamics.KERNELS = tuple(g.derivative_kernel if f.__name__ == "derivative_kernel" else f for f in dynamics.KERNELS)
from rrrobot_gym.control import HeldTargets
from rrrobot_gym.simulation import SimConfig, advance, initial_state
cfg = SimConfig(model=os.environ.get("RR_MODEL", "plane"), backend="numba")
N = int(sys.argv[1])
s0 = np.repeat(initial_state()[None], N, axis=0)
rng = np.random.default_rng(0)
tg = HeldTargets(np.pi/2 + 0.3*rng.uniform(-1,1,(N,2)))
out = advance(cfg, s0, 0.0, 0.05, tg)
if os.environ.get("RR_SAVE"): np.save(os.environ["RR_SAVE"], out if isinstance(out, np.ndarray) else out[0])
ts=[]
for r in range(7):
    t=time.perf_counter()
    for _ in range(5):
        out = advance(cfg, s0, 0.0, 0.05, tg)
    ts.append((time.perf_counter()-t)/5)
print(sys.argv[1], "env steps/s %.0f" % (N/np.median(ts)))
