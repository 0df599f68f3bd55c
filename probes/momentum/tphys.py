import sys, time, statistics
import numpy as np
import rrrobot_gym
from rrrobot_gym.envs.vector import RRRobotVectorEnv
from rrrobot_gym.control import RampTargets
from rrrobot_gym.simulation import advance
model, N, reps = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
env = RRRobotVectorEnv(num_envs=N, model=model)
env.reset(seed=0)
sim, dt = env.config.sim, env.dt
state = env.states.copy()
rng = np.random.default_rng(0)
a0 = state[:, 6:8].copy()
times = []
for r in range(reps):
    a1 = a0 + rng.uniform(-0.3, 0.3, a0.shape)
    t = time.perf_counter()
    state = advance(sim, state, 0.0, dt, RampTargets(a0, a1, 0.0, dt), check=False)
    el = time.perf_counter() - t
    from rrrobot_gym import compiled
    if hasattr(compiled, "_to_momentum"):
        t = time.perf_counter(); z = compiled._to_momentum(state, sim, 1); compiled._to_momentum(z, sim, -1); el -= time.perf_counter() - t
    times.append(el)
    a0 = a1 if r % 20 else state[:, 6:8].copy()
print(model, N, "us/robot", 1e6 * statistics.median(times[3:]) / N, "finite", np.isfinite(state).all())
