"""The integrator's step record: torques it applied and the ground force, checked against
things that do not share its code (finite differences of the centre of mass, the servo law
written out by hand), and the env's model checks that read it."""

import math
from pathlib import Path

import gymnasium
import numpy as np
import pytest

import rrrobot_gym  # noqa: F401  (registers the env)
from rrrobot_gym import dynamics
from rrrobot_gym.control import Gait, RampTargets, motor_torque
from rrrobot_gym.envs.task import IDEAL_SERVO
from rrrobot_gym.simulation import SimConfig, advance, initial_state, simulate

ROOT = Path(__file__).resolve().parents[1]

FAST_LEGS = Gait(amplitude=1.0, frequency=30.0, phase=(0.0, 2.0), offset=(1.2, 1.4), name="fast")
"""Legs swung at 30 rad/s, 1 rad: the ground force swings between about -2 and +3 m g."""


def _centre_of_mass(states, params, model):
    """World position of the centre of mass, written out from the five point masses."""
    r, l = params.radius, params.leg_length
    rot = dynamics.rotation_matrix(states[:, dynamics.QUAT])
    phi = states[:, dynamics.LEG_ANGLES]
    bodies = [
        (params.mass_bottom, np.broadcast_to([0.0, 0.0, -r], (len(states), 3))),
        (params.mass_pin, np.broadcast_to([0.0, -r, 0.0], (len(states), 3))),
        (params.mass_pin, np.broadcast_to([0.0, r, 0.0], (len(states), 3))),
        (params.mass_tip, np.stack([l * np.cos(phi[:, 0]), np.full(len(states), -r), l * np.sin(phi[:, 0])], 1)),
        (params.mass_tip, np.stack([l * np.cos(phi[:, 1]), np.full(len(states), r), l * np.sin(phi[:, 1])], 1)),
    ]
    moment = sum(mass * np.einsum("nij,nj->ni", rot, body) for mass, body in bodies)
    # The centre sits above the contact point on a plane; the pivot's joint holds it still.
    xy = states[:, 0:2] if model == "plane" else np.zeros((len(states), 2))
    centre = np.column_stack([xy, np.full(len(states), r)])
    return centre + moment / params.total_mass


@pytest.mark.parametrize("model", ["plane", "pivot"])
def test_recorded_ground_force_is_mass_times_centre_of_mass_acceleration_plus_weight(model):
    """Newton's second law for the whole robot, a_com by finite differences of its path."""
    h = 1e-4
    config = SimConfig(model=model, timestep=h)
    params = config.robot
    trajectory = simulate(config, FAST_LEGS, 0.3, sample_dt=h)  # the states at every substep start
    _, record = advance(config, trajectory.states[0], 0.0, 0.3, FAST_LEGS, record=True)
    assert record.force.shape == (3000, 3) and record.times[1] == pytest.approx(h)
    com = _centre_of_mass(trajectory.states, params, model)
    accel = (com[2:] - 2.0 * com[1:-1] + com[:-2]) / h**2
    expected = params.total_mass * (accel + np.array([0.0, 0.0, params.gravity]))
    rot = dynamics.rotation_matrix(trajectory.states[1:-1, dynamics.QUAT])
    recorded = np.einsum("nij,nj->ni", rot, record.force[1 : len(trajectory.states) - 1])
    weight = params.total_mass * params.gravity
    assert np.abs(expected).max() > 2.0 * weight  # the legs are fast: far from the resting load
    np.testing.assert_allclose(recorded, expected, rtol=0, atol=0.01 * weight)
    # the normal part is the world-vertical one
    np.testing.assert_allclose(record.normal[1 : len(trajectory.states) - 1], expected[:, 2], rtol=0, atol=0.01 * weight)


