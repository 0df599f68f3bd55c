import sys, time, numpy as np, gymnasium, rrrobot_gym
N = int(sys.argv[1]); S = int(sys.argv[2])
env = gymnasium.make_vec("RRRobot-v0", num_envs=N, vectorization_mode="vector_entry_point")
rng = np.random.default_rng(0)
phase = rng.uniform(0, 2 * np.pi, (N, 2))
actions = [(0.05 * np.sin(0.4 * k + phase)).astype(np.float32) for k in range(S)]
env.reset(seed=0)
for a in actions[:20]: env.step(a)
best = []
for r in range(7):
    env.reset(seed=0)
    t = time.perf_counter()
    for a in actions: env.step(a)
    best.append((time.perf_counter() - t) / S * 1e6)
print("min %.1f median %.1f us/step" % (min(best), sorted(best)[3]))
