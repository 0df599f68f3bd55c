"""Step 2: scripted closed-loop 'turn, then run' controller.

Gaits are written in a 7-number form g = (a1, a2, o1, o2, w, b1, b2):
    phi_k = o_k + a_k sin(theta + b_k),  theta integrated from w (so blending keeps the phase continuous).
A leg-exchanged (mirror) gait is (a2, a1, o2, o1, w, b2, b1).

Modes per robot: TURN (turning gait T, or its mirror, until the one-period moving-average
yaw, extrapolated by `lead` s with its rate, reaches the target yaw), then RAMP (gait
parameters blended T -> G with a smoothstep over `ramp` s, G re-phased so its targets
match T's at the switch if `rephase`), then RUN (G = searched-plane-own-1 or its mirror; a robot that needs no turn runs G at once, with
the gait's own swing ramp from rest if its file has one, as the agent does).
Target yaw = heading - DELTA (own gait, travel = yaw + DELTA) or heading + DELTA (mirror).
"""
import json, math, sys, time
import numpy as np
from common import *

DT = 0.05
WIN = 15                      # yaw moving-average window, steps (~ one gait period)
DELTA_DEG = 90.0              # own gait: travel direction = cycle-mean body yaw + DELTA (measured 90.2-90.4 over 20 s)
if MODEL != "plane" or RUN_GAIT:  # measured by direction.py (run it first; None until then), to the whole degree as on the plane
    try:                      # (pivot: -89.88, the same to 0.01 deg on 5 starts, own gait and mirror)
        DELTA_DEG = float(round(json.load(open(out_name("direction")))["direction_offset_deg"]))
    except FileNotFoundError:
        DELTA_DEG = None


# The gait helpers are the agent's (agents/turn_then_run.py), which was built from this script.
from rrrobot_gym.agents.turn_then_run import matching_phase_shift as best_shift
from rrrobot_gym.agents.turn_then_run import per_leg_angles as angles7
from rrrobot_gym.agents.turn_then_run import per_leg_gait as seven


class TurnThenRun:
    def __init__(self, T, G_own, heading_deg, use_mirror_gait, lead, ramp, rephase, delta_deg=DELTA_DEG, hold=None):
        n = len(heading_deg)
        self.n = n
        mg = np.asarray(use_mirror_gait, bool)
        self.gG = np.array([seven(G_own, m) for m in mg])
        target = np.radians(np.asarray(heading_deg, float) - np.where(mg, -delta_deg, delta_deg))
        target = (target + math.pi) % (2 * math.pi) - math.pi          # yaw target in (-pi, pi], start yaw 0
        self.target = target
        self.sign = np.sign(target)                                       # + : CCW turn needed
        self.sign[self.sign == 0] = 1
        # T turns CW (yaw rate < 0); its mirror turns CCW
        self.gT = np.array([seven(T, s > 0) for s in self.sign])
        self.lead = np.broadcast_to(np.asarray(lead, float), (n,)).copy()
        self.ramp = np.broadcast_to(np.asarray(ramp, float), (n,)).copy()
        self.rephase = np.broadcast_to(np.asarray(rephase, bool), (n,)).copy()
        self.mode = np.zeros(n, int)          # 0 TURN, 1 RAMP, 2 RUN
        self.mode[np.abs(target) < 1e-9] = 2
        self.at_once = self.mode == 2          # these run the gait from rest: with its own ramp (common.ramped)
        self.theta = np.zeros(n)
        self.shift = np.zeros(n)
        self.t_switch = np.full(n, np.nan)
        self.hist = []
        self.prev_yaw = None
        self.g_from = self.gT.copy()
        self.hold = hold

    def __call__(self, k, states, alive):
        y = yaw_of(states)
        if self.prev_yaw is None:
            uy = y
        else:
            uy = self.prev_yaw + (y - self.prev_yaw + math.pi) % (2 * math.pi) - math.pi
        self.prev_yaw = uy
        self.hist.append(uy)
        h = np.array(self.hist[-2 * WIN:])
        avg = h[-WIN:].mean(0)
        rate = (h[-WIN:].mean(0) - h[:WIN].mean(0)) / (WIN * DT) if len(h) == 2 * WIN else np.zeros(self.n)
        pred = avg + rate * self.lead
        t = k * DT
        switch = (self.mode == 0) & (self.sign * (self.target - pred) <= 0) & (len(h) >= WIN)
        if switch.any():
            self.mode[switch] = 1
            self.t_switch[switch] = t
            sh = best_shift(self.gT[switch], self.gG[switch], self.theta[switch])
            self.shift[switch] = np.where(self.rephase[switch], sh, 0.0)
        s = np.zeros(self.n)
        s[self.mode >= 1] = 1.0
        ramping = self.mode == 1
        if ramping.any():
            x = np.clip((t - self.t_switch[ramping]) / np.maximum(self.ramp[ramping], 1e-9), 0, 1)
            s[ramping] = x * x * (3 - 2 * x)
            self.mode[ramping & (s >= 1)] = 2
        gG = self.gG.copy(); gG[:, 5] += self.shift; gG[:, 6] += self.shift
        g = (1 - s)[:, None] * self.gT + s[:, None] * gG
        g[self.at_once] = ramped(g[self.at_once], (k + 1) * DT)
        self.theta = self.theta + g[:, 4] * DT
        return angles7(g, self.theta)


