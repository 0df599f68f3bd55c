import sys, numpy as np, gymnasium, rrrobot_gym
N, K = int(sys.argv[1]), int(sys.argv[2])
env = gymnasium.make_vec("RRRobot-v0", num_envs=N, vectorization_mode="vector_entry_point")
rng = np.random.default_rng(0)
phase = rng.uniform(0, 2 * np.pi, (N, 2))
env.reset(seed=0)
for k in range(K):
    env.step((0.05 * np.sin(0.4 * k + phase)).astype(np.float32))
