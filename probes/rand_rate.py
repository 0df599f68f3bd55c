import time, sys, numpy as np, gymnasium, rrrobot_gym
N = 64
env = gymnasium.make_vec("RRRobot-v0", num_envs=N, vectorization_mode="vector_entry_point")
env.reset(seed=0)
rng = np.random.default_rng(0)
acts = rng.uniform(-1, 1, (64, N, 2)).astype(np.float32)
for i in range(20): env.step(acts[i % 64])
env.reset(seed=0)
t = time.perf_counter()
for i in range(1500): env.step(acts[i % 64])
print(N * 1500 / (time.perf_counter() - t))
