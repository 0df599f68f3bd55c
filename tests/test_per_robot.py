"""Per-robot physical parameters (``advance(robots=...)``, domain randomisation): each robot of a
batch moves, and is recorded and measured, exactly as it would alone with a config of its own
values; its energy changes by its own servo's work; bad values are refused by name."""

from dataclasses import replace

import numpy as np
import pytest
from conftest import random_states
from scipy.integrate import cumulative_simpson

from rrrobot_gym import compiled, dynamics, simulation, validity
from rrrobot_gym.control import RampTargets, pd_torque, table2_gait
from rrrobot_gym.params import PDGains, RobotParams
from rrrobot_gym.simulation import PER_ROBOT_FIELDS, SimConfig, advance

RECORD_FIELDS = ("times", "torque", "force", "normal", "tangential", "leg_clearance", "leg_rates")
BACKENDS = ["numpy", pytest.param("numba", marks=pytest.mark.skipif(not compiled.available(), reason="numba is not installed"))]
MOTOR = SimConfig(torque_limit=0.4, leg_rate_limit=12.0)
SCENES = {"plane-motor": MOTOR, "pivot": SimConfig(model="pivot"), "plane-torque-limit": SimConfig(torque_limit=0.4)}


def _draw(config, n, seed):
    """Parameters of n robots, each field spread around the config's (the motor limits where it has them)."""
    rng = np.random.default_rng(seed)
    robot, gains = config.robot, config.gains
    robots = {name: getattr(robot, name) * rng.uniform(0.8, 1.25, n) for name in ("mass_bottom", "mass_pin", "mass_tip", "leg_length")}
    robots.update(damping=rng.uniform(-0.03, 0.0, n), kp=gains.kp * rng.uniform(0.8, 1.2, n), kd=gains.kd * rng.uniform(0.8, 1.2, n))
    if config.torque_limit is not None:
        robots.update(torque_limit=rng.uniform(0.2, 0.6, n))
    if config.leg_rate_limit is not None:
        robots.update(leg_rate_limit=rng.uniform(8.0, 16.0, n))
    return robots


def _own_config(config, robots, i):
    """The SimConfig of robot i's own values."""
    value = {name: float(np.asarray(v).reshape(-1)[i if np.size(v) > 1 else 0]) for name, v in robots.items()}
    own = {name: value[name] for name in ("torque_limit", "leg_rate_limit") if name in value}
    return replace(config, robot=replace(config.robot, **{k: value[k] for k in PER_ROBOT_FIELDS[:5] if k in value}),
                   gains=PDGains(value.get("kp", config.gains.kp), value.get("kd", config.gains.kd)), **own)  # fmt: skip


def _ramps(states, seed):
    """Ramps from each robot's legs to far targets: the servo works, the torque limit binds."""
    end = np.random.default_rng(seed).uniform(-0.5, 3.5, (len(states), 2))
    return RampTargets(states[:, dynamics.LEG_ANGLES], end, 0.1, 0.05)


def _assert_same_runs(a, b, label):
    (state_a, record_a), (state_b, record_b) = a, b
    assert np.array_equal(state_a, state_b), label
    for field in RECORD_FIELDS:
        assert np.array_equal(getattr(record_a, field), getattr(record_b, field)), (label, field)
    summary_b = record_b.summary()
    for key, value in record_a.summary().items():
        assert np.array_equal(value, summary_b[key]), (label, key)


def _alone(config, state, targets, row_layout):
    """One robot alone: on Python floats (the row-by-row path, the numba one-robot stepper), or
    with ``row_layout`` False as a batch of copies of itself on numpy's arrays (the batched path)."""
    if row_layout:
        return advance(config, state, 0.1, 0.05, targets, record=True)
    copies = simulation.ROW_BY_ROW_MAX + 1
    states, record = advance(config, np.tile(state, (copies, 1)), 0.1, 0.05, targets, record=True)
    fields = {f: getattr(record, f)[:, 0] for f in RECORD_FIELDS if f not in ("times", "tangential")}
    alone = simulation.StepRecord(times=record.times, step=record.step, **fields)
    object.__setattr__(alone, "_tangential", record.tangential[:, 0])
    return states[0], alone


def _robot_of(state, record, i):
    fields = {f: getattr(record, f)[:, i] for f in RECORD_FIELDS if f not in ("times", "tangential")}
    one = simulation.StepRecord(times=record.times, step=record.step, **fields)
    object.__setattr__(one, "_tangential", record.tangential[:, i])
    return state[i], one


