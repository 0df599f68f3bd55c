"""What the shell's shape and the leg count do to speed: the best searched gait of each family member.

The paper's closing question ("the influence of body shape on the translation", "more legs"),
answered the way the project answers every speed question: each member gets the same gait search
(:func:`rrrobot_gym.gait_search.search`, objective "own", 50 s from the paper's start: :data:`SEARCH`),
the same number of gaits scored with the same seeds, so the machine's load cannot favour one, on the
plane at the paper's masses and the default servo; its best gait is re-scored on starts the search
never saw. Members:

- shells of semi-axes (a, a, c), a = 0.12 m (the paper's radius), for each ratio c/a in ``ratios``
  (c/a < 1 oblate, 1 the paper's sphere, > 1 prolate), with the paper's two legs;
- the sphere with each leg count in ``leg_counts`` (the default rim placement,
  :func:`rrrobot_gym.params.default_legs`).

Only the shape changes along the first axis: the point masses stay the paper's (the bottom mass
at the shell's bottom, (0, 0, -c); the pins on the rim). Along the second each leg brings its own pin
and tip masses, so a four-leg robot is heavier by two legs' 0.22 kg.

    rrrobot shape-study --evaluations 8000 --seeds 0,1 --out-dir docs/studies/shape

writes ``summary.json`` (schema ``rrrobot_gym.shape_study/1``: the command, the wall time, one row a
member), each member's search file under ``gaits/`` (usable by evaluate.py and train.py's
``--bar-from``) and ``speed.png``: the best gait's speed against c/a and against the leg count.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from . import gait_search
from .analysis import json_safe
from .params import leg_count, whole_number

SCHEMA = "rrrobot_gym.shape_study/1"
RADIUS = 0.12
"""m, the paper's shell radius: every shell's equatorial semi-axes a = b."""
DEFAULT_RATIOS = (0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.4)
"""c/a of the shells studied: oblate to prolate through the paper's sphere."""
DEFAULT_LEG_COUNTS = (2, 3, 4)


def members(ratios=DEFAULT_RATIOS, leg_counts=DEFAULT_LEG_COUNTS) -> list:
    """The members studied, in order: (label, env keywords, c/a, leg count); the sphere with two legs
    once, as a member of both axes."""
    ratios, leg_counts = _ratios(ratios), _leg_counts(leg_counts)
    rows = []
    for ratio in ratios:
        kwargs = {} if ratio == 1.0 else {"shell_axes": (RADIUS, RADIUS, round(RADIUS * ratio, 12))}
        rows.append((f"c{ratio:g}-legs2", kwargs, ratio, 2))
    for legs in leg_counts:
        if legs == 2 and 1.0 in ratios:
            continue
        rows.append((f"c1-legs{legs}", {} if legs == 2 else {"num_legs": legs}, 1.0, legs))
    return rows


def _ratios(ratios) -> tuple:
    out = []
    for r in ratios:
        if isinstance(r, bool) or not isinstance(r, (int, float)) or not (math.isfinite(r) and 0.2 <= r <= 5.0):
            raise ValueError(f"a shell ratio c/a must be a number from 0.2 to 5, got {r!r}")
        out.append(float(r))
    if len(set(out)) < len(out):
        raise ValueError(f"shell ratios repeat: {ratios!r}")
    return tuple(out)


def _leg_counts(counts) -> tuple:
    out = []
    for n in counts:
        out.append(leg_count("a leg count", n, 2, "one leg needs timestep='auto', which the study does not mix in"))
    if len(set(out)) < len(out):
        raise ValueError(f"leg counts repeat: {counts!r}")
    return tuple(out)


SEARCH = {"model": "plane", "objective": "own", "duration": 50.0, "reset_noise_scale": 0.0, "start_seeds": (0,)}
"""How every member is searched: evaluate.py's measure, 50 s from the paper's start along the gait's own
net displacement (a 20 s score favours gaits whose paths curve away later)."""


PAPER_GAIT = (1.2923140189181521, 1.2935326613230382, 1.5624350270526661, 1.5770883514697918, 7.50093865244074,
              1.6602917580753251)  # fmt: skip
"""The paper's robot's best searched gait on this measure (``agents/searched/plane_own_50s.json``,
84.8 mm/s towards 269 deg): every member's search scores it, carried over to its legs
(:func:`start_gait`), before its random screen, so that each search begins at least where the
paper's robot stands and the members differ by their shape, not by the luck of a screen."""


