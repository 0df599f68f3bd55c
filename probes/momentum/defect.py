from split import *
from rrrobot_gym.control import motor_torque

def clip(tau, w, T, W):
    return motor_torque(tau, w, T, W)

def hermite(y0, d0, y1, d1, h, s):
    x = s / h
    h00, h10, h01, h11 = 2*x**3 - 3*x**2 + 1, x**3 - 2*x**2 + x, -2*x**3 + 3*x**2, x**3 - x**2
    return h00 * y0 + h10 * h * d0 + h01 * y1 + h11 * h * d1

GL = np.polynomial.legendre.leggauss(8)

def defects(sim, tg, t, z0, z1, a0, a1, h, sub=64, stages=None):
    """Per leg (delta, delta2): the model's quadrature errors of int tau and int (h - s) tau (RK4's weights)."""
    kp, kd, T, W = sim.gains.kp, sim.gains.kd, sim.torque_limit, sim.leg_rate_limit
    out = []
    for j in range(2):
        def pd(s, phi, w):
            ang, rate, _ = tg.leg_targets(t + s)
            return kp * (ang[j] - phi) + kd * (rate[j] - w)
        ang0, rate0, _ = tg.leg_targets(t)
        tau0 = pd(0.0, z0[6 + j], z0[11 + j]); tau1 = pd(h, z1[6 + j], z1[11 + j])
        dt0 = kp * (rate0[j] - z0[11 + j]) - kd * a0[j]
        dt1 = kp * (rate0[j] - z1[11 + j]) - kd * a1[j]
        w0, w1 = z0[11 + j], z1[11 + j]
        model = lambda s: clip(hermite(tau0, dt0, tau1, dt1, h, s), hermite(w0, a0[j], w1, a1[j], h, s), T, W)
        # fine quadrature: sub panels of 8-point Gauss
        I1 = 0.0; I2 = 0.0
        for p in range(sub):
            lo, hi = p * h / sub, (p + 1) * h / sub
            for x, wt in zip(*GL):
                s = 0.5 * (lo + hi) + 0.5 * (hi - lo) * x
                v = model(s) * (0.5 * (hi - lo) * wt)
                I1 = I1 + v; I2 = I2 + (h - s) * v
        if stages is None:
            m0, mh, m1 = model(0.0), model(0.5 * h), model(h)
            out.append((I1 - h / 6 * (m0 + 4 * mh + m1), I2 - h * h / 6 * (m0 + 2 * mh)))
        else:
            s1, s2, s3, s4 = [stage_tau(sim, tg, t + s, zz, j) for s, zz in stages]
            out.append((I1 - h / 6 * (s1 + 2 * (s2 + s3) + s4), I2 - h * h / 6 * (s1 + s2 + s3)))
    return out

def stage_tau(sim, tg, t, zz, j):
    kp, kd, T, W = sim.gains.kp, sim.gains.kd, sim.torque_limit, sim.leg_rate_limit
    ang, rate, _ = tg.leg_targets(t)
    return clip(kp * (ang[j] - zz[6 + j]) + kd * (rate[j] - zz[11 + j]), zz[11 + j], T, W)

ACTUAL = False
def mobility(c, k, layout):
    m_w, cs, Ds, S, _ = dynamics._configuration(c, k, layout)
    # A = D - C^T M^-1 C (2x2), Mob = A^-1; also M^-1 C (3x2)
    mic = [dynamics._sym_solve(m_w, *cc) for cc in cs]
    A = [[(Ds[i] if i == j else 0.0) - sum(cs[i][r] * mic[j][r] for r in range(3)) for j in range(2)] for i in range(2)]
    det = A[0][0] * A[1][1] - A[0][1] * A[1][0]
    mob = [[A[1][1] / det, -A[0][1] / det], [-A[1][0] / det, A[0][0] / det]]
    return mob, mic

def quat_mul(q, r):
    w1, x1, y1, z1 = q; w2, x2, y2, z2 = r
    return (w1*w2 - x1*x2 - y1*y2 - z1*z2, w1*x2 + x1*w2 + y1*z2 - z1*y2, w1*y2 - x1*z2 + y1*w2 + z1*x2, w1*z2 + x1*y2 - y1*x2 + z1*w2)

