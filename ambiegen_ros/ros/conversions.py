"""Every conversion between core objects and ROS messages, in one module.

Messages are built with ``make(typename, **fields)``, the backend-native factory of the transport
seam (``node.new_message``), so the same code fills rclpy classes or the DDS backend's types.
Incoming messages are read by attribute only, which both backends support.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ..core.attributes import Categorical, ScenarioError
from ..core.scenario import Scenario
from ..core.problem import Problem
from ..sims.outcome import FAILURE_KINDS, FAILURE_NAMES, Outcome
from . import topics
from .limits import MAX_JSON_DEPTH, MAX_NAME_LENGTH, NAME_RULE, UnsafeName, check_name, json_depth

Make = Callable[..., Any]


@dataclass
class ScenarioMeta:
    """Identity and surrogate fitness of a scenario as the generator publishes it."""

    run_id: str
    scenario_id: int
    generation: int = 0
    seed: int = 0
    f1: float = 0.0
    f2: float = float("nan")
    valid: bool = True
    reason: str = ""
    worker: str = ""
    attempt: int = 1


# --- small standard pieces ---------------------------------------------------------------------
def stamp(make: Make, now_ns: int) -> Any:
    return make("builtin_interfaces/msg/Time", sec=int(now_ns // 1_000_000_000), nanosec=int(now_ns % 1_000_000_000))


def header(make: Make, now_ns: int, frame_id: str = "map") -> Any:
    return make("std_msgs/msg/Header", stamp=stamp(make, now_ns), frame_id=frame_id)


def stamp_ns(msg_header: Any) -> int:
    return int(msg_header.stamp.sec) * 1_000_000_000 + int(msg_header.stamp.nanosec)


def pose(make: Make, x: float, y: float, yaw: float = 0.0) -> Any:
    return make(
        "geometry_msgs/msg/Pose",
        position=make("geometry_msgs/msg/Point", x=float(x), y=float(y), z=0.0),
        orientation=make("geometry_msgs/msg/Quaternion", x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
    )


def yaw_of(q: Any) -> float:
    """Heading from a quaternion (any roll/pitch ignored)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def pose_stamped(make: Make, now_ns: int, x: float, y: float, yaw: float = 0.0) -> Any:
    return make("geometry_msgs/msg/PoseStamped", header=header(make, now_ns), pose=pose(make, x, y, yaw))


def path(make: Make, now_ns: int, points: np.ndarray | None) -> Any:
    """A polyline as ``nav_msgs/Path``; each pose heads towards the next point."""
    pts = np.zeros((0, 2)) if points is None else np.asarray(points, dtype=float).reshape(-1, 2)
    if len(pts) > 1:
        d = np.diff(pts, axis=0)
        yaw = np.arctan2(d[:, 1], d[:, 0])
        yaw = np.append(yaw, yaw[-1])
    else:
        yaw = np.zeros(len(pts))
    poses = [pose_stamped(make, now_ns, x, y, a) for (x, y), a in zip(pts, yaw)]
    return make("nav_msgs/msg/Path", header=header(make, now_ns), poses=poses)


def path_points(msg_path: Any) -> np.ndarray:
    return np.array([[p.pose.position.x, p.pose.position.y] for p in msg_path.poses], dtype=float).reshape(-1, 2)


# --- a robot's world: odometry, transforms, laser, velocity commands ------------------------------
def odometry(make: Make, now_ns: int, x: float, y: float, yaw: float, v: float = 0.0, w: float = 0.0,
             frame_id: str = "map", child_frame_id: str = "base_link", vy: float = 0.0) -> Any:
    """``nav_msgs/Odometry``: the pose in ``frame_id``, the twist (forward, turn and, for an
    omnidirectional base, sideways ``vy``) in the body frame."""
    twist = make("geometry_msgs/msg/Twist", linear=make("geometry_msgs/msg/Vector3", x=float(v), y=float(vy), z=0.0),
                 angular=make("geometry_msgs/msg/Vector3", x=0.0, y=0.0, z=float(w)))
    return make("nav_msgs/msg/Odometry", header=header(make, now_ns, frame_id), child_frame_id=child_frame_id,
                pose=make("geometry_msgs/msg/PoseWithCovariance", pose=pose(make, x, y, yaw)),
                twist=make("geometry_msgs/msg/TwistWithCovariance", twist=twist))