def test_recorded_torque_is_the_servo_law_on_the_ramp_and_its_rate_at_mid_step():
    config = SimConfig(timestep=0.05 / 16)
    kp, kd = config.gains.kp, config.gains.kd
    state = initial_state()
    state[dynamics.LEG_RATES] = (0.7, -1.1)
    start, end = np.array([1.5, 1.6]), np.array([2.3, 0.4])
    ramp = RampTargets(start, end, 0.0, 0.05)
    _, record = advance(config, state, 0.0, 0.05, ramp, record=True)
    middle = advance(config, state, 0.0, 0.025, ramp)  # the same 8 substeps: the state at sample 8
    assert record.times[8] == pytest.approx(0.025)
    by_hand = kp * (0.5 * (start + end) - middle[dynamics.LEG_ANGLES]) + kd * ((end - start) / 0.05 - middle[dynamics.LEG_RATES])
    np.testing.assert_allclose(record.torque[8], by_hand, rtol=1e-12, atol=1e-12)
    # the target rate matters: the law without it (what a held target would give) is far off
    held = kp * (0.5 * (start + end) - middle[dynamics.LEG_ANGLES]) - kd * middle[dynamics.LEG_RATES]
    assert np.abs(held - record.torque[8]).max() > 0.5
    # the leg rates in the record are the state's
    np.testing.assert_allclose(record.leg_rates[8], middle[dynamics.LEG_RATES], rtol=0, atol=1e-15)


def test_one_robot_and_a_batch_record_the_same_step():
    states = np.tile(initial_state(), (3, 1))
    states[1, dynamics.LEG_RATES] = (2.0, -3.0)
    config = SimConfig()
    _, batch = advance(config, states, 0.0, 0.05, FAST_LEGS, record=True)
    for i in range(3):
        _, one = advance(config, states[i], 0.0, 0.05, FAST_LEGS, record=True)
        for field in ("torque", "force", "normal", "leg_clearance", "leg_rates"):
            np.testing.assert_allclose(getattr(batch, field)[:, i], getattr(one, field), rtol=1e-11, atol=1e-12)


def test_motor_limits_clip_the_torque_inside_the_integration_and_the_record_shows_it():
    free = SimConfig()
    limited = SimConfig(torque_limit=0.2, leg_rate_limit=10.0)
    state = initial_state()
    _, free_record = advance(free, state, 0.0, 0.2, FAST_LEGS, record=True)
    out, record = advance(limited, state, 0.0, 0.2, FAST_LEGS, record=True)
    assert np.abs(free_record.torque).max() > 0.5
    rates = record.leg_rates
    # at most the stall torque, and under the motor's torque-speed line: tau in [-T (1 + w/W), T (1 - w/W)]
    assert np.abs(record.torque).max() == pytest.approx(0.2, rel=1e-12)
    assert np.all(record.torque <= 0.2 * (1.0 - rates / 10.0) + 1e-12)
    assert np.all(record.torque >= -0.2 * (1.0 + rates / 10.0) - 1e-12)
    # the speed limit binds: the legs move differently from a torque limit alone
    torque_only = advance(SimConfig(torque_limit=0.2), state, 0.0, 0.2, FAST_LEGS)
    assert np.abs(out[dynamics.LEG_RATES] - torque_only[dynamics.LEG_RATES]).max() > 0.5
    # and the clipped torque is what moved the legs: they lag far behind the free servo's
    free_out = advance(free, state, 0.0, 0.2, FAST_LEGS)
    assert np.abs(out[dynamics.LEG_ANGLES] - free_out[dynamics.LEG_ANGLES]).max() > 0.1


def test_kinematic_legs_record_the_torque_their_motion_takes():
    """The torque recorded for prescribed legs, fed back to the servo-free dynamics as a
    torque, gives the prescribed leg acceleration."""
    config = SimConfig(legs="kinematic", timestep=0.01)
    state = initial_state()
    state[dynamics.LEG_ANGLES] = FAST_LEGS.leg_targets(0.0)[0]
    state[dynamics.LEG_RATES] = FAST_LEGS.leg_targets(0.0)[1]
    _, record = advance(config, state, 0.0, 0.01, FAST_LEGS, record=True)
    derivative = dynamics.state_derivative(state.tolist(), tuple(record.torque[0]), config.robot, config.model)
    np.testing.assert_allclose(derivative[11:13], FAST_LEGS.leg_targets(0.0)[2], rtol=1e-9, atol=1e-9)


# ---------------------------------------------------------------------------
# The env's model checks, read from the record


def _env_after_grace(**kwargs):
    """The ideal servo (unless ``kwargs`` name another), whose target jumps kick the shell."""
    env = gymnasium.make("RRRobot-v0", reset_noise_scale=0.0, **{**IDEAL_SERVO._asdict(), **kwargs})
    env.reset(seed=0)
    for _ in range(2):  # 0.1 s at rest, legs vertical: past the start-up grace
        _, _, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
        assert not terminated and info["slip_velocity"] == 0.0 and info["liftoff_fraction"] == 0.0
    return env


