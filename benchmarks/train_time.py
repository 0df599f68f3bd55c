"""Wall time of ``python train.py`` on each simulator backend, side by side.

    python -m benchmarks.train_time [--steps 262144] [--rounds 2] [--quick] [--json FILE]

Runs train.py with its defaults (the same PPO settings, batch of 64 robots, evaluation every
250,000 steps) for ``--steps`` env steps, once per backend per round, alternating numpy and
numba in fresh processes so both see the same machine; the whole process is timed (imports,
numba's compilation or cache load, the evaluations, saving). Reports the median seconds per
backend, their ratio, and the default run's steps (train.py's default --total-timesteps)
projected at that rate.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from rrrobot_gym import compiled

from ._common import machine, markdown_table, parser, write_json

HERE = Path(__file__).resolve().parents[1]


def default_run_steps() -> int:
    """train.py's default --total-timesteps."""
    sys.path.insert(0, str(HERE))
    from train import Args

    return Args().total_timesteps


def run(backend: str, steps: int, runs_dir: str) -> float:
    """Seconds for one ``train.py`` run of ``steps`` env steps on ``backend``."""
    command = [sys.executable, "train.py", "--total-timesteps", str(steps), "--backend", backend,
               "--runs-dir", runs_dir, "--no-progress-bar", "--exp-name", f"bench-{backend}"]  # fmt: skip
    start = time.perf_counter()
    subprocess.run(command, cwd=HERE, check=True, capture_output=True, text=True)
    return time.perf_counter() - start


def main(argv=None):
    p = parser(__doc__.split("\n\n")[0])
    p.add_argument("--steps", type=int, default=262_144, help="env steps per run (16 rollouts of 64 x 256)")
    p.add_argument("--rounds", type=int, default=2, help="runs per backend, alternating")
    args = p.parse_args(argv)
    if not compiled.available():
        p.error("numba is not installed: pip install 'rrrobot_gym[fast]'")
    steps, rounds = (16_384, 1) if args.quick else (args.steps, args.rounds)
    seconds = {"numpy": [], "numba": []}
    with tempfile.TemporaryDirectory() as runs_dir:
        for i in range(rounds):
            for backend in ("numpy", "numba") if i % 2 == 0 else ("numba", "numpy"):
                seconds[backend].append(run(backend, steps, runs_dir))
                print(f"round {i + 1}: {backend} {seconds[backend][-1]:.1f} s", flush=True)
    median = {b: statistics.median(v) for b, v in seconds.items()}
    default_steps = default_run_steps()
    rows = [[b, f"{median[b]:.1f}", f"{steps / median[b]:,.0f}", f"{median[b] * default_steps / steps / 60:.0f}"]
            for b in ("numpy", "numba")]  # fmt: skip
    table = markdown_table(["backend", f"seconds for {steps:,} steps", "env steps/s",
                            f"{default_steps / 1e6:g} M steps (min, projected)"], rows)
    ratio = median["numpy"] / median["numba"]
    print(table)
    print(f"numba takes {1 / ratio:.2f}x the time of numpy ({ratio:.2f}x faster)")
    write_json(args.json, {"machine": machine(), "steps": steps, "seconds": seconds, "median": median,
                           "numpy_over_numba": ratio, "table": table})  # fmt: skip


if __name__ == "__main__":
    main()
