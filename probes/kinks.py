"""Probe: RK4 variants across the motor's kinks, on the restarted 5 s windows (numpy, throwaway).

python probes/kinks.py MODEL METHOD [args]   (windows from /tmp/acc_MODEL.pkl, made by probes/windows.py)
"""
import math, pickle, sys, time
import numpy as np
from scipy.integrate import solve_ivp
sys.path.insert(0, "probes")
from windows import err
from rrrobot_gym import dynamics
from rrrobot_gym.control import motor_torque

# ---- the servo laws ------------------------------------------------------------------
def law_clip(tau, w, T, W):
    return motor_torque(tau, w, T, W)

def smin(a, b, eps):
    return 0.5 * (a + b - np.sqrt((a - b) ** 2 + eps * eps))

def law_smooth(eps):
    def law(tau, w, T, W):
        high = smin(T, T - T * w / W, eps)
        low = smin(T, T + T * w / W, eps)
        return smin(-smin(-tau, low, eps), high, eps)
    return law

def piece(tau, w, T, W):
    """0 unsaturated, 1 stall high, 2 line high, 3 stall low, 4 line low."""
    high = np.minimum(T, T - T * w / W)
    low = np.minimum(T, T + T * w / W)
    return np.where(tau > high, np.where(w > 0, 2, 1), np.where(tau < -low, np.where(w < 0, 4, 3), 0))

# ---- one control step's right-hand side, ramps of per-robot slopes ------------------------
class Scene:
    def __init__(self, sim, start, end, dt, law=law_clip):
        self.k = dynamics.constants(sim.robot, sim.depth)
        self.kp, self.kd = sim.gains.kp, sim.gains.kd
        self.T, self.W = sim.torque_limit, sim.leg_rate_limit
        self.a0 = (start[:, 0], start[:, 1])
        self.slope = ((end[:, 0] - start[:, 0]) / dt, (end[:, 1] - start[:, 1]) / dt)
        self.law = law
        self.evals = 0

    def pd(self, t, c):
        return tuple(self.kp * (self.a0[j] + self.slope[j] * t - c[6 + j]) + self.kd * (self.slope[j] - c[11 + j])
                     for j in range(2))

    def f(self, t, c):
        self.evals += 1
        tau = self.pd(t, c)
        applied = (self.law(tau[0], c[11], self.T, self.W), self.law(tau[1], c[12], self.T, self.W))
        return dynamics.derivative_kernel(c, applied, self.k)

    def pieces(self, t, c):
        tau = self.pd(t, c)
        return np.stack([piece(tau[j], c[11 + j], self.T, self.W) for j in range(2)], 1)

def unit(y):
    n = np.sqrt(y[2] ** 2 + y[3] ** 2 + y[4] ** 2 + y[5] ** 2)
    for j in range(2, 6):
        y[j] = y[j] / n
    return y

def rk4(sc, t, y, h, k1=None):
    """One RK4 step; t, h floats or (N,) arrays."""
    k1 = sc.f(t, y) if k1 is None else k1
    k2 = sc.f(t + 0.5 * h, [a + 0.5 * h * b for a, b in zip(y, k1)])
    k3 = sc.f(t + 0.5 * h, [a + 0.5 * h * b for a, b in zip(y, k2)])
    k4 = sc.f(t + h, [a + h * b for a, b in zip(y, k3)])
    return unit([a + h / 6.0 * (b1 + 2.0 * (b2 + b3) + b4) for a, b1, b2, b3, b4 in zip(y, k1, k2, k3, k4)])

def pick(mask, a, b):
    return [np.where(mask, x, z) for x, z in zip(a, b)]

# ---- crossing prediction from the first stage ---------------------------------------------
def predict_crossing(sc, t, y, k1, h, grid=48, bisect=12):
    """Per robot, the first time in (0, h) at which a motor's piece changes, predicted from the
    first stage (PD torque and leg rate linear in time, their rates from k1); h where none."""
    best = np.full(len(y[0]), np.inf)
    for j in range(2):
        tau0 = sc.kp * (sc.a0[j] + sc.slope[j] * t - y[6 + j]) + sc.kd * (sc.slope[j] - y[11 + j])
        dtau = sc.kp * (sc.slope[j] - y[11 + j]) - sc.kd * k1[11 + j]
        w0, dw = y[11 + j], k1[11 + j]
        p0 = piece(tau0, w0, sc.T, sc.W)
        d = np.linspace(0, 1, grid + 1)[1:, None] * np.broadcast_to(h, np.shape(tau0))[None, :]  # (grid, N)
        p = piece(tau0 + dtau * d, w0 + dw * d, sc.T, sc.W)
        changed = p != p0
        anyc = changed.any(axis=0)
        first = np.argmax(changed, axis=0)
        lo = np.where(first > 0, d[np.maximum(first - 1, 0), np.arange(len(p0))], 0.0)
        hi = d[first, np.arange(len(p0))]
        for _ in range(bisect):
            mid = 0.5 * (lo + hi)
            pm = piece(tau0 + dtau * mid, w0 + dw * mid, sc.T, sc.W)
            moved = pm != p0
            hi = np.where(moved, mid, hi)
            lo = np.where(moved, lo, mid)
        best = np.where(anyc, np.minimum(best, 0.5 * (lo + hi)), best)
    return best

