"""Classical Runge-Kutta (RK4): four derivative evaluations a step, order 4.

Written once for the numpy backend, on a list of 13 components that are Python floats (one
robot) or (N,) arrays (a batch): the same expressions give the same roundings on both, and the
compiled lane stepper (:mod:`rrrobot_gym.compiled`) repeats them operation for operation.
"""

from __future__ import annotations

import math

AUTO_STEP_FACTOR = {"plane": 1.28, "pivot": 1.08}
"""h |lambda_servo| of ``timestep="auto"`` with servo legs, per model (RK4 is stable up to 2.785
on the real axis): the cheapest step under 1 mm of contact error after 50 s on every Table II
gait (``benchmarks.work_precision``: plane 1/300 s, pivot 1/140 s). The same h |lambda| costs
the pivot model more contact error than the plane model."""


def amplification(z: complex) -> float:
    """|R(z)| = |1 + z + z^2/2 + z^3/6 + z^4/24|."""
    return abs(1.0 + z + z * z / 2.0 + z**3 / 6.0 + z**4 / 24.0)


def step(f, first, t, y, h, n_steps):
    """``n_steps`` RK4 steps of ``h`` from ``t`` on the 13 components ``y`` (see the package)."""
    half, sixth = 0.5 * h, h / 6.0
    for _ in range(n_steps):
        k1 = first(t, y)
        k2 = f(t + half, [a + half * b for a, b in zip(y, k1)])
        k3 = f(t + half, [a + half * b for a, b in zip(y, k2)])
        k4 = f(t + h, [a + h * b for a, b in zip(y, k3)])
        y = [a + sixth * (b1 + 2.0 * (b2 + b3) + b4) for a, b1, b2, b3, b4 in zip(y, k1, k2, k3, k4)]
        unit_quaternion(y)
        t += h
    return y


def unit_quaternion(y):
    """Scale the quaternion (entries 2:6) of 13 components to unit length, in place."""
    norm2 = y[2] * y[2] + y[3] * y[3] + y[4] * y[4] + y[5] * y[5]
    inv = 1.0 / (math.sqrt(norm2) if isinstance(norm2, float) else norm2**0.5)
    y[2] *= inv
    y[3] *= inv
    y[4] *= inv
    y[5] *= inv
