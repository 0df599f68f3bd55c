"""Plots of the contact-point path in the style of the paper's Figs. 7-9, written to files.

matplotlib is an optional dependency (``pip install rrrobot_gym[plots]``), imported inside the
functions and used on the Agg backend. A panel shows, in metres, with equal aspect:
- the raw contact path (thin): it wiggles back and forth at the gait frequency;
- the path averaged over each gait period: the travel the robot actually makes;
- the start, a solid arrow giving the direction of motion (the paper's "solid
  arrow"), and dotted marks with the robot's position at given times.
"""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np

from .analysis import period_average

RAW_COLOUR = "0.7"
AVERAGE_COLOUR = "tab:blue"
MARK_COLOUR = "tab:red"


def require_matplotlib() -> None:
    """Raise the ImportError of :func:`_pyplot` now if matplotlib is missing."""
    _pyplot()


def check_figure_path(path) -> None:
    """Raise ValueError unless matplotlib writes the format that ``path``'s suffix names, if it
    has one (before a run, not after it); ImportError as :func:`require_matplotlib` if
    matplotlib is missing."""
    _pyplot()
    from matplotlib.backend_bases import FigureCanvasBase

    formats = FigureCanvasBase.get_supported_filetypes()
    suffix = Path(path).suffix.lstrip(".").lower()
    if suffix and suffix not in formats:  # (no suffix: matplotlib writes its default format)
        raise ValueError(f"a figure's file name must end in one of .{', .'.join(sorted(formats))}, got {str(path)!r}")


def _pyplot():
    """matplotlib.pyplot on the Agg backend, or an ImportError saying what to install."""
    try:
        import matplotlib
    except ImportError:
        raise ImportError(
            "plotting needs matplotlib, which is not installed: pip install rrrobot_gym[plots]"
        ) from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def time_mark_spacing(duration: float, max_marks: int = 6) -> float:
    """s, a round spacing (1, 2 or 5 times a power of ten) giving at most ``max_marks`` marks."""
    if not (math.isfinite(duration) and duration > 0.0):
        raise ValueError(f"duration must be a positive finite number of seconds, got {duration}")
    decade = 10.0 ** math.floor(math.log10(duration / max_marks))
    for factor in (1.0, 2.0, 5.0, 10.0):
        if duration / (factor * decade) <= max_marks:
            return factor * decade
    return 10.0 * decade


def draw_contact_path(ax, times, x, y, period: float, title: str = ""):
    """Draw one contact path on the matplotlib axes ``ax`` (see the module docstring).

    ``times`` (T,) s; ``x``, ``y`` (T,) m; ``period`` s, the gait period used to
    average the path. A run shorter than one period is drawn raw only.
    """
    times, x, y = (np.asarray(a, dtype=float) for a in (times, x, y))
    if not (times.shape == x.shape == y.shape and times.ndim == 1 and len(times) >= 2):
        raise ValueError(f"times, x and y must be 1-D arrays of one length >= 2, got {times.shape}, {x.shape}, {y.shape}")
    duration = float(times[-1] - times[0])
    ax.plot(x, y, color=RAW_COLOUR, lw=0.4, label="contact point")
    if duration > period:
        path_times, path = period_average(times, np.stack([x, y], axis=-1), period)
        ax.plot(path[:, 0], path[:, 1], color=AVERAGE_COLOUR, lw=1.6, label="averaged over a gait period")
    else:
        path_times, path = times, np.stack([x, y], axis=-1)
    ax.plot(x[0], y[0], "ko", ms=5, label="start", zorder=5)
    _draw_direction_arrow(ax, path_times, path, period)
    _draw_time_marks(ax, path_times, path, time_mark_spacing(duration), period)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(True, lw=0.3, alpha=0.6)
    ax.tick_params(labelsize=8)
    if title:
        ax.set_title(title, fontsize=10)


def _draw_direction_arrow(ax, times, path, period):
    """Solid arrow along the (averaged) path at mid-run (a circling path ends near its start-up
    transient, where an arrow would be lost among the early wiggles), pointing the way it goes."""
    middle = 0.5 * (times[0] + times[-1])
    half_span = min(2.0 * period, 0.25 * (times[-1] - times[0]))
    tail = np.array([np.interp(middle - half_span, times, path[:, k]) for k in range(2)])
    head = np.array([np.interp(middle + half_span, times, path[:, k]) for k in range(2)])
    if np.allclose(tail, head, rtol=0.0, atol=1e-12):
        return
    ax.annotate(
        "",
        xy=tuple(head),
        xytext=tuple(tail),
        arrowprops=dict(arrowstyle="-|>", color="k", lw=2.0, mutation_scale=18),
        zorder=6,
    )
    # An invisible artist so the arrow has a legend entry.
    ax.plot([], [], color="k", lw=2.0, marker=">", label="direction of motion")