PFIX = False
def make_defect(attitude=True, position=True, only_switch=True):
    def stepper(f, g, t, y, h, n, tg, sim):
        k, layout = dynamics.constants(sim.robot, sim.model), dynamics.leg_layout(sim.robot)
        T, W = sim.torque_limit, sim.leg_rate_limit
        def F(t, z):
            c = swap(z, omega_of(z, k, layout))
            return swap(f(t, c), p_rate(c, z[8:11], k, layout))
        z = swap(y, p_of(y, k, layout))
        half, sixth = 0.5 * h, h / 6.0
        for _ in range(n):
            k1 = F(t, z)
            z2 = [a + half * b for a, b in zip(z, k1)]; k2 = F(t + half, z2)
            z3 = [a + half * b for a, b in zip(z, k2)]; k3 = F(t + half, z3)
            z4 = [a + h * b for a, b in zip(z, k3)]; k4 = F(t + h, z4)
            new = [a + sixth * (b1 + 2.0 * (b2 + b3) + b4) for a, b1, b2, b3, b4 in zip(z, k1, k2, k3, k4)]
            # which lanes switch: the clip's piece at the stage inputs and the end differs from the start
            kp, kd = sim.gains.kp, sim.gains.kd
            def pieces(s, zz):
                ang, rate, _ = tg.leg_targets(t + s)
                return [piece(kp * (ang[j] - zz[6 + j]) + kd * (rate[j] - zz[11 + j]), zz[11 + j], T, W) for j in range(2)]
            p0 = pieces(0.0, z)
            sw = np.zeros(len(z[0]), bool)
            for s, zz in ((half, z2), (half, z3), (h, z4), (h, new)):
                pp = pieces(s, zz)
                sw |= (pp[0] != p0[0]) | (pp[1] != p0[1])
            STATS["split"] += int(sw.sum()); STATS["robot_substeps"] += len(sw); STATS["blocks"] += int(sw.any())
            if sw.any() or not only_switch:
                dfs = defects(sim, tg, t, z, new, (k1[11], k1[12]), (k4[11], k4[12]), h, stages=((0.0, z), (half, z2), (half, z3), (h, z4)) if ACTUAL else None)
                c_mid = swap(z2, omega_of(z2, k, layout))
                mob, mic = mobility(c_mid, k, layout)
                dv = [mob[i][0] * dfs[0][0] + mob[i][1] * dfs[1][0] for i in range(2)]
                dphi = [mob[i][0] * dfs[0][1] + mob[i][1] * dfs[1][1] for i in range(2)]
                mask = sw if only_switch else np.ones_like(sw)
                corr = list(new)
                for i in range(2):
                    corr[11 + i] = new[11 + i] + dv[i]
                    corr[6 + i] = new[6 + i] + dphi[i]
                if attitude:
                    dth = [-(mic[0][r] * dphi[0] + mic[1][r] * dphi[1]) for r in range(3)]
                    q = quat_mul(tuple(new[2:6]), (1.0, 0.5 * dth[0], 0.5 * dth[1], 0.5 * dth[2]))
                    corr[2:6] = list(q)
                    if PFIX:
                        c_new = swap(new, omega_of(new, k, layout))
                        pp = new[8:11]
                        px = dynamics._cross(*pp, *dth)
                        for r in range(3):
                            corr[8 + r] = new[8 + r] + px[r] + k.damping * dth[r]
                    if position:
                        n_ = dynamics._up_vector(*new[2:6])
                        cr = k.pole
                        sd = [-cr * v for v in dynamics._cross(*n_, *dth)]  # s change = -c (n x dth)
                        R = dynamics.rotation_rows(*new[2:6])
                        corr[0] = new[0] + sum(R[0][r] * sd[r] for r in range(3))
                        corr[1] = new[1] + sum(R[1][r] * sd[r] for r in range(3))
                new = [np.where(mask, a, b) for a, b in zip(corr, new)]
            unit_quaternion(new)
            z = new
            t += h
        return swap(z, omega_of(z, k, layout))
    return stepper

if __name__ == "__main__" and len(sys.argv) > 1:
    PFIX = True
    d = load()
    for key in STATS: STATS[key] = 0
    t0 = time.time()
    report("mom+defect all + p", d, run(d, make_defect(True, True), 15), t0)
if __name__ == "__main__" and len(sys.argv) == 1:
    d = load()
    for name, st in (("mom+defect legs", make_defect(False, False)), ("mom+defect legs+att", make_defect(True, False)),
                     ("mom+defect all", make_defect(True, True))):
        for key in STATS: STATS[key] = 0
        t0 = time.time()
        report(name, d, run(d, st, 15), t0)
        print("  switch fraction", STATS["split"] / STATS["robot_substeps"])
