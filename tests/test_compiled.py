"""The compiled stepper (numba) integrates exactly what the Python float stepper does.

Both run derivative_kernel's own code, the compiled one through numba, with the same order
of operations, so a run must agree to the last bit: robot by robot, with the record, under
every kind of target it takes, with motor limits, and whatever the batch size or thread count.
"""

import os
from dataclasses import replace

import gymnasium
import numpy as np
import pytest
from conftest import array_transcendentals_one_ulp_off, random_states

import rrrobot_gym  # noqa: F401
import rrrobot_gym.control
from rrrobot_gym import compiled, dynamics
from rrrobot_gym.control import Gait, HeldTargets, RampTargets, table2_gait
from rrrobot_gym.gait_search import SinusoidGait
from rrrobot_gym.params import PDGains
from rrrobot_gym.simulation import NumericalFailure, SimConfig, advance, initial_state

pytestmark = pytest.mark.skipif(not compiled.available(), reason="numba is not installed")

RECORD_FIELDS = ("times", "torque", "force", "normal", "tangential", "leg_clearance", "leg_rates")


def _states(n, seed=0):
    return random_states(np.random.default_rng(seed), n)


def _targets(kind, n, rng):
    if kind == "ramp":
        return RampTargets(rng.uniform(0.0, 3.0, (n, 2)), rng.uniform(0.0, 3.0, (n, 2)), 0.1, 0.05)
    if kind == "held":
        return HeldTargets(rng.uniform(-1.0, 4.0, (n, 2)))
    if kind == "gait":
        return Gait(amplitude=0.9, frequency=11.0, phase=(0.3, 2.0), offset=(1.2, 1.9))
    return SinusoidGait(0.8, 1.1, 7.0, 2.1, 1.6, 1.5)


def _float_path(config, states, targets, t0, duration):
    """Each robot alone on the numpy backend's Python-float stepper: (states, record fields)."""
    runs = []
    for i, state in enumerate(states):
        robot = targets.robot(i) if hasattr(targets, "robot") else targets
        runs.append(advance(replace(config, backend="numpy"), state, t0, duration, robot, record=True))
    fields = {f: np.stack([getattr(r, f) for _, r in runs], axis=1) for f in RECORD_FIELDS if f != "times"}
    fields["summary"] = {key: np.array([r.summary()[key] for _, r in runs]) for key in runs[0][1].summary()}
    return np.stack([s for s, _ in runs]), fields


def _assert_compiled_is_the_float_stepper(config, states, targets):
    """One env step of a batch on the compiled stepper equals each robot's own float run to the
    bit: states, every record field and the summary. Returns the compiled record."""
    fast, record = advance(replace(config, backend="numba"), states, 0.1, 0.05, targets, record=True)
    slow, slow_fields = _float_path(config, states, targets, 0.1, 0.05)
    assert np.array_equal(fast, slow)
    summaries = slow_fields.pop("summary")
    for field, values in slow_fields.items():
        assert np.array_equal(getattr(record, field), values), field
    for key, values in record.summary().items():
        assert np.array_equal(values, summaries[key]), key
    return record


KINDS = ("ramp", "held", "gait", "sinusoid")
SCENES = {
    "plane": SimConfig(), "pivot": SimConfig(model="pivot"), "plane-torque-limit": SimConfig(torque_limit=0.3),
    "pivot-motor": SimConfig(model="pivot", torque_limit=0.5, leg_rate_limit=10.0),
    "pivot-auto-step": SimConfig(model="pivot", timestep="auto"),
    "plane-stiff-servo": SimConfig(gains=PDGains(kp=200.0, kd=5.0), timestep="auto"),
}  # fmt: skip
"""Scenes that compile differently (the limits or their absence) meet every kind of target; the
others (another model, step or gains: other numbers through the same code) one kind each."""
SCENE_KINDS = [(scene, kind) for scene in ("plane", "plane-torque-limit", "pivot-motor") for kind in KINDS] + [
    ("pivot", "gait"), ("pivot-auto-step", "sinusoid"), ("plane-stiff-servo", "ramp")]


