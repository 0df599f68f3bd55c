"""rrrobot video: animations of a policy or a gait from the env's rgb_array frames."""

import math
from pathlib import Path

import numpy as np
import pytest

from rrrobot_gym import cli

ROOT = Path(__file__).resolve().parents[1]
POLICY = ROOT / "agents" / "pretrained" / "best_model.zip"

pytest.importorskip("imageio")


def video(argv, capsys):
    """``rrrobot video ARGV``: (exit status, stdout, stderr)."""
    capsys.readouterr()
    status = cli.main(["video", *map(str, argv)])
    out = capsys.readouterr()
    return status, out.out, out.err


def gif_frames(path):
    """A GIF's frames as RGB arrays and each frame's duration (ms)."""
    from PIL import Image, ImageSequence

    with Image.open(path) as image:
        frames = [(np.asarray(frame.convert("RGB")), frame.info["duration"]) for frame in ImageSequence.Iterator(image)]
    return [f for f, _ in frames], [d for _, d in frames]


def test_a_gait_s_gif_holds_the_env_s_frames_in_one_small_palette(tmp_path, capsys):
    from rrrobot_gym.agents import gait_agent
    from rrrobot_gym.envs import RRRobotEnv

    out = tmp_path / "gait1.gif"
    status, printed, _ = video(["--gait", 1, "--heading", -90, "--seconds", 2, "--every", 2, "--width", 160,
                                "--height", 80, "--colors", 16, "--out", out], capsys)
    assert status == 0 and f"wrote {out}: 21 frames at 10 frames/s" in printed
    frames, durations = gif_frames(out)
    assert len(frames) == 21 and set(durations) == {100}  # every other 0.05 s step of 2 s, and the start; real time
    assert len(np.unique(np.concatenate(frames).reshape(-1, 3), axis=0)) <= 16
    # the frames are the env's drawings of the gait's episode from the paper's start, to the palette's error
    env = RRRobotEnv(render_mode="rgb_array", width=160, height=80, target_direction=math.radians(-90),
                     reset_noise_scale=0.0)
    obs, _ = env.reset(seed=0)
    agent, state, drawn = gait_agent("gait1"), None, [env.render()]
    for step in range(1, 41):
        action, state = agent.predict(obs[None], state=state, episode_start=np.array([step == 1]))
        obs, *_ = env.step(action[0])
        if step % 2 == 0:
            drawn.append(env.render())
    for ours, theirs in zip(frames, drawn):
        assert np.mean(np.abs(ours.astype(int) - theirs.astype(int)) > 40) < 0.015  # (a step late: over 0.02)
    assert np.mean(frames[0] != frames[-1]) > 0.01  # the robot moved


@pytest.mark.slow
def test_the_shipped_policy_s_mp4_plays_at_the_speed_asked(tmp_path, capsys):
    import imageio.v2 as imageio

    out = tmp_path / "policy.mp4"
    status, printed, _ = video(["--policy", POLICY, "--seconds", 1, "--speed", 0.5, "--width", 160, "--height", 80,
                                "--out", out], capsys)
    assert status == 0 and "21 frames at 10 frames/s" in printed
    reader = imageio.get_reader(out, format="FFMPEG")
    try:
        assert reader.get_meta_data()["fps"] == 10 and reader.count_frames() == 21
        assert reader.get_data(0).shape == (80, 160, 3)
    finally:
        reader.close()


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--policy", "missing.zip"], "--policy: no model file at missing.zip"),
        (["--gait", "1", "--out-suffix", ".png"], "--out must name a .gif or .mp4 file"),
        (["--gait", "1", "--width", "30"], "--width must be at least 64 pixels, got 30"),
        (["--gait", "1", "--width", "161", "--out-suffix", ".mp4"], "an MP4 needs an even --width and --height"),
        (["--policy", str(POLICY), "--model", "pivot"], "was trained on the plane model"),
        (["--gait", "1", "--heading", "400"], "must be a heading in degrees, in [-360, 360], got '400'"),
        (["--gait", "1", "--heading", "inf"], "must be finite"),
        (["--gait", "1", "--colors", "1"], "must be 2 to 256 colours"),
        (["--gait", "1", "--every", "0"], "must be a positive integer"),
        (["--gait", "4"], "invalid choice: 4"),
    ],
)
def test_a_bad_video_option_is_one_line_naming_it(argv, words, tmp_path, capsys):
    suffix = ".gif"
    if "--out-suffix" in argv:
        suffix = argv[argv.index("--out-suffix") + 1]
        argv = argv[: argv.index("--out-suffix")]
    out = tmp_path / f"robot{suffix}"
    try:
        status, _, err = video([*argv, "--out", out], capsys)
    except SystemExit as exit_info:  # (argparse's own errors)
        status, err = exit_info.code, capsys.readouterr().err
    assert status == 2 and words in err.strip().splitlines()[-1]
    assert not out.exists()
