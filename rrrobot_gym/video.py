"""Animations of an agent on RRRobot-v0 (a trained policy or a gait), from ``render_mode="rgb_array"``
frames: ``rrrobot video``.

    rrrobot video --policy agents/pretrained/best_model.zip --heading 90 --out robot.gif
    rrrobot video --gait 1 --seconds 20 --out gait1.mp4

One episode from the paper's start (no start noise) on the nominal robot, under the env keywords
the agent was trained or searched with: each frame is the env's drawing, the top view with the
path so far and the commanded heading, and the side view along the heading. Every
``every``-th control step becomes a frame, played at ``speed`` times real time. A GIF gets
one palette of ``colors`` colours for all its frames (the drawing has few), so that it stays small;
an MP4 is H.264 (imageio-ffmpeg's own ffmpeg). Needs Pillow and imageio (``rrrobot_gym[video]``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

FORMATS = (".gif", ".mp4")


def record(agent, heading_deg: float, seconds: float, every: int = 2, width: int = 480, height: int = 240,
           model: str = "plane", **env_kwargs) -> tuple:
    """(frames, frame_dt, ended_at): the uint8 (height, width, 3) frames of one episode of ``agent``
    (SB3's ``predict``) along ``heading_deg`` (degrees from +X towards +Y) for ``seconds`` s, every
    ``every``-th control step from the start, on the ``model`` with ``env_kwargs``; the robot's
    time between frames (s); and the time (s) the episode ended by leaving the model, or None (its
    last frame is then that step's)."""
    from .envs import RRRobotEnv

    env = RRRobotEnv(render_mode="rgb_array", width=width, height=height, model=model,
                     target_direction=math.radians(heading_deg), reset_noise_scale=0.0, randomize=None, **env_kwargs)
    try:
        steps = max(1, round(seconds / env.dt))
        observation, _ = env.reset(seed=0)
        frames, state, ended_at = [env.render()], None, None
        for step in range(1, steps + 1):
            action, state = agent.predict(observation[None], state=state, episode_start=np.array([step == 1]),
                                          deterministic=True)
            observation, _, terminated, _, _ = env.step(np.asarray(action, dtype=np.float32).reshape(env.action_space.shape))
            if step % every == 0 or terminated:
                frames.append(env.render())
            if terminated:
                ended_at = step * env.dt
                break
        return frames, every * env.dt, ended_at
    finally:
        env.close()


def shared_palette(frames, colors: int):
    """The frames as RGB arrays with at most ``colors`` colours, all mapped to one palette (made
    from a sample of the frames), so a GIF's frames share it and differ only where the robot moved."""
    from PIL import Image

    sample = frames[:: max(1, len(frames) // 8)]
    palette = Image.fromarray(np.concatenate(sample, axis=0)).quantize(
        colors=colors, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    return [np.asarray(Image.fromarray(frame).quantize(palette=palette, dither=Image.Dither.NONE).convert("RGB"))
            for frame in frames]


def write_animation(path, frames, fps: float, colors: int = 32) -> Path:
    """Write ``frames`` to ``path`` (.gif or .mp4, :data:`FORMATS`) at ``fps`` frames a second."""
    import imageio.v2 as imageio

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".gif":
        # (imageio's Pillow writer; duration in ms, loop 0: for ever)
        imageio.mimwrite(path, shared_palette(frames, colors), format="GIF", duration=1000.0 / fps, loop=0)
    elif suffix == ".mp4":
        with imageio.get_writer(path, format="FFMPEG", fps=fps, codec="libx264", pixelformat="yuv420p",
                                macro_block_size=2, quality=7) as writer:
            for frame in frames:
                writer.append_data(frame)
    else:
        raise ValueError(f"an animation's file name must end in {' or '.join(FORMATS)}, got {str(path)!r}")
    return path
