"""Drawing RRRobot-v0: a top view and a side view of the robot, its path and its heading.

numpy geometry, Pillow for the raster and matplotlib for ``render_mode="human"``'s window (the
``plots`` extra), imported only when a frame is drawn or a window opened.
"""

from __future__ import annotations

import math

import numpy as np
from gymnasium.error import DependencyNotInstalled

from .. import dynamics

TOP_VIEW_HALF_WIDTH = 0.35  # m of ground shown each side of the robot in the top view
SIDE_VIEW_HALF_WIDTH = 0.3  # m shown each side of the robot in the side view
GRID_SPACING = 0.1  # m between grid lines (top view) and ground ticks (side view)

_BACKGROUND = (250, 250, 247)
_GRID = (222, 222, 215)
_PATH = (70, 110, 200)
_HEADING = (215, 80, 40)
_SHELL = (225, 200, 150)
_OUTLINE = (90, 70, 40)
_LEGS = ((40, 90, 200), (30, 150, 70), (200, 110, 30), (150, 40, 160), (20, 150, 160), (180, 40, 60))  # leg 1 (body -Y), leg 2, ...
_TEXT = (30, 30, 30)


def check_frame_size(width, height):
    """Validate the frame size keywords; returns (width, height) as ints."""
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise TypeError(f"{name} must be an integer number of pixels, got {value!r}")
        if value < 64:
            raise ValueError(f"{name} must be at least 64 pixels, got {value}")
    return int(width), int(height)


def check_human_display():
    """Raise a clear error unless matplotlib can open a window (render_mode="human")."""
    try:
        import matplotlib
    except ImportError:
        raise DependencyNotInstalled('render_mode="human" needs matplotlib: pip install "rrrobot_gym[plots]"') from None
    backend = matplotlib.get_backend().lower()
    try:
        from matplotlib.backends import BackendFilter, backend_registry

        non_interactive = backend_registry.list_builtin(BackendFilter.NON_INTERACTIVE)
    except ImportError:  # matplotlib < 3.9
        from matplotlib import rcsetup

        non_interactive = [name.lower() for name in rcsetup.non_interactive_bk]
    if backend in non_interactive:
        raise RuntimeError(
            f'render_mode="human" needs a display, but matplotlib uses the non-interactive backend '
            f"{backend!r} (no display found, or MPLBACKEND set). Use render_mode=\"rgb_array\" to get "
            "frames as arrays, or run where a display is available."
        )


def _convex_hull(points):
    """Counter-clockwise convex hull of 2-D points (Andrew's monotone chain), as a list of tuples."""
    pts = sorted(set(map(tuple, np.round(points, 3).tolist())))
    if len(pts) < 3:
        return pts

    def half(seq):
        chain = []
        for p in seq:
            while len(chain) >= 2:
                (ax, ay), (bx, by) = chain[-2], chain[-1]
                if (bx - ax) * (p[1] - ay) - (by - ay) * (p[0] - ax) > 0.0:
                    break
                chain.pop()
            chain.append(p)
        return chain

    lower, upper = half(pts), half(reversed(pts))
    return lower[:-1] + upper[:-1]


def _shell_points(axes):
    """Body-frame points on the shell (the lower half of the ellipsoid of semi-axes ``axes``), rim first."""
    a, b, c = axes
    azimuth = np.linspace(0.0, 2.0 * math.pi, 48, endpoint=False)
    rings = []
    for elevation in np.linspace(0.0, 0.5 * math.pi, 7):
        ring = math.cos(elevation)
        depth = np.full(48, -c * math.sin(elevation))
        rings.append(np.stack([a * ring * np.cos(azimuth), b * ring * np.sin(azimuth), depth], -1))
    return np.concatenate(rings), 48


