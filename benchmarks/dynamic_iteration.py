"""A probe of a partitioned step: the body on kinematic legs, the legs on the servo's linear ODE.

    python -m benchmarks.dynamic_iteration [--quick] [--json FILE] [--markdown FILE] [--workers W]

Not a shipped integrator: an experiment toward issue 10's "at most 16 derivative evaluations per
env step". The servo's stiffness lives in the legs' equation alone, and that equation is linear
in the legs' state once two slowly varying things are known: ``a0``, the legs' acceleration with
no torque, and ``G``, the legs' mobility (the legs' block of M^-1). One servo evaluation of
``derivative_kernel`` with ``mobility_out`` gives both, and also the kinematic-legs derivative
for any leg acceleration (the torque that acceleration takes is G^-1 (alpha - a0), and the body's
answer to it is linear), so nothing here re-implements the equations of motion. An env step H:

1. the legs: phi'' = a0(t) + G(t) (kp (phi_target - phi) + kd (phi_target' - phi')), a0 and G
   quartic in t through five samples, integrated (here by RK4 at H / 120; a compiled stepper
   would use the closed form of this linear system, see below);
2. the body: RK4 at H / 2 with the legs following that path (4 + 4 evaluations, the legs'
   angles and rates set from the path at every stage);
3. the samples: the evaluations at t0, t0 + H/2 and t0 + H, with the last step's first two.
   The first pass fits the last step's five samples (extrapolated); a second pass, if asked,
   refits with this step's three. Each pass costs 8 evaluations.

The step keeps samples from one env step to the next: a multistep memory that ``advance``
(a pure function of the state) does not have. The start (the legs slammed from upright) is
integrated by RK4 at 1/1200 s for 0.5 s, which also fills the memory. Reported: the six Table II
cases for 50 s (--quick: 10 s) against ``simulate_reference`` (DOP853, rtol = atol = 1e-10),
and, for ``--policy``, the shipped policy's first 10 s of leg-target ramps
(``benchmarks.policy_replay``). The leg ODE's RK4 is not counted in "evaluations": it is 480
evaluations of a 2x2 linear map a pass, which the closed form would replace with a 4x4 matrix
exponential and a few products.
"""

from __future__ import annotations

import math
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from rrrobot_gym import dynamics
from rrrobot_gym.control import RampTargets, pd_torque, table2_gait
from rrrobot_gym.simulation import SimConfig, _stage_fns, advance, initial_state

from ._common import contact_error, fmt, machine, markdown_table, parser, reference, write_json
from .exp_rosenbrock import FINE_N, FINE_START_S

ENV_STEP = 0.05
START_S, START_N = FINE_START_S, FINE_N
"""The start, exp_rosenbrock's fine one: RK4 at ENV_STEP / START_N for START_S seconds (it also
fills the samples' memory)."""
LEG_SUBSTEPS = 120
BODY = [0, 1, 2, 3, 4, 5, 8, 9, 10]
CASES = [(model, gait) for model in ("plane", "pivot") for gait in (1, 2, 3)]


class Servo:
    """One robot's evaluations: the derivative and the linear maps it implies."""

    def __init__(self, config: SimConfig, targets):
        self.config = config
        self.set_targets(targets)
        self.evaluations = 0

    def set_targets(self, targets):
        self.targets = targets
        _, self.first = _stage_fns(self.config, targets)

    def evaluate(self, t, state):
        """(derivative, G (2, 2), P (3, 2), a0 (2,), the body's acceleration with no leg torque (3,))."""
        self.evaluations += 1
        mobility = [0.0] * 9
        derivative, torque = self.first(t, state.tolist(), mobility)
        derivative, torque = np.array(derivative, dtype=float), np.array(torque, dtype=float)
        g = np.array([[mobility[0], mobility[1]], [mobility[1], mobility[2]]])
        p = np.array(mobility[3:]).reshape(2, 3).T
        return derivative, g, p, derivative[11:13] - g @ torque, derivative[8:11] - p @ torque

    @staticmethod
    def kinematic(evaluation, leg_accel):
        """The derivative with the legs' acceleration prescribed, from a servo evaluation."""
        derivative, g, p, a0, body0 = evaluation
        out = derivative.copy()
        out[8:11] = body0 + p @ np.linalg.solve(g, leg_accel - a0)
        out[11:13] = leg_accel
        return out

    def leg_path(self, t0, angles, rates, a0_of, g_of, n_half):
        """[(angles, rates, accelerations)] at t0 + j H / (2 n_half), j = 0 .. 2 n_half: the servo's
        linear ODE with the coefficient functions a0_of(t), g_of(t)."""
        h = ENV_STEP / LEG_SUBSTEPS
        every = LEG_SUBSTEPS // (2 * n_half)

        def accel(t, phi, rate):
            return a0_of(t) + g_of(t) @ np.array(pd_torque(self.config.gains, phi, rate, self.targets.leg_targets(t)))

        phi, rate = np.array(angles, dtype=float), np.array(rates, dtype=float)
        out = []
        for i in range(LEG_SUBSTEPS + 1):
            t = t0 + i * h
            if i % every == 0:
                out.append((phi.copy(), rate.copy(), accel(t, phi, rate)))
            if i == LEG_SUBSTEPS:
                return out
            k1p, k1v = rate, accel(t, phi, rate)
            k2p, k2v = rate + 0.5 * h * k1v, accel(t + 0.5 * h, phi + 0.5 * h * k1p, rate + 0.5 * h * k1v)
            k3p, k3v = rate + 0.5 * h * k2v, accel(t + 0.5 * h, phi + 0.5 * h * k2p, rate + 0.5 * h * k2v)
            k4p, k4v = rate + h * k3v, accel(t + h, phi + h * k3p, rate + h * k3v)
            phi = phi + h / 6.0 * (k1p + 2.0 * (k2p + k3p) + k4p)
            rate = rate + h / 6.0 * (k1v + 2.0 * (k2v + k3v) + k4v)


