"""A robot scenario from a robot bag as an animation: a failure you can watch, not only a verdict.

Drawn from a ``ros.robot_bag.RobotRun`` (read here by attribute only, so this module needs no ROS):
the map's walls, start and goal, the trajectory so far, the pioneer2dx footprint at the pose
(``sims.robot_world.PIONEER2DX``, the body the oracles judge), the latest laser scan as beam ends,
the stack's latest global plan, and once the verdict falls the failure point and the result's
detail. A world with hazards (issue 48, ``RobotRun.markers``) adds what is in it but not in the
map: boxes and posts in orange, and people as purple discs where they are at the frame's time, each
one's path dashed. Layers a bag does not hold (a stack without ``/plan``, a world without hazards)
are left out, legend entries too.

Frames are sampled at a fixed simulated rate: one every ``speed / fps`` simulated seconds, played
at ``fps``; a run that would need more than ``MAX_FRAMES`` frames is played faster so that it fits
(the factor used is returned), so a long run still makes a GIF of a reasonable size. The view is
the part of the map the robot used (start, trajectory, failure point, the goal when it is near,
and the hazards within ``HAZARD_NEAR`` of those, plus a margin), since on the whole 50 m map a
0.44 m robot is a few pixels; an overview beside it shows the whole map. Everything that does not
move is drawn once into a background picture.
"""
from __future__ import annotations

import math
import os
import secrets
import textwrap
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib import animation  # noqa: E402
from matplotlib.patches import Circle, Polygon, Rectangle  # noqa: E402

MAX_FRAMES = 300  # at the default 10 fps a 30 s GIF; longer runs are sped up to fit
FORMATS = (".gif", ".mp4")
VIEW_MARGIN = 2.0  # metres of map around what the run used
MIN_VIEW = 8.0  # the smallest side of the view [m]
HOLD_S = 1.5  # the last frame (the verdict) stays this long before the GIF loops [s]
FIGSIZE = (7.4, 5.6)  # [in]: the map around the robot, and a column for the overview, legend and clock
MAX_VIEW = 24.0  # the goal is in the view when that keeps its side within this [m]
FAILURE_COLOR = "red"  # used by nothing else in the picture, so the verdict's marker stands out
HAZARD_NEAR = 3.0  # a box, post or person this close to where the robot went is kept in the view [m]
UNMAPPED_COLOR, POST_COLOR = "tab:orange", "darkorange"  # in the world, not in the map (as viz/robot.py)
PERSON_COLOR = "tab:purple"  # people and their paths (as viz/robot.py and the world's markers)
TRAIL_COLOR = "tab:brown"  # the path driven: not the people's purple