def transform(make: Make, now_ns: int, parent: str, child: str, x: float = 0.0, y: float = 0.0,
              yaw: float = 0.0) -> Any:
    """``geometry_msgs/TransformStamped`` of a planar pose (for ``tf2_msgs/TFMessage``)."""
    return make("geometry_msgs/msg/TransformStamped", header=header(make, now_ns, parent), child_frame_id=child,
                transform=make("geometry_msgs/msg/Transform",
                               translation=make("geometry_msgs/msg/Vector3", x=float(x), y=float(y), z=0.0),
                               rotation=make("geometry_msgs/msg/Quaternion", x=0.0, y=0.0, z=math.sin(yaw / 2),
                                             w=math.cos(yaw / 2))))


def laser_scan(make: Make, now_ns: int, frame_id: str, angle_min: float, angle_max: float, ranges: np.ndarray,
               range_max: float, scan_time: float = 0.0) -> Any:
    """``sensor_msgs/LaserScan`` of beams spread evenly from ``angle_min`` to ``angle_max``."""
    ranges = np.asarray(ranges, dtype=np.float32)
    n = len(ranges)
    return make("sensor_msgs/msg/LaserScan", header=header(make, now_ns, frame_id), angle_min=float(angle_min),
                angle_max=float(angle_max), angle_increment=float((angle_max - angle_min) / max(n - 1, 1)),
                time_increment=0.0, scan_time=float(scan_time), range_min=0.0, range_max=float(range_max),
                ranges=ranges, intensities=np.zeros(0, dtype=np.float32))


