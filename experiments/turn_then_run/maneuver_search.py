"""Step 2b: the spin gait overshoots (spin momentum), so search the turning gait T together with
the controller's lead and ramp, scored THROUGH the closed-loop TurnThenRun controller:
fitness = mean over headings {0, 45, 180} (after the turn the running gait or its mirror,
whichever needs the smaller turn, as the agent chooses: on the plane the own gait on all three) and starts {paper, noise seed 21}
of the upright-contact speed along the heading over DUR s; any termination -> -1 + 0.25 * survived share.

    python maneuver_search.py [--model pivot] [--run-gait FILE] [budget_s [warm_start.json [sigma0]]]   # reads yaw_search[_pivot].json, writes maneuver_search[_pivot].json"""
import json, math, sys, time
import numpy as np, cma
from common import *
from turn_then_run import TurnThenRun, score, DT, DELTA_DEG, smaller_turn_mirror

HEAD = np.array([0.0, 45.0, 180.0]); SEEDS = [None, 21]
DUR = 20.0
RAMP_MAX, LEAD_MAX = 2.0, 1.5   # s, the blend's and the lead's upper bounds
if own_gait().ramp_s > 0:
    # A running gait searched with a ramp from rest slips when blended into within ~4 s of a turn
    # (swap_robust.py: 0.5-4 s all slip, 8 s does not): allow blends up to 5 ramps, scored over 30 s.
    # A first search (0, 45, 180 deg, paper's start and seed 21) put the lead at its bound and
    # overshot the one turn it did not score, 45 deg anticlockwise with the own gait (135 deg):
    # a wider lead, 135 deg and a third start.
    DUR, RAMP_MAX, LEAD_MAX = 30.0, 5.0 * own_gait().ramp_s, 3.0
    HEAD, SEEDS = np.array([0.0, 45.0, 135.0, 180.0]), [None, 21, 22]
STEPS = int(DUR / DT)
if MODEL == "pivot":
    # The pivot's running gait drifts clockwise (own; its mirror anticlockwise, direction.py), and a
    # 45 deg turn in the sense of the drift can leave it spinning: 135 deg (mirror gait after an
    # anticlockwise 45 deg turn) adds that case. With 0, 45, 180 the four turns are then all scored.
    HEAD = np.array([0.0, 45.0, 135.0, 180.0])
BUDGET = float(sys.argv[1]) if __name__ == "__main__" and len(sys.argv) > 1 else 420.0
WARM = sys.argv[2] if __name__ == "__main__" and len(sys.argv) > 2 else None   # a maneuver JSON whose best joins the screen
SIGMA0 = float(sys.argv[3]) if __name__ == "__main__" and len(sys.argv) > 3 else 0.2   # CMA-ES's first step, in the unit box
POP = 32
lows = np.array([BOUNDS[n][0] for n in PARAMETER_NAMES] + [0.0, 0.0]); highs = np.array([BOUNDS[n][1] for n in PARAMETER_NAMES] + [LEAD_MAX, RAMP_MAX])
def to_params(u):
    p = lows + np.clip(u, 0, 1) * (highs - lows)
    p[:6] = repair(p[:6]); return p
to_unit = lambda p: (np.asarray(p) - lows) / (highs - lows)
G = own_gait().as_array()
K = len(HEAD) * len(SEEDS)

def evaluate(params):
    P = len(params)
    heads = np.tile(np.repeat(HEAD, len(SEEDS)), P)
    starts = np.tile(start_states(1, SEEDS), (P * len(HEAD), 1))
    rows = np.repeat(params, K, axis=0)
    # T per robot: TurnThenRun takes one T; build per-robot by running the class with row-wise T
    ctl = TurnThenRunRows(rows[:, :6], G, heads, smaller_turn_mirror(heads), rows[:, 6], rows[:, 7], np.ones(len(heads), bool))
    r = run(ctl, starts, STEPS, targets=np.radians(heads))
    sp = score(r, heads, DUR).reshape(P, K)
    term = r["terminated"].reshape(P, K); share = (r["end_step"] / STEPS).reshape(P, K)
    fit = np.where(term.any(1), -1 + 0.25 * share.mean(1) + 0.1 * np.clip(sp.mean(1), -1, 1), sp.mean(1))
    return fit, sp, term

class TurnThenRunRows(TurnThenRun):
    def __init__(self, Ts, G, *a, **kw):
        super().__init__(Ts[0], G, *a, **kw)
        from turn_then_run import seven
        self.gT = np.array([seven(T, s > 0) for T, s in zip(Ts, self.sign)])
        self.g_from = self.gT.copy()

if __name__ == "__main__":
    t0 = time.time(); rng = np.random.default_rng(1)
    top = json.load(open(out_name("yaw_search", gait=False)))["top"][0]
    T0 = np.array(top["params"])
    if top["yaw_rate"] > 0:   # the controller's turning gait turns clockwise (its mirror anticlockwise)
        T0 = mirror_gait(T0)
    seeds_p = [np.r_[T0, 0.6, 1.0]]
    for f in (0.3, 0.5, 0.7):   # gentler versions of the spin gait
        Ts = T0.copy(); Ts[0] *= f; Ts[1] *= f; seeds_p.append(np.r_[Ts, 0.4, 1.0])
    if WARM:
        warm = np.array(json.load(open(WARM))["top"][0]["params"])
        seeds_p.append(warm)
        if RAMP_MAX > 2.0:
            seeds_p += [np.r_[warm[:7], b] for b in (4.0, 6.0, 8.0) if b <= RAMP_MAX]
    screen = np.array(seeds_p + [to_params(u) for u in rng.uniform(size=(60, 8))])
    archive = []
    def rec(params, out):
        for i in range(len(params)):
            archive.append(dict(params=params[i].tolist(), fitness=float(out[0][i]), speeds=out[1][i].tolist(), terminated=out[2][i].tolist()))
    for ch in np.array_split(screen, 2):
        rec(ch, evaluate(ch))
    best = max(archive, key=lambda a: a["fitness"])
    print(f"screen {len(screen)} {time.time()-t0:.0f}s best {best['fitness']:.4f}", best, flush=True)
    es = cma.CMAEvolutionStrategy(np.clip(to_unit(best["params"]), 1e-6, 1 - 1e-6), SIGMA0, {"bounds": [0, 1], "popsize": POP, "seed": 2, "verbose": -9})
    gen = 0; hist = []
    while time.time() - t0 < BUDGET and not es.stop():
        U = es.ask(); params = np.array([to_params(u) for u in U]); out = evaluate(params); rec(params, out)
        es.tell(U, (-out[0]).tolist()); gen += 1
        b = max(archive, key=lambda a: a["fitness"])
        hist.append(dict(gen=gen, t=round(time.time() - t0, 1), best=b["fitness"], median=float(np.median(out[0]))))
        print(hist[-1], flush=True)
    archive.sort(key=lambda a: -a["fitness"])
    json.dump(dict(**({} if MODEL == "plane" else dict(model=MODEL, physics=PHYSICS, direction_offset_deg=DELTA_DEG)), headings=HEAD.tolist(), seeds=SEEDS, duration=DUR, generations=gen, seconds=time.time() - t0,
                   evaluations=len(archive), history=hist, top=archive[:10]), open(out_name("maneuver_search"), "w"), indent=1)
    for a in archive[:3]: print(a)
