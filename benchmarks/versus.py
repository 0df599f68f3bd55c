"""Env throughput of this tree against another commit, side by side on this machine.

A machine's speed drifts (the shared 2-core machines here by tens of per cent within minutes),
so a change's effect on speed is measured against the tree before it, not against a figure
taken on another day. This checks the given commit out in a temporary git worktree and runs the
default ``gymnasium.make("RRRobot-v0")`` env (and ``make_vec`` at the given batch sizes) of both
trees in alternating fresh processes, so both see the same machine, and reports medians and
their ratio (this tree over the other):

    python -m benchmarks.versus main                                   # this tree against main
    python -m benchmarks.versus main --num-envs 64 4096 --json out.json  # and the vector env
    python -m benchmarks.versus HEAD~1 --instructions 201              # also instructions per env step
    python -m benchmarks.versus main --backend numpy                   # both trees on the numpy backend
    python -m benchmarks.versus main --model pivot                     # both trees' envs on the pivot model
    python -m benchmarks.versus HEAD --quick                           # a smoke run (one short round)

The tree measured as "this tree" is the working tree, uncommitted changes included. Each tree's
first process compiles its numba stepper (or loads its cache) before the timed steps.

Besides the ratio of the medians it reports the median of each round's ratio (the two trees' runs
of one round are neighbours in time, so a drift of the machine's speed cancels in their ratio) and
those ratios' range: a change smaller than the range is not shown by the run. ``--cpu K`` pins
every timed process to CPU K (Linux), so that none shares or changes its core.

``--instructions S`` also counts the instructions an env step takes in each tree under
valgrind's callgrind (runs of S steps and of 1 step, differenced): the same numbers whatever
else the machine is doing, so a ratio that does not drift with the machine's load. These runs
build numba's code for a generic x86-64 CPU (``NUMBA_CPU_NAME=generic``, SSE2 vectors: the same
work, narrower lanes than this CPU's build): numba keys its cache by the CPU it sees, and under
valgrind it would see another and compile again, under valgrind, for an hour. ``--backend`` and
``--model`` pass the env keywords ``backend`` and ``model`` to both trees.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from ._common import machine, write_json

HERE = Path(__file__).resolve().parents[1]

_MEASURE = r"""
import json, sys, time
import numpy as np
import gymnasium
import rrrobot_gym  # noqa: F401
print("rrrobot_gym", rrrobot_gym.__file__)
num_envs, steps = int(sys.argv[1]), int(sys.argv[2])
kwargs = json.loads(sys.argv[3]) if len(sys.argv) > 3 else {}
rng = np.random.default_rng(0)
if num_envs == 0:
    env = gymnasium.make("RRRobot-v0", **kwargs)
    shape = (2,)
else:
    env = gymnasium.make_vec("RRRobot-v0", num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)
    shape = (num_envs, 2)
phase = rng.uniform(0, 2 * np.pi, shape)
actions = [(0.05 * np.sin(0.4 * k + phase)).astype(np.float32) for k in range(steps)]
env.reset(seed=0)
for action in actions[:20]:
    env.step(action)
env.reset(seed=0)
start = time.perf_counter()
for action in actions:
    env.step(action)
print(max(num_envs, 1) * steps / (time.perf_counter() - start))
"""


def run_fresh(tree: Path, *args, prefix=(), cpu=None, **env) -> subprocess.CompletedProcess:
    """_MEASURE with ``args`` in a fresh process importing ``tree``'s rrrobot_gym, with one BLAS
    thread (``prefix``: a command to run it under, e.g. valgrind; ``cpu``: the one CPU it may run
    on; ``env``: more variables). Raises RuntimeError with the process's error output if it fails,
    or if it imported another tree's rrrobot_gym (an installed copy shadowing ``tree``)."""
    variables = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1", **env}
    pin = None if cpu is None else (lambda: os.sched_setaffinity(0, {cpu}))
    out = subprocess.run([*prefix, sys.executable, "-c", _MEASURE, *map(str, args)], cwd=tree, env=variables,
                         capture_output=True, text=True, preexec_fn=pin)  # fmt: skip
    if out.returncode != 0:
        raise RuntimeError(f"the env of {tree} failed (exit {out.returncode}):\n{out.stderr[-3000:]}")
    imported = Path(out.stdout.split("rrrobot_gym ", 1)[1].split()[0]).resolve()
    if not imported.is_relative_to(tree.resolve()):
        raise RuntimeError(f"the process for {tree} imported {imported}, not that tree's rrrobot_gym")
    return out


def rate(tree: Path, num_envs: int, steps: int, backend=None, cpu=None, model=None) -> float:
    """Env steps/s of ``tree``'s env in a fresh process (num_envs 0: the single gymnasium.make env;
    ``backend``, ``model``: the env's, else its defaults; ``cpu``: the CPU to pin it to)."""
    return float(run_fresh(tree, num_envs, steps, *_keywords(backend, model), cpu=cpu).stdout.split()[-1])


def _keywords(backend, model=None):
    """_MEASURE's env keywords argument: none, or a JSON object of those given."""
    given = {name: value for name, value in (("backend", backend), ("model", model)) if value is not None}
    return (json.dumps(given),) if given else ()


