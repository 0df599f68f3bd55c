"""What a policy's legs do: frequency, centre, half-range and phase gap of its leg angles after
5 s, on the 8 compass headings (evaluate.run_episodes: 50 s from the paper's start, deterministic),
beside a searched gait's.

Frequency: the peak of the leg angles' power spectrum (both legs summed, the mean removed);
centre: the mean angle; half-range: half the 5-95 percentile spread; phase gap: the phase of leg 2
minus leg 1 at that frequency (a least-squares sinusoid fit of each leg), wrapped to (-pi, pi].

    python experiments/policy_gait/describe.py [POLICY_ZIP] [GAIT_FILE]
    (defaults: agents/pretrained/best_model.zip, agents/searched/plane_own_robust.json; on the
    model the policy was trained on, under its motor limits)
"""
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from rrrobot_gym.agents import load_ppo_agent  # noqa: E402
from rrrobot_gym.agents.searched import load_gait_agents  # noqa: E402
from rrrobot_gym.evaluation import COMPASS_DEG, run_episodes  # noqa: E402


def describe(legs, dt):
    """legs (T, 2) rad after the settling time -> dict of the leg motion's numbers."""
    x = legs - legs.mean(axis=0)
    freqs = np.fft.rfftfreq(len(x), dt)
    power = (np.abs(np.fft.rfft(x, axis=0)) ** 2).sum(axis=1)
    f = freqs[1:][np.argmax(power[1:])]
    t = np.arange(len(x)) * dt
    basis = np.stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t), np.ones_like(t)], axis=1)
    coef = np.linalg.lstsq(basis, legs, rcond=None)[0]  # phi = s sin + c cos + o = A sin(wt + p)
    phase = np.arctan2(coef[1], coef[0])
    gap = (phase[1] - phase[0] + np.pi) % (2 * np.pi) - np.pi
    half = (np.percentile(legs, 95, axis=0) - np.percentile(legs, 5, axis=0)) / 2
    return dict(hz=f, rad_s=2 * np.pi * f, centre=legs.mean(axis=0), half_range=half, gap=gap)


def main():
    policy = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "agents" / "pretrained" / "best_model.zip"
    gaits = Path(sys.argv[2]) if len(sys.argv) > 2 else ROOT / "agents" / "searched" / "plane_own_robust.json"
    gait_name, gait = next(iter(load_gait_agents(gaits).items()))
    agent = load_ppo_agent(policy)
    runs = run_episodes({"ppo": agent, gait_name: gait}, agent.env_config.get("model", "plane"), COMPASS_DEG)
    for name, run in runs.items():
        dt = run["times"][1] - run["times"][0]
        k0 = int(round(5.0 / dt))
        print(f"{name}:")
        for h, heading in enumerate(COMPASS_DEG):
            d = describe(run["leg_angles"][k0:, h], dt)
            print(f"  {heading:5.0f} deg: {d['hz']:.2f} Hz ({d['rad_s']:.1f} rad/s), centre {d['centre'][0]:.2f} / "
                  f"{d['centre'][1]:.2f} rad, half-range {d['half_range'][0]:.2f} / {d['half_range'][1]:.2f} rad, "
                  f"gap {d['gap']:+.2f} rad")
            if name != "ppo":
                break  # an open-loop gait does the same on every heading


if __name__ == "__main__":
    main()