def scan_beams(msg: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A LaserScan's beam angles, ranges and which beams hit something within range (finite,
    inside [range_min, range_max]; REP 117: inf = no return)."""
    ranges = np.asarray(msg.ranges, dtype=float)
    angles = np.linspace(float(msg.angle_min), float(msg.angle_max), len(ranges)) if len(ranges) > 1 \
        else np.full(len(ranges), float(msg.angle_min))
    with np.errstate(invalid="ignore"):
        hits = np.isfinite(ranges) & (ranges >= float(msg.range_min)) & (ranges <= float(msg.range_max))
    return angles, ranges, hits


def velocity_command(msg: Any) -> tuple[float, float]:
    """(forward m/s, turn rad/s) of a ``geometry_msgs/Twist`` or ``TwistStamped``; both finite."""
    twist = getattr(msg, "twist", msg)
    v, w = require_finite((twist.linear.x, twist.angular.z), "twist")
    return float(v), float(w)


STATUS_OK, STATUS_WARN, STATUS_ERROR = 0, 1, 2  # diagnostic_msgs/DiagnosticStatus levels
STATUS_TEXT_LIMIT = 240  # characters of a status's reason kept (a sentence with its numbers: a contact's speeds)


def status_report(make: Make, now_ns: int, name: str, problem: str = "", frame_id: str = "", note: str = "") -> Any:
    """A stamped status (``diagnostic_msgs/DiagnosticArray``, one status): level ERROR with
    ``problem`` as its message (the stack gave up, the body touches a wall), else WARN with
    ``note`` (something a judge records but does not count: a person walked into a standing
    robot), else OK. Sent every cycle, the OK and WARN ones are heartbeats: they tell a judge that
    nothing happened up to their stamp."""
    level = STATUS_ERROR if problem else STATUS_WARN if note else STATUS_OK
    status = make("diagnostic_msgs/msg/DiagnosticStatus", level=level, name=name,
                  message=problem or note, hardware_id="")
    return make("diagnostic_msgs/msg/DiagnosticArray", header=header(make, now_ns, frame_id), status=[status])


PARTS = ("stack", "ours")  # whose process an event is about: the system under test's, or ours


def stack_event(make: Make, now_ns: int, process: str, part: str, what: str) -> Any:
    """An event of a run's processes (``topics.STACK_EVENTS``): ``process`` (e.g. controller_server)
    of ``part`` (stack | ours) ``what`` (killed by SIGKILL, hung: no /cmd_vel for 30 s)."""
    if part not in PARTS:
        raise ValueError(f"part: {part!r} is not one of {PARTS}")
    status = make("diagnostic_msgs/msg/DiagnosticStatus", level=STATUS_ERROR, name=plain_text(process),
                  message=plain_text(what, STATUS_TEXT_LIMIT), hardware_id=part)
    return make("diagnostic_msgs/msg/DiagnosticArray", header=header(make, now_ns, ""), status=[status])


def plain_text(text: Any, limit: int = 80) -> str:
    """A received string made safe to echo in words: printable characters only, clipped."""
    text = "".join(c if c.isprintable() else "?" for c in str(text))
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def stack_events_of(msg: Any) -> list[tuple[str, str, str]]:
    """(process, part, what) of each ERROR status of a stack event message (unknown parts: stack)."""
    out = []
    for status in msg.status:
        level = status.level[0] if isinstance(status.level, (bytes, bytearray)) else int(status.level)
        if level == STATUS_ERROR:
            part = str(status.hardware_id) if str(status.hardware_id) in PARTS else "stack"
            out.append((plain_text(status.name) or "a process", part,
                        plain_text(status.message, STATUS_TEXT_LIMIT) or "died"))
    return out


# --- a hosted world's unmapped obstacles and people (issue 48) -----------------------------------
MARKER_CUBE, MARKER_CYLINDER, MARKER_LINE_STRIP = 1, 3, 4


def obstacles_message(make: Make, stamp_ns_: int, obstacles: dict) -> Any:
    """What a world holds besides the map (``sims.obstacles.Obstacles.to_dict``) for the scenario
    whose map and start pose carry ``stamp_ns_``: ``std_msgs/String`` JSON (a contract of ours,
    like the thermostat's room model topic)."""
    return make("std_msgs/msg/String", data=json.dumps({"stamp_ns": int(stamp_ns_), "obstacles": obstacles}))


def obstacles_from_message(msg: Any) -> tuple[int, dict]:
    """(stamp ns, obstacles dict) of ``obstacles_message``; raises ValueError on anything else."""
    try:
        data = json.loads(msg.data)
        return int(data["stamp_ns"]), dict(data["obstacles"])
    except (TypeError, ValueError, KeyError) as exc:
        raise ValueError(f"obstacles message: expected JSON {{'stamp_ns', 'obstacles'}} ({exc})") from None


def obstacle_markers(make: Make, now_ns: int, obstacles: Any, t: float, frame_id: str = "map") -> Any:
    """``visualization_msgs/MarkerArray`` of what is in the world but not in the map, at world time
    ``t``: boxes (orange cubes), posts (orange cylinders), people (purple cylinders, and each one's
    path as a line), so RViz and Foxglove show what the stack was not told."""
    markers = []
    head = header(make, now_ns, frame_id)

    def marker(ns: str, k: int, kind: int, x: float, y: float, sx: float, sy: float, sz: float, rgba, points=()):
        markers.append(make(
            "visualization_msgs/msg/Marker", header=head, ns=ns, id=int(k), type=kind, action=0,
            pose=pose(make, x, y), scale=make("geometry_msgs/msg/Vector3", x=float(sx), y=float(sy), z=float(sz)),
            color=make("std_msgs/msg/ColorRGBA", r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3]),
            points=[make("geometry_msgs/msg/Point", x=float(px), y=float(py), z=0.0) for px, py in points]))

    orange, purple = (1.0, 0.5, 0.0, 0.9), (0.5, 0.2, 0.7, 0.9)
    for k, (x0, y0, x1, y1) in enumerate(np.asarray(obstacles.boxes, dtype=float)):
        marker("unmapped_boxes", k, MARKER_CUBE, (x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0, 0.5, orange)
    for k, (x, y, r) in enumerate(np.asarray(obstacles.posts, dtype=float)):
        marker("unmapped_posts", k, MARKER_CYLINDER, x, y, 2 * r, 2 * r, 1.0, orange)
    for k, person in enumerate(obstacles.people):
        x, y = person.position(t)
        marker("people", k, MARKER_CYLINDER, x, y, 2 * person.radius, 2 * person.radius, 1.7, purple)
        marker("people_paths", k, MARKER_LINE_STRIP, 0.0, 0.0, 0.03, 0.0, 0.0, (0.5, 0.2, 0.7, 0.5),
               points=np.asarray(person.path, dtype=float))
    return make("visualization_msgs/msg/MarkerArray", markers=markers)


def status_note(msg: Any) -> str | None:
    """The first WARN status's message of a ``DiagnosticArray`` (``status_report``'s ``note``), else None."""
    for status in msg.status:
        level = status.level[0] if isinstance(status.level, (bytes, bytearray)) else int(status.level)
        if level == STATUS_WARN:
            return clip_text(status.message, STATUS_TEXT_LIMIT) or "no reason given"
    return None


def status_problem(msg: Any) -> tuple[int, str | None]:
    """(stamp ns, the first ERROR status's message, else None) of a ``DiagnosticArray``; rclpy
    gives a ``byte`` level as bytes, the DDS backend as an int."""
    for status in msg.status:
        level = status.level[0] if isinstance(status.level, (bytes, bytearray)) else int(status.level)
        if level == STATUS_ERROR:
            return stamp_ns(msg.header), clip_text(status.message, STATUS_TEXT_LIMIT) or clip_text(status.name) \
                or "no reason given"
    return stamp_ns(msg.header), None


def key_values(make: Make, values: dict[str, Any]) -> list[Any]:
    return [make("diagnostic_msgs/msg/KeyValue", key=str(k), value=_text(v)) for k, v in values.items()]


def _text(value: Any) -> str:
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (dict, list, tuple)):
        return json.dumps(value)
    return str(value)