# numpy: N = 5 its row-by-row path, N = 40 its batched arrays (a robot alone: a batch of copies of
# itself, the same layout). numba: 5 robots one by one (the one-robot stepper), a padded lane block
# alone, a block of LANES robots in SIMD lanes (each lane its own constants, gains and limits) and
# 5 one by one, a block and a padded block.
NUMBA_SIZES = (5, compiled.PADDED_MIN + 4, compiled.LANES + 5, compiled.LANES + compiled.PADDED_MIN)
SIZES = [("numpy", 5), ("numpy", 40)] + [pytest.param("numba", n, marks=BACKENDS[1].marks) for n in NUMBA_SIZES]


@pytest.mark.parametrize("backend, n", SIZES)
@pytest.mark.parametrize("scene", SCENES)
def test_each_robot_of_a_varied_batch_moves_as_it_would_alone(backend, scene, n):
    assert 5 < compiled.PADDED_MIN < compiled.LANES
    config = replace(SCENES[scene], backend=backend)
    states = random_states(np.random.default_rng(n), n)
    targets, robots = _ramps(states, 1), _draw(config, n, 2)
    state, record = advance(config, states, 0.1, 0.05, targets, record=True, robots=robots)
    row_layout = backend == "numba" or n <= simulation.ROW_BY_ROW_MAX
    for i in range(n):
        own = _own_config(config, robots, i)
        _assert_same_runs(_robot_of(state, record, i), _alone(own, states[i], targets.robot(i), row_layout), (scene, i))
    if config.torque_limit is not None:  # the limits were each robot's own, and bound (the rate limit lowers some)
        peak = np.max(np.abs(record.torque), axis=(0, 2))
        assert np.all(peak <= robots["torque_limit"]) and np.any(peak == robots["torque_limit"])
        assert np.any(peak > config.torque_limit)
    shared = advance(config, states, 0.1, 0.05, targets)
    assert np.all(np.any(state != shared, axis=1))  # no robot moved as the config's robot would


@pytest.mark.skipif(not compiled.available(), reason="numba is not installed")
@pytest.mark.parametrize("n", [5, 40])
def test_numba_and_numpy_agree_on_a_varied_batch(n):
    # numba's steppers (lanes, one robot) are numpy's float stepper and its batched arrays to the bit
    # (tests/test_compiled.py), each robot with its own values too.
    states = random_states(np.random.default_rng(7), n)
    targets, robots = _ramps(states, 8), _draw(MOTOR, n, 9)
    fast, fast_record = advance(replace(MOTOR, backend="numba"), states, 0.1, 0.05, targets, record=True, robots=robots)
    slow, slow_record = advance(replace(MOTOR, backend="numpy"), states, 0.1, 0.05, targets, record=True, robots=robots)
    assert (n <= simulation.ROW_BY_ROW_MAX) == (n == 5)  # (robot by robot on floats, and batched arrays)
    _assert_same_runs((fast, fast_record), (slow, slow_record), "numba vs numpy")
    threaded = advance(replace(MOTOR, backend="numba"), states, 0.1, 0.05, targets, record=True, robots=robots, workers=2)
    _assert_same_runs(threaded, (fast, fast_record), "threads")


