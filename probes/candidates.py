"""Probe: candidate fixes for the default scene's accuracy, measured as benchmarks.scene_accuracy and
evaluate.py --check-accuracy measure the shipped code (throwaway; numpy path, monkeypatched).

    python probes/candidates.py CANDIDATE [--models ...] [--actions ...] [--quick] [--closed-loop] [--json FILE]

CANDIDATE: a motor law and a stepper, "LAW/STEPPER": LAW "clip" (today's) or "smoothE" (smooth
saturation of width E N m), STEPPER "rk4" (today's), "split" (a substep the first stage predicts a
motor switch in is taken in two pieces split there), "stages" (a substep whose stages see a switch
is taken again in 32: what locating switches exactly would buy), "locked" (RK4 on the body's locked
rate), "locked+split", "locked+stages", and a step "@N" (substeps per 0.05 s control step, default 15).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import rrrobot_gym.compiled as compiled  # noqa: E402

compiled.available = lambda: False  # numpy everywhere: the patched law and steppers act on every path
import rrrobot_gym.control as control  # noqa: E402
import rrrobot_gym.simulation as simulation  # noqa: E402
from rrrobot_gym import dynamics  # noqa: E402
from rrrobot_gym.dynamics import _configuration, _rotation_products, _sym_solve  # noqa: E402

simulation.ROW_BY_ROW_MAX = 0  # every batch on (N,) arrays

CLIP = control.motor_torque


# ---- motor laws ---------------------------------------------------------------------------------
def smooth_motor(eps):
    """The clip with each min/max a hyperbolic smooth min of width eps (N m): at most eps / 2 from
    the clip (at a corner), eps^2 / (4 d) at a distance d from one."""

    def smin(a, b):
        d = a - b
        return 0.5 * (a + b - (d * d + eps * eps) ** 0.5)

    def motor_torque(tau, rate, torque_limit, rate_limit=None):
        drop = torque_limit * rate / rate_limit
        high = smin(torque_limit, torque_limit - drop)
        low = smin(torque_limit, torque_limit + drop)
        return smin(-smin(-tau, low), high)

    return motor_torque


def piece(tau, w, T, W):
    """The clip's piece: 0 unsaturated, 1 stall high, 2 line high, 3 stall low, 4 line low."""
    high = np.minimum(T, T - T * w / W)
    low = np.minimum(T, T + T * w / W)
    return np.where(tau > high, np.where(w > 0, 2, 1), np.where(tau < -low, np.where(w < 0, 4, 3), 0))


# ---- one advance call's right-hand side at per-robot times ------------------------------------------
class Scene:
    """f(t, c) of an advance call (ramp or held targets, the config's servo), t a float or (N,) array."""

    def __init__(self, config, targets, t0):
        self.k = dynamics.constants(config.robot, config.depth)
        self.kp, self.kd = config.gains.kp, config.gains.kd
        self.T, self.W = config.torque_limit, config.leg_rate_limit
        (a1, a2), (r1, r2), _ = targets.leg_targets(t0)
        self.t0, self.a0, self.slope = t0, (a1, a2), (r1, r2)  # (within a control step the ramp is linear)
        self.evals = 0

    def pd(self, t, c):
        dt = t - self.t0
        return tuple(self.kp * (self.a0[j] + self.slope[j] * dt - c[6 + j]) + self.kd * (self.slope[j] - c[11 + j])
                     for j in range(2))  # fmt: skip

    def f(self, t, c):
        self.evals += 1
        tau = self.pd(t, c)
        if self.T is not None:
            tau = (control.motor_torque(tau[0], c[11], self.T, self.W), control.motor_torque(tau[1], c[12], self.T, self.W))
        return list(dynamics.derivative_kernel(c, tau, self.k))

    def pieces(self, t, c):
        tau = self.pd(t, c)
        return np.stack([piece(tau[j], c[11 + j], self.T, self.W) for j in range(2)], 1)


def unit(y):
    n = (y[2] * y[2] + y[3] * y[3] + y[4] * y[4] + y[5] * y[5]) ** 0.5
    return y[:2] + [y[2] / n, y[3] / n, y[4] / n, y[5] / n] + y[6:]