def test_a_held_target_jump_kicks_the_servo_with_the_full_step_at_once():
    """action_hold="zero_order": the servo sees the whole jump at the first substep."""
    action = np.array([0.3, 0.3], dtype=np.float32)
    kicked = _env_after_grace(action_hold="zero_order", terminate_outside_model=False)
    ramped = _env_after_grace(action_hold="linear", terminate_outside_model=False)
    jump = 0.3 * 0.75 * math.pi  # rad: action 0.3 from the rest pose
    kp = kicked.unwrapped.config.sim.gains.kp
    _, _, _, _, kick = kicked.step(action)
    _, _, _, _, ramp = ramped.step(action)
    assert kick["torque_peak"] == pytest.approx(kp * jump, rel=1e-6)  # a float32 action
    assert ramp["torque_peak"] < 0.6 * kp * jump


@pytest.mark.parametrize("quadrature", ["rectangle", "trapezoid"])
def test_grip_beyond_friction_ends_the_episode_and_unlimited_grip_does_not(quadrature):
    """A target jump that needs 4x the normal force in grip but never pulls on the floor."""
    action = np.array([0.3, 0.3], dtype=np.float32)
    results = {}
    for mu in (1.0, None):
        env = _env_after_grace(action_hold="zero_order", friction_coefficient=mu, contact_quadrature=quadrature)
        _, reward, terminated, _, info = env.step(action)
        results[mu] = (terminated, info)
    slipping, info = results[1.0]
    assert info["normal_force"] > 0.0 and info["liftoff_time"] == 0.0 and info["friction_ratio"] > 2.0
    assert info["slip_velocity"] > 0.02 and slipping and info["outside_model"]
    assert info["reward_forward"] == 0.0
    holding, info = results[None]
    assert info["slip_velocity"] == 0.0 and not holding and not info["outside_model"]


@pytest.mark.parametrize("quadrature", ["rectangle", "trapezoid"])
def test_losing_ground_contact_for_longer_than_the_tolerance_ends_the_episode(quadrature):
    # the pull's missing impulse alone would count as a hop past the default max_slip_velocity: lift it
    kwargs = dict(friction_coefficient=None, max_slip_velocity=10.0, contact_quadrature=quadrature)
    env = _env_after_grace(max_liftoff_time=0.005, **kwargs)
    _, _, terminated, _, info = env.step(np.array([1.0, 1.0], dtype=np.float32))
    assert info["normal_force"] < 0.0 and info["liftoff_time"] > 0.005 and 0.0 < info["liftoff_fraction"] <= 1.0
    assert terminated and info["outside_model"] and info["reward_forward"] == 0.0
    tolerant = _env_after_grace(max_liftoff_time=1.0, **kwargs)
    _, _, terminated, _, info = tolerant.step(np.array([1.0, 1.0], dtype=np.float32))
    assert not terminated and info["liftoff_time"] > 0.005


def test_the_pivot_joint_holds_any_force_so_nothing_lifts_off_or_slips():
    env = _env_after_grace(model="pivot")
    _, _, terminated, _, info = env.step(np.array([1.0, 1.0], dtype=np.float32))
    assert info["normal_force"] < 0.0  # the joint pulls the shell down, which it may
    assert info["liftoff_time"] == 0.0 and info["slip_velocity"] == 0.0 and not terminated


