"""The package as a user installs it: a wheel built from this tree, run outside the repository."""

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # (a wheel built and installed)

REPO = Path(__file__).resolve().parents[1]


def test_the_wheel_holds_every_module_and_runs_the_env_outside_the_repository(tmp_path):
    # Built as pip builds it for a user (in isolation, with the setuptools pyproject.toml asks
    # for), from a copy of what the wheel is made of, so setuptools' build/ directory neither
    # lands in the tree nor carries a module over from an earlier build.
    source = tmp_path / "source"
    shutil.copytree(REPO / "rrrobot_gym", source / "rrrobot_gym", ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(REPO / name, source / name)
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path), str(source)],
        capture_output=True, text=True, timeout=600,
    )
    assert build.returncode == 0, build.stderr
    (wheel,) = tmp_path.glob("rrrobot_gym-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    modules = {str(p.relative_to(REPO)) for p in (REPO / "rrrobot_gym").rglob("*.py")}
    assert modules <= names, sorted(modules - names)
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    script = (
        "import sys; sys.path.insert(0, sys.argv[1])\n"
        "import gymnasium, numpy as np, rrrobot_gym\n"
        "assert rrrobot_gym.__file__.startswith(sys.argv[1]), rrrobot_gym.__file__\n"
        "env = gymnasium.make('RRRobot-v0', backend='numpy'); env.reset(seed=0)  # (numba: compiled elsewhere)\n"
        "for _ in range(20): obs, *_ = env.step(np.array([0.5, -0.5]))\n"
        "assert np.isfinite(obs).all() and obs.shape == (15,)\n"
        "print(rrrobot_gym.simulation.simulate(rrrobot_gym.simulation.SimConfig(backend='numpy'), rrrobot_gym.control.table2_gait(1), 1.0).x[-1])\n"
    )
    run = subprocess.run([sys.executable, "-c", script, str(site)], capture_output=True, text=True, timeout=300,
                         cwd=tmp_path)  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert abs(float(run.stdout.split()[-1])) > 1e-3  # Gait 1 moved the robot in its first second