@pytest.mark.parametrize("backend", BACKENDS)
def test_one_robots_state_takes_numbers_or_one_entry_arrays(backend):
    config = replace(MOTOR, backend=backend)
    state = random_states(np.random.default_rng(3), 1)[0]
    targets = _ramps(state[None], 4).robot(0)
    numbers = {"mass_tip": 0.05, "kp": 2.4, "torque_limit": 0.3}
    own = _own_config(config, numbers, 0)
    alone = advance(own, state, 0.1, 0.05, targets, record=True)
    _assert_same_runs(advance(config, state, 0.1, 0.05, targets, record=True, robots=numbers), alone, "numbers")
    arrays = {name: np.array([value]) for name, value in numbers.items()}
    _assert_same_runs(advance(config, state, 0.1, 0.05, targets, record=True, robots=arrays), alone, "(1,) arrays")


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_varied_robots_energy_changes_by_its_own_servos_work_and_damping(backend):
    # dE/dt = tau . phidot + k |w|^2 for each robot, with its own masses, leg length, gains and
    # damping (robot 0 undamped: the legs' work alone). Energy and torque from its own values.
    model = "plane"
    config = SimConfig(model=model, timestep=1.0 / 4000.0, backend=backend)
    gait, dt, n = table2_gait(3), 1.0 / 2000.0, 3
    robots = _draw(config, n, 11)
    robots["damping"][0] = 0.0
    (a1, a2), (r1, r2), _ = gait.leg_targets(0.0)
    states = simulation.initial_state(n, (a1, a2))
    states[:, dynamics.LEG_RATES] = (r1, r2)  # on the gait: no servo kick at the start
    times = dt * np.arange(801)
    samples = [states]
    for t in times[:-1]:
        samples.append(advance(config, samples[-1], t, dt, gait, robots=robots))
    samples = np.array(samples)  # (T, N, 13)
    for i in range(n):
        own = _own_config(config, robots, i)
        s = samples[:, i]
        torque = np.array([pd_torque(own.gains, x[6:8], x[11:13], gait.leg_targets(t)) for t, x in zip(times, s)])
        power = np.sum(torque * s[:, dynamics.LEG_RATES], axis=1) + own.robot.damping * np.sum(s[:, dynamics.BODY_RATE] ** 2, axis=1)
        work = cumulative_simpson(power, x=times, initial=0.0)
        change = dynamics.total_energy(s, own.robot, model) - dynamics.total_energy(s[0], own.robot, model)
        assert np.max(np.abs(change)) > 1e-3, i
        assert np.max(np.abs(change - work)) < 1e-5 * np.max(np.abs(change)), i
        # with the config's robot the books do not balance: the varied values did the moving
        shared = dynamics.total_energy(s, config.robot, model) - dynamics.total_energy(s[0], config.robot, model)
        assert np.max(np.abs(shared - work)) > 1e-3 * np.max(np.abs(change)), i


@pytest.mark.parametrize("quadrature", validity.QUADRATURES)
def test_step_measures_of_a_varied_batch_are_each_robots_own(quadrature):
    # Each robot on its own floor and with its own masses; some slip or lift off, so the missing
    # impulse is divided by each robot's own total mass.
    n = 6
    config = replace(MOTOR, backend="numpy")
    states = random_states(np.random.default_rng(13), n, max_rate=4.0)
    targets, robots = _ramps(states, 14), _draw(config, n, 15)
    friction = np.random.default_rng(16).uniform(0.02, 0.3, n)
    _, record = advance(config, states, 0.1, 0.05, targets, record=True, robots=robots)
    lost = np.linspace(0.0, 0.05, n)
    measures, after = validity.step_measures(record, config, friction, lost, quadrature, robots=robots)
    assert np.count_nonzero(measures["slip_velocity"]) >= 3
    for i in range(n):
        own = _own_config(config, robots, i)
        _, alone = advance(own, states[i], 0.1, 0.05, targets.robot(i), record=True)
        own_measures, own_after = validity.step_measures(alone, own, friction[i], lost[i : i + 1], quadrature)
        for key, value in own_measures.items():
            assert np.array_equal(measures[key][i : i + 1], value), (i, key)
        assert np.array_equal(after[i : i + 1], own_after)
    shared, _ = validity.step_measures(record, config, friction, lost, quadrature)  # with the config's mass
    slipped = measures["slip_velocity"] > 0.0
    assert np.all(shared["slip_velocity"][slipped] != measures["slip_velocity"][slipped])


def _states(n=4):
    return random_states(np.random.default_rng(0), n)