# --- scenarios -----------------------------------------------------------------------------------
def genome_cells(problem: Problem, scenario: Scenario) -> np.ndarray:
    """The scenario's used genome cells as an (elements, attributes) matrix of codes."""
    G, lengths = problem.codec.split(problem.codec.to_row(scenario))
    return G[0, : lengths[0]]


def scenario_header(
    make: Make, now_ns: int, problem: Problem, scenario: Scenario, meta: ScenarioMeta, cells: np.ndarray | None = None
) -> Any:
    codec = problem.codec
    genome = (genome_cells(problem, scenario) if cells is None else cells).reshape(-1)
    categorical = ["|".join(map(str, a.values)) if isinstance(a, Categorical) else "" for a in codec.attributes]
    return make(
        "ambiegen_msgs/msg/ScenarioHeader",
        header=header(make, now_ns),
        run_id=meta.run_id,
        scenario_id=int(meta.scenario_id),
        generation=int(meta.generation),
        seed=int(meta.seed),
        problem=problem.name,
        attribute_names=list(codec.names),
        categorical_values=categorical,
        genome=np.asarray(genome, dtype=np.float64),
        scenario_json=json.dumps(scenario.to_dict(), separators=(",", ":")),
        f1=float(meta.f1),
        f2=float(meta.f2),
        surrogate_valid=bool(meta.valid),
        invalid_reason=meta.reason or "",
        assigned_worker=meta.worker,
        attempt=int(meta.attempt),
    )