def check_output(path: str | Path, overwrite: bool = False) -> Path:
    """The output path, or ``ValueError`` (one line): an unknown format, an mp4 without ffmpeg, an existing file."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise ValueError(f"{path}: an animation is written as {' or '.join(FORMATS)}, not {suffix or 'no suffix'!r}")
    if suffix == ".mp4" and not animation.FFMpegWriter.isAvailable():
        raise ValueError(f"{path}: an .mp4 needs ffmpeg, which is not installed (matplotlib finds no ffmpeg "
                         "on PATH); write a .gif instead")
    if path.exists() and not overwrite:
        raise ValueError(f"{path} already exists; refusing to overwrite it (another -o, or --overwrite)")
    return path


def frame_times(duration: float, fps: float, speed: float, max_frames: int = MAX_FRAMES) -> tuple[np.ndarray, float]:
    """Simulated times of the frames (from 0 to ``duration``, the end always included) and the playback
    factor used: ``speed``, or more when the run needs more than ``max_frames`` frames."""
    if not (fps > 0 and speed > 0 and max_frames >= 2):
        raise ValueError("fps and speed must be > 0, and at least 2 frames allowed")
    step = speed / fps
    count = int(math.ceil(duration / step - 1e-9)) + 1 if duration > 0 else 1
    if count > max_frames:
        count, step = max_frames, duration / (max_frames - 1)
    times = np.minimum(np.arange(count) * step, duration)
    times[-1] = duration
    return times, step * fps


def _latest(items: list[tuple[float, Any]], t: float) -> Any:
    """The last item stamped at or before ``t`` (None: nothing yet)."""
    found = None
    for stamp, value in items:
        if stamp > t:
            break
        found = value
    return found


def _hazards(run: Any) -> tuple[np.ndarray, np.ndarray, list[np.ndarray], int]:
    """What a run's markers hold that stays put, each once: boxes (B, 4), posts (P, 3), the people's
    paths; and the most people shown at one time."""
    markers = getattr(run, "markers", None) or []
    boxes = np.unique(np.vstack([np.zeros((0, 4))] + [m["boxes"] for _, m in markers]), axis=0)
    posts = np.unique(np.vstack([np.zeros((0, 3))] + [m["posts"] for _, m in markers]), axis=0)
    paths: dict[bytes, np.ndarray] = {}
    for _, m in markers:
        for path in m["people_paths"]:
            paths.setdefault(np.ascontiguousarray(path, dtype=float).tobytes(), path)
    return boxes, posts, list(paths.values()), max((len(m["people"]) for _, m in markers), default=0)


def _near(points: np.ndarray, route: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """Which ``points`` lie within ``HAZARD_NEAR`` + their ``reach`` of some point of ``route``."""
    if not len(points):
        return np.zeros(0, dtype=bool)
    route = np.unique(np.round(route, 1), axis=0)  # 10 cm is plenty, and keeps the distance table small
    gap = np.hypot(*(points[:, None, :] - route[None, :, :]).transpose(2, 0, 1)).min(axis=1)
    return gap <= HAZARD_NEAR + reach


def _hazard_points(run: Any, route: np.ndarray) -> np.ndarray:
    """The extent of every box, post and person (wherever they walked) near ``route``, as points."""
    boxes, posts, _, _ = _hazards(run)
    people = np.vstack([np.zeros((0, 3))] + [m["people"] for _, m in (getattr(run, "markers", None) or [])])
    people = np.unique(np.round(people, 1), axis=0)
    centres = (boxes[:, :2] + boxes[:, 2:]) / 2
    half = np.hypot(boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1]) / 2
    keep = [boxes[_near(centres, route, half)].reshape(-1, 2)]  # both corners of each box kept
    for circles in (posts, people):
        near = circles[_near(circles[:, :2], route, circles[:, 2])]
        keep += [near[:, :2] - near[:, 2:3], near[:, :2] + near[:, 2:3]]
    return np.vstack(keep)


def _view(run: Any) -> tuple[tuple[float, float], tuple[float, float]]:
    """x and y limits: where the robot went (start, trajectory, failure point) plus a margin, square,
    within the map; the goal too when that keeps the view within ``MAX_VIEW`` (the overview shows it);
    and the hazards (boxes, posts, people where they walked) within ``HAZARD_NEAR`` of those."""
    point = getattr(run.entry.outcome, "failure_point", None)
    pts = np.vstack([run.poses[:, 1:3]] + [np.asarray([p], dtype=float) for p in (run.start, point) if p])
    with_goal = np.vstack([pts, [run.goal]]) if run.goal else pts
    if float((with_goal.max(axis=0) - with_goal.min(axis=0)).max()) + 2 * VIEW_MARGIN <= MAX_VIEW:
        pts = with_goal
    pts = np.vstack([pts, _hazard_points(run, pts)])
    lo, hi = pts.min(axis=0) - VIEW_MARGIN, pts.max(axis=0) + VIEW_MARGIN
    side = max(float((hi - lo).max()), MIN_VIEW)
    centre = (lo + hi) / 2
    h, w = run.grid.shape
    limits = []
    for c, start, size in ((centre[0], run.origin[0], w * run.resolution),
                           (centre[1], run.origin[1], h * run.resolution)):
        span = min(side, size)
        low = min(max(c - span / 2, start), start + size - span)
        limits.append((low, low + span))
    return limits[0], limits[1]


def _footprint(x: float, y: float, yaw: float) -> np.ndarray:
    from ..sims.robot_world import PIONEER2DX

    c, s = math.cos(yaw), math.sin(yaw)
    return PIONEER2DX @ np.array([[c, s], [-s, c]]) + [x, y]


def _freeze_background(fig: Any, moving: list[Any]) -> None:
    """Draw what never changes (map, axes, legend, title) once, as a picture behind the moving artists.

    Every frame then draws a few lines and two texts instead of re-laying out every tick label
    twice (matplotlib draws the whole figure for each frame it saves): about 10x faster on a busy
    2-core machine. The layout is fixed first, so the moving artists keep their place."""
    for artist in moving:
        artist.set_visible(False)
    fig.canvas.draw()  # the constrained layout settles in two rounds (tick labels follow the axes' size)
    fig.canvas.draw()
    fig.set_layout_engine("none")
    fig.canvas.draw()
    background = np.asarray(fig.canvas.buffer_rgba()).copy()
    for ax in fig.axes:
        for artist in ax.get_children():
            if artist not in moving:
                artist.set_visible(False)
        ax.set_axis_off()
    for text in fig.texts:
        text.set_visible(False)
    fig.figimage(background, 0, 0, origin="upper", zorder=-10)
    for artist in moving:
        artist.set_visible(True)


def _draw_map(ax: Any, run: Any) -> None:
    h, w = run.grid.shape
    ox, oy = run.origin
    ax.imshow(run.grid.astype(float), cmap="Greys", vmin=0, vmax=1.4, origin="lower", interpolation="nearest",
              extent=(ox, ox + w * run.resolution, oy, oy + h * run.resolution))
    ax.set_aspect("equal")


def _draw_hazards(ax: Any, run: Any) -> list[Any]:
    """The run's static hazards (boxes, posts, people's paths dashed) drawn once; returns a disc per
    person, placed by ``_place_people`` each frame (labelled only when the run has them)."""
    boxes, posts, paths, most = _hazards(run)
    for k, (x0, y0, x1, y1) in enumerate(boxes):
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fc=UNMAPPED_COLOR, ec="black", lw=0.5, alpha=0.85,
                               zorder=3, label="box, not in the map" if k == 0 else None))
    for k, (x, y, r) in enumerate(posts):
        ax.add_patch(Circle((x, y), max(r, 0.1), fc=POST_COLOR, ec="black", lw=0.5, zorder=3,
                            label="post, not in the map" if k == 0 else None))
    for path in paths:
        ax.plot(path[:, 0], path[:, 1], "--", color=PERSON_COLOR, lw=1.0, alpha=0.7, zorder=2)
    people = [Circle((0.0, 0.0), 0.25, fc=PERSON_COLOR, ec="black", lw=0.5, alpha=0.8, zorder=4,
                     label="person (dashed: path)" if k == 0 else None) for k in range(most)]
    for disc in people:
        ax.add_patch(disc)
    return people


def _place_people(people: list[Any], now: dict[str, Any] | None) -> None:
    """The discs where the people are in ``now`` (the latest markers; None: none yet, all hidden)."""
    rows = now["people"] if now is not None else np.zeros((0, 3))
    for k, disc in enumerate(people):
        if k < len(rows):
            disc.set_center(rows[k, :2])
            disc.set_radius(rows[k, 2])
        disc.set_visible(k < len(rows))


def robot_animation(run: Any, fps: float = 10.0, speed: float = 1.0, max_frames: int = MAX_FRAMES,
                    dpi: int = 80) -> tuple[Any, animation.FuncAnimation, dict[str, Any]]:
    """(figure, animation, facts): the animation of one ``RobotRun``, not yet written.

    Left the map around the robot; right an overview of the whole map (the view's frame, start,
    goal), the legend, the simulated clock and, once the verdict falls, the result's detail."""
    times, played = frame_times(float(run.poses[-1, 0]), fps, speed, max_frames)
    hold = max(int(round(HOLD_S * fps)), 0)
    outcome, verdict, t_verdict = run.entry.outcome, run.entry.verdict, run.t_verdict
    point = getattr(outcome, "failure_point", None)
    failed = bool(getattr(outcome, "failed", False))
    fig = plt.figure(figsize=FIGSIZE, dpi=dpi, layout="constrained")
    grid = fig.add_gridspec(3, 2, width_ratios=[4.2, 1.6], height_ratios=[1.5, 1.4, 1.5])
    ax, over, side = fig.add_subplot(grid[:, 0]), fig.add_subplot(grid[0, 1]), fig.add_subplot(grid[1:, 1])
    side.set_axis_off()
    _draw_map(ax, run)
    (x0, x1), (y0, y1) = _view(run)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"scenario {run.entry.scenario_id}: {verdict[:60]}", fontsize=10)
    _draw_map(over, run)
    over.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="tab:purple", lw=1.2))
    over.set_xticks([])
    over.set_yticks([])
    over.set_title("whole map", fontsize=7)
    for where in (ax, over):
        where.plot(*run.start, "o", color="tab:green", ms=8 if where is ax else 4, label="start")
        where.plot(*run.goal, "*", color="gold", mec="black", mew=0.5, ms=14 if where is ax else 8, label="goal")
    plan_line, = ax.plot([], [], "--", color="tab:blue", lw=1.3, label="its plan (/plan)") if run.plans else (None,)
    scan_dots, = ax.plot([], [], ".", color="tab:orange", ms=3, label="laser (/scan)") if run.scans else (None,)
    people = _draw_hazards(ax, run)
    trail, = ax.plot([], [], "-", color=TRAIL_COLOR, lw=1.6, label="driven (/odom)")
    body = Polygon(_footprint(*run.poses[0, 1:4]), closed=True, fc="tab:cyan", ec="black", lw=0.8, zorder=5,
                   label="pioneer2dx")
    ax.add_patch(body)
    heading, = ax.plot([], [], "-", color="black", lw=1.2, zorder=6)
    marker, = ax.plot([point[0] if point else np.nan], [point[1] if point else np.nan], "X", color=FAILURE_COLOR,
                      mec="black", ms=16, alpha=0.85, zorder=7,
                      label=f"failure point ({outcome.failure_kind})" if point else None)
    side.legend(*ax.get_legend_handles_labels(), loc="upper left", fontsize=7, frameon=False)
    clock = side.text(0.02, 0.47, "", transform=side.transAxes, va="top", fontsize=8)
    detail = side.text(0.02, 0.29, "", transform=side.transAxes, va="top", fontsize=7, visible=False,
                       bbox=dict(fc="mistyrose" if failed else "honeydew", ec="0.5"))
    if outcome is not None and outcome.detail:
        detail.set_text(textwrap.fill(outcome.detail, 30, max_lines=9))
    _freeze_background(fig, [a for a in (plan_line, scan_dots, trail, body, heading, marker, clock, detail) if a]
                       + people)
    ts = run.poses[:, 0]
    total = float(ts[-1])

    def draw(k: int):
        k = min(k, len(times) - 1)
        t = float(times[k])
        i = max(int(np.searchsorted(ts, t, side="right")) - 1, 0)
        x, y, yaw = run.poses[i, 1:4]
        trail.set_data(run.poses[: i + 1, 1], run.poses[: i + 1, 2])
        body.set_xy(_footprint(x, y, yaw))
        heading.set_data([x, x + 0.5 * math.cos(yaw)], [y, y + 0.5 * math.sin(yaw)])
        if scan_dots is not None:
            ends = _latest(run.scans, t)
            scan_dots.set_data(*(ends.T if ends is not None and len(ends) else ([], [])))
        if plan_line is not None:
            plan = _latest(run.plans, t)
            plan_line.set_data(*(plan.T if plan is not None else ([], [])))
        if people:
            _place_people(people, _latest(run.markers, t))
        decided = k == len(times) - 1 or (t_verdict is not None and t >= t_verdict)
        marker.set_visible(decided and point is not None)
        detail.set_visible(decided and bool(detail.get_text()))
        clock.set_text(f"t = {t:5.1f} s of {total:.1f} s\n(simulated; {played:.3g}x)"
                       + (f"\n{verdict[:30]}" if decided else ""))
        return (trail, body, heading, marker, detail, clock, *people)

    anim = animation.FuncAnimation(fig, draw, frames=len(times) + hold, blit=False, repeat=False)
    facts = {"frames": len(times), "hold_frames": hold, "fps": fps, "playback": played, "duration_s": total,
             "pixels": (int(round(FIGSIZE[0] * dpi)), int(round(FIGSIZE[1] * dpi)))}
    return fig, anim, facts


