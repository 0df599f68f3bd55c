"""Momentum formulation for the pivot: p = M_w Omega + sum c_k phi_k' (body frame, about the centre)."""
from common import *
from rrrobot_gym.dynamics import _configuration, _sym_apply, _sym_solve, _cross, _up_vector

def parts(c, k, layout):
    m_w, cs, Ds, S, _ = _configuration(c, k, layout)
    return m_w, cs, S

def p_of(c, k, layout):
    m_w, cs, S = parts(c, k, layout)
    L = len(layout)
    lx, ly, lz = _sym_apply(m_w, c[6 + L], c[7 + L], c[8 + L])
    for m, (cx, cy, cz) in enumerate(cs):
        r = c[9 + L + m]
        lx, ly, lz = lx + cx * r, ly + cy * r, lz + cz * r
    return lx, ly, lz

def omega_of(z, k, layout):
    """z holds p at the body-rate rows: Omega."""
    m_w, cs, S = parts(z, k, layout)
    L = len(layout)
    bx, by, bz = z[6 + L], z[7 + L], z[8 + L]
    for m, (cx, cy, cz) in enumerate(cs):
        r = z[9 + L + m]
        bx, by, bz = bx - cx * r, by - cy * r, bz - cz * r
    return _sym_solve(m_w, bx, by, bz)

def p_rate(c, p, k, layout):
    """-Omega x p + k Omega - g S x n."""
    L = len(layout)
    ox, oy, oz = c[6 + L], c[7 + L], c[8 + L]
    _, _, S = parts(c, k, layout)
    n = _up_vector(c[2], c[3], c[4], c[5])
    a = _cross(ox, oy, oz, *p)
    gs = _cross(*S, *n)
    g, damp = k.gravity, k.damping
    return tuple(-a[j] + damp * (ox, oy, oz)[j] - g * gs[j] for j in range(3))

def swap(c, vec, L=2):
    return list(c[:6 + L]) + list(vec) + list(c[9 + L:])

if __name__ == "__main__":
    d = load()
    sim = d["sim"]
    k, layout = dynamics.constants(sim.robot, sim.model), dynamics.leg_layout(sim.robot)
    targets = RampTargets(d["ws"][:, 3], d["we"][:, 3], 0.0, d["dt"])
    f, _ = simulation._stage_fns(sim, targets)
    c = list(np.array(d["start"].T))
    t = 0.01
    dc = f(t, c)
    eps = 1e-6
    cp = [a + eps * b for a, b in zip(c, dc)]
    cm = [a - eps * b for a, b in zip(c, dc)]
    fd = [(a - b) / (2 * eps) for a, b in zip(p_of(cp, k, layout), p_of(cm, k, layout))]
    an = p_rate(c, p_of(c, k, layout), k, layout)
    print("fd  ", np.array(fd)[:, :3])
    print("form", np.array(an)[:, :3])
    om = omega_of(swap(c, p_of(c, k, layout)), k, layout)
    print("omega roundtrip", max(np.max(abs(om[j] - c[8 + j])) for j in range(3)))
    fd, an = np.array(fd), np.array(an)
    print("rel diff", np.max(abs(fd - an)) / np.max(abs(an)), np.max(abs(an)))
