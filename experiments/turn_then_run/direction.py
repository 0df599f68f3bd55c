"""Step 0: the running gait's direction of travel relative to the body's yaw (the controller's
DELTA), measured: run it (and its leg-exchanged mirror) from the paper's start and from 4
start-noise seeds, and compare the heading of the upright contact point's displacement with
the body's mean yaw, over the run after a settling time (the first period of the gait).
A gait whose body yaw drifts at a steady rate travels at its mean yaw + the offset; its chord over
the run then points at the yaw at the run's start + offset + half the drift ("chord_offset_deg").

    python direction.py [--model pivot] [seconds]     # writes direction[_pivot].json
"""
import json, math, sys
import numpy as np
from common import *
from turn_then_run import DT, angles7, seven

DUR = float(sys.argv[1]) if len(sys.argv) > 1 else 50.0
SETTLE = 2.0                                   # s left out at the start
SEEDS = [None, 31, 32, 33, 34]

if __name__ == "__main__":
    G = own_gait()
    cases = [(m, s) for m in (False, True) for s in SEEDS]
    g = np.array([seven(G.as_array(), m) for m, _ in cases])
    steps = int(round(DUR / DT))
    r = run(lambda k, states, alive: angles7(ramped(g, (k + 1) * DT), g[:, 4] * (k + 1) * DT), start_states(1, [s for _, s in cases]), steps)
    k0 = int(round(SETTLE / DT))
    d = r["up"][-1] - r["up"][k0]
    travel = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    yaw = np.degrees(r["yaw"][k0:].mean(0))
    yaw_drift = np.degrees(r["yaw"][-1] - r["yaw"][k0])
    offset = (travel - yaw + 180.0) % 360.0 - 180.0
    chord = (travel - np.degrees(r["yaw"][k0]) + 180.0) % 360.0 - 180.0    # relative to the yaw at the window's start
    rows = [dict(run_gait="mirror" if m else "own", start_seed=s, travel_deg=float(travel[i]), mean_yaw_deg=float(yaw[i]),
                 yaw_drift_deg=float(yaw_drift[i]), yaw_rate_degps=float(yaw_drift[i] / (DUR - SETTLE)), offset_deg=float(offset[i]),
                 chord_offset_deg=float(chord[i]),
                 speed_mps=float(np.linalg.norm(d[i]) / (DUR - SETTLE)), terminated=bool(r["terminated"][i]), why=r["why"][i],
                 torque_peak=float(r["torque_peak"][i]), leg_rate_peak=float(r["leg_rate_peak"][i]))
            for i, (m, s) in enumerate(cases)]
    own = np.array([x["offset_deg"] for x in rows if x["run_gait"] == "own" and not x["terminated"]])
    mirror = np.array([x["offset_deg"] for x in rows if x["run_gait"] == "mirror" and not x["terminated"]])
    # the mirror's offset is the own gait's negated: pool them
    delta = float(np.mean(np.r_[own, -mirror]))
    ok = [x for x in rows if not x["terminated"]]
    chord_delta = float(np.mean([x["chord_offset_deg"] * (-1 if x["run_gait"] == "mirror" else 1) for x in ok]))
    rate = float(np.mean([x["yaw_rate_degps"] * (-1 if x["run_gait"] == "mirror" else 1) for x in ok]))
    out = dict(model=MODEL, physics=PHYSICS, run_gait=G.name, run_gait_file=OWN_FILE, duration=DUR, settle_s=SETTLE,
               direction_offset_deg=delta, run_yaw_rate_degps=rate, chord_offset_deg=chord_delta, rows=rows)
    json.dump(out, open(out_name("direction"), "w"), indent=1)
    for x in rows:
        print({k: (round(v, 3) if isinstance(v, float) else v) for k, v in x.items()})
    print(f"{MODEL}: {G.name} travels at yaw + {delta:.2f} deg (own {own.min():.2f}..{own.max():.2f}, "
          f"mirror {mirror.min():.2f}..{mirror.max():.2f}); its yaw drifts {rate:+.3f} deg/s, so over "
          f"{DUR - SETTLE:.0f} s its chord points at the starting yaw + {chord_delta:.2f} deg")
