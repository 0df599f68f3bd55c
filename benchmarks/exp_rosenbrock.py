"""How far about 16 evaluations an env step go: exponential integrators as a probe (issue 10).

    python -m benchmarks.exp_rosenbrock [--quick] [--json FILE] [--markdown FILE] [--workers W] [--policy]

An experiment that bounds what a better method could do within the "at most 16 derivative
evaluations per env step" aim. Its ETDRK4-B with the servo's A is now shipped
(``SimConfig(integrator="etdrk4b")``, phi-functions in closed form); this full-matrix, expm-based
version is what ``tests/test_integrators.py`` checks the shipped step against. Three exponential methods, each written
for u' = F(u), u = (state, t), with a matrix A frozen at the step's start:

- ``exprb43`` (Hochbruck, Ostermann and Schweitzer 2009), an exponential Rosenbrock method:
  three evaluations a step, order 4 when A is the exact Jacobian at the step's start;
- ``etdrk4b`` (Krogstad 2005's ETDRK4-B) and ``ho5`` (Hochbruck and Ostermann 2005, stiff
  order 4), exponential Runge-Kutta methods: four and five evaluations a step. They integrate
  u' = A u + (F(u) - A u) with the second term as the "nonlinear" part, so their order asks that
  part to be smooth along the path, not A to be the exact Jacobian.

A is one of two Jacobians:

- ``full``: forward differences of the derivative on every coordinate it depends on (the
  quaternion, leg angles, body and leg rates, and time: 12 more evaluations a step; x and y
  do not enter it), that is, the exact Jacobian to ~1e-7, a bound on any linearisation;
- ``servo``: the servo torque's part only, free with the step's first evaluation (the legs'
  columns of M^-1 that ``derivative_kernel`` reports, as the shipped ``rosw`` uses them), and
  the targets' time derivative. It has five non-zero columns (leg angles, leg rates, time), so
  its phi-functions are the 14x14 identity plus a product with the phi-functions of its 5x5
  block: a compiled stepper would need those of the legs' 4x4 servo block, not scipy's expm.

The six Table II cases (both models, gaits 1-3, 50 s from the paper's start; --quick: 10 s) are
run against ``simulate_reference`` (DOP853, rtol = atol = 1e-10) from three starts: ``coarse``
(the method from t = 0), ``fine`` (RK4 at 1/1200 s for the first 0.5 s, through Gait 2's
transient, where the legs are slammed from upright to their offset), ``first`` (RK4 at
1/2400 s for the first env step only, where ``benchmarks.start_halves --accuracy`` finds the
gaits' error is made) and ``own`` (the method itself in OWN_N steps for the first env step). ``--policy`` also replays the shipped policy's first 10 s of leg-target
ramps along four headings (``benchmarks.policy_replay``; needs the ``train`` extra), each
control step from t = 0 as the envs step it, with the steps in a control step equal or graded
(shorter first, where a new ramp kicks the servo), beside RK4 at the default step.
The phi-functions come from scipy's expm of a block matrix, so CPU time says nothing here:
only evaluations and errors are reported. Every run calls the one ``derivative_kernel``.
The probe integrates the body rate Omega, as the shipped step did when these rows were measured;
``Problem(locked=True)`` (a ``Setting``'s ``locked``) follows the locked rate instead, as the shipped
``etdrk4b`` now does (``dynamics.locked_share``; ``tests/test_integrators.py`` checks the shipped step
against it so, and ``benchmarks.graded_schedule`` runs it in steps of any ratio).
"""

from __future__ import annotations

import math
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from rrrobot_gym import dynamics
from rrrobot_gym.control import RampTargets, table2_gait
from rrrobot_gym.simulation import SimConfig, _ServoJacobian, _stage_fns, _to_locked, advance, initial_state

from ._common import contact_error, fmt, machine, markdown_table, parser, reference, write_json

ENV_STEP = 0.05
FINE_START_S, FINE_N = 0.5, 60
"""The ``fine`` start: RK4 at ENV_STEP / FINE_N for the first FINE_START_S seconds."""
FIRST_N = 120
"""The ``first`` start: RK4 at ENV_STEP / FIRST_N for the first env step."""
OWN_N = 12
"""The ``own`` start: the method itself in OWN_N equal steps for the first env step."""
FD_COLUMNS = (2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13)
"""Coordinates the derivative depends on (13 is time): the ``full`` Jacobian's columns."""
SIZE = dynamics.STATE_SIZE + 1  # the state and time
CASES = [(model, gait) for model in ("plane", "pivot") for gait in (1, 2, 3)]
POLICY_HEADINGS = (0.0, 90.0, 180.0, 270.0)
POLICY_S = 10.0


