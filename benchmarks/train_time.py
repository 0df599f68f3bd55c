"""Wall time of ``python train.py`` on each simulator backend, or with one torch thread or two, side by side.

    python -m benchmarks.train_time [--steps 262144] [--rounds 2] [--quick] [--json FILE] [--threads]

Runs train.py with its defaults (its PPO settings, batch of robots and evaluation cadence) for
``--steps`` env steps, once per backend per round, alternating numpy and numba in fresh processes
so both see the same machine; the whole process is timed (imports, numba's compilation or cache
load, the evaluations, saving). Reports the median seconds per backend, their ratio, and the
default run's steps (train.py's default --total-timesteps) projected at that rate.

``--threads`` compares ``--torch-threads 1`` with ``--torch-threads 2`` instead (torch's threads
for PPO's updates, train.threads_for_updates), both on the default backend, and says whether
the two runs' final models are the same to the bit.
"""

from __future__ import annotations

import hashlib
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

from rrrobot_gym import compiled

from ._common import machine, markdown_table, parser, write_json

HERE = Path(__file__).resolve().parents[1]


def default_run_steps() -> int:
    """train.py's default --total-timesteps."""
    from rrrobot_gym.training import Args

    return Args().total_timesteps


def run(setting: str, steps: int, runs_dir: str) -> float:
    """Seconds for one ``train.py`` run of ``steps`` env steps on a backend (``setting``
    "numpy"/"numba") or with that many torch threads (``setting`` "1"/"2")."""
    flags = ["--torch-threads", setting] if setting.isdigit() else ["--backend", setting]
    command = [sys.executable, "train.py", "--total-timesteps", str(steps), *flags,
               "--runs-dir", runs_dir, "--no-progress-bar", "--exp-name", f"bench-{setting}"]  # fmt: skip
    start = time.perf_counter()
    subprocess.run(command, cwd=HERE, check=True, capture_output=True, text=True)
    return time.perf_counter() - start


def final_policies(runs_dir: str, setting: str) -> set:
    """sha256 of the final policy weights of each run of ``setting`` in ``runs_dir``."""
    return {hashlib.sha256(zipfile.ZipFile(path).read("policy.pth")).hexdigest()
            for path in Path(runs_dir).glob(f"*__bench-{setting}__*/final_model.zip")}  # fmt: skip


def main(argv=None):
    p = parser(__doc__.split("\n\n")[0])
    p.add_argument("--steps", type=int, default=262_144, help="env steps per run (16 rollouts of 64 x 256)")
    p.add_argument("--rounds", type=int, default=2, help="runs per setting, alternating")
    p.add_argument("--threads", action="store_true", help="--torch-threads 1 against 2 instead of the backends")
    args = p.parse_args(argv)
    if not args.threads and not compiled.available():
        p.error("numba is not installed: pip install 'rrrobot_gym[fast]'")
    steps, rounds = (16_384, 1) if args.quick else (args.steps, args.rounds)
    settings = ("1", "2") if args.threads else ("numpy", "numba")
    seconds = {setting: [] for setting in settings}
    with tempfile.TemporaryDirectory() as runs_dir:
        for i in range(rounds):
            for setting in settings if i % 2 == 0 else settings[::-1]:
                seconds[setting].append(run(setting, steps, runs_dir))
                print(f"round {i + 1}: {setting} {seconds[setting][-1]:.1f} s", flush=True)
        policies = {setting: final_policies(runs_dir, setting) for setting in settings}
    median = {b: statistics.median(v) for b, v in seconds.items()}
    default_steps = default_run_steps()
    rows = [[b, f"{median[b]:.1f}", f"{steps / median[b]:,.0f}", f"{median[b] * default_steps / steps / 60:.0f}"]
            for b in settings]  # fmt: skip
    table = markdown_table(["torch threads for updates" if args.threads else "backend", f"seconds for {steps:,} steps",
                            "env steps/s", f"{default_steps / 1e6:g} M steps (min, projected)"], rows)  # fmt: skip
    ratio = median[settings[0]] / median[settings[1]]
    print(table)
    payload = {"machine": machine(), "steps": steps, "seconds": seconds, "median": median, "table": table}
    if args.threads:
        same = len(policies["1"] | policies["2"]) == 1
        print(f"two threads take {1 / ratio:.2f}x the time of one; final models the same to the bit: {same}")
        payload.update(one_over_two_threads=ratio, same_final_model=same)
    else:
        print(f"numba takes {1 / ratio:.2f}x the time of numpy ({ratio:.2f}x faster)")
        payload["numpy_over_numba"] = ratio
    write_json(args.json, payload)


if __name__ == "__main__":
    main()
