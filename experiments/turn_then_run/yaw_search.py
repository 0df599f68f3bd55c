"""Step 1: search the 6-number sinusoid family for the largest sustained |yaw rate|,
inside the model from the paper's start and from 2 start-noise seeds. Random screen + CMA-ES.

    python yaw_search.py [--model pivot] [budget_s]   # writes yaw_search[_pivot].json"""
import json, math, sys, time
import numpy as np, cma
from common import *

DUR = 10.0; DT = 0.05; STEPS = int(DUR / DT)
SEEDS = [None, 11, 12]          # paper's start + 2 noisy starts (noise 0.01, as the env)
BUDGET = float(sys.argv[1]) if __name__ == "__main__" and len(sys.argv) > 1 else 480.0
POP = 64; SCREEN = 512
lows = np.array([BOUNDS[n][0] for n in PARAMETER_NAMES]); highs = np.array([BOUNDS[n][1] for n in PARAMETER_NAMES])
to_params = lambda u: repair(lows + np.clip(u, 0, 1) * (highs - lows))
to_unit = lambda p: (np.asarray(p) - lows) / (highs - lows)
S = len(SEEDS); STARTS1 = start_states(1, SEEDS)


def yaw_rate(yaw, dt, t0=1.0):
    """slope (rad/s) of a least-squares line through yaw(t), t >= t0 (removes the in-cycle wobble)."""
    t = np.arange(len(yaw)) * dt
    m = t >= t0
    tt = t[m] - t[m].mean()
    return (tt[:, None] * (yaw[m] - yaw[m].mean(0))).sum(0) / (tt ** 2).sum()


def score(params):
    P = len(params)
    rows = np.repeat(params, S, axis=0)
    r = run(sinusoid_controller(rows, DT), np.tile(STARTS1, (P, 1)), STEPS)
    rate = yaw_rate(r["yaw"], DT).reshape(P, S)
    disp = (r["up"][-1] - r["up"][0]).reshape(P, S, 2)
    term = r["terminated"].reshape(P, S)
    share = (r["end_step"] / STEPS).reshape(P, S)
    mean_rate = rate.mean(1)
    # consistent turning: all starts turning the same way; fitness |mean rate| (rad/s)
    fit = np.where(term.any(1), -1.0 + 0.25 * share.mean(1) + 0.1 * np.clip(np.abs(mean_rate), 0, 1), np.abs(mean_rate))
    speed = np.linalg.norm(disp, axis=2).mean(1) / DUR
    return fit, mean_rate, speed, term.sum(1), rate


if __name__ == "__main__":
    t_start = time.time()
    rng = np.random.default_rng(0)
    archive = []
    def record(params, out):
        fit, mr, sp, nt, rate = out
        for i in range(len(params)):
            archive.append(dict(params=params[i].tolist(), fitness=float(fit[i]), yaw_rate=float(mr[i]), speed=float(sp[i]),
                                terminated=int(nt[i]), rates=rate[i].tolist()))
    # include the own gait and a few hand guesses (one leg still)
    own = own_gait().as_array()
    guesses = [own, [1.5, 0.0, 1.57, 1.57, 8.6, 0.0], [0.0, 1.5, 1.57, 1.57, 8.6, 0.0], [1.5, 1.5, 1.57, 1.57, 8.6, 0.0],
               [1.5, 1.5, 1.57, 1.57, 8.6, math.pi]]
    screen = np.vstack([repair(np.array(guesses))] + [to_params(u)[None] for u in rng.uniform(size=(SCREEN, 6))])
    for chunk in np.array_split(screen, 4):
        record(chunk, score(chunk))
    print(f"screen {len(screen)} in {time.time()-t_start:.0f}s; best", max(a['fitness'] for a in archive), flush=True)
    ok = [a for a in archive if a["terminated"] == 0]
    print("screen: in-model", len(ok), "of", len(archive))
    best = max(archive, key=lambda a: a["fitness"])
    es = cma.CMAEvolutionStrategy(np.clip(to_unit(best["params"]), 1e-6, 1 - 1e-6), 0.2,
                                  {"bounds": [0, 1], "popsize": POP, "seed": 1, "verbose": -9})
    gen = 0; hist = []
    while time.time() - t_start < BUDGET and not es.stop():
        U = es.ask(); params = np.array([to_params(u) for u in U])
        out = score(params); record(params, out)
        es.tell(U, (-out[0]).tolist()); gen += 1
        b = max(archive, key=lambda a: a["fitness"])
        hist.append(dict(gen=gen, t=round(time.time() - t_start, 1), best=b["fitness"], median=float(np.median(out[0]))))
        print(hist[-1], flush=True)
    archive.sort(key=lambda a: -a["fitness"])
    json.dump(dict(**({} if MODEL == "plane" else dict(model=MODEL, physics=PHYSICS)), seeds=[s for s in SEEDS], duration=DUR, generations=gen, seconds=time.time() - t_start,
                   evaluations=len(archive), history=hist, top=archive[:20],
                   screen_top=sorted(archive[:0] + [a for a in archive], key=lambda a: -a['fitness'])[:5]),
              open(out_name("yaw_search", gait=False), "w"), indent=1)
    for a in archive[:5]:
        print(a)
