"""RK4 in the body's locked rate (``integrator="rk4_locked"``) against RK4: error, CPU time, speed, energy.

    python -m benchmarks.locked_rate [--quick] [--json FILE] [--markdown FILE] [--policy] [--workers W]

``rk4_locked`` is RK4's tableau on the locked rate Lambda = Omega + M_omega^-1 (c_1 phidot_1 +
c_2 phidot_2) (``dynamics.locked_share``, the body rows of the momentum, which the leg torques do
not change) in place of the body rate Omega, converting to Lambda and back at each ``advance``
call, as the exponential step does: a new target's torque step is then in the legs' rows alone.
The same steps, the same stability limit and the same evaluations as RK4, so every part here sets
the two side by side at the same steps (1/300 s, the default, 1/240 and 1/200 s), through the
shipped steppers. The parts are ``benchmarks.exponential_step``'s (its ``report``), with these
settings:

- gaits: the six Table II cases (50 s; --quick 10 s) against ``simulate_reference``, worst max
  contact error, and CPU time of one robot's run on numpy and compiled (the same states to the bit);
- batches: one env step of N = 64 and 4096 robots, physics alone, side by side, alternating;
- energy: the undamped servo's energy book (kd = 0, no damping: body energy plus kp/2
  |phi - target|^2 is conserved);
- env: the env with its checks, single env and N = 64 and 4096 (``benchmarks.throughput``'s),
  alternating;
- ``--policy``: the env's slip measure on the shipped policy's first 2 s, and its leg-target
  ramps along four headings replayed control step by control step (``benchmarks.policy_replay``),
  also with graded starts (``start_halves``).

That RK4's tableau on the locked equations is what ``rk4_locked`` runs is tested against the
probe of ``benchmarks.exp_rosenbrock`` (matrices, an implementation sharing only the equations;
``tests/test_integrators.py``).
"""

from __future__ import annotations

from .exponential_step import report

GAIT_SETTINGS = [(integrator, n, False, 0) for n in (15, 12, 10) for integrator in ("rk4", "rk4_locked")]
"""(integrator, steps an env step, fine first env step, ``start_halves``): 1/300, 1/240 and 1/200 s."""
BATCH_SETTINGS = [("rk4", 15, 0), ("rk4_locked", 15, 0), ("rk4_locked", 12, 0), ("rk4_locked", 10, 0)]
"""(integrator, steps an env step, ``start_halves``) timed compiled; on numpy RK4 and rk4_locked at 1/300 s."""
ENERGY_SETTINGS = [("rk4", 15), ("rk4_locked", 15), ("rk4", 10), ("rk4_locked", 10), ("rk4", 30), ("rk4_locked", 30)]
ENV_SETTINGS = [("rk4", 15, 0), ("rk4_locked", 15, 0), ("rk4_locked", 12, 0), ("rk4_locked", 10, 0)]
POLICY_SETTINGS = [(integrator, n, halves) for n, halves in ((15, 0), (12, 0), (10, 0), (15, 2), (12, 2))
                   for integrator in ("rk4", "rk4_locked")]  # fmt: skip
ENVELOPE_SETTINGS = [("rk4", 15, 0), ("rk4_locked", 15, 0), ("rk4_locked", 12, 0)]


def main(argv=None):
    report(__doc__.splitlines()[0], "benchmarks.locked_rate", argv, GAIT_SETTINGS, BATCH_SETTINGS, ("rk4_locked", 15),
           ENERGY_SETTINGS, ENV_SETTINGS, POLICY_SETTINGS, ENVELOPE_SETTINGS)  # fmt: skip


if __name__ == "__main__":
    main()