def scenario_message(make: Make, now_ns: int, problem: Problem, scenario: Scenario, meta: ScenarioMeta) -> Any:
    """The problem's scenario message: the genome plus its environment in standard types."""
    cells = genome_cells(problem, scenario)
    meta_msg = scenario_header(make, now_ns, problem, scenario, meta, cells)
    typename = topics.SCENARIO_TYPES[problem.name]
    if problem.name == "thermostat":
        # Straight from the genome: problem.environment() would simulate the whole schedule
        # (~10 ms) only to hand back these columns. The room starts at the first set point, as in
        # ThermostatProblem.environment (a test keeps the two in step).
        # In the replication profile, elements past the 24th hour are not part of the day.
        col = {name: j for j, name in enumerate(problem.codec.names)}
        day = cells[: int(problem.scored_lengths(cells[None], np.array([len(cells)]))[0])]
        return make(
            typename,
            meta=meta_msg,
            setpoints=np.ascontiguousarray(day[:, col["temperature"]], dtype=np.float64),
            durations_min=np.rint(day[:, col["duration"]]).astype(np.uint32),
            room_models=np.rint(day[:, col["model"]]).astype(np.uint8),
            initial_temperature=float(day[0, col["temperature"]]) if len(day) else 0.0,
        )
    env = problem.environment(scenario)
    if problem.name == "robot":
        return make(typename, meta=meta_msg, map=occupancy_grid(make, now_ns, env),
                    start=pose_stamped(make, now_ns, *env.start_m, env.start_yaw or 0.0),
                    goal=pose_stamped(make, now_ns, *env.goal_m, env.goal_yaw or 0.0))
    if problem.name == "vehicle":
        cfg = problem.config
        return make(
            typename,
            meta=meta_msg,
            road=path(make, now_ns, env.nodes),
            road_points=[make("geometry_msgs/msg/Point", x=float(x), y=float(y), z=0.0) for x, y in np.asarray(env.spine, dtype=float).reshape(-1, 2)],
            lane_width=float(env.lane_width),
            speed_limit=float(getattr(cfg, "speed_limit", 70 / 3.6)),
            map_size=float(cfg.map_size),
        )
    raise ScenarioError("problem", f"no ROS message for problem {problem.name!r}", "|".join(topics.SCENARIO_TYPES))


def occupancy_grid(make: Make, now_ns: int, env: Any) -> Any:
    grid = np.asarray(env.grid, dtype=bool)
    height, width = grid.shape
    info = make(
        "nav_msgs/msg/MapMetaData",
        map_load_time=stamp(make, now_ns),
        resolution=float(env.resolution),
        width=int(width),
        height=int(height),
        origin=pose(make, 0.0, 0.0),
    )
    data = np.where(grid, 100, 0).astype(np.int8).reshape(-1)  # row-major from cell (0, 0): index y * width + x
    return make("nav_msgs/msg/OccupancyGrid", header=header(make, now_ns), info=info, data=data)


def upsampled_grid(make: Make, msg_grid: Any, factor: int, now_ns: int, frame_id: str = "map") -> Any:
    """An ``OccupancyGrid`` with every cell split into ``factor`` x ``factor`` cells: the same walls,
    the resolution a navigation stack's costmaps expect (Nav2's static layer takes the map's)."""
    info = msg_grid.info
    data = np.asarray(msg_grid.data, dtype=np.int8).reshape(int(info.height), int(info.width))
    data = np.repeat(np.repeat(data, factor, axis=0), factor, axis=1)
    fine = make("nav_msgs/msg/MapMetaData", map_load_time=stamp(make, now_ns),
                resolution=float(info.resolution) / factor, width=int(data.shape[1]), height=int(data.shape[0]),
                origin=info.origin)
    return make("nav_msgs/msg/OccupancyGrid", header=header(make, now_ns, frame_id), info=fine, data=data.reshape(-1))


def grid_from_message(msg_grid: Any, field: str = "map") -> np.ndarray:
    """``nav_msgs/OccupancyGrid`` -> bool ``[y, x]`` (unknown cells count as occupied).

    Raises ``ScenarioError`` naming the field when the size does not match the data or the
    resolution / origin are not finite.
    """
    info = msg_grid.info
    width, height, cells = int(info.width), int(info.height), len(msg_grid.data)
    if width * height != cells or not cells:
        raise ScenarioError(f"{field}.info", f"{width} x {height} cells but {cells} data values",
                            "width * height == len(data) > 0")
    res = float(info.resolution)
    if not (math.isfinite(res) and res > 0):
        raise ScenarioError(f"{field}.info.resolution", f"{res!r}", "a finite number > 0")
    position = info.origin.position
    require_finite((position.x, position.y), f"{field}.info.origin.position")
    data = np.asarray(msg_grid.data, dtype=np.int16).reshape(height, width)
    return (data != 0)


def require_finite(values: Any, field: str) -> np.ndarray:
    """``values`` as a float array, or ``ScenarioError`` naming ``field`` if any is NaN or infinite."""
    array = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(array)):
        raise ScenarioError(field, "holds NaN or infinite values", "finite numbers")
    return array