@pytest.mark.parametrize("scene, kind", SCENE_KINDS, ids=[f"{s}-{k}" for s, k in SCENE_KINDS])
def test_compiled_batch_is_the_float_stepper_to_the_bit(scene, kind):
    # 33 robots: more than ROW_BY_ROW_MAX, so the numpy backend would batch them with numpy;
    # each is compared with its own run on Python floats. They are a block of the lane (SIMD)
    # stepper and one robot on the one-robot stepper.
    assert compiled.LANES < 33 < 2 * compiled.LANES
    config = SCENES[scene]
    record = _assert_compiled_is_the_float_stepper(config, _states(33), _targets(kind, 33, np.random.default_rng(7)))
    if config.torque_limit is not None:
        peak = np.max(np.abs(record.torque))
        assert peak <= config.torque_limit
        if kind in ("ramp", "held"):  # far targets: the limit binds, so the limited torques were compared
            assert peak == config.torque_limit


@pytest.mark.parametrize("n", [compiled.PADDED_MIN + 4, compiled.LANES + compiled.PADDED_MIN])
@pytest.mark.parametrize("scene, kind", [("plane", "ramp"), ("pivot-motor", "gait")])
def test_a_padded_lane_block_is_the_float_stepper_to_the_bit(scene, kind, n):
    # fewer robots than a block (alone, or after a whole block), but at least PADDED_MIN: a lane
    # block padded with copies of the last; each robot, its record and summary are its own run's
    assert compiled.PADDED_MIN <= n % compiled.LANES
    _assert_compiled_is_the_float_stepper(SCENES[scene], _states(n, seed=5), _targets(kind, n, np.random.default_rng(3)))


@pytest.mark.parametrize("config", [SimConfig(), SimConfig(model="pivot")], ids=["plane", "pivot"])
def test_one_robot_over_a_paper_run_is_the_float_stepper_to_the_bit(config):
    # 4 s of Gait 2 from the paper's start, the hardest start transient, in env-sized steps.
    fast = slow = initial_state()
    for i in range(80):
        fast, fast_record = advance(config, fast, 0.05 * i, 0.05, table2_gait(2), record=True)
        slow, slow_record = advance(replace(config, backend="numpy"), slow, 0.05 * i, 0.05, table2_gait(2), record=True)
        assert np.array_equal(fast, slow), i
    for field in RECORD_FIELDS:
        assert np.array_equal(getattr(fast_record, field), getattr(slow_record, field)), field
    assert np.hypot(fast[0], fast[1]) > 1e-3  # it travelled


def test_compiled_is_the_numpy_batch_to_the_bit_with_numpys_transcendentals_off():
    # The batched numpy stepper evaluates the derivative on (N,) arrays, from operations that round
    # alike everywhere (the leg trig is numerics.sincos): the compiled lanes' bits, whatever
    # numpy's own transcendentals give.
    states = _states(40, seed=3)
    targets = RampTargets(states[:, dynamics.LEG_ANGLES], np.random.default_rng(2).uniform(0, 3, (40, 2)), 0.0, 0.05)
    config = SimConfig(backend="numba", torque_limit=0.5, leg_rate_limit=10.0)
    fast, fast_record = advance(config, states, 0.0, 0.05, targets, record=True)
    assert not np.array_equal(fast, states)
    with array_transcendentals_one_ulp_off():
        numpy, numpy_record = advance(replace(config, backend="numpy"), states, 0.0, 0.05, targets, record=True)
    assert np.array_equal(fast, numpy)
    for field in RECORD_FIELDS:
        assert np.array_equal(getattr(fast_record, field), getattr(numpy_record, field)), field


@pytest.mark.parametrize("workers, rest", [(2, 5), (3, compiled.PADDED_MIN + 3)])
def test_threads_give_the_one_thread_result(workers, rest):
    n = 3 * compiled.LANES + rest  # lane blocks and single robots or a padded block, shared among the threads
    states = _states(n, seed=4)
    targets = RampTargets(states[:, dynamics.LEG_ANGLES], np.random.default_rng(5).uniform(0, 3, (n, 2)), 0.0, 0.05)
    config = SimConfig(backend="numba")
    one, one_record = advance(config, states, 0.0, 0.05, targets, record=True)
    many, many_record = advance(config, states, 0.0, 0.05, targets, record=True, workers=workers)
    assert np.array_equal(one, many)
    for field in RECORD_FIELDS:
        assert np.array_equal(getattr(one_record, field), getattr(many_record, field)), field
    one_summary, many_summary = one_record.summary(), many_record.summary()
    for key in one_summary:
        assert np.array_equal(one_summary[key], many_summary[key]), key