def polynomial(samples, index):
    """The interpolant through [(t, a0, G)]'s item ``index``, as a function of t."""
    times = np.array([s[0] for s in samples])
    values = np.array([s[index] for s in samples])
    coeffs = np.polyfit(times - times[0], values.reshape(len(times), -1), len(times) - 1)

    def at(t):
        powers = (t - times[0]) ** np.arange(len(times) - 1, -1, -1)
        return (powers @ coeffs).reshape(values.shape[1:])

    return at


def env_step(servo: Servo, t0, state, first, memory, passes):
    """(state, evaluation at it, samples) after one env step from (t0, state); ``first``: the
    evaluation at (t0, state); ``memory``: the samples [(t, a0, G)] of the last step and t0."""
    h = ENV_STEP / 2
    samples = memory[-5:]
    for _ in range(passes):
        legs = servo.leg_path(t0, state[6:8], state[11:13], polynomial(samples, 1), polynomial(samples, 2), 2)

        def on_path(j, base):
            base[6:8], base[11:13] = legs[j][0], legs[j][1]
            return base

        y, evaluation, new = state.copy(), first, []
        for s in range(2):
            j, ts = 2 * s, t0 + s * h
            k1 = servo.kinematic(evaluation, legs[j][2])
            k2 = servo.kinematic(servo.evaluate(ts + h / 2, on_path(j + 1, y + h / 2 * k1)), legs[j + 1][2])
            k3 = servo.kinematic(servo.evaluate(ts + h / 2, on_path(j + 1, y + h / 2 * k2)), legs[j + 1][2])
            k4 = servo.kinematic(servo.evaluate(ts + h, on_path(j + 2, y + h * k3)), legs[j + 2][2])
            y = on_path(j + 2, y + h / 6.0 * (k1 + 2.0 * (k2 + k3) + k4))
            y[dynamics.QUAT] /= np.linalg.norm(y[dynamics.QUAT])
            evaluation = servo.evaluate(ts + h, y)
            new.append((ts + h, evaluation[3], evaluation[1]))
        samples = [m for m in memory if m[0] < t0 - 1e-12][-2:] + [memory[-1]] + new
    return y, evaluation, samples


def run(servo: Servo, state, n_steps: int, passes: int, targets_at=None):
    """(contact points (n_steps + 1, 2), evaluations a step after the start, the time in s at which
    the state stopped being finite or None); the points are inf from a blow-up on."""
    fine = SimConfig(model=servo.config.model, timestep=ENV_STEP / START_N, backend="numpy")
    n_start = round(START_S / ENV_STEP)
    out = np.full((n_steps + 1, 2), np.inf)
    out[0] = state[:2]
    memory = []
    for i in range(n_steps):
        t = i * ENV_STEP
        if targets_at is not None:
            servo.set_targets(targets_at(i))
        if i < n_start:
            if i >= n_start - 2:
                evaluation = servo.evaluate(t, state)
                memory.append((t, evaluation[3], evaluation[1]))
            state = advance(fine, state, t, ENV_STEP, servo.targets, check=False)
            if i == n_start - 1:
                first = servo.evaluate(t + ENV_STEP, state)
                memory.append((t + ENV_STEP, first[3], first[1]))
                servo.evaluations = 0
        else:
            with np.errstate(all="ignore"):
                state, first, memory = env_step(servo, t, state, first, memory, passes)
            if not np.all(np.isfinite(state)):
                return out, servo.evaluations / max(1, i + 1 - n_start), t + ENV_STEP
        out[i + 1] = state[:2]
    return out, servo.evaluations / max(1, n_steps - n_start), None


