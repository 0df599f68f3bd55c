from split import *
import split as S_

def slope(pc, dtau, dw, T, W):
    return np.where(pc == 0, dtau, np.where((pc == 2) | (pc == 4), -T / W * dw, 0.0))

def predictJ(sim, tg, t, y, k1, horizon, grid=48, bisect=14):
    kp, kd, T, W = sim.gains.kp, sim.gains.kd, sim.torque_limit, sim.leg_rate_limit
    ang, rate, _ = tg.leg_targets(t)
    best = np.full(len(y[0]), np.inf); bestJ = np.zeros(len(y[0]))
    for j in range(2):
        tau0 = kp * (ang[j] - y[6 + j]) + kd * (rate[j] - y[11 + j])
        dtau = kp * (rate[j] - y[11 + j]) - kd * k1[11 + j]
        w0, dw = y[11 + j], k1[11 + j]
        p0 = piece(tau0, w0, T, W)
        dd = np.linspace(0, 1, grid + 1)[1:, None] * np.broadcast_to(horizon, p0.shape)[None, :]
        pcs = piece(tau0 + dtau * dd, w0 + dw * dd, T, W)
        changed = pcs != p0
        found = changed.any(axis=0)
        first = np.argmax(changed, axis=0)
        cols = np.arange(len(p0))
        p1 = pcs[first, cols]
        lo = np.where(first > 0, dd[np.maximum(first - 1, 0), cols], 0.0)
        hi = dd[first, cols]
        for _ in range(bisect):
            mid = 0.5 * (lo + hi)
            moved = piece(tau0 + dtau * mid, w0 + dw * mid, T, W) != p0
            hi, lo = np.where(moved, mid, hi), np.where(moved, lo, mid)
        J = abs(slope(p0, dtau, dw, T, W) - slope(p1, dtau, dw, T, W))
        D = 0.5 * (lo + hi)
        take = found & (D < best)
        best = np.where(take, D, best); bestJ = np.where(take, J, bestJ)
    return best, bestJ

JS = []
THRESH = [0.0]
def predict_thr(sim, tg, t, y, k1, horizon):
    D, J = predictJ(sim, tg, t, y, k1, horizon)
    JS.extend(J[D < horizon].tolist())
    return np.where(J > THRESH[0], D, np.inf)

S_.predict = predict_thr
if __name__ == "__main__":
    d = load()
    for thr in [float(a) for a in sys.argv[1:]]:
        THRESH[0] = thr
        for key in STATS: STATS[key] = 0
        JS.clear()
        t0 = time.time()
        report(f"momentum+split J>{thr}", d, run(d, make(True, True), 15), t0)
        print("  split fraction", STATS["split"] / STATS["robot_substeps"], "J quantiles", np.quantile(JS, [0.1, 0.25, 0.5, 0.75, 0.9]))