def _draw_time_marks(ax, times, path, every, period):
    """Dotted leaders from the path to labels 't s', at multiples of ``every`` seconds.

    Each label sits off the path, across it from the local direction of travel and
    away from the path's centre, so it does not cover the path it marks.
    """
    scale = max(float(np.ptp(path, axis=0).max()), 1e-3)
    centre = path.mean(axis=0)
    marks = np.arange(every * math.ceil(times[0] / every), times[-1] + 1e-9, every)
    first = True
    for mark in marks:
        if mark <= 0.0:
            continue
        point, before, after = (
            np.array([np.interp(t, times, path[:, 0]), np.interp(t, times, path[:, 1])])
            for t in (mark, mark - period, mark + period)
        )
        tangent = after - before
        normal = np.array([tangent[1], -tangent[0]])  # right of the direction of travel
        norm = float(np.hypot(*normal))
        normal = normal / norm if norm > 1e-12 else np.array([1.0, 0.0])
        if np.dot(normal, point - centre) < -0.05 * scale:
            normal = -normal
        label_at = point + 0.1 * scale * normal
        ax.plot(*point, "o", color=MARK_COLOUR, ms=3, zorder=5, label="position at the time marked" if first else None)
        ax.annotate(
            f"{mark:g} s",
            xy=tuple(point),
            xytext=tuple(label_at),
            fontsize=7,
            color=MARK_COLOUR,
            ha="center",
            va="center",
            arrowprops=dict(arrowstyle="-", linestyle=":", color=MARK_COLOUR, lw=0.9),
        )
        first = False


def _save(fig, path, dpi):
    """Write ``fig``; a PNG is reduced to a 128-colour palette (a third of the size, and it looks the same)."""
    if Path(path).suffix.lower() != ".png":
        fig.savefig(path, dpi=dpi)
        return
    from PIL import Image  # a dependency of matplotlib

    buffer = io.BytesIO()
    fig.savefig(buffer, dpi=dpi, format="png")
    buffer.seek(0)
    with Image.open(buffer) as image:
        palette = image.convert("RGB").quantize(colors=128, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
        palette.save(path, format="PNG", optimize=True)


def plot_contact_path(path, times, x, y, period: float, title: str = "", dpi: int = 100):
    """Write one contact-path panel to the image file ``path``."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(5.0, 5.6), layout="constrained")
    try:
        draw_contact_path(ax, times, x, y, period, title)
        fig.legend(loc="outside lower center", ncol=2, fontsize=8, frameon=False)
        _save(fig, path, dpi)
    finally:
        plt.close(fig)


def plot_gait_panels(path, runs, dpi: int = 100):
    """Write the Figs. 7-9 grid to ``path``: one row a gait, one column a model.

    ``runs`` maps (gait_number, model) to a dict with ``times``, ``x``, ``y`` and
    ``period``; rows and columns follow the sorted gait numbers and the models'
    first-seen order.
    """
    if not runs:
        raise ValueError("no runs to plot")
    plt = _pyplot()
    gaits = sorted({gait for gait, _ in runs})
    models = list(dict.fromkeys(model for _, model in runs))
    fig, axes = plt.subplots(
        len(gaits), len(models), figsize=(4.2 * len(models), 3.9 * len(gaits)), layout="constrained", squeeze=False
    )
    try:
        for row, gait in enumerate(gaits):
            for col, model in enumerate(models):
                ax = axes[row][col]
                run = runs.get((gait, model))
                if run is None:
                    ax.set_axis_off()
                    continue
                draw_contact_path(ax, run["times"], run["x"], run["y"], run["period"], f"Gait {gait}, {model}")
        handles, labels = axes[0][0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=8, frameon=False)
        _save(fig, path, dpi)
    finally:
        plt.close(fig)


def plot_learning_curves(path, curves, bar=None, title: str = "", dpi: int = 110):
    """Write learning curves against wall time to ``path``: above, the worst compass heading's speed
    at each evaluation (mm/s); below, the mean length of the training episodes that ended before it
    (s). ``curves`` maps a label (one colour a label: an algorithm) to a list of runs (one line a
    run: a seed), each a dict with ``wall_time_s``, ``worst_heading_mm_s`` and ``train_episode_s``
    (lists, one entry an evaluation); ``bar``, mm/s, is drawn dashed."""
    if not curves:
        raise ValueError("no learning curves to plot")
    plt = _pyplot()
    fig, (speed, episodes) = plt.subplots(2, 1, figsize=(7.0, 6.0), sharex=True, height_ratios=(2, 1),
                                          layout="constrained")
    try:
        for index, (label, runs) in enumerate(curves.items()):
            for k, run in enumerate(runs):
                minutes = np.asarray(run["wall_time_s"], dtype=float) / 60.0
                kwargs = dict(color=f"C{index}", lw=1.0, marker=".", ms=3, label=label if k == 0 else None)
                speed.plot(minutes, np.asarray(run["worst_heading_mm_s"], dtype=float), **kwargs)
                episodes.plot(minutes, np.asarray(run["train_episode_s"], dtype=float), **{**kwargs, "label": None})
        if bar is not None:
            speed.axhline(bar, color="k", ls="--", lw=1, label=f"bar {bar:g} mm/s")
        speed.set(ylabel="worst heading speed (mm/s)", title=title)
        episodes.set(xlabel="wall time (min)", ylabel="training episode (s)", ylim=(0, None))
        for ax in (speed, episodes):
            ax.grid(alpha=0.3)
        speed.legend(fontsize=8)
        _save(fig, path, dpi)
    finally:
        plt.close(fig)