BAD_ROBOTS = [
    ({"mass_tp": 0.05}, SimConfig(), ValueError, "unknown per-robot parameter 'mass_tp' \\(did you mean 'mass_tip'\\?\\)"),
    ({"radius": 0.1}, SimConfig(), ValueError, "'radius'.*the shell and gravity are the config's"),
    ({"mass_tip": np.ones(3) * 0.05}, SimConfig(), ValueError, "robots\\['mass_tip'\\] has shape \\(3,\\).*\\(4,\\) for 4 robots"),
    ({"kp": np.ones((4, 1))}, SimConfig(), ValueError, "robots\\['kp'\\] has shape \\(4, 1\\)"),
    ({"leg_length": [0.1, np.nan, 0.1, 0.1]}, SimConfig(), ValueError, "robots\\['leg_length'\\] must be finite.*nan for robot 1"),
    ({"mass_bottom": [0.3, 0.3, np.inf, 0.3]}, SimConfig(), ValueError, "mass_bottom.*inf for robot 2"),
    ({"mass_pin": [0.05, 0.0, 0.05, 0.05]}, SimConfig(), ValueError, "mass_pin'\\] must be finite and positive, got 0.0 for robot 1"),
    ({"mass_tip": -0.05}, SimConfig(), ValueError, "mass_tip'\\] must be finite and positive"),
    ({"leg_length": [0.1, 0.1, 0.1, -0.1]}, SimConfig(), ValueError, "leg_length'\\] must be finite and positive, got -0.1 for robot 3"),
    ({"kp": [2.0, 0.0, 2.0, 2.0]}, SimConfig(), ValueError, "kp'\\] must be finite and positive"),
    ({"kd": [0.05, -0.01, 0.05, 0.05]}, SimConfig(), ValueError, "kd'\\] must be finite and >= 0, got -0.01 for robot 1"),
    ({"damping": [0.0, 0.01, 0.0, 0.0]}, SimConfig(), ValueError, "damping'\\] must be finite and <= 0 \\(the paper's sign"),
    ({"torque_limit": 0.3}, SimConfig(), ValueError, "motor limit.*config has no torque_limit"),
    ({"leg_rate_limit": 10.0}, SimConfig(), ValueError, "motor limit.*config has no torque_limit"),
    ({"torque_limit": [0.3, 0.0, 0.3, 0.3]}, MOTOR, ValueError, "torque_limit'\\] must be finite and positive"),
    ({"leg_rate_limit": [10.0, 10.0, -1.0, 10.0]}, MOTOR, ValueError, "leg_rate_limit'\\] must be finite and positive"),
    ({"kp": 2.0}, SimConfig(legs="kinematic"), ValueError, "robots sets kp: servo values, and kinematic legs have no servo"),
    ({"kd": [True] * 4}, SimConfig(), TypeError, "robots\\['kd'\\] must be real numbers, got bool"),
    ({"kd": "0.1"}, SimConfig(), TypeError, "must be real numbers"),
    ([("kp", 2.0)], SimConfig(), TypeError, "robots must be a dict"),
]  # fmt: skip


@pytest.mark.parametrize("robots, config, error, match", BAD_ROBOTS)
def test_bad_per_robot_values_are_refused_by_name(robots, config, error, match):
    with pytest.raises(error, match=match):
        advance(config, _states(), 0.0, 0.05, _ramps(_states(), 0), robots=robots)


def test_one_robots_state_refuses_more_than_one_value():
    with pytest.raises(ValueError, match="one robot's state takes a number or shape \\(1,\\)"):
        advance(SimConfig(), _states(1)[0], 0.0, 0.05, table2_gait(1), robots={"kp": [2.0, 2.1]})


def test_a_kinematic_scene_takes_varied_masses():
    # kinematic legs: the body's equations take each robot's masses (servo values are refused above)
    config = SimConfig(legs="kinematic", backend="numpy")
    states, robots = _states(3), {"mass_bottom": np.array([0.25, 0.3, 0.35])}
    moved = advance(config, states, 0.0, 0.05, table2_gait(1), robots=robots)
    for i in range(3):
        own = replace(config, robot=RobotParams(mass_bottom=robots["mass_bottom"][i]))
        assert np.array_equal(moved[i], advance(own, states[i], 0.0, 0.05, table2_gait(1)))


BAD_FRICTION = [
    (np.array([0.1, 0.2]), "one per robot, shape \\(4,\\), got shape \\(2,\\)"),
    (np.array([0.1, 0.0, 0.2, 0.3]), "finite and positive for every robot, got 0.0"),
    (np.array([0.1, np.nan, 0.2, 0.3]), "finite and positive for every robot, got nan"),
    (np.array([0.1, np.inf, 0.2, 0.3]), "finite and positive for every robot, got inf"),
    (-0.5, "must be positive or None"),
]


@pytest.mark.parametrize("friction, match", BAD_FRICTION)
def test_bad_per_robot_friction_is_refused_by_name(friction, match):
    _, record = advance(SimConfig(backend="numpy"), _states(), 0.0, 0.05, _ramps(_states(), 0), record=True)
    with pytest.raises(ValueError, match=match):
        validity.step_measures(record, SimConfig(), friction)
