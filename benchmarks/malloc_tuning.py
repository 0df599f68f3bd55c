"""What glibc's malloc settings do to a large batch: time and resident memory, in fresh processes.

    python -m benchmarks.malloc_tuning [--quick] [--json FILE] [--num-envs 4096] [--rounds 5]

``advance`` tunes glibc's malloc once per process for batches of >= 1024 robots
(``simulation._keep_freed_heap``: trim threshold raised to the working set, mmap threshold
32 MiB, both left in place). The tuning cannot be undone inside a process (setting any threshold
turns glibc's dynamic mmap threshold off for good), so each setting runs in its own fresh
process, the settings alternating round by round:

- ``tuned``: the shipped behaviour;
- ``untuned``: ``_keep_freed_heap`` a no-op, glibc's defaults (trim 128 KiB, dynamic mmap threshold);
- ``dynamic off``: untuned, but with the trim threshold set once to its default 128 KiB through
  mallopt, which is the state the earlier put-back code left glibc in between integrations
  (every array >= 128 KiB mmapped and page-faulted afresh).

Each process builds ``make_vec("RRRobot-v0", num_envs=N)`` (checks on), times env steps of
small sinusoidal actions, then ``validity.step_measures`` on one recorded step, and reads its
resident memory (VmRSS now, VmHWM the peak) from /proc/self/status. Linux and glibc only.
Medians over rounds.
"""

from __future__ import annotations

import json
import statistics
import sys
from pathlib import Path

from ._common import machine, markdown_table, parser, run_fresh, write_json

HERE = Path(__file__).resolve().parents[1]
SETTINGS = ("tuned", "untuned", "dynamic off")

_MEASURE = r"""
import ctypes, json, sys, time
import numpy as np
import gymnasium
import rrrobot_gym
from rrrobot_gym import simulation, validity
from rrrobot_gym.control import RampTargets
from rrrobot_gym.envs import task

setting, num_envs, steps = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
if setting != "tuned":
    simulation._keep_freed_heap = lambda num_robots: None
if setting == "dynamic off":
    ctypes.CDLL(None).mallopt(simulation._M_TRIM_THRESHOLD, ctypes.c_int(128 * 1024))  # glibc's default value
env = gymnasium.make_vec("RRRobot-v0", num_envs=num_envs, vectorization_mode="vector_entry_point")
rng = np.random.default_rng(0)
phase = rng.uniform(0, 2 * np.pi, (num_envs, 2))
actions = [(0.05 * np.sin(0.4 * k + phase)).astype(np.float32) for k in range(steps + 5)]
env.reset(seed=0)
for action in actions[:5]:
    env.step(action)
start = time.perf_counter()
for action in actions[5:]:
    env.step(action)
rate = num_envs * steps / (time.perf_counter() - start)
inner = env.unwrapped
config = inner.config
held = RampTargets(inner.leg_targets, inner.leg_targets + 0.01, 0.0, config.dt)
_, record = simulation.advance(config.sim, inner.states, 0.0, config.dt, held, check=False, record=True)
times = []
for _ in range(15):
    t = time.perf_counter()
    validity.step_measures(record, config.sim, config.friction_coefficient, np.zeros(num_envs))
    times.append(time.perf_counter() - t)
status = dict(line.split(":", 1) for line in open("/proc/self/status").read().splitlines() if ":" in line)
kib = lambda key: int(status[key].split()[0])
print(json.dumps({"env_steps_per_s": rate, "step_measures_ms": 1e3 * float(np.median(times)),
                  "rss_mb": kib("VmRSS") / 1024, "peak_rss_mb": kib("VmHWM") / 1024}))
"""


def measure(setting: str, num_envs: int, steps: int) -> dict:
    """One fresh process under ``setting``: its env rate, step_measures time and memory."""
    return json.loads(run_fresh(HERE, _MEASURE, setting, num_envs, steps).stdout.strip().splitlines()[-1])


def main(argv=None) -> None:
    p = parser(__doc__.split("\n\n")[0])
    p.add_argument("--num-envs", type=int, default=4096, help="robots in the batch (tuning starts at 1024)")
    p.add_argument("--rounds", type=int, default=5, help="fresh processes per setting (medians)")
    args = p.parse_args(argv)
    if not sys.platform.startswith("linux"):
        p.error("malloc_tuning measures glibc's malloc: Linux only")
    if args.num_envs < 1 or args.rounds < 1:
        p.error("--num-envs and --rounds must be positive integers")
    rounds, steps = (1, 10) if args.quick else (args.rounds, 40)
    runs = {setting: [] for setting in SETTINGS}
    for _ in range(rounds):
        for setting in SETTINGS:
            runs[setting].append(measure(setting, args.num_envs, steps))
    keys = ("env_steps_per_s", "step_measures_ms", "rss_mb", "peak_rss_mb")
    medians = {s: {k: statistics.median(run[k] for run in runs[s]) for k in keys} for s in SETTINGS}
    tuned = medians["tuned"]["env_steps_per_s"]
    rows = [[s, f"{m['env_steps_per_s']:,.0f}", f"{m['env_steps_per_s'] / tuned:.2f}", f"{m['step_measures_ms']:.2f}",
             f"{m['rss_mb']:.0f}", f"{m['peak_rss_mb']:.0f}"] for s, m in medians.items()]  # fmt: skip
    print(f"N = {args.num_envs}, {steps} env steps a process, medians of {rounds}:")
    print(markdown_table(["setting", "env steps/s", "vs tuned", "step_measures (ms)", "RSS (MB)", "peak RSS (MB)"], rows))
    write_json(args.json, {"machine": machine(), "num_envs": args.num_envs, "steps": steps, "rounds": rounds,
                           "medians": medians, "runs": runs})  # fmt: skip


if __name__ == "__main__":
    main()