def _robot_geometry(state, robot):
    """World positions: shell points (K, 3), rim count, leg pins (L, 3), leg tips (L, 3)."""
    fields = dynamics.state_fields(robot.num_legs)
    rot = dynamics.rotation_matrix(state[fields.quat])
    a, b, c = robot.shell_axes
    up = rot[2]  # world up in the body: the centre stands sqrt(n^T A n) above the contact
    contact = -np.array([a * a, b * b, c * c]) * up / math.sqrt(a * a * up[0] ** 2 + b * b * up[1] ** 2 + c * c * up[2] ** 2)
    centre = np.array([state[0], state[1], 0.0]) - rot @ contact
    shell, rim_count = _shell_points(robot.shell_axes)
    phi = state[fields.leg_angles]
    pins = np.array([leg.hinge for leg in robot.legs])
    tips = np.array([np.add(leg.hinge, length * (math.cos(angle) * np.array(leg.zero) + math.sin(angle) * np.array(leg.up)))
                     for leg, length, angle in zip(robot.legs, robot.leg_lengths, phi)])  # fmt: skip
    to_world = lambda p: centre + p @ rot.T  # noqa: E731
    return to_world(shell), rim_count, to_world(pins), to_world(tips)


def _draw_robot(draw, project, shell, rim_count, pins, tips, scale):
    hull = _convex_hull(project(shell))
    draw.polygon(hull, fill=_SHELL, outline=_OUTLINE)
    rim = [tuple(p) for p in project(shell[:rim_count])]
    draw.line(rim + rim[:1], fill=_OUTLINE, width=2)
    leg_width = max(2, round(0.012 * scale))
    dot = max(3, round(0.012 * scale))
    for k in range(len(pins)):
        (px, py), (tx, ty) = project(pins[k : k + 1])[0], project(tips[k : k + 1])[0]
        colour = _LEGS[k % len(_LEGS)]
        draw.line([(px, py), (tx, ty)], fill=colour, width=leg_width)
        draw.ellipse([tx - dot, ty - dot, tx + dot, ty + dot], fill=colour)


def _arrow(draw, start, end, colour, width):
    draw.line([start, end], fill=colour, width=width)
    dx, dy = end[0] - start[0], end[1] - start[1]
    length = math.hypot(dx, dy) or 1.0
    ux, uy = dx / length, dy / length
    head = 4.0 * width
    left = (end[0] - head * (ux + 0.5 * uy), end[1] - head * (uy - 0.5 * ux))
    right = (end[0] - head * (ux - 0.5 * uy), end[1] - head * (uy + 0.5 * ux))
    draw.polygon([end, left, right], fill=colour)


def _font(size):
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1 has one bitmap size
        return ImageFont.load_default()