@pytest.mark.parametrize("servo", ["ideal", "default"])
def test_the_env_measures_come_from_the_same_step_the_env_integrated(servo):
    """The env's info equals the record of an independent `advance` of the same ramp: to the
    action's target under the ideal servo, to the motion profile's first reference from rest
    under the default one."""
    servo_kwargs = IDEAL_SERVO._asdict() if servo == "ideal" else {}
    env = gymnasium.make("RRRobot-v0", reset_noise_scale=0.0, terminate_outside_model=False, **servo_kwargs)
    env.reset(seed=0)
    action = np.array([0.2, -0.1], dtype=np.float32)
    before = env.unwrapped.state.copy()
    _, _, _, _, info = env.step(action)
    from rrrobot_gym.envs.task import SERVO, action_to_leg_targets

    config = env.unwrapped.config
    start, end = before[dynamics.LEG_ANGLES], action_to_leg_targets(action)
    if servo == "default":  # from rest the reference's rate rises by a dt: it moves a dt^2 (a = 60 rad/s^2)
        assert config.leg_accel_limit == SERVO.leg_accel_limit == 60.0
        end = start + np.sign(end - start) * 60.0 * config.dt**2
    ramp = RampTargets(start, end, 0.0, config.dt)
    after, record = advance(config.sim, before, 0.0, config.dt, ramp, record=True)
    np.testing.assert_allclose(env.unwrapped.state, after, rtol=0, atol=1e-15)
    assert info["torque_rms"] == pytest.approx(float(np.sqrt(np.mean(record.torque**2))), rel=1e-12)
    assert info["normal_force"] == pytest.approx(float(record.normal.min()), rel=1e-12)
    assert info["leg_rate_peak"] == pytest.approx(float(np.abs(record.leg_rates).max()), rel=1e-12)


@pytest.mark.parametrize("backend", ["numpy", "numba"])
@pytest.mark.parametrize("num_robots", [None, 3, 40])
def test_recorded_tangential_force_is_the_force_minus_its_normal_part(backend, num_robots):
    # the integrator records sqrt(|F|^2 - normal^2) itself (contact_kernel); it must be that
    # number, to the bit, on every path: one robot, a row-by-row batch, a vectorised one
    import dataclasses

    if backend == "numba":
        pytest.importorskip("numba")
    rng = np.random.default_rng(5)
    state = initial_state() if num_robots is None else initial_state(num_robots)
    state[..., 6:8] += rng.uniform(-0.3, 0.3, state[..., 6:8].shape)
    ends = state[..., 6:8] + rng.uniform(-1.0, 1.0, state[..., 6:8].shape)
    _, record = advance(SimConfig(backend=backend), state, 0.0, 0.05, RampTargets(state[..., 6:8], ends, 0.0, 0.05),
                        record=True)  # fmt: skip
    force, normal = record.force, record.normal
    fx, fy, fz = force[..., 0], force[..., 1], force[..., 2]
    expected = np.sqrt(np.maximum(fx * fx + fy * fy + fz * fz - normal * normal, 0.0))
    assert record._tangential is not None and np.array_equal(record.tangential, expected)
    assert np.all(record.tangential > 0.0)  # rocking needs grip
    # a record changed by hand answers from its own force and normal, not the integrator's numbers
    pushed = dataclasses.replace(record, normal=normal + 1.0)
    assert np.array_equal(pushed.tangential, np.sqrt(np.maximum(fx * fx + fy * fy + fz * fz - (normal + 1.0) ** 2, 0.0)))


@pytest.mark.parametrize("model", ["plane", "pivot"])
@pytest.mark.parametrize("num_robots", [None, 40])
def test_the_compiled_steppers_summary_is_the_records_own_to_the_bit(model, num_robots):
    # the compiled stepper summarises each block of robots as it finishes it; those numbers must
    # be StepRecord.summary's from the record's arrays, to the bit, lift-off samples included
    # (40 robots: a lane block of 32 and 8 robots stepped one by one)
    import dataclasses

    from rrrobot_gym.simulation import SUMMARY_KEYS

    pytest.importorskip("numba")
    rng = np.random.default_rng(11)
    state = initial_state() if num_robots is None else initial_state(num_robots)
    state[..., 6:8] += rng.uniform(-0.5, 0.5, state[..., 6:8].shape)
    state[..., 11:13] += rng.uniform(-20.0, 20.0, state[..., 11:13].shape)
    config = SimConfig(model=model, backend="numba", torque_limit=2.0, leg_rate_limit=60.0)
    _, record = advance(config, state, 0.0, 0.3, FAST_LEGS, record=True)
    assert record._summary is not None
    made, summarised = record.summary(), dataclasses.replace(record).summary()  # (replace drops the summary)
    assert list(made) == list(SUMMARY_KEYS) == list(summarised)
    for key in SUMMARY_KEYS:
        assert np.shape(made[key]) == np.shape(summarised[key]) == np.shape(record.normal[0])
        assert np.array_equal(made[key], summarised[key]), key
    if model == "plane":  # the fast legs pull the shell off the ground: the quotient meets normal <= 0
        assert np.any(record.normal <= 0.0)


