import sys, importlib.util, numpy as np
spec = importlib.util.spec_from_file_location("genkernel", sys.argv[1]); g = importlib.util.module_from_spec(spec); spec.loader.exec_module(g)
from rrrobot_gym import dynamics
from rrrobot_gym.params import RobotParams
p = RobotParams(); model = sys.argv[2] if len(sys.argv) > 2 else "plane"
k, layout = dynamics.constants(p, model), dynamics.leg_layout(p)
rng = np.random.default_rng(1)
size, at, out, drive, scratch, rec = dynamics.kernel_work(2)
worst = 0; diff = 0
for trial in range(2000):
    q = rng.normal(size=4); q /= np.linalg.norm(q)
    y = [*rng.normal(size=2), *q, *rng.uniform(-3, 3, 2), *rng.normal(size=3), *rng.normal(size=2) * 5]
    tau = list(rng.normal(size=2) * 0.3)
    w1 = [0.0] * size; w1[at:at + 13] = y; w1[drive:drive + 2] = tau
    w2 = list(w1)
    dynamics.derivative_kernel(w1, at, out, 1, k, layout, drive, scratch, False, rec)
    g.derivative_kernel(w2, at, out, 1, k, layout, drive, scratch, False, rec)
    a = np.array(w1[out:out + 13] + w1[rec:rec + 9]); b = np.array(w2[out:out + 13] + w2[rec:rec + 9])
    diff += int(np.sum(a != b)); worst = max(worst, np.max(np.abs(a - b) / (np.abs(a) + 1e-300)))
print("values differing:", diff, "worst relative", worst)
