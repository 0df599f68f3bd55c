"""The clip's ensemble at 1/3000 s on numba (probes/ensemble.py), kept for probes/ensemble_cand.py."""
import pickle, sys
sys.path.insert(0, "probes")
from ensemble import speeds
from rrrobot_gym.agents.ppo import load_ppo_agent
from benchmarks._common import POLICIES
model, starts = sys.argv[1], int(sys.argv[2])
v = speeds(load_ppo_agent(POLICIES[model]), model, (0.0, 45.0, 90.0, 135.0, 180.0), 1 / 3000, 150, starts)
pickle.dump(v, open(f"/tmp/cand/fine2_{model}_{starts}_numba.pkl", "wb"))
print("kept", v.shape)