@pytest.mark.parametrize("compiled_copy", [False, True])
def test_a_summary_lets_nan_win_and_sums_squares_sample_by_sample_as_the_records_arrays_do(compiled_copy):
    # what the compiled stepper's summary does with NaN and inf (advance raises on a non-finite
    # state, so no integration makes them: the stepper's function is called on made-up rows)
    from rrrobot_gym import compiled
    from rrrobot_gym.simulation import SUMMARY_KEYS, _Recorder

    summarise = compiled._summarise
    if compiled_copy:
        pytest.importorskip("numba")
        summarise = compiled._stepper(False).py_func.__globals__["_summarise"]
    rng = np.random.default_rng(12)
    samples, robots = 17, 6
    rows = rng.normal(0.0, 1.0, (samples, compiled.record_rows(2), robots))
    rows[:, 5] = rng.uniform(0.5, 2.0, (samples, robots))  # pushing: normal > 0
    rows[:, 6] = np.abs(rows[:, 6])
    rows[4, 5, 0] = np.nan  # a normal force (and so its quotient) at a middle sample
    rows[0, 1, 1] = np.nan  # a torque at the first sample
    rows[samples - 1, 8, 2] = np.nan  # the second leg's clearance at the last sample
    rows[3, 9, 3], rows[5, 7, 3] = -np.inf, -np.inf  # a leg rate and a clearance
    rows[2, 5, 4] = 0.0  # a sample without push: the quotient is inf
    rows[:, 0:2, 4] *= 1e3  # large squares, summed in order
    rows[:, 5, 5] = -rows[:, 5, 5]  # pulling at every sample: the greatest quotient is negative
    rows[:, 0:2, 5] = 0.0  # no torque: the squares sum to 0
    rows[:, 7:9, 5] = np.inf  # legs infinitely far from the ground: the least clearance is inf
    summary = np.full((compiled.SUMMARY_ROWS, robots), -7.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        summarise(rows, summary, 0, robots, 2)
    expected = _Recorder.record_of(rows, 0.0, 0.01).summary()
    for j, key in enumerate(SUMMARY_KEYS):
        assert np.array_equal(summary[j], expected[key], equal_nan=True), key
    assert np.isnan(summary[0, 0]) and np.isnan(summary[1, 0]) and np.isnan(summary[3, 1]) and np.isnan(summary[4, 1])
    assert np.isnan(summary[2, 2]) and summary[5, 3] == np.inf and summary[2, 3] == -np.inf and summary[1, 4] == np.inf
    assert summary[1, 5] < 0.0 and summary[3, 5] == 0.0 and summary[4, 5] == 0.0 and summary[2, 5] == np.inf
    squares = rows[:, 0, 4] ** 2 + rows[:, 1, 4] ** 2
    total = 0.0
    for value in squares:
        total += value
    assert summary[3, 4] == total


def test_a_record_of_no_samples_has_no_summary():
    from rrrobot_gym.simulation import StepRecord

    empty = StepRecord(times=np.zeros(0), step=0.01, torque=np.zeros((0, 2)), force=np.zeros((0, 3)), normal=np.zeros(0),
                       leg_clearance=np.zeros((0, 2)), leg_rates=np.zeros((0, 2)))  # fmt: skip
    with pytest.raises(ValueError, match="no samples"):
        empty.summary()


def _largest_measures(agent, substeps, quadrature, duration, headings=(0.0, 90.0), **env_kwargs):
    """The largest slip velocity (m/s) and lift-off spell (s) of any step after the start-up
    grace, per heading, of ``agent`` in the env at ``substeps`` integration steps a control step."""
    from rrrobot_gym.evaluation import run_episodes
    from rrrobot_gym.envs.task import STARTUP_GRACE

    run = run_episodes({"agent": agent}, "plane", list(headings), duration, info_keys=("slip_velocity", "liftoff_time"),
                       timestep=0.05 / substeps, frame_skip=substeps, contact_quadrature=quadrature,
                       **env_kwargs)["agent"]  # fmt: skip
    first = math.ceil(STARTUP_GRACE / 0.05 - 1e-9)
    assert not run["terminated"].any()
    return run["slip_velocity"][first:].max(axis=0), run["liftoff_time"][first:].max(axis=0)


def test_the_trapezoid_measures_of_a_searched_gait_converge_with_the_step():
    """The robust search's best gait peaks in grip and lifts off for fractions of a millisecond.
    Each rectangle-rule sample stands for a whole step, so at the default step its measures are
    about twice the converged slip and ten times the spells; the trapezoid's agree from 1/260 s
    (where the rectangle rule ends its episodes) to 1/2400 s."""
    from rrrobot_gym.agents import load_gait_agents

    gait = load_gait_agents(ROOT / "agents" / "searched" / "plane_own_robust.json")["searched-plane-own-1"]
    heading = (90.0,)  # (an open-loop gait: every heading the same motion)
    servo = gait.search_env_kwargs  # (the ideal servo it was searched under)
    fine_slip, fine_spell = _largest_measures(gait, 120, "trapezoid", 3.0, heading, **servo)
    for substeps in (13, 15):
        slip, spell = _largest_measures(gait, substeps, "trapezoid", 3.0, heading, **servo)
        np.testing.assert_allclose(slip, fine_slip, rtol=0.15)
        np.testing.assert_allclose(spell, fine_spell, rtol=0, atol=2e-4)  # s, of max_liftoff_time's 5e-3
    slip, spell = _largest_measures(gait, 15, "rectangle", 3.0, heading, **servo)  # the default, for scale
    assert (slip > 1.6 * fine_slip).all() and (spell > fine_spell + 2e-3).all()


@pytest.mark.slow
def test_the_trapezoid_slip_measure_of_a_policys_kicks_converges_with_the_step():
    """Each new action kicks the servo: the grip needed jumps past the floor's and falls back
    within about a millisecond, which the rectangle rule counts as a whole step. The shipped
    policy along 45 and 90 deg for 5 s: the converged measure (1/2400 s, the same at 1/4800 s) is
    2.8 and 1.5 mm/s; the trapezoid rule's holds within 1 mm/s of it from 1/200 s (0.5 and 0.6 mm/s
    off), while the rectangle rule's at the default 1/300 s is 7.7 and 6.8 mm/s."""
    from rrrobot_gym.agents import load_ppo_agent

    policy = load_ppo_agent(ROOT / "agents" / "pretrained" / "best_model.zip")
    headings = (45.0, 90.0)
    fine, _ = _largest_measures(policy, 120, "trapezoid", 5.0, headings)
    assert (fine > 1e-3).all()  # (the policy's kicks need more grip than the floor's at some step)
    for substeps in (10, 15):
        slip, _ = _largest_measures(policy, substeps, "trapezoid", 5.0, headings)
        np.testing.assert_allclose(slip, fine, rtol=0, atol=1e-3)
    slip, _ = _largest_measures(policy, 15, "rectangle", 5.0, headings)
    assert (slip > 2.5 * fine).all() and (slip > fine + 4e-3).all()


def test_the_motors_rounded_corners_stay_inside_the_clip_and_leave_no_kink():
    """The motor law is the clip of the servo's torque to [-T (1 + w / W), T (1 - w / W)] and to
    +-T, with the corners where the torque meets a bound rounded over T / 10
    (control.CORNER_WIDTH): inside the motor's envelope, at most T / 60 from the clip, equal to it
    T / 10 from a corner, and with a continuous slope (RK4 keeps its order)."""
    limit, rate_limit = 0.5, 10.0
    taus = np.linspace(-1.5, 1.5, 30001)
    for rate in (-12.0, -4.0, -0.01, 0.0, 0.02, 3.0, 9.5):
        high, low = min(limit, limit - rate * (limit / rate_limit)), min(limit, limit + rate * (limit / rate_limit))
        clip = np.clip(taus, -low, high)
        law = motor_torque(taus, np.full_like(taus, rate), limit, rate_limit)
        assert np.all((law <= high) & (law >= -low))  # inside the motor's envelope
        assert np.max(np.abs(law - clip)) <= limit / 60 + 1e-15
        far = np.minimum(np.abs(taus - high), np.abs(taus + low)) > 0.1 * limit
        np.testing.assert_array_equal(law[far], clip[far])
        slope = np.diff(law) / np.diff(taus)
        assert np.max(np.abs(np.diff(slope))) < 0.01  # the clip's slope jumps by 1 at a corner
        floats = [motor_torque(float(t), rate, limit, rate_limit) for t in taus[::997]]
        assert floats == law[::997].tolist()  # floats and arrays: the same operations, the same bits
