"""Heading correction, step 1: which small change of the running gait turns it, and how fast?

The running gait (searched-plane-own-1 / searched-pivot-own-1) from the paper's start, 20 s,
with a constant change d (rad, or a fraction for amplitudes) in per-leg form:

    offset:    leg 1's offset + d, leg 2's offset - d
    amplitude: leg 1's amplitude x (1 + d), leg 2's x (1 - d)

Yaw rate: least-squares slope of the body's yaw over 5-20 s (deg/s; compare with the d = 0
row); speed: the upright contact point's straight-line displacement / the whole run; runs that
ended show yaw rate 0. By the robot's mirror symmetry a per-leg change d turns the leg-exchanged
(mirror) gait at minus the rate -d turns the gait itself (for small d: the same way as d turns the
gait); two mirror rows check it.

    python steer_response.py [--model pivot] [from_s]   # writes steer_response[_pivot][_from<from_s>].json

from_s (default 0): the change starts at from_s s (the gait unchanged before: a running robot
steered, as the agent does after its blend); the slope is then taken over from_s + 5 to 20 + from_s s.
(steer_response.json / steer_response_pivot.json were written before from_s existed: from_s 0.)
"""
import sys
import json, time
import numpy as np
from common import *
from rrrobot_gym.agents.turn_then_run import per_leg_gait, per_leg_angles

FROM = float(sys.argv[1]) if len(sys.argv) > 1 else 0.0
DT, DUR = 0.05, 20.0 + FROM
G = own_gait().as_array()
cases = [("offset", d) for d in (-0.2, -0.1, -0.05, -0.02, 0.0, 0.02, 0.05, 0.1, 0.2)]
cases += [("amplitude", d) for d in (-0.2, -0.1, -0.05, 0.05, 0.1, 0.2)]
cases += [("offset", d) for d in (-0.05, 0.05)]   # the mirror gait (checks the symmetry)
mirror = np.array([False] * (len(cases) - 2) + [True, True])
g = np.array([per_leg_gait(G, m) for m in mirror])
g0 = g.copy()
for i, (kind, d) in enumerate(cases):
    if kind == "offset":
        g[i, 2] += d; g[i, 3] -= d
    else:
        g[i, 0] *= 1 + d; g[i, 1] *= 1 - d


def controller(k, states, alive):
    return per_leg_angles(ramped(g if (k + 1) * DT >= FROM else g0, (k + 1) * DT), g[:, 4] * (k + 1) * DT)


t0 = time.time()
r = run(controller, start_states(1, [None] * len(cases)), int(DUR / DT))
t = np.arange(len(r["yaw"])) * DT
sel = t >= FROM + 5.0
slope = np.degrees(np.polyfit(t[sel], r["yaw"][sel], 1)[0])
disp = r["up"][-1] - r["up"][0]
rows = []
for i, (kind, d) in enumerate(cases):
    rows.append(dict(change=kind, d=d, mirror=bool(mirror[i]), yaw_rate_dps=float(slope[i]),
                     speed_mps=float(np.hypot(*disp[i]) / DUR), terminated=bool(r["terminated"][i]), why=r["why"][i],
                     torque_peak=float(r["torque_peak"][i]), leg_rate_peak=float(r["leg_rate_peak"][i]),
                     clear_min=float(r["clear_min"][i])))
    print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in rows[-1].items()})
json.dump(dict(model=MODEL, from_s=FROM, physics=PHYSICS, run_gait=G.tolist(), duration=DUR, wall_s=time.time() - t0, rows=rows),
          open(out_name("steer_response")[:-5] + (f"_from{sys.argv[1]}.json" if FROM else ".json"), "w"), indent=1)
