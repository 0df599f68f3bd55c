"""The specialised kernel (rrrobot_gym.specialise) against the family's general kernel: the same
values on any finite state, for the paper's robot and for other members, with the record."""

import numpy as np
import pytest

from rrrobot_gym import dynamics, specialise
from rrrobot_gym.params import Leg, RobotParams


def _skewed(robot: RobotParams) -> RobotParams:
    """``robot`` with its legs turned about a skew axis: the same masses, no zero in the layout."""
    from scipy.spatial.transform import Rotation

    turn = Rotation.from_rotvec(0.3 * np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)).as_matrix()
    legs = tuple(Leg(tuple(turn @ leg.hinge), tuple(turn @ leg.zero), tuple(turn @ leg.up)) for leg in robot.legs)
    return RobotParams(num_legs=robot.num_legs, shell_axes=robot.shell_axes, legs=legs)


MEMBERS = {
    "paper-plane": (RobotParams(), "plane"),
    "paper-pivot": (RobotParams(), "pivot"),
    "three-legs-oblate": (RobotParams(num_legs=3, shell_axes=(0.12, 0.12, 0.09)), "plane"),
    "four-legs-prolate-pivot": (RobotParams(num_legs=4, shell_axes=(0.11, 0.12, 0.14)), "pivot"),
    "skew-legs": (_skewed(RobotParams()), "plane"),
}


def _specialised(robot, model, momentum):
    namespace = dict(vars(dynamics))
    exec(specialise.kernel_source(robot, model, momentum), namespace)
    return namespace["derivative_kernel"]


@pytest.mark.parametrize("momentum", [False, True], ids=["rate", "momentum"])
@pytest.mark.parametrize("member", MEMBERS)
def test_specialised_kernel_gives_the_general_kernels_values(member, momentum):
    """(``momentum``: the body rows hold the angular momentum, as the pivot's steppers give them;
    the plane's never do.)"""
    robot, model = MEMBERS[member]
    if momentum and model != "pivot":
        pytest.skip("only the pivot's steppers integrate the momentum")
    legs = robot.num_legs
    k, layout = dynamics.constants(robot, model), dynamics.leg_layout(robot)
    size, at, out, drive, scratch, record = dynamics.kernel_work(legs)
    kernel = _specialised(robot, model, momentum)
    rng = np.random.default_rng(7)
    for _ in range(300):
        quat = rng.normal(size=4)
        state = [*rng.normal(size=2), *(quat / np.linalg.norm(quat)), *rng.uniform(-4.0, 4.0, legs),
                 *rng.normal(size=3) * 3.0, *rng.normal(size=legs) * 8.0]  # fmt: skip
        general = [0.0] * size
        general[at : at + 9 + 2 * legs] = state
        general[drive : drive + legs] = rng.normal(size=legs) * 0.3
        special = list(general)
        dynamics.derivative_kernel(general, at, out, 1, k, layout, drive, scratch, False, record, momentum)
        kernel(special, at, out, 1, k, layout, drive, scratch, False, record, momentum)
        expected = np.array(general[out : out + 9 + 2 * legs] + general[record : record + 2 * legs + 5])
        got = np.array(special[out : out + 9 + 2 * legs] + special[record : record + 2 * legs + 5])
        assert np.all(np.isfinite(got))
        np.testing.assert_array_equal(got, expected)  # (equal floats: folds are exact, not close)


def test_specialising_the_paper_robot_leaves_out_its_zeros():
    """Its legs swing in the body's x-z plane: the folds leave 429 operations on the plane, against
    513 for the same robot with skew legs; on the pivot (no rolling terms, the momentum's solve
    added) 442, against the skew robot's 534."""
    robot = RobotParams()
    for model in ("plane", "pivot"):
        assert specialise.operation_count(robot, model) < 0.9 * specialise.operation_count(_skewed(robot), model)


def test_the_default_envs_take_the_specialised_kernel_and_other_robots_the_general_one():
    import gymnasium

    import rrrobot_gym  # noqa: F401
    from rrrobot_gym import compiled

    for model in ("plane", "pivot"):
        sim = gymnasium.make("RRRobot-v0", model=model).unwrapped.config.sim
        assert compiled.specialised(sim.robot, sim.model) == specialise.kernel_source(RobotParams(), model)
    for keywords in ({"num_legs": 3}, {"shell_axes": (0.12, 0.12, 0.09)}):
        sim = gymnasium.make("RRRobot-v0", **keywords).unwrapped.config.sim
        assert compiled.specialised(sim.robot, sim.model) is None