def clip_text(text: Any, limit: int = 80) -> str:
    """A hostile string shortened for an error message (repr, so control characters show)."""
    text = str(text)
    return repr(text) if len(text) <= limit else f"{text[:limit]!r}... ({len(text)} characters)"


def safe_echo(name: str) -> str:
    """An identifier as it may be echoed in a result: unchanged when safe, else defanged and clipped."""
    try:
        return check_name(name, "name", allow_empty=True)
    except UnsafeName:
        out = "".join(c if c.isascii() and (c.isalnum() or c in "_-") else "_" for c in str(name)[:MAX_NAME_LENGTH])
        # a name may not start with "-" (it would read as an option): "-" alone is echoed as "_-"
        return ("_" + out)[:MAX_NAME_LENGTH] if out.startswith("-") else out


def scenario_from_message(problem: Problem, msg: Any) -> tuple[Scenario, dict[str, Any]]:
    """Validate an incoming scenario message; raises ``ScenarioError`` naming the bad field.

    The JSON form in ``meta.scenario_json`` is authoritative; the genome must agree with it.
    """
    meta = msg.meta
    if meta.problem != problem.name:
        raise ScenarioError("meta.problem", f"this node executes {problem.name!r}, got {clip_text(meta.problem)}", problem.name)
    try:
        check_name(meta.run_id, "meta.run_id")
    except UnsafeName:
        raise ScenarioError("meta.run_id", f"unsafe name {clip_text(meta.run_id)}", NAME_RULE) from None
    depth = json_depth(meta.scenario_json)
    if depth > MAX_JSON_DEPTH:
        raise ScenarioError("meta.scenario_json", f"nested {depth} levels deep", f"at most {MAX_JSON_DEPTH} levels")
    try:
        data = Scenario.parse_json(meta.scenario_json)
    except ScenarioError as exc:  # keep the field a bad number sits in (a NaN names it)
        field = "meta.scenario_json" if exc.field == "json" else f"meta.scenario_json.{exc.field}"
        raise ScenarioError(field, exc.message, exc.allowed)
    try:
        scenario = problem.parse(data)
    except ScenarioError as exc:
        raise ScenarioError(f"meta.scenario_json.{exc.field}", exc.message, exc.allowed)
    genome = np.asarray(meta.genome, dtype=float)
    if not np.all(np.isfinite(genome)):
        raise ScenarioError("meta.genome", "holds NaN or infinite values", "finite attribute codes")
    expected = problem.codec.split(problem.codec.to_row(scenario))
    cells = expected[0][0, : expected[1][0]].reshape(-1)
    if genome.shape != cells.shape or not np.allclose(genome, cells):
        raise ScenarioError("meta.genome", "does not match meta.scenario_json", "the scenario's attribute codes")
    info = {
        "run_id": meta.run_id,
        "scenario_id": int(meta.scenario_id),
        "generation": int(meta.generation),
        "seed": int(meta.seed),
        "worker": meta.assigned_worker,
        "attempt": int(meta.attempt),
        "f1": float(meta.f1),
    }
    return scenario, info


# --- results -------------------------------------------------------------------------------------
def result_message(
    make: Make, now_ns: int, run_id: str, scenario_id: int, problem: str, worker: str, outcome: Outcome
) -> Any:
    names = list(outcome.objectives)
    return make(
        topics.RESULT_TYPE,
        header=header(make, now_ns),
        run_id=run_id,
        scenario_id=int(scenario_id),
        problem=problem,
        worker=worker,
        objective_names=names,
        objectives=np.asarray([float(outcome.objectives[n]) for n in names], dtype=np.float64),
        failed=bool(outcome.failed),
        failure_kind=FAILURE_KINDS[outcome.failure_kind],
        detail=outcome.detail,
        metrics=key_values(make, _with_failure_point(outcome)),
        elapsed_sec=float(outcome.elapsed_sec),
        trajectory=path(make, now_ns, outcome.trajectory),
    )