def test_a_ramps_parameters_are_its_ends_whatever_their_memory_layout():
    # RampTargets builds the compiled stepper's (N, 8) parameters in one piece from its (N, 2)
    # ends (as complex pairs): C-ordered, Fortran-ordered and strided ends give the same
    rng = np.random.default_rng(13)
    start, end = rng.uniform(0.0, 3.0, (7, 2)), rng.uniform(0.0, 3.0, (7, 2))
    expected = np.column_stack([start, end, end - start, (end - start) / 0.05])
    states = np.zeros((7, dynamics.STATE_SIZE))
    states[:, dynamics.LEG_ANGLES] = start
    for first in (start, np.asfortranarray(start), states[:, dynamics.LEG_ANGLES]):
        for last in (end, np.asfortranarray(end), np.repeat(end, 2, axis=0)[::2]):
            ramp = RampTargets(first, last, 0.1, 0.05)
            kind, params, shared = compiled.target_arrays(ramp)
            assert np.array_equal(params, expected) and params.flags.c_contiguous
            angles, rates, _ = ramp.leg_targets(0.125)  # halfway: the numpy steppers' view of the same ramp
            assert np.array_equal(angles[0], start[:, 0] + (end - start)[:, 0] * ((0.125 - 0.1) / 0.05))
            assert np.array_equal(rates[1], expected[:, 7])


def test_auto_takes_numba_where_it_applies_and_numpy_elsewhere(monkeypatch):
    states = _states(30, seed=6)
    gait = table2_gait(1)
    numpy = advance(SimConfig(backend="numpy"), states, 0.0, 0.05, gait)
    numba = advance(SimConfig(backend="numba"), states, 0.0, 0.05, gait)
    assert np.array_equal(advance(SimConfig(), states, 0.0, 0.05, gait), numba)
    # scenes and targets it does not cover go to numpy under "auto"
    kinematic = SimConfig(legs="kinematic")
    assert np.array_equal(advance(kinematic, states, 0.0, 0.05, gait),
                          advance(replace(kinematic, backend="numpy"), states, 0.0, 0.05, gait))  # fmt: skip

    class Custom:
        def leg_targets(self, t):
            return gait.leg_targets(t)

    assert np.array_equal(advance(SimConfig(), states, 0.0, 0.05, Custom()), numpy)
    # without numba, "auto" is numpy
    monkeypatch.setattr(compiled, "available", lambda: False)
    assert np.array_equal(advance(SimConfig(), states, 0.0, 0.05, gait), numpy)
    with pytest.raises(ImportError, match="numba"):
        SimConfig(backend="numba")


def test_bad_backend_requests_name_the_problem():
    with pytest.raises(ValueError, match="unknown backend 'numbaa'"):
        SimConfig(backend="numbaa")
    with pytest.raises(ValueError, match="servo legs with integrator 'rk4'.*kinematic"):
        SimConfig(backend="numba", legs="kinematic")

    class Custom:
        def leg_targets(self, t):
            return (1.0, 1.0), (0.0, 0.0), (0.0, 0.0)

    with pytest.raises(TypeError, match="not Custom"):
        advance(SimConfig(backend="numba"), initial_state(), 0.0, 0.05, Custom())
    with pytest.raises(ValueError, match="unknown backend"):
        gymnasium.make("RRRobot-v0", backend="fortran")


def test_a_compiled_blow_up_is_a_numerical_failure():
    state = initial_state()
    state[dynamics.BODY_RATE] = (0.0, 0.0, 5000.0)  # far past the ~1,100 rad/s where RK4 fails
    with pytest.raises(NumericalFailure, match="turns too fast"):
        advance(SimConfig(backend="numba"), state, 0.0, 0.05, table2_gait(1))


def test_a_blow_up_in_a_lane_block_stays_in_its_lane():
    # one robot of a SIMD block blows up: the batch fails by name, and its block-mates, run
    # without it, are what they were beside it (no lane reads another's numbers)
    n = compiled.LANES
    states = _states(n, seed=11)
    states[5, dynamics.BODY_RATE] = (0.0, 0.0, 5000.0)
    n_steps = 15
    config = SimConfig(backend="numba")
    with pytest.raises(NumericalFailure, match="turns too fast"):
        advance(config, states, 0.0, 0.05, table2_gait(1))
    gait = compiled.target_arrays(table2_gait(1))
    blown = compiled.integrate(config, gait, states, 0.0, 0.05 / n_steps, n_steps, False)[0]
    assert not np.isfinite(blown[5]).all() and np.isfinite(np.delete(blown, 5, axis=0)).all()
    calm = states.copy()
    calm[5] = states[4]
    alone = compiled.integrate(config, gait, calm, 0.0, 0.05 / n_steps, n_steps, False)[0]
    assert np.array_equal(np.delete(blown, 5, axis=0), np.delete(alone, 5, axis=0))