# ---- the steppers of one control step ---------------------------------------------------------
def step_plain(sc, y, dt, n):
    h = dt / n
    for i in range(n):
        y = rk4(sc, i * h, y, h)
    return y, 4 * n * np.ones(len(y[0]))

def step_refine(sc, y, dt, n, refine=64):
    """A substep across which a motor changes piece, taken again in ``refine`` substeps (the ceiling)."""
    h = dt / n
    cost = np.zeros(len(y[0]))
    for i in range(n):
        t = i * h
        new = rk4(sc, t, y, h)
        cost += 4
        changed = (sc.pieces(t, y) != sc.pieces(t + h, new)).any(axis=1)
        if changed.any():
            fine = y
            for r in range(refine):
                fine = rk4(sc, t + r * h / refine, fine, h / refine)
            new = pick(changed, fine, new)
            cost += 4 * refine * changed
        y = new
    return y, cost

def step_split(sc, y, dt, n, min_piece=0.0):
    """Predict a crossing from the first stage; where one falls inside the substep, take the substep
    in two pieces split there (the first reusing k1): 7 evaluations instead of 4."""
    h = dt / n
    cost = np.zeros(len(y[0]))
    for i in range(n):
        t = i * h
        k1 = sc.f(t, y)
        tc = predict_crossing(sc, t, y, k1, h)
        split = (tc > min_piece * h) & (tc < (1 - min_piece) * h)
        new = rk4(sc, t, y, h, k1)
        cost += 4
        if split.any():
            theta = np.where(split, tc, 0.5 * h)
            mid = rk4(sc, t, y, theta, k1)
            two = rk4(sc, t + theta, mid, h - theta)
            new = pick(split, two, new)
            cost += 3 * split
        y = new
    return y, cost

STEPPERS = {"plain": step_plain, "refine": step_refine, "split": step_split}

def run(sim, start, s, e, dt, n, method, law=law_clip, **kw):
    y = list(start.T.copy())
    out = [start[:, :2].copy()]
    cost = 0.0
    for i in range(s.shape[1]):
        sc = Scene(sim, s[:, i], e[:, i], dt, law)
        y, c = STEPPERS[method](sc, y, dt, n, **kw)
        cost = cost + c
        out.append(np.stack(y[:2], 1))
    return np.array(out), cost / s.shape[1]

def reference(sim, start, s, e, dt, law, rtol=1e-10):
    y = start.copy()
    out = [y[:, :2].copy()]
    for i in range(s.shape[1]):
        sc = Scene(sim, s[:, i], e[:, i], dt, law)
        fun = lambda t, flat: np.array(sc.f(t, flat.reshape(13, -1))).ravel()
        sol = solve_ivp(fun, (0, dt), y.T.ravel(), method="DOP853", rtol=rtol, atol=rtol)
        y = sol.y[:, -1].reshape(13, -1).T.copy()
        y[:, 2:6] /= np.linalg.norm(y[:, 2:6], axis=1, keepdims=True)
        out.append(y[:, :2].copy())
    return np.array(out)


def step_graded(sc, y, dt, n, halves=1, refine=1):
    """The first ``halves`` substeps of the control step in two halves each (the kick of a new ramp);
    with refine > 1 also step_refine's treatment of kinked substeps."""
    h = dt / n
    cost = np.zeros(len(y[0]))
    for i in range(n):
        t = i * h
        if i < halves:
            new = rk4(sc, t + 0.5 * h, rk4(sc, t, y, 0.5 * h), 0.5 * h)
            cost += 8
        else:
            new = rk4(sc, t, y, h)
            cost += 4
        if refine > 1:
            changed = (sc.pieces(t, y) != sc.pieces(t + h, new)).any(axis=1)
            if changed.any():
                fine = y
                for r in range(refine):
                    fine = rk4(sc, t + r * h / refine, fine, h / refine)
                new = pick(changed, fine, new)
                cost += 4 * refine * changed
        y = new
    return y, cost

STEPPERS["graded"] = step_graded

# ---- the body's locked rate (rk4_locked of b1afa25, re-derived here on today's kernel) ----------
from rrrobot_gym.dynamics import _configuration, _rotation_products, _sym_solve, Constants
from candidates import _configuration_rate  # (b1afa25's, kept in candidates.py)

