"""Write the agent's file (common.AGENT_FILE: with --run-gait plane_own_robust.json,
agents/searched/turn_then_run_robust.json) from a maneuver search: its best turning gait, lead and
blend, the running gait's measured direction offset (turn_then_run.DELTA_DEG), a start needing a
smaller turn than run_at_once_below_deg runs at once, and no heading correction (a change of the
robust running gait's offsets or amplitudes of 0.05 slips: steer_response_plane_own_robust_from5.json).

    python write_agent.py --run-gait plane_own_robust.json maneuver_search_plane_own_robust_0-45-180.json 10
"""
import json, sys
from common import *
from turn_then_run import DELTA_DEG

MANEUVER, AT_ONCE = sys.argv[1], float(sys.argv[2])
best = json.load(open(MANEUVER))["top"][0]["params"]
spec = dict(turn_gait=best[:6], lead_s=best[6], ramp_s=best[7], run_gait_file=OWN_FILE, run_gait=own_gait().name,
            direction_offset_deg=DELTA_DEG, window_steps=15, dt=0.05, model=MODEL, **({"env_kwargs": PHYSICS} if PHYSICS else {}),
            run_at_once_below_deg=AT_ONCE,
            made_by=["cd experiments/turn_then_run",
                     f"python direction.py --run-gait {OWN_FILE} 50   (direction_offset_deg: its offset to the whole degree)",
                     f"python maneuver_search.py --run-gait {OWN_FILE} 420 maneuver_search.json   (headings 0, 45, 180 deg, the paper's "
                     f"start and seed 21, 30 s, warm-started from the shipped maneuver with blends of 4-8 s; renamed to "
                     f"{Path(MANEUVER).name} after the run)",
                     f"python write_agent.py --run-gait {OWN_FILE} {Path(MANEUVER).name} {AT_ONCE:g}"],
            parameter_names=dict(turn_gait=list(PARAMETER_NAMES)))
AGENT_FILE.write_text(json.dumps(spec, indent=1) + "\n")
print(AGENT_FILE)
