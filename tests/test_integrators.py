"""The linearly implicit integrator ("rosw"): what it is for (stiff servos) and what it refuses."""

import numpy as np
import pytest

from rrrobot_gym import simulation
from rrrobot_gym.control import table2_gait
from rrrobot_gym.params import PDGains
from rrrobot_gym.simulation import NumericalFailure, SimConfig, simulate, simulate_reference, stable_step_limit

STIFF = PDGains(kp=200.0, kd=5.0)
"""A servo 100x stiffer than the default: its fast pole is ~-2e4 1/s (pivot)."""


def test_rosw_follows_a_stiff_servo_at_steps_far_beyond_rk4s_stability_limit():
    """RK4 must step under 1/7,300 s here; the Rosenbrock-W method steps at 1/3000 s and
    stays within 0.1 mm of the reference over 1 s of Gait 1, while the robot travels far more."""
    step = 1.0 / 3000.0
    assert step > 2 * stable_step_limit("pivot", SimConfig().robot, STIFF, "rk4")
    with pytest.raises(ValueError, match="stability limit"):
        SimConfig(model="pivot", gains=STIFF, timestep=step)
    implicit = simulate(SimConfig(model="pivot", gains=STIFF, integrator="rosw", timestep=step), table2_gait(1), 1.0)
    reference = simulate_reference(SimConfig(model="pivot", gains=STIFF, timestep="auto"), table2_gait(1), 1.0)
    error = np.hypot(*(implicit.states[:, 0:2] - reference.states[:, 0:2]).T).max()
    travel = np.hypot(*(reference.states[-1, 0:2] - reference.states[0, 0:2]))
    assert error < 1e-4 and travel > 20 * error


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # the point: it overflows
def test_rosw_needs_its_servo_jacobian(monkeypatch):
    """With the servo left out of A the same tableau is an explicit method, and blows up at that step."""

    class NoServoJacobian(simulation._ServoJacobian):
        def set(self, *mobility):
            super().set(*(0.0 * np.asarray(m) for m in mobility))

    monkeypatch.setattr(simulation, "_ServoJacobian", NoServoJacobian)
    with pytest.raises(NumericalFailure):
        simulate(SimConfig(model="pivot", gains=STIFF, integrator="rosw", timestep=1.0 / 3000.0), table2_gait(1), 0.2)