def _with_failure_point(outcome: Outcome) -> dict[str, Any]:
    """The metrics, plus where it failed (``failure_point``, which the message has no field for): a
    failure's place decides which failures are distinct, also for results that crossed ROS."""
    if outcome.failure_point is None or "failure_point" in outcome.metrics:
        return outcome.metrics
    return {**outcome.metrics, "failure_point": [float(v) for v in outcome.failure_point]}


def _failure_point(metrics: dict[str, str]) -> tuple[float, ...] | None:
    try:
        point = tuple(float(v) for v in json.loads(metrics["failure_point"]))
    except (KeyError, TypeError, ValueError):
        return None
    return point if point and all(math.isfinite(v) for v in point) else None


def outcome_from_message(msg: Any) -> Outcome:
    kind = FAILURE_NAMES.get(int(msg.failure_kind))
    if kind is None:
        raise ScenarioError("failure_kind", f"unknown code {msg.failure_kind}", ", ".join(map(str, FAILURE_NAMES)))
    if len(msg.objective_names) != len(msg.objectives):
        raise ScenarioError("objectives", f"{len(msg.objectives)} values for {len(msg.objective_names)} names",
                            "one value per objective name")
    values = require_finite(msg.objectives, "objectives")
    objectives = {str(n): float(v) for n, v in zip(msg.objective_names, values)}
    traj = path_points(msg.trajectory)
    metrics = {kv.key: kv.value for kv in msg.metrics}
    checked = metrics.get("reference_check")
    return Outcome(
        objectives=objectives,
        failed=bool(msg.failed),
        failure_kind=kind,
        detail=str(msg.detail),
        metrics=metrics,
        trajectory=traj if len(traj) else None,
        elapsed_sec=float(msg.elapsed_sec),
        failure_point=_failure_point(metrics),
        reference=None if checked is None else {"check": checked, "passed": kind != "invalid_test",
                                                "reason": str(msg.detail) if kind == "invalid_test" else ""},
    )


# --- executed timelines (standard messages, so Foxglove can show a run) ----------------------------
def timeline_messages(make: Make, start_ns: int, problem: str, timeline: dict[str, Any], period_s: float) -> list[Any]:
    """Odometry (robot, car) or Temperature (thermostat) samples every ``period_s`` simulated seconds.

    Stamps are the execution's start plus simulated time, so a log replays the run in order.
    """
    t = np.asarray(timeline.get("t", []), dtype=float)
    if len(t) == 0:
        return []
    keep = np.unique(np.searchsorted(t, np.arange(t[0], t[-1] + 1e-9, max(period_s, 1e-9))).clip(0, len(t) - 1))
    keep = np.union1d(keep, [len(t) - 1])
    out = []
    for i in keep:
        stamp_ns = start_ns + int(t[i] * 1e9)
        if problem == "thermostat":
            out.append(
                make(
                    "sensor_msgs/msg/Temperature",
                    header=header(make, stamp_ns, frame_id="room"),
                    temperature=float(timeline["temperature"][i]),
                    variance=0.0,
                )
            )
            continue
        v = float(timeline["v"][i]) if "v" in timeline else 0.0
        out.append(odometry(make, stamp_ns, timeline["x"][i], timeline["y"][i], float(timeline["yaw"][i]), v))
    return out


# --- run status / config -------------------------------------------------------------------------
def run_config_message(make: Make, now_ns: int, run_id: str, config: dict[str, Any], version: str) -> Any:
    return make(
        topics.RUN_CONFIG_TYPE,
        header=header(make, now_ns),
        run_id=run_id,
        config_json=json.dumps(config, sort_keys=True),
        package_version=version,
    )


def status_message(make: Make, now_ns: int, **fields: Any) -> Any:
    return make(topics.STATUS_TYPE, header=header(make, now_ns), **fields)


def heartbeat_message(
    make: Make, worker: str, problem: str, in_flight: int, executed: int, extra: dict[str, Any] | None = None
) -> Any:
    """A worker's heartbeat; ``extra`` adds key/values (e.g. the fidelity profile it scores)."""
    return make(
        topics.WORKERS_TYPE,
        level=0,
        name=worker,
        message="busy" if in_flight else "idle",
        hardware_id=problem,
        values=key_values(make, {"in_flight": in_flight, "executed": executed, **(extra or {})}),
    )