@dataclass(frozen=True)
class Setting:
    """A method, its matrix A, the steps of an env step (their relative lengths) and the start."""

    method: str
    jacobian: str
    weights: tuple = (1,) * 5
    start: str = "coarse"
    locked: bool = False  # follow the locked rate, as the shipped etdrk4b does (Problem)

    @property
    def uniform(self) -> bool:
        return len(set(self.weights)) == 1

    def step_label(self) -> str:
        if self.uniform:
            return f"1/{len(self.weights) / ENV_STEP:.0f} s"
        return "graded " + ":".join(f"{w:g}" for w in self.weights)


SETTINGS = [
    Setting("exprb43", "full", (1,) * 5, "coarse"),
    Setting("exprb43", "full", (1,) * 5, "fine"),
    Setting("exprb43", "full", (1,) * 4, "fine"),
    Setting("exprb43", "servo", (1,) * 5, "coarse"),
    Setting("exprb43", "servo", (1,) * 5, "fine"),
    Setting("exprb43", "servo", (1,) * 4, "fine"),
    Setting("etdrk4b", "servo", (1,) * 4, "coarse"),
    Setting("etdrk4b", "servo", (1,) * 4, "first"),
    Setting("etdrk4b", "servo", (1,) * 4, "own"),
    Setting("etdrk4b", "servo", (1,) * 3, "first"),
    Setting("etdrk4b", "servo", (1, 1, 2, 2), "first"),
    Setting("ho5", "servo", (1,) * 3, "first"),
    Setting("ho5", "servo", (1,) * 4, "first"),
]
POLICY_SETTINGS = [
    Setting("etdrk4b", "servo", (1,) * 4),
    Setting("etdrk4b", "servo", (1, 1, 2, 2)),
    Setting("etdrk4b", "servo", (1, 2, 4, 8)),
    Setting("etdrk4b", "servo", (1,) * 15),
    Setting("ho5", "servo", (1,) * 12),
]


def phi_functions(a, count):
    """[exp(a), phi_1(a), ..., phi_count(a)] from one exponential of a block matrix."""
    n = a.shape[0]
    big = np.zeros(((count + 1) * n, (count + 1) * n))
    big[:n, :n] = a
    for j in range(count):
        big[j * n : (j + 1) * n, (j + 1) * n : (j + 2) * n] = np.eye(n)
    top = expm(big)[:n]
    return [top[:, j * n : (j + 1) * n] for j in range(count + 1)]


class Problem:
    """u' = F(u) for u = (state, t) of one robot under ``targets``, and its Jacobians."""

    def __init__(self, config: SimConfig, targets, locked: bool = False):
        self.config = config
        self.targets = targets
        self.locked = locked  # rows 8-10 the locked rate, as the shipped etdrk4b integrates (dynamics.locked_share)
        self.f, self.first = _stage_fns(config, targets, locked=locked)
        self.servo = _ServoJacobian(config.gains, 1.0)
        self.evaluations = 0

    def __call__(self, u):
        self.evaluations += 1
        return np.append(self.f(u[-1], u[:-1].tolist()), 1.0)

    def to_locked(self, u, sign):
        """u with rows 8-10 from the body rate to the locked rate (sign 1) or back (-1), if ``locked``."""
        if not self.locked:
            return u
        u = u.copy()
        _to_locked(u, dynamics.constants(self.config.robot, self.config.depth), sign)
        return u

    def full_jacobian(self, u, fu):
        jac = np.zeros((SIZE, SIZE))
        for j in FD_COLUMNS:
            du = 1e-7 * max(1.0, abs(u[j]))
            shifted = u.copy()
            shifted[j] += du
            jac[:, j] = (self(shifted) - fu) / du
        return jac

    def servo_jacobian(self, u, fu):
        """The servo's part, from the mobility the first evaluation reports (not counted again)."""
        mobility = [0.0] * 9
        self.first(u[-1], u[:-1].tolist(), mobility)
        self.servo.set(*mobility)
        rows = (6, 7, 11, 12, 8, 9, 10)  # what A w fills: leg angles, leg rates, body rates
        jac = np.zeros((SIZE, SIZE))
        for j, w in zip((6, 7, 11, 12), np.eye(4)):
            jac[rows, j] = np.concatenate(self.servo.apply(*w))
        # time: d tau / dt = kp phi_target' + kd phi_target'', the same map as -(phi, phidot) -> tau
        _, rates, accels = self.targets.leg_targets(u[-1])
        jac[rows[2:], -1] = -np.concatenate(self.servo.apply(rates[0], rates[1], accels[0], accels[1])[1:])
        return jac


