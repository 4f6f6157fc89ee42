"""One robot scenario's streams out of a robot bag: what ``ambiegen show RUN.mcap --scenario ID`` animates.

A robot bag is a run's MCAP that also holds the robot's own topics (``ambiegen campaign --stack
nd`` records them): ``/odom``, ``/scan``, ``/plan``, ``/tf``. A bag may hold several runs (a
``bench/nav2_maps.py`` batch logs a run per map): every run is indexed, the first one is shown unless
another is picked (``ambiegen show RUN.mcap --run ID``). A scenario's stretch of the bag is found by log
time: it ends at its result on ``/ambiegen/results``, and starts at the last ``/initialpose``
(else ``/goal_pose``, ``/map``) logged between its scenario message and that result, else at the
scenario message (one system under test runs one scenario at a time, so that is its set-up).
Within it every stream is put on one clock, the messages' header stamps: simulated seconds for a
simulator in lockstep, whose run goes faster than the log's wall clock. A recorder that lagged
on a loaded machine took a fast run's last states after its result: a message logged after the
result (up to the next scenario's message) still belongs to the run when its publish time (when
it was sent, which the recorder keeps beside the time it took it) is not after the result's.
Only those late ones are judged by publish time, so a host whose clock is off cuts nothing more.

Poses are turned into the map frame with ``/tf``'s ``map -> <odom frame>`` (identity when absent)
and each scan into map-frame beam ends from the pose at its stamp and ``/tf_static``'s sensor
offset, so the drawing side needs no ROS. Samples from before the robot is shown at the
scenario's start (a world still showing the last run) are dropped, as ``sut_adapter`` ignores them.

A hosted world with unmapped obstacles (issue 48: boxes, thin posts, walking people) shows them on
``/ambiegen/world/markers`` with every scan (``conversions.obstacle_markers``); they are read into
``RobotRun.markers`` as plain arrays in the map frame. A bag without them (older bags, worlds
without hazards) gives an empty list.
"""
from __future__ import annotations

import bisect
import math
import struct
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..core.errors import BadInput
from ..sims.outcome import Outcome
from . import topics
from .conversions import grid_from_message, outcome_from_message, path_points, safe_echo, stamp_ns, yaw_of
from .runlog import iter_timed

ROBOT_SCENARIOS = topics.scenarios("robot")
ODOM, SCAN, PLAN, TF, TF_STATIC = "/odom", "/scan", "/plan", "/tf", "/tf_static"
SETUP_TOPICS = ("/initialpose", "/goal_pose", "/map")  # what starts a scenario on the stack, most telling first
START_TOLERANCE = 0.5  # a pose this close to the scenario's start shows the new run [m] (sut_adapter's default)
MARKERS = topics.WORLD_MARKERS  # the world's unmapped obstacles and people (a stack in /<ns>: /<ns> + this)
MARKER_ADD = 0  # visualization_msgs/Marker ADD (= MODIFY); DELETE and DELETEALL draw nothing


@dataclass
class ScenarioEntry:
    """A scenario of one run of the bag, as listed: id, verdict and its stretch of log time."""

    scenario_id: int
    outcome: Outcome | None  # None: no result logged
    start_ns: int  # log time of its set-up (see the module docstring)
    end_ns: int  # log time of its result (of the bag's last message when there is none)
    goal_ns: int | None = None  # log time of its goal on /goal_pose, when logged
    # its result's and goal's publish times (= log times in a bag that kept none), and the log time up
    # to which a lagging recorder may still have logged the run (the next scenario's message, or the bag's end)
    end_pub_ns: int | None = None
    goal_pub_ns: int | None = None
    read_end_ns: int | None = None

    @property
    def verdict(self) -> str:
        """PASS, FAIL(kind), ... on one line (a logged detail may hold anything)."""
        return "NO RESULT" if self.outcome is None else " ".join(self.outcome.verdict.split())


