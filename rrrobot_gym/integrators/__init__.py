"""The fixed-step integrators: one table from name to module.

An integrator is a module with

- ``step(f, first, t, y, h, n_steps)``: ``n_steps`` steps of ``h`` from time ``t`` on ``y``, the
  13 state components as a list of Python floats (one robot) or of (N,) arrays (a batch), with
  the quaternion (entries 2:6) put back to unit length after each step; returns the new list.
  ``f(t, c)`` gives the 13 derivative components; ``first(t, c)`` gives the same and is called
  once at the start of every step (the step record is made there).
- ``amplification(z)``: |R(z)|, its growth factor per step on y' = lambda y at z = h lambda,
  from which :func:`rrrobot_gym.simulation.stable_step_limit` finds the servo's stability limit.
- ``AUTO_STEP_FACTOR``: {model: h |lambda_servo|} of ``timestep="auto"``, or None if uncalibrated.

Adding an integrator is a new module here and one entry in :data:`INTEGRATORS`;
``SimConfig(integrator=...)`` checks names against it and :func:`rrrobot_gym.simulation.advance`
steps through it (on the numpy backend; the compiled backend has its own table,
:data:`rrrobot_gym.compiled.INTEGRATORS`).
"""

from . import rk4

INTEGRATORS = {"rk4": rk4}
"""Integrator name (``SimConfig.integrator``) to module."""
