"""Our equations of motion against an independent implementation of the paper's own form.

``tests/paper_form.py`` derives eq. (1)-(4) with sympy: seven coordinates with the
paper's ZXY Euler angles and the rolling constraints of eq. (2) enforced by Lagrange
multipliers. It shares no code with ``rrrobot_gym``. Both are integrated to tight
tolerances from a tilted, spinning start while a Table II gait drives the legs.
"""

import numpy as np
import pytest

from paper_form import omega_world_from_rates, simulate_paper_form
from rrrobot_gym import dynamics
from rrrobot_gym.control import pd_torque, table2_gait
from rrrobot_gym.params import PDGains, RobotParams
from rrrobot_gym.simulation import SimConfig, initial_state, simulate_reference

pytestmark = pytest.mark.slow  # (the paper's Euler-angle form, solved with sympy)

THETA0 = np.array([0.3, -0.5, 0.2])
THETA_DOT0 = np.array([0.5, 1.0, -0.7])
PHI0 = np.array([1.2, 0.4])
PHI_DOT0 = np.array([2.0, -1.0])


def _our_start():
    state = initial_state()
    state[dynamics.QUAT] = dynamics.quat_from_paper_angles(THETA0)
    rot = dynamics.rotation_matrix(state[dynamics.QUAT])
    state[dynamics.BODY_RATE] = rot.T @ omega_world_from_rates(THETA0, THETA_DOT0)
    state[dynamics.LEG_ANGLES] = PHI0
    state[dynamics.LEG_RATES] = PHI_DOT0
    return state


@pytest.mark.parametrize("model", ["plane", "pivot"])
def test_equations_agree_with_the_papers_euler_angle_form(model):
    gait = table2_gait(3)  # (the equations are under test, the gait only their input: Gait 3 moves every angle)
    gains = PDGains()
    config = SimConfig(model=model, robot=RobotParams(), gains=gains)

    def torque(t, phi, phi_dot):
        return np.array(pd_torque(gains, phi, phi_dot, gait.leg_targets(t)))

    duration = 2.0
    ours = simulate_reference(config, gait, duration, state=_our_start(), sample_dt=duration, rtol=1e-12, atol=1e-12)
    final = ours.states[-1]
    theirs = simulate_paper_form(
        model, theta=THETA0, theta_dot=THETA_DOT0, phi=PHI0, phi_dot=PHI_DOT0, t_final=duration, torque=torque
    )
    rot = dynamics.rotation_matrix(final[dynamics.QUAT])
    # The start is far from rest: the robot has moved and turned, so agreement is not trivial.
    assert np.hypot(final[0], final[1]) > 0.01
    assert np.abs(final[0] - theirs["x"]) < 1e-8
    assert np.abs(final[1] - theirs["y"]) < 1e-8
    assert np.max(np.abs(rot - theirs["rotation"])) < 1e-8
    assert np.max(np.abs(rot @ final[dynamics.BODY_RATE] - theirs["omega_world"])) < 1e-8
    assert np.max(np.abs(final[dynamics.LEG_ANGLES] - theirs["phi"])) < 1e-8
    assert np.max(np.abs(final[dynamics.LEG_RATES] - theirs["phi_dot"])) < 1e-8
