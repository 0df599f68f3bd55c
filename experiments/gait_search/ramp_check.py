"""Does a swing ramped in from rest keep a searched gait inside the model on new starts?

    python experiments/gait_search/ramp_check.py experiments/gait_search/no_ramp_8starts.json \
        --ramps 0 0.5 1 2 --seeds 16

Runs the file's best gait for 50 s from ``--seeds`` start-noise seeds the search never used
(``--first-seed`` + i, by default the re-score's seeds, noise 0.01 as the search's), once per ramp length, and
prints how many starts left the model, when, and the survivors' mean speed along the gait's
searched direction. ``no_ramp_8starts.json`` is a search made before the ramp existed:
``rrrobot gait-search --model plane --objective own --budget-seconds 600 --seed 0 --starts 8
--out ...`` (no ramp; its best gait survived all 8 search starts and ended on 5 of 8 new ones).
"""

import argparse
import math

import numpy as np

from rrrobot_gym import gait_search


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("file")
    p.add_argument("--ramps", type=float, nargs="+", default=[0.0, 0.5, 1.0, 2.0])
    p.add_argument("--seeds", type=int, default=16)
    p.add_argument("--duration", type=float, default=50.0)
    p.add_argument("--first-seed", type=int, default=gait_search.ROBUSTNESS_SEED_OFFSET,
                   help="starts are seeds FIRST .. FIRST + SEEDS - 1 (default: the search's re-score seeds)")
    args = p.parse_args(argv)
    gait = gait_search.load_gaits(args.file)[0]
    import json

    direction = math.radians(json.load(open(args.file))["gaits"][0]["direction_deg"])
    unit = np.array([math.cos(direction), math.sin(direction)])
    seeds = [args.first_seed + i for i in range(args.seeds)]
    print(f"{gait.name} from {args.file}, {args.seeds} new starts, {args.duration:g} s")
    for ramp in args.ramps:
        runs = gait_search.rollout_population(gait.as_array()[None], start_seeds=seeds, duration=args.duration,
                                              ramp_s=ramp)  # fmt: skip
        ended = runs.terminated[0]
        speed = runs.displacement[0] @ unit / runs.duration
        kept = f"{1e3 * speed[~ended].mean():.1f} mm/s" if (~ended).any() else "-"
        print(f"ramp {ramp:g} s: {ended.sum()} of {len(seeds)} left the model (at {np.round(runs.end_time[0][ended], 2).tolist()} s); "
              f"the others' mean speed along {math.degrees(direction):.0f} deg: {kept}")


if __name__ == "__main__":
    main()
