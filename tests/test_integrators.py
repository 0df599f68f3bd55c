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
