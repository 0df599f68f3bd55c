"""Can the turn-then-run controller blend into the robust search's running gait after a turn?

The shipped maneuver (maneuver_search.json's best: turning gait, switch lead) turns the body, and
the running gait of `--run-gait` (default here: plane_own_robust.json, whose best gait starts with
a 2 s ramp from rest) takes over with the controller's blend, on headings 0, 45 and 180 deg from
the paper's start, for each of several blend times, 30 s. Each row: when the switch came, whether
and when the episode ended and why, and the speed along the heading over the 30 s.

    python swap_robust.py [--run-gait FILE]     # writes swap_robust_<file stem>.json
"""
import json, sys
if "--run-gait" not in sys.argv:
    sys.argv += ["--run-gait", "plane_own_robust.json"]
from common import *
from turn_then_run import DT, DELTA_DEG, score, smaller_turn_mirror
from maneuver_search import TurnThenRunRows

DUR = 30.0
BLENDS = [0.5, None, 4.0, 8.0]   # s; None: the shipped maneuver's own blend
heads = np.array([0.0, 45.0, 180.0])
m = np.array(json.load(open("maneuver_search.json"))["top"][0]["params"])
T, lead, own_blend = m[:6], m[6], m[7]
blends = np.array([own_blend if b is None else b for b in BLENDS])
H = np.tile(heads, len(blends)); B = np.repeat(blends, len(heads))
G = own_gait().as_array()
ctl = TurnThenRunRows(np.tile(T, (len(H), 1)), G, H, smaller_turn_mirror(H), np.full(len(H), lead), B, np.ones(len(H), bool))
r = run(ctl, start_states(1, [None] * len(H)), int(DUR / DT), targets=np.radians(H))
sp = score(r, H, DUR)
rows = [dict(heading=float(H[i]), blend_s=float(B[i]), t_switch=float(ctl.t_switch[i]), terminated=bool(r["terminated"][i]),
             why=r["why"][i], end_s=float(r["end_step"][i] * DT), speed_mps=float(sp[i])) for i in range(len(H))]
json.dump(dict(run_gait_file=OWN_FILE, run_gait=G.tolist(), run_gait_ramp_s=own_gait().ramp_s, direction_offset_deg=DELTA_DEG,
               maneuver=dict(turn_gait=T.tolist(), lead_s=lead, blend_s=own_blend), duration=DUR, rows=rows),
          open(out_name("swap_robust"), "w"), indent=1)
for x in rows:
    print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in x.items()})