def exprb43(problem: Problem, u, h, jacobian):
    """One exprb43 step: U2 = u + h/2 phi1(hJ/2) F, U3 = u + h phi1(hJ) (F + D2),
    u1 = u + h phi1(hJ) F + h phi3(hJ) (16 D2 - 2 D3) + h phi4(hJ) (-48 D2 + 12 D3),
    with D_i = F(U_i) - F(u) - J (U_i - u)."""
    fu = problem(u)
    jac = jacobian(u, fu)
    half = phi_functions(0.5 * h * jac, 1)
    whole = phi_functions(h * jac, 4)
    u2 = u + 0.5 * h * half[1] @ fu
    d2 = problem(u2) - fu - jac @ (u2 - u)
    base = u + h * whole[1] @ fu
    u3 = base + h * whole[1] @ d2
    d3 = problem(u3) - fu - jac @ (u3 - u)
    return base + h * (whole[3] @ (16.0 * d2 - 2.0 * d3) + whole[4] @ (-48.0 * d2 + 12.0 * d3))


def _exponential_rk(problem: Problem, u, h, jacobian):
    """What the exponential Runge-Kutta steps share: F(u), A, the phi-functions of h A / 2 and
    h A (up to phi_3), and D(U) = F(U) - F(u) - A (U - u), the nonlinear part's change. Written so,
    U_i = u + c_i h phi_1(c_i h A) F(u) + h sum_j a_ij D(U_j) is the stage of the tableau whose
    first column is c_i phi_1(c_i h A) - sum_j a_ij."""
    fu = problem(u)
    jac = jacobian(u, fu)
    half = phi_functions(0.5 * h * jac, 3)
    whole = phi_functions(h * jac, 3)

    def change(stage):
        return problem(stage) - fu - jac @ (stage - u)

    return fu, half, whole, change


def etdrk4b(problem: Problem, u, h, jacobian):
    """One step of Krogstad's ETDRK4-B (c = 0, 1/2, 1/2, 1): a32 = phi_2(hA/2), a43 = 2 phi_2,
    b2 = b3 = 2 phi_2 - 4 phi_3, b4 = -phi_2 + 4 phi_3 (phi_j of h A unless said); RK4 when A = 0."""
    fu, (_, p1h, p2h, _), (_, p1, p2, p3), change = _exponential_rk(problem, u, h, jacobian)
    u2 = u + 0.5 * h * p1h @ fu
    d2 = change(u2)
    d3 = change(u2 + h * p2h @ d2)
    base = u + h * p1 @ fu
    d4 = change(base + 2.0 * h * p2 @ d3)
    return base + h * ((2.0 * p2 - 4.0 * p3) @ (d2 + d3) + (4.0 * p3 - p2) @ d4)


def ho5(problem: Problem, u, h, jacobian):
    """One step of Hochbruck and Ostermann's five-stage method of stiff order 4 (c = 0, 1/2,
    1/2, 1, 1/2): a32 = phi_2(hA/2), a42 = a43 = phi_2, a52 = a53 = phi_2(hA/2)/2 - phi_3 +
    phi_2/4 - phi_3(hA/2)/2, a54 = phi_2(hA/2)/4 - a52, b4 = -phi_2 + 4 phi_3, b5 = 4 phi_2 - 8 phi_3."""
    fu, (_, p1h, p2h, p3h), (_, p1, p2, p3), change = _exponential_rk(problem, u, h, jacobian)
    u2 = u + 0.5 * h * p1h @ fu
    d2 = change(u2)
    d3 = change(u2 + h * p2h @ d2)
    base = u + h * p1 @ fu
    d4 = change(base + h * p2 @ (d2 + d3))
    a52 = 0.5 * p2h - p3 + 0.25 * p2 - 0.5 * p3h
    d5 = change(u2 + h * (a52 @ (d2 + d3) + (0.25 * p2h - a52) @ d4))
    return base + h * ((4.0 * p3 - p2) @ d4 + (4.0 * p2 - 8.0 * p3) @ d5)


def rk4(problem: Problem, u, h, jacobian):
    """One step of RK4's tableau: ETDRK4-B with A = 0 (``jacobian`` unused). On a locked problem it is
    RK4 in the locked rate, as ``integrator="rk4_locked"`` steps (``tests/test_integrators.py``)."""
    return etdrk4b(problem, u, h, lambda u, fu: np.zeros((u.size, u.size)))