def rk4(f, t, y, h, k1):
    k2 = f(t + 0.5 * h, [a + 0.5 * h * b for a, b in zip(y, k1)])
    k3 = f(t + 0.5 * h, [a + 0.5 * h * b for a, b in zip(y, k2)])
    k4 = f(t + h, [a + h * b for a, b in zip(y, k3)])
    return unit([a + h / 6.0 * (b1 + 2.0 * (b2 + b3) + b4) for a, b1, b2, b3, b4 in zip(y, k1, k2, k3, k4)])


def pick(mask, a, b):
    return [np.where(mask, x, z) for x, z in zip(a, b)]


# ---- the body's locked rate (rk4_locked of b1afa25 on today's kernel) --------------------------------
def _configuration_rate(legs, rate1, rate2, n, n_rate, k):
    """(M_omega', (c_1', c_2')) as the legs turn and n turns at n_rate (b1afa25's dynamics.py)."""
    _, _, ml, h, _, _, _, _, _, _, _, ml_r, mb_r, mt, _, neg_ml, _, ml_h, _, _ = k
    (lc1, ls1, sy1), (lc2, ls2, sy2) = legs
    nx, ny, nz = n
    dnx, dny, dnz = n_rate
    dlc1, dls1, dlc2, dls2 = -ls1 * rate1, lc1 * rate1, -ls2 * rate2, lc2 * rate2
    dm2 = 2.0 * ml * (lc1 * dlc1 + lc2 * dlc2)
    dixy = ml_r * (dlc1 - dlc2)
    dixz = neg_ml * (dlc1 * ls1 + lc1 * dls1 + dlc2 * ls2 + lc2 * dls2)
    diyz = ml_r * (dls1 - dls2)
    if h == 0.0:
        return (-dm2, dixy, dixz, 0.0, diyz, dm2), ((-ml_r * dlc1, 0.0, -ml_r * dls1), (ml_r * dlc2, 0.0, ml_r * dls2))
    hsx, hsz = h * (ml * (lc1 + lc2)), h * (ml * (ls1 + ls2) - mb_r)
    dhsx, dhsz = h * ml * (dlc1 + dlc2), h * ml * (dls1 + dls2)
    ax, az = mt * nx + hsx, mt * nz + hsz
    dax, daz = mt * dnx + dhsx, mt * dnz + dhsz
    ddiag = 2.0 * (dhsx * nx + hsx * dnx + dhsz * nz + hsz * dnz)
    m_rate = (
        -dm2 + ddiag - dnx * (ax + hsx) - nx * (dax + dhsx),
        dixy - (dny * ax + ny * dax),
        dixz - (dnz * ax + nz * dax) - (dhsz * nx + hsz * dnx),
        ddiag - 2.0 * mt * ny * dny,
        diyz - (dny * az + ny * daz),
        dm2 + ddiag - dnz * (az + hsz) - nz * (daz + dhsz),
    )
    dsy = ml * h * dny
    ml_sy1, ml_sy2 = ml * sy1, ml * sy2
    dc1 = (dsy * lc1 + ml_sy1 * dlc1, -ml_h * (dnx * lc1 + nx * dlc1 + dnz * ls1 + nz * dls1), dsy * ls1 + ml_sy1 * dls1)
    dc2 = (dsy * lc2 + ml_sy2 * dlc2, -ml_h * (dnx * lc2 + nx * dlc2 + dnz * ls2 + nz * dls2), dsy * ls2 + ml_sy2 * dls2)
    return m_rate, (dc1, dc2)


def _locked_terms(c, k):
    xx, yy, _, _, xz, yz, wx, wy, _ = _rotation_products(c[2], c[3], c[4], c[5])
    n = (xz - wy, yz + wx, 1.0 - (xx + yy))
    legs, _, _, m, (c1, c2) = _configuration(c[6], c[7], n, k)
    s = _sym_solve(m, c1[0] * c[11] + c2[0] * c[12], c1[1] * c[11] + c2[1] * c[12], c1[2] * c[11] + c2[2] * c[12])
    return n, legs, m, c1, c2, s