def test_envs_step_alike_on_both_backends():
    """One robot and a batch of up to ROW_BY_ROW_MAX take the float stepper on numpy: bit-identical,
    with numpy's array transcendentals one ulp off (another CPU's SIMD kernels) and the compiled
    code on libm's, so no compared quantity comes from one of them."""
    makers = (lambda **kw: gymnasium.make("RRRobot-v0", **kw),
              lambda **kw: gymnasium.make_vec("RRRobot-v0", num_envs=5, vectorization_mode="vector_entry_point", **kw))  # fmt: skip
    for make in makers:  # (numba compiles the steppers here, and could not while numpy is patched)
        env = make(backend="numba", target_direction=0.5)
        env.reset(seed=11)
        env.step(env.action_space.sample())
    with array_transcendentals_one_ulp_off():
        for make in makers:
            envs = [make(backend=b, target_direction=0.5) for b in ("numba", "numpy")]
            # the results agree to the bit, so check that each env really got the backend it was asked for
            assert [env.unwrapped.config.sim.backend for env in envs] == ["numba", "numpy"]
            obs = [env.reset(seed=11)[0] for env in envs]
            rng = np.random.default_rng(0)
            for _ in range(10):
                action = rng.uniform(-1.0, 1.0, envs[0].action_space.shape).astype(np.float32)
                steps = [env.step(action) for env in envs]
                assert np.array_equal(steps[0][0], steps[1][0])
                assert np.array_equal(steps[0][1], steps[1][1])
                for key in ("tilt", "x_upright", "forward_velocity", "slip_velocity", "termination"):
                    assert np.array_equal(steps[0][4][key], steps[1][4][key]), key
            assert not np.array_equal(obs[0], steps[0][0])


def test_the_cache_directory_follows_every_compiled_source(tmp_path):
    # numba re-checks only a function's own file; the directory must change with any of them
    sources = [compiled.__file__, dynamics.__file__, rrrobot_gym.control.__file__]
    copies = []
    for i, path in enumerate(sources):
        copy = tmp_path / f"{i}.py"
        copy.write_bytes(open(path, "rb").read())
        copies.append(str(copy))
    base = compiled.cache_dir(copies)
    assert base == compiled.cache_dir(sources)
    for copy in copies:
        original = open(copy, "rb").read()
        open(copy, "ab").write(b"\n# an edit\n")
        assert compiled.cache_dir(copies) != base, copy
        open(copy, "wb").write(original)


@pytest.mark.slow
def test_a_second_process_loads_the_compiled_steppers_from_the_cache(tmp_path):
    import shutil
    import subprocess
    import sys
    import time

    # this process's cache holds both steppers (compiled here or by an earlier process); a copy
    # of it is what a second process finds after the first compiled: it loads, and says nothing,
    # even run from a copy of the package at another path with newer files (a Ray worker's
    # unpacked working directory): the cache is keyed by the sources' content, not their path or time
    _use_both_steppers()
    package = tmp_path / "elsewhere" / "rrrobot_gym"
    shutil.copytree(os.path.dirname(compiled.__file__), package, ignore=shutil.ignore_patterns("__pycache__"))
    for path in package.rglob("*.py"):
        os.utime(path, (time.time() + 100, time.time() + 100))
    script = (
        "import warnings, numba\n"
        "warnings.simplefilter('error', numba.NumbaPerformanceWarning)\n"
        "from rrrobot_gym import compiled, simulation as sim\n"
        "from rrrobot_gym.control import table2_gait\n"
        "for workers in (1, 2):\n"
        "    sim.advance(sim.SimConfig(backend='numba'), sim.initial_state(3), 0.0, 0.05, table2_gait(1), workers=workers)\n"
        "kernel = compiled.specialised(sim.SimConfig().robot, 'plane')\n"
        "stats = [compiled._stepper(False, None, 2, kernel, False).stats]\n"
        "print(sum(sum(s.cache_hits.values()) for s in stats), sum(sum(s.cache_misses.values()) for s in stats),\n"
        "      compiled.cache_dir(None, kernel), compiled.__file__)\n"
    )
    # (the paper robot's shared stepper runs its specialised kernel, cached in a directory of its own)
    warm = compiled.cache_dir(None, compiled.specialised(SimConfig().robot, "plane"))
    # (another test process may be writing into it: numba writes each file as *.tmp.* and renames it)
    shutil.copytree(warm, tmp_path / "rrrobot_gym" / os.path.basename(warm), ignore=shutil.ignore_patterns("*.tmp.*"))
    # the caches of other sources: one unused for 40 days (removed), one used yesterday (kept)
    stale, recent = (tmp_path / "rrrobot_gym" / name for name in ("numba-0000000000000000", "numba-1111111111111111"))
    for folder, days in ((stale, 40), (recent, 1)):
        (folder / "sub").mkdir(parents=True)
        (folder / "sub" / "f.nbi").write_text("")
        os.utime(folder, (time.time() - days * 86400, time.time() - days * 86400))
    env = dict(os.environ, XDG_CACHE_HOME=str(tmp_path), PYTHONPATH=str(package.parent))
    run = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True,
                         cwd=package.parent)
    assert not stale.exists() and recent.exists()
    hits, misses, where, source = run.stdout.split()
    assert source == str(package / "compiled.py")
    assert (hits, misses) == ("1", "0") and "compiling" not in run.stderr
    assert where == str(tmp_path / "rrrobot_gym" / os.path.basename(warm))
    # numba names cache files by the function's name: a stepper for another leg count has its own
    names = os.listdir(where)
    assert any(n.startswith("compiled._batch_2_legs-") for n in names) and "specialised_kernel.py" in names


