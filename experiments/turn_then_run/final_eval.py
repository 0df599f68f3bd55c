"""Step 2 final: the searched maneuver (turn gait T + lead + ramp) through TurnThenRun, 50 s,
deterministic from the paper's start, headings 0..315 (own gait and mirror variants), and
from 8 start-noise seeds for robustness. Speed = upright contact displacement along heading / 50 s;
also the env's own reward_forward summed (reward geometry check).

    python final_eval.py [--model pivot] [maneuver_file [delta_deg]]   # writes final_eval[_pivot].json

delta_deg (default: turn_then_run.DELTA_DEG, the running gait's measured direction of travel
minus the body's yaw) is the controller's direction offset; given, the output is
final_eval[_pivot]_delta<delta_deg>.json."""
import json, sys, time
import numpy as np
from common import *
from turn_then_run import DT, DELTA_DEG, score, smaller_turn_mirror
from maneuver_search import TurnThenRunRows

DUR = 50.0
m = json.load(open(sys.argv[1] if len(sys.argv) > 1 else out_name("maneuver_search")))["top"][0]["params"]
m = np.array(m); T, lead, ramp = m[:6], m[6], m[7]
DELTA = float(sys.argv[2]) if len(sys.argv) > 2 else DELTA_DEG
OUT = out_name("final_eval") if len(sys.argv) <= 2 else out_name("final_eval")[:-5] + f"_delta{sys.argv[2]}.json"
G = own_gait().as_array()
heads = np.arange(0, 360, 45.0)
cases = [(h, mg, None) for h in heads for mg in (False, True)]
cases += [(h, bool(smaller_turn_mirror(h, DELTA)), s) for h in (0.0, 45.0, 180.0) for s in range(200, 208)]   # plane: own gait
H = np.array([c[0] for c in cases]); MG = np.array([c[1] for c in cases]); S = [c[2] for c in cases]
ctl = TurnThenRunRows(np.tile(T, (len(cases), 1)), G, H, MG, lead, ramp, np.ones(len(cases), bool), delta_deg=DELTA)
t0 = time.time()
r = run(ctl, start_states(1, S), int(DUR / DT), targets=np.radians(H))
wall = time.time() - t0
sp = score(r, H, DUR); rew = r["reward_forward_sum"] / 100 * DT / DUR
rows = []
for i, (h, mg, s) in enumerate(cases):
    rows.append(dict(heading=float(h), run_gait="mirror" if mg else "own", start_seed=s, speed_mps=float(sp[i]), reward_speed_mps=float(rew[i]),
                     terminated=bool(r["terminated"][i]), why=r["why"][i], end_s=float(r["end_step"][i] * DT),
                     yaw_target_deg=float(np.degrees(ctl.target[i])), t_switch=float(ctl.t_switch[i]),
                     final_dir_deg=float(np.degrees(np.arctan2(*(r["up"][-1, i] - r["up"][-200, i])[::-1]))),
                     torque_peak=float(r["torque_peak"][i]), leg_rate_peak=float(r["leg_rate_peak"][i])))
json.dump(dict(**({} if MODEL == "plane" else dict(model=MODEL, physics=PHYSICS, direction_offset_deg=DELTA)), maneuver=dict(turn_gait=T.tolist(), lead_s=lead, ramp_s=ramp), run_gait=G.tolist(), duration=DUR, wall_s=wall, rows=rows),
          open(OUT, "w"), indent=1)
print(f"T={np.round(T,4).tolist()} lead={lead:.3f} ramp={ramp:.3f}; {len(cases)} robots, wall {wall:.0f}s")
for x in rows:
    print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in x.items()})
