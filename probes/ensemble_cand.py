"""The closed-loop ensemble of probes/ensemble.py under a candidate of probes/candidates.py (numpy):
its means at the default step against the clip's (or its own law's) at 1/3000 s.

    PYTHONPATH=. python probes/ensemble_cand.py MODEL STARTS CANDIDATE [FINE_CANDIDATE]
"""
import os, pickle, sys, time
import numpy as np
sys.path.insert(0, os.path.dirname(__file__))
import candidates  # noqa: E402  (patches the package: numpy everywhere)
from ensemble import speeds  # noqa: E402
from rrrobot_gym.agents.ppo import load_ppo_agent  # noqa: E402
from benchmarks._common import POLICIES  # noqa: E402

model, starts, cand = sys.argv[1], int(sys.argv[2]), sys.argv[3]
fine_cand = sys.argv[4] if len(sys.argv) > 4 else None
agent = load_ppo_agent(POLICIES[model])
headings = (0.0, 45.0, 90.0, 135.0, 180.0)

def run(c, refine):
    n = candidates.choose(c)
    for k in candidates.STATS:
        candidates.STATS[k] = 0
    t = time.time()
    v = speeds(agent, model, headings, 0.05 / (n * refine), n * refine, starts)
    return v, dict(candidates.STATS), time.time() - t

coarse, stats, sec = run(cand, 1)
fine_path = f"/tmp/cand/fine2_{model}_{starts}_{(fine_cand or 'numba').replace('/', '_')}.pkl"
if os.path.exists(fine_path):
    fine = pickle.load(open(fine_path, "rb"))
elif fine_cand is None:
    raise SystemExit(f"no {fine_path}: make it with probes/ensemble_fine.py")
else:
    fine = run(fine_cand, 10)[0]
    pickle.dump(fine, open(fine_path, "wb"))
pickle.dump(coarse, open(f"/tmp/cand/coarse2_{model}_{starts}_{cand.replace('/', '_')}.pkl", "wb"))
extra = ""
if stats.get("robot_substeps"):
    q = stats["split"] / stats["robot_substeps"]
    extra = f"; switch substeps {100 * q:.2f} % of a robot's, {100 * (1 - (1 - q) ** 32):.0f} % of 32-lane blocks' (independent robots)"
print(f"{cand} {model} ({sec:.0f} s){extra}")
worst = 0.0
for i, hd in enumerate(headings):
    ma, mb = np.nanmean(coarse[i]), np.nanmean(fine[i])
    se = np.sqrt(np.nanvar(coarse[i], ddof=1) / starts + np.nanvar(fine[i], ddof=1) / starts)
    worst = max(worst, abs(ma / mb - 1))
    print(f"  {hd:5g} deg: mean {ma:.2f} vs {mb:.2f} at 1/3000 s: {100 * (ma / mb - 1):+.3f} % +- {100 * se / mb:.3f} %; "
          f"runs {np.nanmin(coarse[i]):.2f}-{np.nanmax(coarse[i]):.2f}")
print(f"  largest change of a mean {100 * worst:.3f} %")