def instructions(tree: Path, num_envs: int, steps: int, backend=None, model=None) -> float:
    """Instructions per env step of ``tree``'s env (num_envs 0: the single env) under callgrind:
    runs of ``steps`` and of 1 timed step, differenced, so imports and start-up cancel."""

    generic = {"NUMBA_CPU_NAME": "generic", "PYTHONHASHSEED": "0"}
    run_fresh(tree, num_envs, 1, *_keywords(backend, model), **generic)  # builds (or loads) the generic code natively

    def collected(n: int) -> int:
        out = run_fresh(tree, num_envs, n, *_keywords(backend, model),
                        prefix=("valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null"), **generic)  # fmt: skip
        match = re.search(r"Collected : (\d+)", out.stderr)
        if match is None:
            raise RuntimeError(f"no instruction count in valgrind's output:\n{out.stderr[-2000:]}")
        return int(match.group(1))

    return (collected(steps) - collected(1)) / ((steps - 1) * max(num_envs, 1))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("revision", help="the commit to compare with (anything git rev-parse takes)")
    parser.add_argument("--num-envs", type=int, nargs="*", default=[], help="make_vec batch sizes besides the single env")
    parser.add_argument("--steps", type=int, help="env steps per timed run (default 400; --quick 50)")
    parser.add_argument("--rounds", type=int, help="alternating runs of each tree, for medians (default 5; --quick 1)")
    parser.add_argument("--json", metavar="FILE", help="write the results as JSON")
    parser.add_argument("--quick", action="store_true", help="one round of 50 steps (a smoke run; medians need more)")
    parser.add_argument("--instructions", type=int, metavar="S",
                        help="also count instructions per env step under valgrind, from runs of S and 1 steps")
    parser.add_argument("--cpu", type=int, metavar="K", help="pin every timed process to CPU K (Linux)")
    parser.add_argument("--backend", choices=("auto", "numpy", "numba"),
                        help="the simulator backend of both trees' envs (default: each tree's own default)")
    parser.add_argument("--model", choices=("plane", "pivot"), help="the dynamic model of both trees' envs (default: the env's, plane)")
    args = parser.parse_args(argv)
    if args.steps is None:
        args.steps = 50 if args.quick else 400
    if args.rounds is None:
        args.rounds = 1 if args.quick else 5
    if args.instructions is not None:
        if args.instructions < 2:
            parser.error("--instructions must be at least 2 steps")
        if shutil.which("valgrind") is None:
            parser.error("--instructions needs valgrind on the PATH")
    for name in ("steps", "rounds"):
        if getattr(args, name) < 1:
            parser.error(f"--{name} must be a positive integer")
    if any(n < 1 for n in args.num_envs):
        parser.error("--num-envs must be positive integers")
    if args.cpu is not None:
        if not hasattr(os, "sched_getaffinity"):
            parser.error("--cpu needs a system that pins processes to CPUs (Linux)")
        allowed = os.sched_getaffinity(0)
        if args.cpu not in allowed:
            parser.error(f"--cpu must be one of the CPUs this process may use, {sorted(allowed)}; got {args.cpu}")
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        old = Path(tmp) / "old"
        added = subprocess.run(["git", "worktree", "add", "--detach", str(old), args.revision], cwd=HERE,
                               capture_output=True, text=True)  # fmt: skip
        if added.returncode != 0:
            parser.error(f"cannot check out {args.revision!r}: {added.stderr.strip()}")
        try:
            for num_envs in [0, *args.num_envs]:
                rates = {"old": [], "new": []}
                for _ in range(args.rounds):
                    rates["old"].append(rate(old, num_envs, args.steps, args.backend, args.cpu, args.model))
                    rates["new"].append(rate(HERE, num_envs, args.steps, args.backend, args.cpu, args.model))
                old_median, new_median = statistics.median(rates["old"]), statistics.median(rates["new"])
                paired = [b / a for a, b in zip(rates["old"], rates["new"])]
                results.append({"env": "single" if num_envs == 0 else "vector", "num_envs": max(num_envs, 1),
                                "old_steps_per_s": old_median, "new_steps_per_s": new_median,
                                "ratio": new_median / old_median, "paired_ratio_median": statistics.median(paired),
                                "paired_ratio_range": [min(paired), max(paired)], "rounds": rates})  # fmt: skip
                print(f"{results[-1]['env']:>6} N={max(num_envs, 1):<5} {args.revision}: {old_median:9,.0f}  "
                      f"this tree: {new_median:9,.0f} env steps/s  ratio {new_median / old_median:.2f}  "
                      f"(round by round {statistics.median(paired):.2f}, {min(paired):.2f}-{max(paired):.2f})", flush=True)
                if args.instructions is not None:
                    counts = {name: instructions(tree, num_envs, args.instructions, args.backend, args.model)
                              for name, tree in (("old", old), ("new", HERE))}  # fmt: skip
                    results[-1]["instructions_per_env_step"] = counts
                    print(f"{'':>6} {'':<7} {args.revision}: {counts['old']:11,.0f}  this tree: "
                          f"{counts['new']:11,.0f} instructions an env step  ratio "
                          f"{counts['old'] / counts['new']:.3f}", flush=True)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(old)], cwd=HERE, capture_output=True)
    write_json(args.json, {"machine": machine(), "revision": args.revision, "steps": args.steps,
                           "backend": args.backend, "model": args.model, "cpu": args.cpu, "results": results})  # fmt: skip


if __name__ == "__main__":
    main()
