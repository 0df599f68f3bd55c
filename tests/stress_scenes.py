"""Stress scenes of ``tests/test_stress.py`` (short), also run long by ``python -m benchmarks.stress``.

A scene is a batch of robots, a SimConfig and a policy of leg targets (one per
control step of 0.05 s). :func:`run_scene` advances it and keeps the books a
stress test checks: finiteness, quaternion norms, tilt-limit crossings, and the
energy balance E(t) - E(0) = W(t), where W integrates the servo's power
tau . phidot plus the damping power k |Omega|^2 beside the state (an extra
component carried through RK4 at a fine step).

It lives with the tests, which need it to check the physics; the benchmark imports it from
here (``tests.stress_scenes``, from the repository root), so the scenes are written once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rrrobot_gym import dynamics
from rrrobot_gym.control import HeldTargets, pd_torque
from rrrobot_gym.integrators import INTEGRATORS
from rrrobot_gym.simulation import SimConfig, advance, initial_state

CONTROL_STEP = 0.05


@dataclass
class SceneResult:
    finite: bool
    max_quat_norm_error: float
    crossed_tilt_limit: int  # robots whose tilt reached the rim limit at some control step
    max_body_rate: float  # rad/s
    max_leg_rate: float  # rad/s
    energy_balance_error: float  # max over robots and steps of |E - E0 - W|, over the batch's max |E - E0| or |W|
    max_energy_gain_over_work: float  # J, max of (E - E0) - W (> 0: energy from nowhere)
    final_state: np.ndarray


def random_targets(rng, num_robots, low=-math.pi, high=math.pi, n_steps=1000):
    """New uniform random targets every control step (a table, so step k always gives the same)."""
    table = rng.uniform(low, high, (n_steps, num_robots, 2))
    return lambda step: table[step]


def bang_bang_targets(num_robots, low=-0.5 * math.pi, high=1.5 * math.pi):
    """Each control step flips every leg between two extremes, the legs out of phase."""
    a = np.full((num_robots, 2), low)
    b = np.full((num_robots, 2), high)
    a[:, 1], b[:, 1] = high, low
    return lambda step: a if step % 2 else b


def start_states(rng, num_robots, max_tilt=0.3, max_rate=1.0):
    state = initial_state(num_robots)
    axis = rng.normal(size=(num_robots, 3))
    axis[:, 2] = 0.0
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    tilt = rng.uniform(0.0, max_tilt, num_robots)
    state[:, 2] = np.cos(0.5 * tilt)
    state[:, 3:6] = np.sin(0.5 * tilt)[:, None] * axis
    state[:, dynamics.LEG_ANGLES] += rng.uniform(-1.0, 1.0, (num_robots, 2))
    state[:, dynamics.BODY_RATE] = rng.uniform(-max_rate, max_rate, (num_robots, 3))
    return state


def _power_stepper(config: SimConfig, targets: HeldTargets):
    """f(t, c) for 14 components: the 13 of the state and the work W (J) done on the robot."""
    derivative = dynamics.derivative_function(config.robot, config.model)
    gains, damping = config.gains, config.robot.damping

    def f(t, c):
        target = targets.leg_targets(t)
        tau = pd_torque(gains, (c[6], c[7]), (c[11], c[12]), target)
        deriv = tuple(derivative(c[:13], tau))
        power = tau[0] * c[11] + tau[1] * c[12] + damping * (c[8] * c[8] + c[9] * c[9] + c[10] * c[10])
        return deriv + (power,)

    return f


def run_scene(config: SimConfig, state, policy, n_control_steps: int, energy_refinement: int = 0) -> SceneResult:
    """Advance ``state`` (N, 13) under ``policy(step) -> (N, 2)`` held targets.

    ``energy_refinement`` > 0 (servo legs only) keeps the energy books, integrating
    state and work together by RK4 (whatever ``config.integrator``: the books check the
    model's energy balance, not a stepper) with steps that many times finer than
    ``config.step``: the work needs the servo's power resolved in time, and at the default
    step (h |lambda_servo| ~ 1.3) RK4's stage values give the state to ~1 % but the
    power's integral only to a factor ~2 after a target jump.
    """
    energy = energy_refinement > 0 and config.legs == "servo"
    e0 = dynamics.total_energy(state, config.robot, config.model)
    work = np.zeros(len(state))
    balance, gain, crossed = 0.0, -math.inf, np.zeros(len(state), bool)
    max_body, max_leg = 0.0, 0.0
    n_sub = max(1, math.ceil(CONTROL_STEP / config.step - 1e-9)) * max(1, energy_refinement)
    stepper = INTEGRATORS[config.integrator].step
    for step in range(n_control_steps):
        targets = HeldTargets(policy(step))
        t0 = step * CONTROL_STEP
        if energy:
            # The state and the work advance together through the same stepper as advance() uses.
            f = _power_stepper(config, targets)
            with np.errstate(all="ignore"):
                y = stepper(f, f, t0, [*state.T, work], CONTROL_STEP / n_sub, n_sub)
            state, work = np.stack(y[:13], axis=1), y[13]
            if not np.all(np.isfinite(state)):
                return SceneResult(False, math.nan, int(crossed.sum()), math.nan, math.nan, math.nan, math.nan, state)
        else:
            state = advance(config, state, t0, CONTROL_STEP, targets, check=False)
        crossed |= dynamics.tilt(state) >= dynamics.TILT_LIMIT
        max_body = max(max_body, float(np.max(np.linalg.norm(state[:, dynamics.BODY_RATE], axis=-1))))
        max_leg = max(max_leg, float(np.max(np.abs(state[:, dynamics.LEG_RATES]))))
        if energy:
            change = dynamics.total_energy(state, config.robot, config.model) - e0
            scale = max(float(np.max(np.abs(change))), float(np.max(np.abs(work))), 1e-12)
            balance = max(balance, float(np.max(np.abs(change - work))) / scale)
            gain = max(gain, float(np.max(change - work)))
    q_err = float(np.max(np.abs(np.linalg.norm(state[:, dynamics.QUAT], axis=-1) - 1.0)))
    return SceneResult(
        bool(np.all(np.isfinite(state))), q_err, int(crossed.sum()), max_body, max_leg,
        balance if energy else math.nan, gain if energy else math.nan, state,
    )  # fmt: skip