def _use_both_steppers():
    """Compile (or load) the shared and the per-robot stepper in this process, as a randomized batch run does."""
    advance(SimConfig(backend="numba"), initial_state(2), 0.0, 0.05, table2_gait(1), workers=2)
    advance(SimConfig(backend="numba"), initial_state(2), 0.0, 0.05, table2_gait(1), robots={"kp": [2.0, 2.1]})


def test_making_a_stepper_says_it_compiles_only_when_the_cache_lacks_it(tmp_path, monkeypatch, capsys):
    # (making the dispatcher prints the notice; numba compiles on its first call, not made here)
    _use_both_steppers()
    capsys.readouterr()
    kernel = compiled.specialised(SimConfig().robot, "plane")  # (the shared stepper's, for the paper robot)
    for per_robot in (False, True):
        compiled._stepper.__wrapped__(per_robot, None, 2, None if per_robot else kernel)
    assert capsys.readouterr().err == ""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    for per_robot in (False, True):
        compiled._stepper.__wrapped__(per_robot, None, 2, None if per_robot else kernel)
    notices = capsys.readouterr().err.splitlines()
    assert [line.split(":")[1] for line in notices] == [" compiling the numba stepper (2 legs)",
                                                        " compiling the numba stepper (2 legs) (per-robot)"]
    assert all("cached after" in line for line in notices)


def test_the_stepper_run_as_plain_python_gives_what_numba_compiled():
    # compiled._batch is ordinary Python: run it uncompiled, on a block of the lanes and two robots
    # one at a time
    config = SimConfig(torque_limit=0.4, leg_rate_limit=9.0)
    n = compiled.LANES + 2
    states = _states(n, seed=8)
    targets = compiled.target_arrays(_targets("ramp", n, np.random.default_rng(9)))
    k, gains, layout = compiled._scene(config.robot, config.model, config.gains)
    h = 0.05 / 15
    y = states.copy()
    rows = np.empty((3, compiled.record_rows(2), n))
    summary = np.empty((compiled.SUMMARY_ROWS, n))
    compiled._batch(y, 0.1, h, 3, k, gains, 0.4, 9.0, *targets, layout, rows, summary, np.empty(0))
    fast, fast_rows, fast_summary = compiled.integrate(replace(config, backend="numba"), targets, states, 0.1, h, 3, True)
    assert np.array_equal(y, fast) and np.array_equal(rows, fast_rows) and np.array_equal(summary, fast_summary)


def test_pruning_caches_marks_the_one_in_use_and_removes_only_stale_siblings(tmp_path):
    now = 1.0e9
    folders = {name: tmp_path / name for name in ("numba-current", "numba-old", "numba-young", "other-old")}
    for name, folder in folders.items():
        folder.mkdir()
        age = {"numba-current": 90, "numba-old": 31, "numba-young": 29, "other-old": 90}[name]
        os.utime(folder, (now - age * 86400, now - age * 86400))
    removed = compiled._prune_stale_caches(str(folders["numba-current"]), unused_days=30, now=now)
    assert removed == [str(folders["numba-old"])]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["numba-current", "numba-young", "other-old"]
    assert os.stat(folders["numba-current"]).st_mtime == now  # in use: its own age starts again