@dataclass
class BagIndex:
    """The light pass over a bag: the run shown, its scenarios in id order, where the bag starts, which
    topics it has, and every run of the bag (``select`` shows another)."""

    path: Path
    run_id: str  # as it may be echoed (``conversions.safe_echo``)
    entries: dict[int, ScenarioEntry]
    scenario_msgs: dict[int, Any]  # the first scenario message of each id
    bag_start_ns: int
    topic_counts: dict[str, int]
    # every run in the order of its first scenario message: logged run id -> (entries, scenario messages)
    runs: dict[str, tuple[dict[int, ScenarioEntry], dict[int, Any]]] = field(default_factory=dict)

    def select(self, run_id: str) -> "BagIndex":
        """The same index showing another run, named as logged or as echoed (``BadInput``: no such run)."""
        for logged, (entries, msgs) in self.runs.items():
            if run_id in (logged, safe_echo(logged)):
                return replace(self, run_id=safe_echo(logged), entries=entries, scenario_msgs=msgs)
        shown = ", ".join(safe_echo(r) for r in list(self.runs)[:10]) + (", ..." if len(self.runs) > 10 else "")
        raise BadInput(f"{self.path}: no run {safe_echo(run_id)!r} in the bag (runs: {shown})")


@dataclass
class RobotRun:
    """One scenario's streams, in the map frame, on the stamps' clock (``t`` in s from the first pose).

    ``poses`` is (N, 4): t, x, y, yaw; ``scans`` and ``plans`` are (t, (K, 2) points) in stamp
    order; ``grid`` is bool [y, x] (walls), cell (0, 0) at ``origin``. ``markers`` are (t, what the
    world held besides the map then), in stamp order: ``boxes`` (B, 4) x0, y0, x1, y1; ``posts``
    (P, 3) and ``people`` (M, 3) cx, cy, r; ``people_paths`` a (K, 2) polyline per person."""

    entry: ScenarioEntry
    run_id: str
    grid: np.ndarray
    resolution: float
    origin: tuple[float, float]
    start: tuple[float, float] | None
    goal: tuple[float, float] | None
    poses: np.ndarray
    scans: list[tuple[float, np.ndarray]] = field(default_factory=list)
    plans: list[tuple[float, np.ndarray]] = field(default_factory=list)
    markers: list[tuple[float, dict[str, Any]]] = field(default_factory=list)
    dropped_before_start: int = 0  # poses of the last run still shown at the start of the stretch
    t_goal: float = 0.0  # when the goal was given: the first pose logged after it (the adapter's t = 0)

    @property
    def t_verdict(self) -> float | None:
        """When the verdict fell on this clock: the goal's time + the result's ``time`` metric (None: unknown)."""
        try:
            t = self.t_goal + float((self.entry.outcome.metrics or {})["time"])
        except (AttributeError, KeyError, TypeError, ValueError):
            return None
        return t if math.isfinite(t) else None