def gait_case(job):
    (model, gait), passes, duration = job
    config = SimConfig(model=model)
    path, evaluations, _ = run(Servo(config, table2_gait(gait)), initial_state(), round(duration / ENV_STEP), passes)
    ref = reference(config, table2_gait(gait), duration, ENV_STEP)
    return float(contact_error(path, ref[:, :2]).max()), evaluations


def policy_case(passes: int, duration: float = 10.0):
    """The shipped policy's leg-target ramps along 0 deg (benchmarks.policy_replay)."""
    from rrrobot_gym.agents.ppo import load_ppo_agent

    from .policy_replay import MODEL, replay, rollout

    states, starts, ends, dt, sim = rollout(load_ppo_agent(MODEL), 0.0, round(duration / ENV_STEP))
    ref, _ = replay(sim, states[:1], starts[None], ends[None], dt, reference=True)
    ramps = [RampTargets(start, end, i * dt, dt) for i, (start, end) in enumerate(zip(starts, ends))]  # at run()'s times
    servo = Servo(sim, ramps[0])
    path, _, diverged_at = run(servo, states[0], len(starts), passes, ramps.__getitem__)
    return float(contact_error(path, ref[:, 0]).max()), diverged_at


def main(argv=None):
    p = parser(__doc__.splitlines()[0], markdown=True, workers=True)
    p.add_argument("--policy", action="store_true", help="also the shipped policy's first 10 s (needs the train extra)")
    args = p.parse_args(argv)
    duration = 10.0 if args.quick else 50.0
    for model, gait in CASES:  # fill the reference cache before the workers read it
        reference(SimConfig(model=model), table2_gait(gait), duration, ENV_STEP)
    rows = []
    for passes in (1, 2):
        jobs = [(case, passes, duration) for case in CASES]
        with ProcessPoolExecutor(max_workers=args.workers) as pool:
            results = dict(zip(CASES, pool.map(gait_case, jobs)))
        row = {
            "passes": passes,
            "evals_per_env_step": max(e for _, e in results.values()),
            "contact_max_m": max(err for err, _ in results.values()),
            "per_case_max_m": {f"{m}_gait{g}": err for (m, g), (err, _) in results.items()},
        }
        if args.policy:
            row["policy_10s_max_m"], row["policy_diverged_at_s"] = policy_case(passes)
        rows.append(row)
        print(
            f"passes={passes} ({row['evals_per_env_step']:.0f} evaluations an env step after the start): worst max "
            f"contact error {row['contact_max_m'] * 1e3:.3g} mm: "
            + ", ".join(f"{k} {v * 1e3:.3g}" for k, v in row["per_case_max_m"].items())
            + (f"; policy 10 s: {row['policy_10s_max_m'] * 1e3:.3g} mm (diverged at t = {row['policy_diverged_at_s']} s)" if args.policy else ""),
            flush=True,
        )
    header = ["passes", "evaluations / env step", f"worst max contact error, {duration:g} s (mm)"]
    header += [f"{m} gait {g}" for m, g in CASES] + (["policy, 10 s (mm)"] if args.policy else [])
    table = markdown_table(
        header,
        [[r["passes"], f"{r['evals_per_env_step']:.0f}", fmt(r["contact_max_m"] * 1e3)]
         + [fmt(v * 1e3) for v in r["per_case_max_m"].values()]
         + ([fmt(r["policy_10s_max_m"] * 1e3) if math.isfinite(r["policy_10s_max_m"]) else f"diverged at t = {r['policy_diverged_at_s']:.2f} s"] if args.policy else [])
         for r in rows],
    )  # fmt: skip
    print(table)
    if args.markdown:
        with open(args.markdown, "w") as fh:
            flags = (" --quick" if args.quick else "") + (" --policy" if args.policy else "")
            fh.write(f"`python -m benchmarks.dynamic_iteration{flags}`, {duration:g} s\n\n{table}\n")
    write_json(args.json, {"machine": machine(), "duration_s": duration, "rows": rows})


if __name__ == "__main__":
    main()