def shift_rate(c, k, sign):
    """Rows 8-10: Omega -> Lambda = Omega + M_omega^-1 (c_1 phi1' + c_2 phi2') (sign +1) or back (-1)."""
    s = _locked_terms(c, k)[5]
    return list(c[:8]) + [c[8] + sign * s[0], c[9] + sign * s[1], c[10] + sign * s[2]] + list(c[11:])


def locked(f, k):
    """f on states whose rows 8-10 hold the locked rate; Lambda' = Omega' + M_omega^-1 (C phi'' + C' phi' - M_omega' s)."""

    def g(t, c):
        n, legs, m, c1, c2, s = _locked_terms(c, k)
        om = (c[8] - s[0], c[9] - s[1], c[10] - s[2])
        d = f(t, list(c[:8]) + list(om) + list(c[11:]))
        r1, r2 = c[11], c[12]
        nx, ny, nz = n
        n_rate = (ny * om[2] - nz * om[1], nz * om[0] - nx * om[2], nx * om[1] - ny * om[0])
        (a, bb, cc, dd, ee, ff), (e1, e2) = _configuration_rate(legs, r1, r2, n, n_rate, k)
        ms = (a * s[0] + bb * s[1] + cc * s[2], bb * s[0] + dd * s[1] + ee * s[2], cc * s[0] + ee * s[1] + ff * s[2])
        acc1, acc2 = d[11], d[12]
        corr = _sym_solve(m, *[c1[j] * acc1 + c2[j] * acc2 + e1[j] * r1 + e2[j] * r2 - ms[j] for j in range(3)])
        d[8], d[9], d[10] = d[8] + corr[0], d[9] + corr[1], d[10] + corr[2]
        return d

    return g


# ---- switch prediction from the first stage --------------------------------------------------------
def predicted_switch(sc, t, y, k1, horizon, grid=48, bisect=14):
    """Per robot, the first time in (0, horizon] at which a motor changes piece, the PD torque and
    the leg rate taken linear in time with their rates from the first stage (k1); inf where none."""
    best = np.full(len(y[0]), np.inf)
    dt = t - sc.t0
    for j in range(2):
        tau0 = sc.kp * (sc.a0[j] + sc.slope[j] * dt - y[6 + j]) + sc.kd * (sc.slope[j] - y[11 + j])
        dtau = sc.kp * (sc.slope[j] - y[11 + j]) - sc.kd * k1[11 + j]
        w0, dw = y[11 + j], k1[11 + j]
        p0 = piece(tau0, w0, sc.T, sc.W)
        d = np.linspace(0, 1, grid + 1)[1:, None] * np.broadcast_to(horizon, p0.shape)[None, :]
        changed = piece(tau0 + dtau * d, w0 + dw * d, sc.T, sc.W) != p0
        found = changed.any(axis=0)
        first = np.argmax(changed, axis=0)
        cols = np.arange(len(p0))
        lo = np.where(first > 0, d[np.maximum(first - 1, 0), cols], 0.0)
        hi = d[first, cols]
        for _ in range(bisect):
            mid = 0.5 * (lo + hi)
            moved = piece(tau0 + dtau * mid, w0 + dw * mid, sc.T, sc.W) != p0
            hi, lo = np.where(moved, mid, hi), np.where(moved, lo, mid)
        best = np.where(found, np.minimum(best, 0.5 * (lo + hi)), best)
    return best


# ---- steppers: one advance call of n substeps of h from t0 -------------------------------------------
STATS = {"substeps": 0, "split": 0, "evals": 0, "robot_substeps": 0}


def step_rk4(sc, f, first, t0, y, h, n):
    for i in range(n):
        t = t0 + i * h
        y = rk4(f, t, y, h, first(t, y))
    return y