def save_robot_animation(run: Any, path: str | Path, fps: float = 10.0, speed: float = 1.0,
                         max_frames: int = MAX_FRAMES, overwrite: bool = False) -> dict[str, Any]:
    """Write the animation (.gif with Pillow, .mp4 with ffmpeg); an existing file is refused unless
    ``overwrite``. Written beside the target and moved in at the end, so a failed or interrupted
    drawing never leaves half a file under the name (and a file that appeared meanwhile is kept)."""
    path = check_output(path, overwrite)
    fig, anim, facts = robot_animation(run, fps, speed, max_frames)
    writer = animation.PillowWriter(fps=fps) if path.suffix.lower() == ".gif" else animation.FFMpegWriter(fps=fps)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.{secrets.token_hex(4)}.partial{path.suffix}")
    try:
        anim.save(tmp, writer=writer, dpi=fig.dpi)
        if overwrite:
            os.replace(tmp, path)
        else:
            try:
                os.link(tmp, path)  # fails if the name was taken meanwhile: never drawn over
            except FileExistsError:
                raise ValueError(f"{path} already exists; refusing to overwrite it "
                                 "(another -o, or --overwrite)") from None
    finally:
        plt.close(fig)
        Path(tmp).unlink(missing_ok=True)
    return {**facts, "path": str(path)}


__all__ = ["MAX_FRAMES", "check_output", "frame_times", "robot_animation", "save_robot_animation"]