def read_index(path: str | Path, run_id: str | None = None) -> BagIndex:
    """Scenarios, results and set-up messages of every robot run of the bag (one light pass), showing
    ``run_id`` (default: the first run logged).

    Raises ``BadInput`` (one line) for a file that is not an MCAP, holds no robot scenario or not that run."""
    from mcap.exceptions import McapError

    path = Path(path)
    if not path.is_file():
        raise BadInput(f"{path}: no such file")
    scenario_ns: dict[str, dict[int, int]] = {}  # run id -> scenario id -> log time of its first message
    scenario_msgs: dict[str, dict[int, Any]] = {}
    results: dict[tuple[str, int], tuple[int, Any, int]] = {}  # (run id, scenario id) -> (log time, message, publish time)
    setups: list[tuple[int, str, int]] = []  # log time, topic, publish time
    other_problems: set[str] = set()
    wanted = {ROBOT_SCENARIOS, topics.RESULTS, *SETUP_TOPICS} | {topics.scenarios(p) for p in topics.SCENARIO_TYPES}
    try:
        counts, first_ns, last_ns = bag_summary(path)
        for topic, _, log_ns, pub_ns, msg in _messages(path, wanted & set(counts)):
            if topic == ROBOT_SCENARIOS:
                sid = int(msg.meta.scenario_id)
                if sid not in scenario_msgs.setdefault(msg.meta.run_id, {}):
                    scenario_msgs[msg.meta.run_id][sid] = msg
                    scenario_ns.setdefault(msg.meta.run_id, {})[sid] = log_ns
            elif topic == topics.RESULTS:
                results.setdefault((msg.run_id, int(msg.scenario_id)), (log_ns, msg, pub_ns))
            elif topic in SETUP_TOPICS:
                setups.append((log_ns, topic, pub_ns))
            else:
                other_problems.add(topic.split("/")[2])
    except (McapError, OSError, ValueError, KeyError, IndexError, EOFError, struct.error) as exc:  # not an MCAP
        raise BadInput(f"{path}: not a readable MCAP log ({type(exc).__name__}: {exc}; a log cut short by a "
                       "killed recorder: `ambiegen recover` rebuilds it)") from None
    if not scenario_msgs:
        what = f"a {'/'.join(sorted(other_problems))} run" if other_problems else "no scenario messages"
        raise BadInput(f"{path}: not a robot bag ({what}; nothing on {ROBOT_SCENARIOS})")
    runs = {}
    sent = sorted(t for ids in scenario_ns.values() for t in ids.values())  # every run's scenario messages
    for run, msgs in scenario_msgs.items():
        entries = {}
        for sid in sorted(msgs):
            logged = results.get((run, sid))
            end = logged[0] if logged else last_ns
            start = scenario_ns[run][sid]
            for name in SETUP_TOPICS:  # the last set-up of this scenario, most telling topic first
                found = [t for t, topic, _ in setups if topic == name and start <= t < end]
                if found:
                    start = found[-1]
                    break
            goals = [(t, pub) for t, topic, pub in setups if topic == "/goal_pose" and start <= t < end]
            k = bisect.bisect_right(sent, end)  # the next scenario message after the result
            entries[sid] = ScenarioEntry(sid, outcome_from_message(logged[1]) if logged else None, start, end,
                                         goals[-1][0] if goals else None, logged[2] if logged else None,
                                         goals[-1][1] if goals else None,
                                         sent[k] if k < len(sent) else last_ns + 1)
        runs[run] = (entries, dict(sorted(msgs.items())))
    first = next(iter(runs))
    index = BagIndex(path, safe_echo(first), runs[first][0], runs[first][1], first_ns, counts, runs)
    return index if run_id is None else index.select(run_id)


def _messages(path: Path, names: set[str], start_ns: int | None = None, end_ns: int | None = None):
    """``runlog.iter_timed`` of these topics only: none named reads nothing (not the whole bag)."""
    return iter_timed(path, names, start_ns, end_ns) if names else iter(())