def step_split(sc, f, first, t0, y, h, n):
    for i in range(n):
        t = t0 + i * h
        k1 = first(t, y)
        tc = predicted_switch(sc, t, y, k1, h)
        split = tc < h
        new = rk4(f, t, y, h, k1)
        if split.any():
            theta = np.where(split, tc, 0.5 * h)
            mid = rk4(f, t, y, theta, k1)
            two = rk4(f, t + theta, mid, h - theta, f(t + theta, mid))
            new = pick(split, two, new)
        STATS["split"] += int(split.sum())
        STATS["substeps"] += 1
        STATS["robot_substeps"] += len(split)
        STATS.setdefault("blocks_split", 0)
        STATS["blocks_split"] += int(split.any())
        y = new
    return y


def step_stages(sc, f, first, t0, y, h, n, refine=32):
    """A substep whose stage inputs (or end) sit on another piece than its start taken again in ``refine``."""
    for i in range(n):
        t = t0 + i * h
        k1 = first(t, y)
        p0 = sc.pieces(t, y)
        k2in = [a + 0.5 * h * b for a, b in zip(y, k1)]
        k2 = f(t + 0.5 * h, k2in)
        k3in = [a + 0.5 * h * b for a, b in zip(y, k2)]
        k3 = f(t + 0.5 * h, k3in)
        k4in = [a + h * b for a, b in zip(y, k3)]
        k4 = f(t + h, k4in)
        new = unit([a + h / 6.0 * (b1 + 2.0 * (b2 + b3) + b4) for a, b1, b2, b3, b4 in zip(y, k1, k2, k3, k4)])
        changed = np.zeros(len(y[0]), dtype=bool)
        for tt, st in ((t + 0.5 * h, k2in), (t + 0.5 * h, k3in), (t + h, k4in), (t + h, new)):
            changed |= (sc.pieces(tt, st) != p0).any(axis=1)
        if changed.any():
            fine = y
            for r in range(refine):
                fine = rk4(f, t + r * h / refine, fine, h / refine, f(t + r * h / refine, fine))
            new = pick(changed, fine, new)
        STATS["split"] += int(changed.sum())
        STATS["substeps"] += 1
        STATS["robot_substeps"] += len(changed)
        y = new
    return y


STEPPERS = {"rk4": step_rk4, "split": step_split, "stages": step_stages}
CHOSEN = {"stepper": "rk4", "locked": False}


def _integrate(config, targets, blend, y, t0, h, n_steps, record, scene=None):
    """simulation._integrate with the chosen stepper (servo legs, RK4 configs)."""
    f0, first0 = simulation._stage_fns(config, targets, blend, scene)
    recorder = simulation._Recorder(first0, n_steps, len(y[0])) if record else None
    sc = Scene(config, targets, t0)
    base_first = recorder or sc.f
    f = sc.f
    if CHOSEN["locked"]:
        k = sc.k
        y = shift_rate(y, k, +1)
        f = locked(sc.f, k)
        plain_first = base_first

        def first(t, c):
            return locked(lambda tt, cc: list(plain_first(tt, cc)), k)(t, c)
    else:
        def first(t, c):
            return list(base_first(t, c))
    y = STEPPERS[CHOSEN["stepper"]](sc, f, first, t0, list(y), h, n_steps)
    if CHOSEN["locked"]:
        y = shift_rate(y, sc.k, -1)
    STATS["evals"] += sc.evals + (n_steps if record else 0)
    return y, recorder


def choose(candidate: str):
    """Set the law and stepper of a "LAW/STEPPER[@N]" name; returns N (substeps a control step)."""
    spec, _, n = candidate.partition("@")
    law, _, stepper = spec.partition("/")
    control.motor_torque = CLIP if law == "clip" else smooth_motor(float(law[len("smooth"):]))
    CHOSEN["locked"] = stepper.startswith("locked")
    name = stepper.split("+")[1] if "+" in stepper else ("rk4" if stepper == "locked" else stepper)
    CHOSEN["stepper"] = name
    if stepper == "rk4":  # (the package's own stepper: a patched law acts through control.motor_torque)
        simulation._integrate = ORIGINAL_INTEGRATE
    else:
        simulation._integrate = _integrate
    return int(n) if n else 15


ORIGINAL_INTEGRATE = simulation._integrate