def turn_deg(heading_deg, use_mirror_gait, delta_deg=None):
    """The yaw turn (deg, in (-180, 180]) from the paper's start (yaw 0) that points the running
    gait (or its mirror) along each heading."""
    delta = DELTA_DEG if delta_deg is None else delta_deg
    t = np.asarray(heading_deg, float) - np.where(use_mirror_gait, -delta, delta)
    return (t + 180.0) % 360.0 - 180.0


def smaller_turn_mirror(heading_deg, delta_deg=None):
    """Whether the mirror gait needs the smaller turn (ties: the own gait), as the agent chooses."""
    own, mirror = np.abs(turn_deg(heading_deg, False, delta_deg)), np.abs(turn_deg(heading_deg, True, delta_deg))
    return mirror < own - 1e-6


def score(r, heading_deg, dur):
    h = np.radians(heading_deg)
    d = r["up"][-1] - r["up"][0]
    return (d[:, 0] * np.cos(h) + d[:, 1] * np.sin(h)) / dur


if __name__ == "__main__":
    top = json.load(open(out_name("yaw_search", gait=False)))["top"][0]
    T = np.array(top["params"])
    if top["yaw_rate"] > 0:   # TurnThenRun's turning gait turns clockwise
        T = mirror_gait(T)
    G = own_gait().as_array()
    dur = float(sys.argv[1]) if len(sys.argv) > 1 else 50.0
    headings, mirrors, leads, ramps, reph = [], [], [], [], []
    for hd in (0.0, 45.0, 180.0):
        for m in (False, True):
            if abs(turn_deg(hd, m)) > 91.0: continue    # (plane: the mirror on 45 deg) a 135 deg turn
            for L in (0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.3):
                for rp in (0.0, 0.4, 1.0, 2.0):
                    for ph in (False, True):
                        headings.append(hd); mirrors.append(m); leads.append(L); ramps.append(rp); reph.append(ph)
    headings = np.array(headings)
    n = len(headings)
    ctl = TurnThenRun(T, G, headings, mirrors, leads, ramps, reph)
    t0 = time.time()
    r = run(ctl, start_states(1, [None] * n), int(dur / DT), targets=np.radians(headings))
    wall = time.time() - t0
    sp = score(r, headings, dur)
    rew = r["reward_forward_sum"] / 100 * DT / dur
    rows = []
    for i in range(n):
        rows.append(dict(heading=headings[i], mirror_gait=bool(mirrors[i]), lead=leads[i], ramp=ramps[i], rephase=bool(reph[i]),
                         speed_mps=float(sp[i]), reward_speed_mps=float(rew[i]), terminated=bool(r["terminated"][i]), why=r["why"][i],
                         end_s=float(r["end_step"][i] * DT), t_switch=float(ctl.t_switch[i]),
                         yaw_end_deg=float(np.degrees(r["yaw"][-1, i])), yaw_target_deg=float(np.degrees(ctl.target[i]))))
    json.dump(dict(duration=dur, wall_s=wall, turn_gait=T.tolist(), run_gait=G.tolist(), rows=rows), open(out_name(f"sweep_{int(dur)}s"), "w"), indent=1)
    print(f"{n} robots, {dur} s, wall {wall:.0f} s")
    for hd in (0.0, 45.0, 180.0):
        ok = [x for x in rows if x["heading"] == hd and not x["terminated"]]
        print(f"heading {hd}: {len(ok)} of {sum(1 for x in rows if x['heading']==hd)} in model")
        for x in sorted(ok, key=lambda x: -x["speed_mps"])[:5]:
            print("   ", {k: (round(v, 4) if isinstance(v, float) else v) for k, v in x.items()})
    from collections import Counter
    print(Counter(x["why"] for x in rows if x["terminated"]))