METHODS = {"exprb43": exprb43, "etdrk4b": etdrk4b, "ho5": ho5, "rk4": rk4}


def env_step(problem: Problem, u, setting: Setting, duration: float = ENV_STEP):
    """u after ``duration`` s in ``setting``'s steps (the quaternion renormalised after each, as advance does)."""
    method = METHODS[setting.method]
    jacobian = problem.full_jacobian if setting.jacobian == "full" else problem.servo_jacobian
    total = sum(setting.weights)
    u = problem.to_locked(u, 1.0)
    for weight in setting.weights:
        u = method(problem, u, duration * weight / total, jacobian)
        u[dynamics.QUAT] /= np.linalg.norm(u[dynamics.QUAT])
    return problem.to_locked(u, -1.0)


def run_case(job):
    """Max and end contact error (m) and the steady evaluations per env step of one setting and case."""
    setting, (model, gait), duration = job
    config = SimConfig(model=model)
    problem = Problem(config, table2_gait(gait), locked=setting.locked)
    u = np.append(initial_state(), 0.0)
    n_env = round(duration / ENV_STEP)
    states = np.empty((n_env + 1, dynamics.STATE_SIZE))
    states[0] = u[:-1]
    steady_evaluations = 0
    start_s, start_n = {"fine": (FINE_START_S, FINE_N), "first": (ENV_STEP, FIRST_N)}.get(setting.start, (0.0, None))
    fine = SimConfig(model=model, timestep=ENV_STEP / start_n, backend="numpy") if start_n else None
    own = Setting(setting.method, setting.jacobian, (1,) * OWN_N) if setting.start == "own" else None
    for i in range(n_env):
        if i * ENV_STEP < start_s - 1e-9:
            u[:-1] = advance(fine, u[:-1], i * ENV_STEP, ENV_STEP, problem.targets, check=False)
        elif i == 0 and own is not None:
            u = env_step(problem, u, own)
        else:
            before = problem.evaluations
            u = env_step(problem, u, setting)
            steady_evaluations = problem.evaluations - before
        u[-1] = (i + 1) * ENV_STEP
        states[i + 1] = u[:-1]
        if not np.all(np.isfinite(u)):
            return math.inf, math.inf, steady_evaluations
    err = contact_error(states, reference(config, table2_gait(gait), duration, ENV_STEP))
    return float(err.max()), float(err[-1]), steady_evaluations


def policy_episode(job):
    """States (n + 1, 13) of one policy episode's ramps replayed in ``setting``, each control step
    from t = 0 (as the envs step), and the evaluations an env step."""
    setting, config, start, starts, ends, dt = job
    u = np.append(start, 0.0)
    out = [u[:-1].copy()]
    evaluations = 0
    for ramp_start, ramp_end in zip(starts, ends):
        problem = Problem(config, RampTargets(ramp_start, ramp_end, 0.0, dt), locked=setting.locked)
        u[-1] = 0.0
        with np.errstate(all="ignore"):
            u = env_step(problem, u, setting, dt)
        evaluations = problem.evaluations
        if not np.all(np.isfinite(u)):  # inf from here on
            out += [np.full(dynamics.STATE_SIZE, np.inf)] * (len(starts) + 1 - len(out))
            break
        out.append(u[:-1].copy())
    return np.array(out), evaluations


def policy_rows(workers: int, settings=POLICY_SETTINGS, seconds: float = POLICY_S):
    """The shipped policy's first ``seconds`` along POLICY_HEADINGS: RK4 at the default step (the
    envs' own stepping), then each of ``settings``; the worst contact error over the path."""
    from rrrobot_gym.agents.ppo import load_ppo_agent

    from .policy_replay import MODEL, error_fields, replay, rollouts

    _, start, starts, ends, dt, sim = rollouts(load_ppo_agent(MODEL), POLICY_HEADINGS, round(seconds / ENV_STEP))
    ref, _ = replay(sim, start, starts, ends, dt, reference=True)
    path, _ = replay(sim, start, starts, ends, dt)
    rows = [{"method": "rk4", "setting": f"1/{1 / sim.step:.0f} s (the default)",
             "evals_per_env_step": 4 * round(dt / sim.step), **error_fields(contact_error(path, ref), POLICY_HEADINGS)}]  # fmt: skip
    jobs = [(setting, sim, start[j], starts[j], ends[j], dt) for setting in settings for j in range(len(start))]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        results = list(pool.map(policy_episode, jobs))
    for i, setting in enumerate(settings):
        episodes = results[i * len(start) : (i + 1) * len(start)]
        path = np.stack([p for p, _ in episodes], axis=1)  # (n + 1, N, 13)
        rows.append({"method": setting.method, "jacobian": setting.jacobian, "setting": setting.step_label(),
                     "weights": setting.weights, "evals_per_env_step": episodes[0][1],
                     **error_fields(contact_error(path, ref), POLICY_HEADINGS)})  # fmt: skip
    for r in rows:
        print(f"policy, {seconds:g} s: {r['method']} A={r.get('jacobian', '-')} {r['setting']} ({r['evals_per_env_step']} evaluations an env step): "
              f"worst max contact error {r['contact_max_m'] * 1e3:.3g} mm", flush=True)  # fmt: skip
    return rows


