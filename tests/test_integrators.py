"""The integrator table: a new integrator is one module plus one table entry (a toy: explicit
midpoint, order 2), and a name outside the table is refused."""

import math
import types

import numpy as np
import pytest

from rrrobot_gym import integrators
from rrrobot_gym.control import table2_gait
from rrrobot_gym.simulation import SimConfig, advance, initial_state, simulate, stable_step_limit


def _midpoint():
    """Explicit midpoint (order 2) as an integrator module: ``step``, ``amplification``, ``AUTO_STEP_FACTOR``."""
    module = types.ModuleType("midpoint")

    def step(f, first, t, y, h, n_steps):
        half = 0.5 * h
        for _ in range(n_steps):
            k1 = first(t, y)
            k2 = f(t + half, [a + half * b for a, b in zip(y, k1)])
            y = [a + h * b for a, b in zip(y, k2)]
            integrators.rk4.unit_quaternion(y)
            t += h
        return y

    module.step = step
    module.amplification = lambda z: abs(1.0 + z + z * z / 2.0)
    module.AUTO_STEP_FACTOR = None
    return module


def _end_state(integrator, step, duration=1.0):
    """One robot after ``duration`` s of plane Gait 2 from the paper's start (the numpy backend)."""
    config = SimConfig(integrator=integrator, timestep=step, backend="numpy")
    return simulate(config, table2_gait(2), duration, sample_dt=duration).states[-1]


def _observed_order(integrator, steps):
    """log2 of the error ratio between two steps, against RK4 at 1/9600 s."""
    truth = _end_state("rk4", 1 / 9600)
    errors = [np.abs(_end_state(integrator, h) - truth).max() for h in steps]
    return math.log2(errors[0] / errors[1])


def test_a_new_integrator_is_one_module_and_one_table_entry(monkeypatch):
    monkeypatch.setitem(integrators.INTEGRATORS, "midpoint", _midpoint())
    assert 1.8 < _observed_order("midpoint", (1 / 600, 1 / 1200)) < 2.2
    # it runs through advance like RK4, batch and record included (the compiled backend keeps its own table)
    config = SimConfig(integrator="midpoint", timestep=1 / 600)
    states = initial_state(24)
    states[:, 6] += np.linspace(-0.3, 0.3, 24)
    out, record = advance(config, states, 0.0, 0.05, table2_gait(1), record=True)
    alone = advance(config, states[5], 0.0, 0.05, table2_gait(1))
    np.testing.assert_allclose(out[5], alone, rtol=0, atol=1e-12)
    assert record.torque.shape == (30, 24, 2)
    # its own stability polynomial sets its servo limit: midpoint's is below RK4's, and refused past it
    limit = stable_step_limit("plane", config.robot, config.gains, "midpoint")
    assert limit < 0.8 * stable_step_limit("plane", config.robot, config.gains, "rk4")
    with pytest.raises(ValueError, match="stability limit"):
        SimConfig(integrator="midpoint", timestep=1.05 * limit)
    with pytest.raises(ValueError, match="not calibrated for integrator 'midpoint'"):
        SimConfig(integrator="midpoint", timestep="auto")


def test_an_integrator_outside_the_table_is_refused_by_name():
    with pytest.raises(ValueError, match="unknown integrator 'midpoint': expected one of rk4"):
        SimConfig(integrator="midpoint")