def draw_frame(state, path, target_direction, robot, time, width=800, height=400):
    """An RGB frame (height, width, 3) uint8. Left, the top view centred on the robot: a 0.1 m grid,
    the contact point's ``path`` so far ((x, y) m, or None) and the heading as an arrow. Right, the
    side view along the heading (travel goes right), ground ticks every 0.1 m. Leg 1 (at body -Y)
    is blue, leg 2 green."""
    try:
        from PIL import Image, ImageDraw
    except ImportError:
        raise DependencyNotInstalled('rendering needs Pillow: pip install "rrrobot_gym[plots]"') from None

    state = np.asarray(state, dtype=float)
    image = Image.new("RGB", (width, height), _BACKGROUND)
    draw = ImageDraw.Draw(image)
    panel = width // 2
    shell, rim_count, pins, tips = _robot_geometry(state, robot)
    cx, cy = float(state[0]), float(state[1])
    heading = np.array([math.cos(target_direction), math.sin(target_direction)])

    # Top view.
    scale = min(panel, height) / (2.0 * TOP_VIEW_HALF_WIDTH)

    def top(points):
        points = np.atleast_2d(points)
        return np.stack([0.5 * panel + (points[:, 0] - cx) * scale, 0.5 * height - (points[:, 1] - cy) * scale], -1)

    half_x, half_y = 0.5 * panel / scale, 0.5 * height / scale
    for k in range(math.floor((cx - half_x) / GRID_SPACING), math.ceil((cx + half_x) / GRID_SPACING) + 1):
        u = top(np.array([[k * GRID_SPACING, cy]]))[0, 0]
        draw.line([(u, 0), (u, height)], fill=_GRID, width=1)
    for k in range(math.floor((cy - half_y) / GRID_SPACING), math.ceil((cy + half_y) / GRID_SPACING) + 1):
        v = top(np.array([[cx, k * GRID_SPACING]]))[0, 1]
        draw.line([(0, v), (panel, v)], fill=_GRID, width=1)
    _draw_robot(draw, top, shell, rim_count, pins, tips, scale)
    # Drawn over the shell: in 50 s the robot travels about its own size.
    if path is not None and len(path) > 1:
        draw.line([tuple(p) for p in top(np.asarray(path)).tolist()], fill=_PATH, width=2)
    arrow_from = top(np.array([[cx, cy]]))[0]
    arrow_to = top(np.array([[cx + 0.22 * heading[0], cy + 0.22 * heading[1]]]))[0]
    _arrow(draw, tuple(arrow_from), tuple(arrow_to), _HEADING, 3)

    # Side view: horizontal axis along the heading, vertical axis world z.
    side_scale = min(panel, height) / (2.0 * SIDE_VIEW_HALF_WIDTH)
    ground = 0.78 * height
    along_robot = cx * heading[0] + cy * heading[1]

    def side(points):
        points = np.atleast_2d(points)
        along = points[:, 0] * heading[0] + points[:, 1] * heading[1] - along_robot
        return np.stack([panel + 0.5 * panel + along * side_scale, ground - points[:, 2] * side_scale], -1)

    draw.rectangle([panel, ground, width, height], fill=_GRID)
    half_along = 0.5 * panel / side_scale
    first_tick = math.floor((along_robot - half_along) / GRID_SPACING)
    for k in range(first_tick, math.ceil((along_robot + half_along) / GRID_SPACING) + 1):
        u = panel + 0.5 * panel + (k * GRID_SPACING - along_robot) * side_scale
        if u >= panel:
            draw.line([(u, ground), (u, ground + 8)], fill=_OUTLINE, width=1)
    draw.line([(panel, ground), (width, ground)], fill=_OUTLINE, width=2)
    _draw_robot(draw, side, shell, rim_count, pins, tips, side_scale)
    draw.line([(panel, 0), (panel, height)], fill=_OUTLINE, width=1)

    font = _font(max(10, height // 28))
    tilt_deg = math.degrees(float(dynamics.tilt(state)))
    draw.text((8, 6), f"top view   t = {time:6.2f} s   tilt {tilt_deg:5.1f} deg", fill=_TEXT, font=font)
    draw.text((8, height - 6 - height // 28), f"contact ({cx:+.3f}, {cy:+.3f}) m", fill=_TEXT, font=font)
    draw.text((panel + 8, 6), "side view along the heading (to the right)", fill=_HEADING, font=font)
    return np.asarray(image, dtype=np.uint8)


class HumanViewer:
    """A matplotlib window that shows frames as they come (render_mode="human")."""

    def __init__(self, title):
        check_human_display()
        import matplotlib.pyplot as plt

        self._plt = plt
        self._figure = None
        self._image = None
        self._title = title

    def show(self, frame, fps):
        plt = self._plt
        if self._figure is None or not plt.fignum_exists(self._figure.number):
            height, width = frame.shape[:2]
            self._figure = plt.figure(self._title, figsize=(width / 100.0, height / 100.0), dpi=100)
            axes = self._figure.add_axes((0.0, 0.0, 1.0, 1.0))
            axes.set_axis_off()
            self._image = axes.imshow(frame)
            plt.show(block=False)
        else:
            self._image.set_data(frame)
        plt.pause(1.0 / fps)

    def close(self):
        if self._figure is not None:
            self._plt.close(self._figure)
            self._figure = None