def test_rosw_one_robot_and_a_batch_agree():
    config = SimConfig(integrator="rosw", timestep=1.0 / 300.0)
    states = np.tile(simulation.initial_state(), (3, 1))
    states[1, 11:13] = (2.0, -3.0)
    states[2, 6:8] = (0.3, 2.0)
    batch, batch_record = simulation.advance(config, states, 0.0, 0.05, table2_gait(2), record=True)
    for i in range(3):
        one, one_record = simulation.advance(config, states[i], 0.0, 0.05, table2_gait(2), record=True)
        np.testing.assert_allclose(batch[i], one, rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(batch_record.force[:, i], one_record.force, rtol=1e-11, atol=1e-12)


def test_rosw_refuses_what_it_cannot_do():
    with pytest.raises(ValueError, match="kinematic legs have no servo"):
        SimConfig(legs="kinematic", integrator="rosw")
    with pytest.raises(ValueError, match="fixed step"):
        SimConfig(integrator="rosw", timestep="auto")


def test_a_large_batch_tunes_glibcs_malloc_once_and_both_thresholds(monkeypatch):
    """Setting any threshold turns glibc's dynamic mmap threshold off for good, so the tuning
    sets the mmap threshold too (else big arrays are mmapped and faulted in afresh) and is
    left in place: raised for a bigger batch, never put back."""
    calls = []
    numpy = SimConfig(backend="numpy")  # the compiled stepper makes no temporaries: nothing to tune
    monkeypatch.setattr(simulation, "_mallopt", lambda: lambda option, value: calls.append((option, value.value)))
    monkeypatch.setattr(simulation, "_heap_kept_for", 0)
    states = simulation.initial_state(1024)
    simulation.advance(numpy, states[:100], 0.0, 0.01, table2_gait(1))
    assert calls == []  # small batches leave malloc alone
    simulation.advance(numpy, states, 0.0, 0.01, table2_gait(1))
    assert calls == [(-3, 32 << 20), (-1, 64 << 20)]  # M_MMAP_THRESHOLD, M_TRIM_THRESHOLD
    simulation.advance(numpy, states, 0.0, 0.01, table2_gait(1))
    assert len(calls) == 2  # once per process, not put back after the call
    big = simulation.initial_state(20_000)
    simulation.advance(numpy, big, 0.0, 0.001, table2_gait(1))
    assert calls[2:] == [(-3, 32 << 20), (-1, 4096 * 20_000)]  # raised for a bigger working set


def _random_ramps(rng, num_robots, steps):
    """Leg-target ramps of an RL-like policy: a new random target every 0.05 s control step."""
    return np.pi / 2 + rng.uniform(-0.8, 0.8, size=(steps + 1, num_robots, 2))


def test_a_graded_start_follows_new_targets_more_closely():
    """Each new ramp kicks the servo's fast mode at the start of its control step, where RK4 at the
    default step errs most (benchmarks.policy_replay). Halving the first substeps there brings
    2 s of random ramps several times closer to the reference (DOP853, rtol 1e-10, step by step)."""
    from rrrobot_gym.control import RampTargets

    targets = _random_ramps(np.random.default_rng(7), 6, 40)
    start = simulation.initial_state(6)

    def run(config, reference=False):
        state = start.copy()
        for i in range(len(targets) - 1):
            ramp = RampTargets(targets[i], targets[i + 1], 0.0, 0.05)
            if reference:
                state = simulate_reference(config, ramp, 0.05, state=state, sample_dt=0.05).states[-1]
            else:
                state = simulation.advance(config, state, 0.0, 0.05, ramp)
        return state

    exact = run(SimConfig(), reference=True)
    errors = [np.hypot(*(run(SimConfig(start_halves=k))[:, :2] - exact[:, :2]).T).max() for k in (0, 1, 2)]
    assert errors[0] < 2e-3  # the uniform default: under a millimetre in 2 s
    assert errors[1] < errors[0] / 2.5
    assert errors[2] < errors[0] / 6.0


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_a_graded_start_keeps_the_record_on_the_substep_grid(backend):
    """The record of a graded advance has the uniform one's samples: one a substep, at t0 + i h,
    the first being the same evaluation; its summary is of those samples."""
    from rrrobot_gym import compiled
    from rrrobot_gym.control import RampTargets

    if backend == "numba" and not compiled.available():
        pytest.skip("numba is not installed")
    targets = _random_ramps(np.random.default_rng(3), 40, 1)
    ramp = RampTargets(targets[0], targets[1], 0.3, 0.05)
    start = simulation.initial_state(40)
    uniform, plain = simulation.advance(SimConfig(backend=backend), start, 0.3, 0.05, ramp, record=True)
    graded, record = simulation.advance(SimConfig(backend=backend, start_halves=2), start, 0.3, 0.05, ramp, record=True)
    assert record.times.shape == plain.times.shape == (15,)
    np.testing.assert_allclose(record.times, plain.times, rtol=0, atol=1e-15)
    assert record.step == plain.step
    np.testing.assert_array_equal(record.torque[0], plain.torque[0])  # the same state and time
    assert not np.array_equal(record.torque[1], plain.torque[1])  # reached through two half steps
    assert 0.0 < np.abs(graded - uniform).max() < 1e-2
    summary = record.summary()
    np.testing.assert_array_equal(summary["peak_torque"], np.abs(record.torque).max(axis=(0, 2)))
    np.testing.assert_array_equal(summary["least_normal"], record.normal.min(axis=0))
    # more halves than substeps: the whole advance in halves
    short, short_record = simulation.advance(SimConfig(backend=backend, start_halves=9), start, 0.3, 0.01, ramp, record=True)
    halves, _ = simulation.advance(SimConfig(backend=backend, timestep=1 / 600), start, 0.3, 0.01, ramp, record=True)
    np.testing.assert_array_equal(short, halves)
    assert short_record.times.shape == (3,)


def test_a_graded_start_is_refused_where_it_means_nothing():
    for bad in (-1, 1.5, True, "2"):
        with pytest.raises(ValueError, match="start_halves"):
            SimConfig(start_halves=bad)
    with pytest.raises(ValueError, match="start_halves applies to servo legs"):
        SimConfig(legs="kinematic", start_halves=1)


class _Semilinear:
    """x' = -20 x + y + sin(x y) / 2 + cos 3t, y' = -2 y + x^2 + 0.3 sin t (u = (x, y, t)), its
    Jacobian, and an inexact linear part: a toy for the exponential probes' orders."""

    inexact = np.array([[-20.0, 1.5, 0.0], [0.7, -1.7, 0.0], [0.0, 0.0, 0.0]])

    def __call__(self, u):
        x, y, t = u
        return np.array([-20 * x + y + 0.5 * np.sin(x * y) + np.cos(3 * t), -2 * y + x * x + 0.3 * np.sin(t), 1.0])

    @staticmethod
    def exact(u, fu):
        x, y, t = u
        c = 0.5 * np.cos(x * y)
        return np.array([[-20 + c * y, 1 + c * x, -3 * np.sin(3 * t)], [2 * x, -2.0, 0.3 * np.cos(t)], [0.0, 0.0, 0.0]])


def _observed_order(method, jacobian, steps=(40, 80)):
    """log2 of the error ratio at t = 1 between the two step counts (DOP853 at rtol 1e-13 as truth)."""
    from scipy.integrate import solve_ivp

    toy, start = _Semilinear(), np.array([0.2, 1.0, 0.0])
    truth = solve_ivp(lambda t, u: toy(u), (0.0, 1.0), start, method="DOP853", rtol=1e-13, atol=1e-14).y[:2, -1]
    errors = []
    for n in steps:
        u = start.copy()
        for _ in range(n):
            u = method(toy, u, 1.0 / n, jacobian)
        errors.append(np.abs(u[:2] - truth).max())
    return np.log2(errors[0] / errors[1])


def test_the_exponential_probes_orders_and_what_their_linear_part_must_be():
    """benchmarks.exp_rosenbrock's methods at their orders: the exponential Runge-Kutta steps are
    fourth order with any fixed linear part (so the free servo Jacobian serves), exprb43 only with
    the exact Jacobian, and second order without it: why the probe's exprb43 lost with the servo's."""
    from benchmarks.exp_rosenbrock import METHODS

    toy = _Semilinear()
    for name in ("etdrk4b", "ho5"):
        assert _observed_order(METHODS[name], lambda u, fu: toy.inexact) > 3.8, name
    assert _observed_order(METHODS["exprb43"], toy.exact) > 3.8
    assert _observed_order(METHODS["exprb43"], lambda u, fu: toy.inexact) < 2.5


def test_the_servo_linear_parts_phi_functions_come_from_its_5x5_block():
    """What a compiled exponential step would use (README, the exponential probe): the free servo
    Jacobian has non-zero columns only at the leg angles, leg rates and time, so phi_j(hA) is
    I/j! + h A[:, S] phi_{j+1}(h A[S, S]); checked against scipy's expm of the whole matrix."""
    import math

    from benchmarks.exp_rosenbrock import Problem, phi_functions

    problem = Problem(SimConfig(), table2_gait(2))
    u = np.append(simulation.initial_state(), 0.3)
    u[6], u[7], u[11], u[12] = 0.2, -0.4, 2.0, -1.0  # legs off vertical and moving
    jac = problem.servo_jacobian(u, problem(u))
    columns = [6, 7, 11, 12, 13]
    assert np.array_equal(np.flatnonzero(np.abs(jac).sum(axis=0)), columns)
    h = 1.0 / 80.0
    whole = phi_functions(h * jac, 3)
    block = phi_functions(h * jac[np.ix_(columns, columns)], 4)
    for j in range(4):
        reduced = np.eye(jac.shape[0]) / math.factorial(j)
        reduced[:, columns] += h * jac[:, columns] @ block[j + 1]
        np.testing.assert_allclose(reduced, whole[j], rtol=0, atol=1e-13 * np.abs(whole[j]).max())
