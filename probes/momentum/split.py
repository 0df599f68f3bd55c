from steppers import *

def piece(tau, w, T, W):
    high = np.minimum(T, T - T * w / W)
    low = np.minimum(T, T + T * w / W)
    return np.where(tau > high, np.where(w > 0, 2, 1), np.where(tau < -low, np.where(w < 0, 4, 3), 0))

def predict(sim, tg, t, y, k1, horizon, grid=48, bisect=14):
    kp, kd, T, W = sim.gains.kp, sim.gains.kd, sim.torque_limit, sim.leg_rate_limit
    ang, rate, _ = tg.leg_targets(t)
    best = np.full(len(y[0]), np.inf)
    for j in range(2):
        tau0 = kp * (ang[j] - y[6 + j]) + kd * (rate[j] - y[11 + j])
        dtau = kp * (rate[j] - y[11 + j]) - kd * k1[11 + j]
        w0, dw = y[11 + j], k1[11 + j]
        p0 = piece(tau0, w0, T, W)
        dd = np.linspace(0, 1, grid + 1)[1:, None] * np.broadcast_to(horizon, p0.shape)[None, :]
        changed = piece(tau0 + dtau * dd, w0 + dw * dd, T, W) != p0
        found = changed.any(axis=0)
        first = np.argmax(changed, axis=0)
        cols = np.arange(len(p0))
        lo = np.where(first > 0, dd[np.maximum(first - 1, 0), cols], 0.0)
        hi = dd[first, cols]
        for _ in range(bisect):
            mid = 0.5 * (lo + hi)
            moved = piece(tau0 + dtau * mid, w0 + dw * mid, T, W) != p0
            hi, lo = np.where(moved, mid, hi), np.where(moved, lo, mid)
        best = np.where(found, np.minimum(best, 0.5 * (lo + hi)), best)
    return best

def rk4_from(F, t, z, h, k1):
    half, sixth = 0.5 * h, h / 6.0
    k2 = F(t + half, [a + half * b for a, b in zip(z, k1)])
    k3 = F(t + half, [a + half * b for a, b in zip(z, k2)])
    k4 = F(t + h, [a + h * b for a, b in zip(z, k3)])
    z = [a + sixth * (b1 + 2.0 * (b2 + b3) + b4) for a, b1, b2, b3, b4 in zip(z, k1, k2, k3, k4)]
    unit_quaternion(z)
    return z

STATS = {"split": 0, "robot_substeps": 0, "blocks": 0, "substeps": 0}

def make(momentum=True, split=True):
    def stepper(f, g, t, y, h, n, tg, sim):
        k, layout = dynamics.constants(sim.robot, sim.model), dynamics.leg_layout(sim.robot)
        if momentum:
            def F(t, z):
                c = swap(z, omega_of(z, k, layout))
                return swap(f(t, c), p_rate(c, z[8:11], k, layout))
            to_c = lambda z: swap(z, omega_of(z, k, layout))
            z = swap(y, p_of(y, k, layout))
        else:
            F, to_c, z = f, (lambda z: z), y
        for _ in range(n):
            k1 = F(t, z)
            new = rk4_from(F, t, z, h, k1)
            if split:
                D = predict(sim, tg, t, to_c(z), f(t, to_c(z)) if momentum else k1, h)
                s = D < h
                STATS["split"] += int(s.sum()); STATS["robot_substeps"] += len(s)
                STATS["blocks"] += int(s.any()); STATS["substeps"] += 1
                if s.any():
                    theta = np.where(s, D, 0.5 * h)
                    mid = rk4_from(F, t, z, theta, [b for b in k1])
                    two = rk4_from(F, t + theta, mid, h - theta, F(t + theta, mid))
                    new = [np.where(s, a, b) for a, b in zip(two, new)]
            z = new
            t += h
        return to_c(z)
    return stepper

if __name__ == "__main__":
    d = load()
    for name, st in (("plain+split", make(False, True)), ("momentum+split", make(True, True))):
        for key in STATS: STATS[key] = 0
        t0 = time.time()
        report(name, d, run(d, st, 15), t0)
        print("  split fraction", STATS["split"] / STATS["robot_substeps"])