def main(argv=None):
    p = parser(__doc__.splitlines()[0], markdown=True, workers=True)
    p.add_argument("--policy", action="store_true", help=f"also the shipped policy's first {POLICY_S:g} s (needs the train extra)")
    args = p.parse_args(argv)
    duration = 10.0 if args.quick else 50.0
    for model, gait in CASES:  # fill the reference cache before the workers read it
        reference(SimConfig(model=model), table2_gait(gait), duration, ENV_STEP)
    jobs = [(setting, case, duration) for setting in SETTINGS for case in CASES]
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        results = dict(zip([(s, c) for s, c, _ in jobs], pool.map(run_case, jobs)))
    rows = []
    for setting in SETTINGS:
        per_case = {f"{m}_gait{g}": results[setting, (m, g)] for m, g in CASES}
        rows.append(
            {
                "method": setting.method,
                "jacobian": setting.jacobian,
                "substeps": len(setting.weights),
                "weights": setting.weights,
                "start": setting.start,
                "evals_per_env_step": max(e for _, _, e in per_case.values()),
                "contact_max_m": max(mx for mx, _, _ in per_case.values()),
                "per_case_max_m": {k: mx for k, (mx, _, _) in per_case.items()},
                "per_case_end_m": {k: end for k, (_, end, _) in per_case.items()},
            }
        )
        r = rows[-1]
        print(
            f"{r['method']} A={r['jacobian']:5s} {setting.step_label()} start={r['start']:6s} "
            f"evals/env-step={r['evals_per_env_step']:3d} worst max contact error {r['contact_max_m'] * 1e3:.3g} mm: "
            + ", ".join(f"{k} {v * 1e3:.3g}" for k, v in r["per_case_max_m"].items()),
            flush=True,
        )
    table = markdown_table(
        ["method", "A", "step", "start", "evaluations / env step (after the start)", "worst max contact error (mm)"]
        + [f"{m} gait {g}" for m, g in CASES],
        [
            [r["method"], r["jacobian"], s.step_label(), r["start"], r["evals_per_env_step"], fmt(r["contact_max_m"] * 1e3)]
            + [fmt(v * 1e3) for v in r["per_case_max_m"].values()]
            for s, r in zip(SETTINGS, rows)
        ],
    )  # fmt: skip
    print(table)
    payload = {"machine": machine(), "duration_s": duration, "rows": rows}
    text = f"`python -m benchmarks.exp_rosenbrock{' --quick' if args.quick else ''}{' --policy' if args.policy else ''}`, {duration:g} s\n\n{table}\n"
    if args.policy:
        payload["policy_s"], payload["policy_headings_deg"] = POLICY_S, POLICY_HEADINGS
        payload["policy_rows"] = policy_rows(args.workers)
        policy_table = markdown_table(
            ["method", "A", "steps in a control step", "evaluations / env step", f"worst max contact error, {POLICY_S:g} s (mm)"]
            + [f"{h:g} deg" for h in POLICY_HEADINGS],
            [[r["method"], r.get("jacobian", "-"), r["setting"], r["evals_per_env_step"], fmt(r["contact_max_m"] * 1e3)]
             + [fmt(v * 1e3) for v in r["per_heading_max_m"].values()] for r in payload["policy_rows"]],
        )  # fmt: skip
        print(policy_table)
        text += f"\nThe shipped policy's leg-target ramps, the first {POLICY_S:g} s:\n\n{policy_table}\n"
    if args.markdown:
        with open(args.markdown, "w") as fh:
            fh.write(text)
    write_json(args.json, payload)


if __name__ == "__main__":
    main()