def bag_summary(path: Path) -> tuple[dict[str, int], int, int]:
    """Messages per topic and the log times of the first and last message, from the summary (a bag
    without one, as a killed recorder leaves it: by reading it once, undecoded)."""
    from mcap.reader import make_reader

    with open(path, "rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        if summary is not None and summary.statistics is not None:
            stats = summary.statistics
            counts = {summary.channels[cid].topic: n for cid, n in stats.channel_message_counts.items()}
            return counts, stats.message_start_time, stats.message_end_time
        counts, first, last = {}, None, 0
        for _, channel, message in reader.iter_messages(log_time_order=False):
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            first = message.log_time if first is None else min(first, message.log_time)
            last = max(last, message.log_time)
        return counts, first or 0, last


def read_run(index: BagIndex, scenario_id: int) -> RobotRun:
    """The streams of one scenario (``BadInput``: no such id, or no ``/odom`` for it)."""
    entry = index.entries.get(scenario_id)
    if entry is None:
        ids = list(index.entries)
        shown = ", ".join(map(str, ids[:20])) + (", ..." if len(ids) > 20 else "")
        raise BadInput(f"{index.path}: no scenario {scenario_id} in run {index.run_id} (ids: {shown})")
    if not index.topic_counts.get(ODOM):
        raise BadInput(f"{index.path}: no {ODOM} in the bag, nothing to animate (a campaign with --stack nd "
                       "records the robot's topics)")
    msg = index.scenario_msgs[scenario_id]
    grid = grid_from_message(msg.map)
    info = msg.map.info
    start = (float(msg.start.pose.position.x), float(msg.start.pose.position.y))
    goal = (float(msg.goal.pose.position.x), float(msg.goal.pose.position.y))
    frames = Frames()
    for _, _, _, _, tf in _messages(index.path, {TF_STATIC} & set(index.topic_counts)):
        frames.add(tf, static=True)
    odom: list[tuple[int, int, Any]] = []  # stamp, publish time, message
    scans: list[tuple[int, Any]] = []
    plans: list[tuple[int, Any]] = []
    markers: list[tuple[int, Any]] = []
    markers_topic = world_markers_topic(index.topic_counts)
    wanted = ({ODOM, SCAN, PLAN, TF} & set(index.topic_counts)) | ({markers_topic} if markers_topic else set())
    for topic, _, log_ns, pub_ns, m in _messages(index.path, wanted, entry.start_ns, entry.read_end_ns or entry.end_ns + 1):
        if log_ns > entry.end_ns and (entry.end_pub_ns is None or pub_ns > entry.end_pub_ns):
            continue  # logged after its result, and sent after it too (see the module docstring)
        if topic == TF:
            frames.add(m)
        elif topic == ODOM:
            odom.append((stamp_ns(m.header), pub_ns, m))
        elif topic == markers_topic:
            if m.markers:  # an empty array carries no stamp (and no obstacle)
                markers.append((stamp_ns(m.markers[0].header), m))
        else:
            (scans if topic == SCAN else plans).append((stamp_ns(m.header), m))
    if not odom:
        raise BadInput(f"{index.path}: no {ODOM} message while scenario {scenario_id} ran "
                       f"(log time {entry.start_ns / 1e9:.3f}..{entry.end_ns / 1e9:.3f} s)")
    odom.sort(key=lambda item: item[0])
    poses = np.array([frames.in_map(m.header.frame_id or "map", stamp, m.pose.pose) for stamp, _, m in odom])
    stamps = np.array([stamp for stamp, _, _ in odom], dtype=np.int64)
    near = np.hypot(poses[:, 0] - start[0], poses[:, 1] - start[1]) <= START_TOLERANCE
    first = int(np.argmax(near)) if near.any() else 0
    poses, stamps, odom = poses[first:], stamps[first:], odom[first:]
    t0 = int(stamps[0])
    after_goal = [stamp for stamp, pub_ns, _ in odom if entry.goal_pub_ns is not None and pub_ns >= entry.goal_pub_ns]
    body = odom[0][2].child_frame_id or "base_link"
    run = RobotRun(entry, index.run_id, grid, float(info.resolution),
                   (float(info.origin.position.x), float(info.origin.position.y)), start, goal,
                   np.column_stack([(stamps - t0) / 1e9, poses]), dropped_before_start=first,
                   t_goal=(after_goal[0] - t0) / 1e9 if after_goal else 0.0)
    for stamp, m in sorted(scans, key=lambda item: item[0]):
        if stamp < t0:
            continue
        k = max(int(np.searchsorted(stamps, stamp, side="right")) - 1, 0)
        sensor = frames.static_offset(body, m.header.frame_id)
        run.scans.append(((stamp - t0) / 1e9, beam_ends(m, poses[k], sensor)))
    for stamp, m in sorted(plans, key=lambda item: item[0]):
        points = path_points(m)
        if len(points):
            run.plans.append(((stamp - t0) / 1e9, points))
    for stamp, m in sorted(markers, key=lambda item: item[0]):
        if stamp >= t0:  # from before: the last scenario's world
            run.markers.append(((stamp - t0) / 1e9, hazards_of(m, frames, stamp)))
    return run


def world_markers_topic(topic_counts: dict[str, int]) -> str | None:
    """The bag's ``/ambiegen/world/markers``: the root namespace's, like ``/odom``; else the one stack's
    in a namespace (``/<ns>/ambiegen/world/markers``); None when there is none, or several stacks' to
    choose from (a ``stacks:=K`` campaign: which stack ran the scenario is not in its messages)."""
    if topic_counts.get(MARKERS):
        return MARKERS
    found = [t for t, n in topic_counts.items() if n and t.endswith(MARKERS) and t.startswith("/")]
    return found[0] if len(found) == 1 else None


def hazards_of(msg: Any, frames: "Frames", stamp: int) -> dict[str, Any]:
    """A world's ``MarkerArray`` (``conversions.obstacle_markers``) as plain map-frame arrays: ``boxes``
    (B, 4) x0, y0, x1, y1 (axis-aligned, as the world holds them); ``posts`` and ``people`` (N, 3) cx, cy,
    r; ``people_paths``, a (K, 2) polyline per person. Namespaces it does not know are left out."""
    rows: dict[str, list[tuple[int, Any]]] = {"unmapped_boxes": [], "unmapped_posts": [], "people": [],
                                              "people_paths": []}
    for m in msg.markers:
        if m.ns in rows and int(m.action) == MARKER_ADD:
            x, y, yaw = frames.in_map(m.header.frame_id or "map", stamp, m.pose)
            sx, sy = float(m.scale.x), float(m.scale.y)
            if m.ns == "unmapped_boxes":
                value: Any = (x - sx / 2, y - sy / 2, x + sx / 2, y + sy / 2)
            elif m.ns == "people_paths":
                c, s = math.cos(yaw), math.sin(yaw)
                local = np.array([[p.x, p.y] for p in m.points], dtype=float).reshape(-1, 2)
                value = local @ np.array([[c, s], [-s, c]]) + [x, y]
            else:
                value = (x, y, sx / 2)
            rows[m.ns].append((int(m.id), value))

    def table(ns: str, columns: int) -> np.ndarray:
        return np.array([v for _, v in sorted(rows[ns], key=lambda r: r[0])], dtype=float).reshape(-1, columns)

    return {"boxes": table("unmapped_boxes", 4), "posts": table("unmapped_posts", 3), "people": table("people", 3),
            "people_paths": [v for _, v in sorted(rows["people_paths"], key=lambda r: r[0])]}


def beam_ends(scan: Any, pose: np.ndarray, sensor: tuple[float, float, float]) -> np.ndarray:
    """Map-frame (K, 2) points where the beams of a ``LaserScan`` hit something (no-return beams left out)."""
    ranges = np.asarray(scan.ranges, dtype=float)
    angles = float(scan.angle_min) + float(scan.angle_increment) * np.arange(len(ranges))
    hit = np.isfinite(ranges) & (ranges >= float(scan.range_min)) & (ranges < float(scan.range_max))
    x, y, yaw = pose
    sx, sy, syaw = sensor
    ox, oy = x + sx * math.cos(yaw) - sy * math.sin(yaw), y + sx * math.sin(yaw) + sy * math.cos(yaw)
    a = yaw + syaw + angles[hit]
    return np.column_stack([ox + ranges[hit] * np.cos(a), oy + ranges[hit] * np.sin(a)])


class Frames:
    """The planar transforms a robot bag holds: ``/tf`` edges by stamp, ``/tf_static`` edges once.

    Only single edges are looked up (``map -> odom``, ``base_link -> base_scan``): what a 2D
    robot stack publishes; a missing edge is the identity."""

    def __init__(self) -> None:
        self.dynamic: dict[tuple[str, str], tuple[list[int], list[tuple[float, float, float]]]] = {}
        self.static: dict[tuple[str, str], tuple[float, float, float]] = {}

    def add(self, msg: Any, static: bool = False) -> None:
        for tf in msg.transforms:
            key = (tf.header.frame_id.lstrip("/"), tf.child_frame_id.lstrip("/"))
            planar = (float(tf.transform.translation.x), float(tf.transform.translation.y),
                      yaw_of(tf.transform.rotation))
            if static:
                self.static[key] = planar
            else:
                stamps, values = self.dynamic.setdefault(key, ([], []))
                k = bisect.bisect_right(stamps, stamp_ns(tf.header))  # in stamp order, whatever the log order
                stamps.insert(k, stamp_ns(tf.header))
                values.insert(k, planar)

    def static_offset(self, parent: str, child: str) -> tuple[float, float, float]:
        return self.static.get((parent.lstrip("/"), child.lstrip("/")), (0.0, 0.0, 0.0))

    def in_map(self, frame: str, stamp: int, pose: Any) -> tuple[float, float, float]:
        """A pose of ``frame`` as (x, y, yaw) in ``map``, with the latest ``map -> frame`` at or before ``stamp``."""
        x, y, yaw = float(pose.position.x), float(pose.position.y), yaw_of(pose.orientation)
        frame = frame.lstrip("/")
        if frame == "map":
            return x, y, yaw
        stamps, values = self.dynamic.get(("map", frame), ([], []))
        k = bisect.bisect_right(stamps, stamp)
        tx, ty, tyaw = values[k - 1] if k else self.static.get(("map", frame), (0.0, 0.0, 0.0))
        c, s = math.cos(tyaw), math.sin(tyaw)
        return tx + c * x - s * y, ty + s * x + c * y, tyaw + yaw


__all__ = ["BagIndex", "RobotRun", "ScenarioEntry", "read_index", "read_run"]
