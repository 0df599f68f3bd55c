from defect import *
# one control step per window start (from the reference's states at some control steps), compare single substeps
import defect as D_; D_.PFIX = "p" in sys.argv; D_.ACTUAL = "a" in sys.argv
d = load()
sim = d["sim"]; k, layout = dynamics.constants(sim.robot, sim.model), dynamics.leg_layout(sim.robot)
T, W = sim.torque_limit, sim.leg_rate_limit
rows = []
h = d["dt"] / 15
for i in range(0, 100, 3):
    tg = Lin(d["ws"][:, i], d["we"][:, i], d["dt"])
    f, _ = simulation._stage_fns(sim, tg)
    def F(t, z):
        c = swap(z, omega_of(z, k, layout))
        return swap(f(t, c), p_rate(c, z[8:11], k, layout))
    y = list(np.array(d["ref"][i].T))
    z = swap(y, p_of(y, k, layout))
    for sidx in range(15):
        t = sidx * h
        # fine
        zf = z
        for r in range(64):
            zf = rk4_from(F, t + r * h / 64, zf, h / 64, F(t + r * h / 64, zf))
        plain = make_defect(True, True)
        # single substep via stepper with n=1 from z (convert back to c)
        c0 = swap(z, omega_of(z, k, layout))
        STATS["split"] = 0
        one = D_.make_defect(True, True)(f, None, t, c0, h, 1, tg, sim)
        sw = None
        rk = rk4_from(F, t, z, h, F(t, z))
        rows.append((np.array(zf), np.array(swap(one, p_of(one, k, layout))), np.array(rk)))
        z = zf
import itertools
zf = np.concatenate([r[0] for r in rows], 1); co = np.concatenate([r[1] for r in rows], 1); rk = np.concatenate([r[2] for r in rows], 1)
e_rk = abs(rk - zf); e_co = abs(co - zf)
sw = np.max(abs(co - rk)[6:8], axis=0) > 1e-13
print("switch substeps", sw.sum(), "of", sw.size)
names = ["x","y","qw","qx","qy","qz","phi1","phi2","p1","p2","p3","v1","v2"]
for j in range(13):
    print(f"{names[j]:4s} rk4 switch: med {np.median(e_rk[j, sw]):.2e} max {e_rk[j, sw].max():.2e} | corrected: med {np.median(e_co[j, sw]):.2e} max {e_co[j, sw].max():.2e} | no switch rk4 med {np.median(e_rk[j, ~sw]):.2e} max {e_rk[j, ~sw].max():.2e}")
