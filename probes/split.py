import time, sys, numpy as np, gymnasium, rrrobot_gym
N = int(sys.argv[1]); steps = int(sys.argv[2])
env = gymnasium.make_vec("RRRobot-v0", num_envs=N) if N else gymnasium.make("RRRobot-v0")
env.reset(seed=0)
rng = np.random.default_rng(0)
shape = env.action_space.shape
phase = rng.uniform(0, 2*np.pi, (N,2) if N else (2,)); acts = [(0.05*np.sin(0.4*k+phase)).astype(np.float32) for k in range(64)]
for i in range(20): env.step(acts[i % 64])
import cProfile, pstats
t = time.perf_counter()
pr = cProfile.Profile(); pr.enable()
for i in range(steps): env.step(acts[i % 64])
pr.disable()
el = time.perf_counter() - t
print("steps/s", (max(N,1)*steps)/el)
pstats.Stats(pr).sort_stats("tottime").print_stats(14)
