"""The maneuver's lead and blend on a grid, its turning gait fixed: the robust running gait's CMA-ES
searches with 135 deg added (maneuver_search_plane_own_robust_sigma0.2.json, and a run with first
step 0.05 stopped at 40 generations) found nothing better than their warm start, whose 45 deg
anticlockwise turn (135 deg) overshoots by ~35 deg. Scored as maneuver_search.py scores
(its headings, starts and duration for this running gait).

    python lead_blend_grid.py --run-gait plane_own_robust.json maneuver_file   # writes lead_blend_grid_<stem>.json
"""
import json, sys, time
from common import *
from maneuver_search import evaluate, HEAD, SEEDS, DUR

m = np.array(json.load(open(sys.argv[1]))["top"][0]["params"])
LEADS = np.round(np.arange(0.0, 3.01, 0.25), 2)
BLENDS = np.array([2.0, 2.5, 3.1, 3.5, 4.0, 5.0, 6.0])
params = np.array([np.r_[m[:6], lead, blend] for lead in LEADS for blend in BLENDS])
t0 = time.time()
fit, sp, term = [], [], []
for chunk in np.array_split(params, 4):
    f, s, t = evaluate(chunk); fit.append(f); sp.append(s); term.append(t)
fit, sp, term = np.concatenate(fit), np.concatenate(sp), np.concatenate(term)
rows = [dict(lead_s=float(p[6]), blend_s=float(p[7]), fitness=float(fit[i]), speeds=sp[i].tolist(), ended=int(term[i].sum()),
             worst=float(sp[i].min())) for i, p in enumerate(params)]
rows.sort(key=lambda r: (r["ended"], -r["worst"]))
json.dump(dict(maneuver_file=sys.argv[1], turn_gait=m[:6].tolist(), headings=HEAD.tolist(), seeds=SEEDS, duration=DUR,
               wall_s=time.time() - t0, rows=rows), open(out_name("lead_blend_grid"), "w"), indent=1)
for r in rows[:12]:
    print(r["lead_s"], r["blend_s"], r["ended"], round(1e3 * r["worst"], 1), round(1e3 * r["fitness"], 1),
          np.round(1e3 * np.array(r["speeds"]), 1).tolist())
