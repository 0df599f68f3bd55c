"""How far about 16 evaluations an env step go: an exponential Rosenbrock probe (issue 10).

    python -m benchmarks.exp_rosenbrock [--quick] [--json FILE] [--markdown FILE] [--workers W]

Not a shipped integrator: an experiment that bounds what a better method could do within the
"at most 16 derivative evaluations per env step" aim. It runs exprb43 (Hochbruck, Ostermann and
Schweitzer 2009: three evaluations a step, order 4 when the Jacobian is exact at the step's
start) on the six Table II cases (both models, gaits 1-3, 50 s from the paper's start; --quick:
10 s) against ``simulate_reference`` (DOP853, rtol = atol = 1e-10), with two Jacobians:

- ``full``: forward differences of the derivative on every coordinate it depends on (the
  quaternion, leg angles, body and leg rates, and time: 12 more evaluations a step; x and y
  do not enter it), that is, the exact Jacobian to ~1e-7, a bound on any linearisation;
- ``servo``: the servo torque's part only, free with the step's first evaluation (the legs'
  columns of M^-1 that ``derivative_kernel`` reports, as the shipped ``rosw`` uses them), and
  the targets' time derivative.

and two starts: ``coarse`` (the method from t = 0) and ``fine`` (RK4 at 1/1200 s for the first
0.5 s, through Gait 2's transient, where the legs are slammed from upright to their offset).
The phi-functions come from scipy's expm of a block matrix, so CPU time says nothing here:
only evaluations and errors are reported. Every run calls the one ``derivative_kernel``.
"""

from __future__ import annotations

import math
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from scipy.linalg import expm

from rrrobot_gym import dynamics
from rrrobot_gym.control import table2_gait
from rrrobot_gym.simulation import SimConfig, _ServoJacobian, _stage_fns, advance, initial_state

from ._common import contact_error, fmt, machine, markdown_table, parser, reference, write_json

ENV_STEP = 0.05
FINE_START_S, FINE_N = 0.5, 60
"""The ``fine`` start: RK4 at ENV_STEP / FINE_N for the first FINE_START_S seconds."""
FD_COLUMNS = (2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13)
"""Coordinates the derivative depends on (13 is time): the ``full`` Jacobian's columns."""
SIZE = dynamics.STATE_SIZE + 1  # the state and time
CASES = [(model, gait) for model in ("plane", "pivot") for gait in (1, 2, 3)]
SETTINGS = [  # (jacobian, substeps per env step, start)
    ("full", 5, "coarse"),
    ("full", 5, "fine"),
    ("full", 4, "fine"),
    ("servo", 5, "coarse"),
    ("servo", 5, "fine"),
    ("servo", 4, "fine"),
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
    """u' = F(u) for u = (state, t) of one robot under a Table II gait, and its Jacobians."""

    def __init__(self, model: str, gait: int):
        self.config = SimConfig(model=model)
        self.targets = table2_gait(gait)
        self.f, self.first = _stage_fns(self.config, self.targets)
        self.servo = _ServoJacobian(self.config.gains, 1.0)
        self.evaluations = 0

    def __call__(self, u):
        self.evaluations += 1
        return np.append(self.f(u[-1], u[:-1].tolist()), 1.0)

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


def run_case(job):
    """Max and end contact error (m) and the steady evaluations per env step of one setting and case."""
    (jacobian_kind, n, start), (model, gait), duration = job
    problem = Problem(model, gait)
    jacobian = problem.full_jacobian if jacobian_kind == "full" else problem.servo_jacobian
    u = np.append(initial_state(), 0.0)
    n_env = round(duration / ENV_STEP)
    states = np.empty((n_env + 1, dynamics.STATE_SIZE))
    states[0] = u[:-1]
    steady_evaluations = 0
    fine = SimConfig(model=model, timestep=ENV_STEP / FINE_N, backend="numpy")
    for i in range(n_env):
        if start == "fine" and i * ENV_STEP < FINE_START_S - 1e-9:
            u[:-1] = advance(fine, u[:-1], i * ENV_STEP, ENV_STEP, problem.targets, check=False)
        else:
            before = problem.evaluations
            for _ in range(n):
                u = exprb43(problem, u, ENV_STEP / n, jacobian)
                u[dynamics.QUAT] /= np.linalg.norm(u[dynamics.QUAT])
            steady_evaluations = problem.evaluations - before
        u[-1] = (i + 1) * ENV_STEP
        states[i + 1] = u[:-1]
        if not np.all(np.isfinite(u)):
            return math.inf, math.inf, steady_evaluations
    err = contact_error(states, reference(SimConfig(model=model), table2_gait(gait), duration, ENV_STEP))
    return float(err.max()), float(err[-1]), steady_evaluations


def main(argv=None):
    p = parser(__doc__.splitlines()[0])
    p.add_argument("--markdown", metavar="FILE", help="write the table as Markdown")
    p.add_argument("--workers", type=int, default=2, help="processes for the cases (errors do not depend on it)")
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
                "jacobian": setting[0],
                "substeps": setting[1],
                "start": setting[2],
                "evals_per_env_step": max(e for _, _, e in per_case.values()),
                "contact_max_m": max(mx for mx, _, _ in per_case.values()),
                "per_case_max_m": {k: mx for k, (mx, _, _) in per_case.items()},
                "per_case_end_m": {k: end for k, (_, end, _) in per_case.items()},
            }
        )
        r = rows[-1]
        print(
            f"exprb43 J={r['jacobian']:5s} h=1/{r['substeps'] / ENV_STEP:.0f} start={r['start']:6s} "
            f"evals/env-step={r['evals_per_env_step']:3d} worst max contact error {r['contact_max_m'] * 1e3:.3g} mm: "
            + ", ".join(f"{k} {v * 1e3:.3g}" for k, v in r["per_case_max_m"].items()),
            flush=True,
        )
    table = markdown_table(
        ["Jacobian", "step", "start", "evaluations / env step (after the start)", "worst max contact error (mm)"]
        + [f"{m} gait {g}" for m, g in CASES],
        [
            [r["jacobian"], f"1/{r['substeps'] / ENV_STEP:.0f} s", r["start"], r["evals_per_env_step"],
             fmt(r["contact_max_m"] * 1e3)] + [fmt(v * 1e3) for v in r["per_case_max_m"].values()]
            for r in rows
        ],
    )  # fmt: skip
    print(table)
    if args.markdown:
        with open(args.markdown, "w") as fh:
            fh.write(f"`python -m benchmarks.exp_rosenbrock{' --quick' if args.quick else ''}`, {duration:g} s\n\n{table}\n")
    write_json(args.json, {"machine": machine(), "duration_s": duration, "rows": rows})


if __name__ == "__main__":
    main()