def start_gait(num_legs: int) -> np.ndarray:
    """:data:`PAPER_GAIT` on ``num_legs`` legs placed by default: with an even count the legs at -90
    and +90 deg (the paper's two) swing as the paper's and the others rest upright (a = 0, o = pi/2);
    with an odd one (no leg at +90 deg) leg 1 swings as the paper's leg 1 and every other as its leg 2."""
    a1, a2, o1, o2, w, gap = PAPER_GAIT
    amplitudes, offsets, phases = [0.0] * num_legs, [0.5 * math.pi] * num_legs, [0.0] * num_legs
    amplitudes[0], offsets[0] = a1, o1
    others = [num_legs // 2] if num_legs % 2 == 0 else range(1, num_legs)
    for k in others:
        amplitudes[k], offsets[k], phases[k] = a2, o2, gap
    return np.array([*amplitudes, *offsets, w, *phases[1:]])


def run(out_dir, *, ratios=DEFAULT_RATIOS, leg_counts=DEFAULT_LEG_COUNTS, evaluations: int = 8000,
        seeds=(0, 1), progress=None, command: str | None = None) -> dict:  # fmt: skip
    """Search every member (:func:`members`) with each of ``seeds``, ``evaluations`` gaits a search,
    and write the study into ``out_dir``; returns the summary (the JSON's contents). A member's speed
    is its best search's best gait re-scored on 8 new noisy starts, 50 s each (mean along the gait's
    own direction). ``progress(line)`` hears each member's result."""
    evaluations = whole_number("evaluations", evaluations)
    seeds = tuple(whole_number("seed", seed, minimum=0) for seed in seeds)
    if not seeds:
        raise ValueError("give at least one search seed")
    rows = members(ratios, leg_counts)
    out_dir = Path(out_dir)
    (out_dir / "gaits").mkdir(parents=True, exist_ok=True)
    began = time.perf_counter()
    results = []
    for label, kwargs, ratio, legs in rows:
        searches = []
        for seed in seeds:
            result = gait_search.search(budget_evaluations=evaluations, seed=seed, name=f"{label}-seed{seed}", keep=1,
                                        start=start_gait(legs), progress=False, command=command, **SEARCH,
                                        **kwargs)  # fmt: skip
            result.write_json(out_dir / "gaits" / f"{label}-seed{seed}.json")
            searches.append((seed, result))
        by_seed = {seed: result.gaits[0]["robustness"]["mean_speed_mps"] for seed, result in searches}
        seed, result = max(searches, key=lambda item: (item[1].gaits[0]["robust"], by_seed[item[0]]))
        best = result.gaits[0]
        robust = best["robustness"]
        row = {
            "member": label, "c_over_a": ratio, "num_legs": legs,
            "shell_axes": list(kwargs.get("shell_axes", (RADIUS,) * 3)),
            "speed_mps": robust["mean_speed_mps"], "worst_start_speed_mps": robust["min_speed_mps"],
            "paper_start_speed_mps": robust["paper_start_speed_mps"], "direction_deg": best["direction_deg"],
            "robust": best["robust"], "speed_by_seed_mps": {str(k): v for k, v in by_seed.items()},
            "peak_torque_nm": robust["peak_torque_nm"], "peak_leg_rate_radps": robust["peak_leg_rate_radps"],
            "gait": best["parameters"], "gait_file": f"gaits/{label}-seed{seed}.json",
            "search_seconds": sum(r.used["seconds"] for _, r in searches),
        }  # fmt: skip
        results.append(row)
        if progress is not None:
            progress(f"{label}: {1e3 * row['speed_mps']:.1f} mm/s (seeds: "
                     + ", ".join(f"{1e3 * v:.1f}" for v in by_seed.values())
                     + f"; {'robust' if row['robust'] else 'NOT robust'}, {row['search_seconds']:.0f} s)")
    summary = {
        "schema": SCHEMA, "command": command, "wall_seconds": round(time.perf_counter() - began, 1),
        **{k: list(v) if isinstance(v, tuple) else v for k, v in SEARCH.items()},
        "evaluations_per_search": evaluations, "seeds": list(seeds),
        "start": "every search scores the paper robot's best gait on its legs first (shape_study.start_gait)",
        "speed": "the best search's best gait, re-scored from 8 new starts (noise 0.01) for 50 s: mean speed "
                 "along the gait's own direction",
        "members": results,
    }  # fmt: skip
    gait_search.write_json(out_dir / "summary.json", json_safe(summary))
    plot_summary(summary, out_dir / "speed.png")
    return summary


def plot_summary(summary: dict, path) -> None:
    """speed.png: the best gait's speed against c/a (two legs) and against the leg count (the sphere)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = summary["members"]
    shells = sorted((r for r in rows if r["num_legs"] == 2), key=lambda r: r["c_over_a"])
    legs = sorted((r for r in rows if r["c_over_a"] == 1.0), key=lambda r: r["num_legs"])
    fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.6), sharey=True)
    for ax, group, key, label in ((left, shells, "c_over_a", "shell c/a (a = b = 0.12 m; 1: the paper's sphere)"),
                                  (right, legs, "num_legs", "legs on the sphere")):  # fmt: skip
        x = [r[key] for r in group]
        ax.plot(x, [1e3 * r["speed_mps"] for r in group], "o-", label="mean over new starts")
        ax.plot(x, [1e3 * r["worst_start_speed_mps"] for r in group], "v:", label="worst start")
        ax.set_xlabel(label)
        ax.grid(alpha=0.3)
    right.set_xticks([r["num_legs"] for r in legs])
    left.axvline(1.0, color="0.6", lw=0.8)
    left.set_ylabel("best searched gait's speed (mm/s)")
    left.legend(fontsize=8)
    fig.suptitle(f"RRRobot family on the plane: {len(summary['seeds'])} searches of {summary['evaluations_per_search']:,} gaits a member",
                 fontsize=10)  # fmt: skip
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