def main():
    p = argparse.ArgumentParser()
    p.add_argument("candidate")
    p.add_argument("--models", nargs="+", default=["plane", "pivot"])
    p.add_argument("--actions", nargs="+", default=["policy", "random"])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--closed-loop", action="store_true", help="also the closed-loop speeds against a 10x finer step")
    p.add_argument("--no-windows", action="store_true")
    p.add_argument("--json")
    args = p.parse_args()
    n = choose(args.candidate)
    from benchmarks import scene_accuracy as sa

    sa.STEPS_S = (0.05 / n,)
    sa.SENSITIVITY_STEP_S = 1 / 1200  # (numpy: the amplification roughly)
    at_s = sa.WINDOW_STARTS_S[:1] if args.quick else sa.WINDOW_STARTS_S
    out = {"candidate": args.candidate, "windows": [], "closed_loop": []}
    if not args.no_windows:
        for model in args.models:
            for actions in args.actions:
                began = time.time()
                for key in STATS:
                    STATS[key] = 0
                # rollout under the candidate itself (its own closed-loop states and references)
                sa_steps = sa.STEPS_S
                r = sa.measure(model, actions, at_s[-1] + sa.WINDOW_S, at_s)
                row = r["rows"][0]
                print(f"{args.candidate} {model} {actions}: max {row['max_m'] * 1e3:.3g} mm per window "
                      f"{[round(v * 1e3, 4) if v is not None else None for v in row['per_window_max_m']]}; amplification "
                      f"{[round(v, 3) if v is not None else None for v in r['amplification_m_per_rad']['per_window_max']]} "
                      f"({time.time() - began:.0f} s)", flush=True)  # fmt: skip
                out["windows"].append({"model": model, "actions": actions, "max_m": row["max_m"],
                                       "per_window_max_m": row["per_window_max_m"],
                                       "amplification": r["amplification_m_per_rad"]})  # fmt: skip
    if args.closed_loop:
        from rrrobot_gym.agents.ppo import load_ppo_agent
        from rrrobot_gym.evaluation import run_episodes, score

        from benchmarks._common import POLICIES

        headings = (0.0, 45.0, 90.0, 135.0, 180.0)
        duration = 10.0 if args.quick else 50.0
        for model in args.models:
            agent = load_ppo_agent(POLICIES[model])
            for key in STATS:
                STATS[key] = 0
            began = time.time()
            coarse = score(run_episodes({"a": agent}, model, headings, duration, 0, timestep=0.05 / n, frame_skip=n)["a"], headings)
            stats = dict(STATS)
            fine = score(run_episodes({"a": agent}, model, headings, duration, 0, timestep=0.005 / n, frame_skip=10 * n)["a"],
                         headings)  # fmt: skip
            rel = [abs(c["speed_mps"] / f["speed_mps"] - 1.0) for c, f in zip(coarse, fine)]
            evals = stats["evals"] / (len(headings) * round(duration / 0.05))
            block = None
            if stats.get("robot_substeps"):
                q = stats["split"] / stats["robot_substeps"]
                block = 1.0 - (1.0 - q) ** 32
            print(f"{args.candidate} {model} closed loop: speeds (mm/s) "
                  + ", ".join(f"{h:g} deg {c['speed_mps'] * 1e3:.2f}/{f['speed_mps'] * 1e3:.2f}" for h, c, f in zip(headings, coarse, fine))
                  + f"; largest change {max(rel) * 100:.3f} %; evaluations / env step {evals:.2f}"
                  + (f", split substeps {stats['split'] / stats['robot_substeps'] * 100:.2f} % of a robot's, "
                     f"{block * 100:.0f} % of 32-lane blocks'" if block is not None else "")
                  + f" ({time.time() - began:.0f} s)", flush=True)  # fmt: skip
            out["closed_loop"].append({"model": model, "speeds_mps": [c["speed_mps"] for c in coarse],
                                       "fine_speeds_mps": [f["speed_mps"] for f in fine], "max_relative": max(rel),
                                       "evals_per_env_step": evals, "stats": stats})  # fmt: skip
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
