"""The command line, run as a user runs it: ``python -m rrrobot_gym ...`` in a subprocess.

Runs are a few seconds of simulated time so the whole file stays short; the 50 s
runs of the paper are the physics tests' business.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid

from rrrobot_gym import dynamics
from rrrobot_gym.params import RobotParams

REPO_ROOT = Path(__file__).resolve().parents[1]
DOCUMENTED_ARRAYS = {"t": 1, "x": 1, "y": 1, "theta": 3, "phi": 2, "quat": 4, "body_rate": 3}
"""Name -> columns (1: a plain (T,) array) of what ``rrrobot simulate`` writes."""
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def rrrobot(*args, check=True):
    """Run ``python -m rrrobot_gym *args`` from the repository root, without an install."""
    env = {**os.environ, "PYTHONPATH": str(REPO_ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    env["MPLBACKEND"] = "Agg"
    result = subprocess.run(
        [sys.executable, "-m", "rrrobot_gym", *map(str, args)],
        cwd=REPO_ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    if check and result.returncode != 0:
        raise AssertionError(f"rrrobot {' '.join(map(str, args))} failed ({result.returncode}):\n{result.stderr}")
    return result


def rrrobot_here(capsys, *args):
    """``rrrobot *args`` in this process (as the command line's main, which turns each error it
    knows into one line and exit status 2, and lets any other exception out): (status, stderr)."""
    from rrrobot_gym.cli import main

    capsys.readouterr()
    try:
        status = main([str(arg) for arg in args])
    except SystemExit as exit_info:  # argparse
        status = exit_info.code
    return status, capsys.readouterr().err


# ---------------------------------------------------------------- table1


@pytest.mark.slow
def test_table1_json_reproduces_the_papers_periods():
    records = json.loads(rrrobot("table1", "--json").stdout)  # strict JSON: NaN would not parse as null
    by_entry = {(r["model"], r["axis"]): r for r in records}
    assert set(by_entry) == {("plane", "x"), ("plane", "y"), ("pivot", "x"), ("pivot", "y")}
    tolerance = {("plane", "x"): 0.005, ("plane", "y"): 0.005, ("pivot", "x"): 0.005, ("pivot", "y"): 0.02}
    for entry, rec in by_entry.items():
        assert rec["period_s"] == pytest.approx(rec["paper_s"], rel=tolerance[entry]), entry
    # The paper's eq. (5) needs rho < r; about the plane's X axis rho > r, so the literal formula is undefined.
    assert by_entry[("plane", "x")]["radius_of_gyration_m"] > RobotParams().radius
    assert by_entry[("plane", "x")]["paper_formula_s"] is None


@pytest.mark.slow
def test_table1_text_flags_that_the_literal_formulas_miss_the_paper():
    text = rrrobot("table1").stdout
    for model, axis, paper in (("plane", "X", "1.29"), ("plane", "Y", "1.07"), ("pivot", "X", "1.19"), ("pivot", "Y", "0.96")):
        assert any(line.split()[:2] == [model, axis] and paper in line.split() for line in text.splitlines())
    assert "no real value" in text
    assert "do not reproduce the paper's Table I" in text


# ---------------------------------------------------------------- simulate

SAMPLE_DT = 0.005
DURATION = 3.0


@pytest.fixture(scope="module")
def gait3_runs(tmp_path_factory):
    """Gait 3 on a plane, as given and with the legs' phases swapped, and the normal run's plot."""
    out = tmp_path_factory.mktemp("simulate")
    # (on numpy: a process of its own would otherwise compile the numba stepper on a cold cache;
    # the backends give the same run, test_simulate_on_either_backend_gives_the_same_run)
    common = ("simulate", "--model", "plane", "--gait", "3", "--duration", DURATION, "--sample-dt", SAMPLE_DT,
              "--backend", "numpy")  # fmt: skip
    normal = rrrobot(*common, "--out", out / "normal.npz", "--plot", out / "normal.png")
    rrrobot(*common, "--swap-phase", "--out", out / "swapped.npz")
    return {
        "normal": dict(np.load(out / "normal.npz")),
        "swapped": dict(np.load(out / "swapped.npz")),
        "plot": out / "normal.png",
        "stdout": normal.stdout,
    }


@pytest.mark.slow
def test_simulate_writes_exactly_the_documented_arrays(gait3_runs):
    arrays = gait3_runs["normal"]
    assert set(arrays) == set(DOCUMENTED_ARRAYS)
    samples = round(DURATION / SAMPLE_DT) + 1
    for name, columns in DOCUMENTED_ARRAYS.items():
        expected = (samples,) if columns == 1 else (samples, columns)
        assert arrays[name].shape == expected, name
        assert np.all(np.isfinite(arrays[name])), name
    assert arrays["t"][0] == 0.0
    np.testing.assert_allclose(np.diff(arrays["t"]), SAMPLE_DT, rtol=1e-9)


@pytest.mark.slow
def test_simulate_attitude_arrays_agree(gait3_runs):
    arrays = gait3_runs["normal"]
    np.testing.assert_allclose(np.linalg.norm(arrays["quat"], axis=1), 1.0, atol=1e-12)
    # theta is the paper's ZXY angles of the same attitude: rebuilding the quaternion gives +-quat.
    rebuilt = dynamics.quat_from_paper_angles(arrays["theta"])
    sign = np.sign(np.sum(rebuilt * arrays["quat"], axis=1, keepdims=True))
    np.testing.assert_allclose(sign * rebuilt, arrays["quat"], atol=1e-12)
    assert np.ptp(arrays["theta"], axis=0).min() > 0.01  # all three angles move in Gait 3


@pytest.mark.slow
def test_simulate_body_rate_is_world_frame_and_moves_the_contact_point(gait3_runs):
    # Contact kinematics (paper eq. 2/4): xdot = r w_y, ydot = -r w_x with w in the WORLD frame.
    # The first 0.5 s are skipped: the legs leap to the gait's start there, faster than the sampling.
    arrays = gait3_runs["normal"]
    r = RobotParams().radius
    later = arrays["t"] >= 0.5
    t, w = arrays["t"][later], arrays["body_rate"][later]
    predicted_x = arrays["x"][later][0] + cumulative_trapezoid(r * w[:, 1], t, initial=0.0)
    predicted_y = arrays["y"][later][0] + cumulative_trapezoid(-r * w[:, 0], t, initial=0.0)
    np.testing.assert_allclose(predicted_x, arrays["x"][later], atol=2e-4)
    np.testing.assert_allclose(predicted_y, arrays["y"][later], atol=2e-4)
    # The same test with the body-frame rate fails by far more: the body tilts and turns.
    body_frame = np.einsum("nji,nj->ni", dynamics.rotation_matrix(arrays["quat"][later]), w)
    body_frame_y = arrays["y"][later][0] + cumulative_trapezoid(-r * body_frame[:, 0], t, initial=0.0)
    assert np.abs(body_frame_y - arrays["y"][later]).max() > 10 * 2e-4


@pytest.mark.slow
def test_swap_phase_mirrors_the_path_in_y(gait3_runs):
    normal, swapped = gait3_runs["normal"], gait3_runs["swapped"]
    assert np.ptp(normal["y"]) > 0.01
    np.testing.assert_allclose(swapped["x"], normal["x"], atol=1e-10)
    np.testing.assert_allclose(swapped["y"], -normal["y"], atol=1e-10)


@pytest.mark.slow
def test_simulate_prints_travel_and_draws_the_plot(gait3_runs):
    assert "moved" in gait3_runs["stdout"] and "turned" in gait3_runs["stdout"]
    assert gait3_runs["plot"].read_bytes()[:8] == PNG_SIGNATURE


@pytest.mark.parametrize(
    "args, problem",
    [
        (("--model", "moon", "--gait", "1"), "--model"),
        (("--model", "plane", "--gait", "4"), "--gait"),
        (("--model", "plane", "--gait", "1", "--duration", "-1"), "--duration"),
        (("--model", "plane", "--gait", "1", "--sample-dt", "0"), "--sample-dt"),
        (("--model", "plane", "--gait", "1", "--param", "mass_tip=-0.1"), "mass_tip"),
        (("--model", "pivot", "--gait", "1", "--param", "mass_bottom=-1"), "mass_bottom"),
        (("--model", "plane", "--gait", "1", "--kp", "-2"), "kp"),
        (("--model", "plane", "--gait", "1", "--timestep", "automatic"), "--timestep"),
        (("--model", "plane", "--gait", "1", "--timestep", "1/50"), "stability limit"),
        (("--model", "plane", "--gait", "1", "--backend", "fortran"), "--backend"),
        (("--model", "plane", "--gait", "1", "--integrator", "euler"), "--integrator"),
        # (tracebacks from numpy, cmath, matplotlib, the last after the run and its .npz)
        (("--model", "plane", "--gait", "1", "--duration", "1e300"), "samples, more than"),
        (("--model", "plane", "--gait", "1", "--kp", "1e305"), "fastest pole overflows"),
        (("--model", "plane", "--gait", "1", "--kd", "1e200"), "fastest pole overflows"),
        (("--model", "plane", "--gait", "1", "--duration", "1e300", "--sample-dt", "1e-300"), "samples, more than"),
        (("--model", "plane", "--gait", "1", "--param", "radius=1e300"), "mass matrix"),
        (("--model", "plane", "--gait", "1", "--plot", "figure.txt"), "--plot"),
        (("--model", "plane", "--gait", "1", "--plot", "/no-such-rrrobot-directory/figure.png"), "no directory"),
    ],
)
def test_bad_simulate_argument_is_one_clear_error(tmp_path, args, problem, capsys):
    # A later option wins in argparse, so a bad --duration in ``args`` overrides the short default.
    status, stderr = rrrobot_here(capsys, "simulate", "--duration", "1", *args, "--out", tmp_path / "run.npz")
    assert status == 2
    error_lines = [line for line in stderr.splitlines() if "error:" in line]
    assert len(error_lines) == 1 and problem in error_lines[0], stderr
    assert not (tmp_path / "run.npz").exists()


def test_simulate_takes_the_scene_derived_step(tmp_path, capsys):
    """--timestep auto with 100x stiffer gains: the auto step follows them, where the default
    1/300 s step would be refused as unstable."""
    stiff = ("simulate", "--model", "pivot", "--gait", "1", "--duration", "0.2", "--kp", "200", "--kd", "5")
    status, stderr = rrrobot_here(capsys, *stiff, "--out", tmp_path / "fixed.npz")
    assert status == 2 and "timestep='auto'" in stderr
    assert rrrobot_here(capsys, *stiff, "--timestep", "auto", "--out", tmp_path / "auto.npz")[0] == 0
    data = np.load(tmp_path / "auto.npz")
    assert data["t"][-1] == pytest.approx(0.2)
    # the stiff servo holds the legs closer to the gait's targets (measured: 0.45 of the default's lag)
    from rrrobot_gym.control import table2_gait

    later = data["t"] >= 0.1
    lag = np.abs(data["phi"][later] - table2_gait(1).angles(data["t"][later])).max()
    assert rrrobot_here(capsys, *stiff[:-4], "--out", tmp_path / "default.npz")[0] == 0
    default = np.load(tmp_path / "default.npz")
    assert lag < 0.6 * np.abs(default["phi"][later] - table2_gait(1).angles(default["t"][later])).max()



@pytest.mark.slow
def test_simulate_on_either_backend_gives_the_same_run(tmp_path, monkeypatch):
    import shutil

    from rrrobot_gym import compiled
    from rrrobot_gym.control import table2_gait
    from rrrobot_gym.simulation import SimConfig, advance, initial_state

    if not compiled.available():
        pytest.skip("numba is not installed")
    # the runs agree to the bit, so whether --backend took effect shows in numba's cache: a copy
    # of this process's (warm) cache, which a process that runs the stepper marks used, and only that
    advance(SimConfig(backend="numba"), initial_state(), 0.0, 0.05, table2_gait(2))
    # (the paper robot's stepper runs its specialised kernel, cached in a directory of its own)
    warm = compiled.cache_dir(None, compiled.specialised(SimConfig().robot, "plane"))
    cache = tmp_path / "cache" / "rrrobot_gym" / os.path.basename(warm)
    shutil.copytree(warm, cache, ignore=shutil.ignore_patterns("*.tmp.*"))  # (files numba is writing)
    os.utime(cache, (1e9, 1e9))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    runs = {}
    for backend in ("numpy", "numba"):
        result = rrrobot("simulate", "--model", "plane", "--gait", "2", "--duration", "1", "--backend", backend,
                         "--out", tmp_path / f"{backend}.npz")  # fmt: skip
        runs[backend] = np.load(tmp_path / f"{backend}.npz")
        assert (os.stat(cache).st_mtime > 1e9) == (backend == "numba"), backend
        assert "compiling" not in result.stderr
    assert runs["numba"]["x"][-1] != 0.0
    for key in runs["numpy"].files:
        assert np.array_equal(runs["numba"][key], runs["numpy"][key]), key


# ---------------------------------------------------------------- figures


@pytest.mark.slow
def test_figures_writes_the_panels_and_the_travel_summary(tmp_path):
    out = tmp_path / "figures"
    rrrobot("figures", "--out", out, "--duration", 3, "--backend", "numpy")  # (as simulate's runs above)
    png = (out / "contact_paths.png").read_bytes()
    assert png[:8] == PNG_SIGNATURE and len(png) < 300_000
    summary = json.loads((out / "summary.json").read_text())
    runs = {(run["gait"], run["model"]): run for run in summary["travel"]}
    assert set(runs) == {(g, m) for g in (1, 2, 3) for m in ("plane", "pivot")}
    # each summary is the travel of the run it names (the same run here, summarised alike)
    from rrrobot_gym.analysis import travel_summary
    from rrrobot_gym.control import table2_gait
    from rrrobot_gym.simulation import SimConfig, simulate

    for gait, model in ((1, "plane"), (3, "pivot")):
        core = simulate(SimConfig(model=model), table2_gait(gait), 3.0, sample_dt=summary["settings"]["sample_dt_s"])
        expected = travel_summary(core.times, core.x, core.y, table2_gait(gait).period)
        assert {key: runs[(gait, model)][key] for key in expected} == pytest.approx(expected, rel=1e-9, abs=1e-12)
    # Gait 1 sets off sideways (along Y) even in 3 s: the summary belongs to the runs it names.
    for model in ("plane", "pivot"):
        assert abs(runs[(1, model)]["dy_m"]) > 5 * abs(runs[(1, model)]["dx_m"])
    assert len(summary["table1"]) == 4
    text = (out / "summary.txt").read_text()
    assert "Table I" in text and "turning" in text


@pytest.mark.slow
def test_plot_without_matplotlib_says_what_to_install(tmp_path):
    # sys.modules[name] = None makes "import matplotlib" fail as if it were not installed.
    script = (
        "import sys; sys.modules['matplotlib'] = None; from rrrobot_gym.cli import main; "
        f"sys.exit(main(['simulate', '--model', 'plane', '--gait', '1', '--duration', '1', "
        f"'--out', {str(tmp_path / 'run.npz')!r}, '--plot', {str(tmp_path / 'run.png')!r}]))"
    )
    env = {**os.environ, "PYTHONPATH": str(REPO_ROOT)}
    result = subprocess.run([sys.executable, "-c", script], cwd=REPO_ROOT, env=env, capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert "pip install rrrobot_gym[plots]" in result.stderr
    assert not (tmp_path / "run.png").exists()


@pytest.mark.parametrize("spec, option", [("model=pivot", "--model"), ("reset-noise-scale=0", "--reset-noise-scale")])
def test_gait_search_env_refuses_a_keyword_set_by_an_option_of_its_own(spec, option, capsys):
    from rrrobot_gym.cli import build_parser

    required = ["gait-search", "--model", "plane", "--out", "gaits.json"]
    with pytest.raises(SystemExit):
        build_parser().parse_args([*required, "--env", spec])
    assert f"set {spec.split('=')[0].replace('-', '_')} with {option}, not --env" in capsys.readouterr().err
    assert build_parser().parse_args([*required, "--env", "max_slip_velocity=0.05"]).env == [("max_slip_velocity", 0.05)]


@pytest.mark.parametrize("argv, module, extra", [
    (["shape-study", "--out-dir", "OUT"], "cma", "search"),
    (["shape-study", "--out-dir", "OUT"], "matplotlib", "plots"),
    (["gait-search", "--model", "plane", "--out", "OUT/g.json"], "cma", "search"),
    (["export-onnx", "agents/pretrained/best_model.zip", "--out", "OUT/p.onnx"], "onnx", "train"),
    (["video", "--gait", "1", "--out", "OUT/v.gif"], "imageio", "video"),
])  # fmt: skip
def test_a_missing_extra_is_named_with_its_install_command_before_any_work(argv, module, extra, tmp_path, monkeypatch,
                                                                           capsys):
    monkeypatch.setitem(sys.modules, module, None)  # (import then raises ImportError)
    command = argv[0]
    status, err = rrrobot_here(capsys, *[a.replace("OUT", str(tmp_path)) for a in argv])
    assert status == 2
    assert f"{command} needs {module}: pip install 'rrrobot_gym[{extra}]'" in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []  # nothing written