def _locked_terms(c, k):
    xx, yy, _, _, xz, yz, wx, wy, _ = _rotation_products(c[2], c[3], c[4], c[5])
    n = (xz - wy, yz + wx, 1.0 - (xx + yy))
    legs, _, _, m, (c1, c2) = _configuration(c[6], c[7], n, k)
    s = _sym_solve(m, c1[0] * c[11] + c2[0] * c[12], c1[1] * c[11] + c2[1] * c[12], c1[2] * c[11] + c2[2] * c[12])
    return n, legs, m, c1, c2, s

def to_locked(c, k):
    s = _locked_terms(c, k)[5]
    return c[:8] + [c[8] + s[0], c[9] + s[1], c[10] + s[2]] + c[11:]

def from_locked(c, k):
    s = _locked_terms(c, k)[5]
    return c[:8] + [c[8] - s[0], c[9] - s[1], c[10] - s[2]] + c[11:]

class LockedScene:
    """f on states whose rows 8-10 are the locked rate Lambda = Omega + M_omega^-1 (c_1 phi1' + c_2 phi2')."""
    def __init__(self, sc):
        self.sc, self.k = sc, sc.k
        for name in ("kp", "kd", "T", "W", "a0", "slope"):
            setattr(self, name, getattr(sc, name))

    @property
    def evals(self):
        return self.sc.evals

    def f(self, t, c):
        k = self.k
        n, legs, m, c1, c2, s = _locked_terms(c, k)
        om = (c[8] - s[0], c[9] - s[1], c[10] - s[2])
        d = list(self.sc.f(t, list(c[:8]) + list(om) + list(c[11:])))
        r1, r2 = c[11], c[12]
        nx, ny, nz = n
        n_rate = (ny * om[2] - nz * om[1], nz * om[0] - nx * om[2], nx * om[1] - ny * om[0])
        m_rate, (e1, e2) = _configuration_rate(legs, r1, r2, n, n_rate, k)
        a, bb, cc, dd, ee, ff = m_rate
        ms = (a * s[0] + bb * s[1] + cc * s[2], bb * s[0] + dd * s[1] + ee * s[2], cc * s[0] + ee * s[1] + ff * s[2])
        acc1, acc2 = d[11], d[12]
        rhs = [c1[j] * acc1 + c2[j] * acc2 + e1[j] * r1 + e2[j] * r2 - ms[j] for j in range(3)]
        corr = _sym_solve(m, *rhs)
        d[8], d[9], d[10] = d[8] + corr[0], d[9] + corr[1], d[10] + corr[2]
        return d

    def pieces(self, t, c):
        return self.sc.pieces(t, from_locked(list(c), self.k))

def step_locked(sc, y, dt, n, inner="plain", **kw):
    """RK4 (or another of STEPPERS) on the locked rate: Omega in and out, Lambda inside."""
    lsc = LockedScene(sc)
    yl, cost = STEPPERS[inner](lsc, to_locked(list(y), sc.k), dt, n, **kw)
    return from_locked(list(yl), sc.k), cost

STEPPERS["locked"] = step_locked

def rk4_pieces(sc, t, y, h):
    """RK4 step and whether any stage input (or the end) sits on another piece than the start."""
    p0 = sc.pieces(t, y)
    k1 = sc.f(t, y)
    s2 = [a + 0.5 * h * b for a, b in zip(y, k1)]
    k2 = sc.f(t + 0.5 * h, s2)
    s3 = [a + 0.5 * h * b for a, b in zip(y, k2)]
    k3 = sc.f(t + 0.5 * h, s3)
    s4 = [a + h * b for a, b in zip(y, k3)]
    k4 = sc.f(t + h, s4)
    new = unit([a + h / 6.0 * (b1 + 2.0 * (b2 + b3) + b4) for a, b1, b2, b3, b4 in zip(y, k1, k2, k3, k4)])
    changed = np.zeros(len(y[0]), dtype=bool)
    for tt, st in ((t + 0.5 * h, s2), (t + 0.5 * h, s3), (t + h, s4), (t + h, new)):
        changed |= (sc.pieces(tt, st) != p0).any(axis=1)
    return new, changed

def step_refine_stages(sc, y, dt, n, refine=64, fine_check=False):
    """step_refine, a substep counting as kinked where any stage input sits on another piece (or,
    with fine_check, where the fine path changes piece anywhere: every substep done fine, the ceiling)."""
    h = dt / n
    cost = np.zeros(len(y[0]))
    for i in range(n):
        t = i * h
        new, changed = rk4_pieces(sc, t, y, h)
        cost += 4
        if changed.any() or fine_check:
            fine = y
            p0 = sc.pieces(t, y)
            for r in range(refine):
                fine = rk4(sc, t + r * h / refine, fine, h / refine)
                if fine_check:
                    changed |= (sc.pieces(t + (r + 1) * h / refine, fine) != p0).any(axis=1)
            new = pick(changed, fine, new)
            cost += 4 * refine * changed
        y = new
    return y, cost

STEPPERS["refine_stages"] = step_refine_stages
