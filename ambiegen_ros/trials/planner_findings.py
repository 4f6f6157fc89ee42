"""A planner finding in the form Nav2's maintainers ask for (issue 68): the map as ``map_server``
reads it (yaml + pgm), the params, the start and goal, a script that shows it on a stock Jazzy
(``planner_server`` alone, asked through ``nav2_simple_commander``), the picture and the reruns.

``write_finding`` takes the rows of ``ambiegen rerun --stack planner --repeat N`` for one scenario
and writes ``<out>/<name>.md`` with ``<name>.yaml``, ``<name>.pgm``, ``<name>_params.yaml`` and
``<name>_reproduce.py`` beside it. The map is the one the adapter sent: each scenario cell as k x k
cells at the costmap's resolution (``map_upsample``). No ROS here: the script written is for the
user's Jazzy, and it judges the answer by Nav2's own costmap, read back (``getGlobalCostmap``).
"""
from __future__ import annotations

import json
import math
from collections import Counter
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import yaml

LABELS = {
    "new": "new: not on Nav2's tracker, not fixed on main",
    "fixed_on_main": "fixed on main, still in Jazzy: a backport request",
    "known": "known: on Nav2's tracker",
}


def write_map(occupied: np.ndarray, resolution: float, stem: Path, origin: tuple[float, float] = (0.0, 0.0)) -> None:
    """``stem.pgm`` and ``stem.yaml`` as ``map_server`` loads them: occupied cells black (0), free
    white (254), the first pgm row the map's highest y (map_server flips rows), trinary."""
    grid = np.asarray(occupied, dtype=bool)
    image = np.where(grid[::-1], 0, 254).astype(np.uint8)
    height, width = image.shape
    stem.with_suffix(".pgm").write_bytes(f"P5\n{width} {height}\n255\n".encode() + image.tobytes())
    stem.with_suffix(".yaml").write_text(
        f"image: {stem.name}.pgm\nmode: trinary\nresolution: {resolution:g}\n"
        f"origin: [{origin[0]:g}, {origin[1]:g}, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.25\n")


def read_pgm(path: Path) -> np.ndarray:
    """A P5 pgm written by ``write_map`` back as bool ``[y, x]`` occupied (for tests and the script)."""
    data = path.read_bytes()
    fields, pos = [], 0
    while len(fields) < 4:
        end = data.index(b"\n", pos)
        fields += data[pos:end].split()
        pos = end + 1
    width, height = int(fields[1]), int(fields[2])
    image = np.frombuffer(data[pos:pos + width * height], dtype=np.uint8).reshape(height, width)
    return image[::-1] < 128


def map_of(problem: Any, scenario: Any, upsample: int) -> tuple[np.ndarray, float, tuple, tuple]:
    """(occupied at the costmap's resolution, resolution, start (x, y, yaw), goal (x, y, yaw)) of a
    scenario, as the adapter publishes them."""
    env = problem.environment(scenario)
    fine = np.repeat(np.repeat(np.asarray(env.grid, dtype=bool), upsample, axis=0), upsample, axis=1)
    res = float(env.resolution)  # the poses' yaw is in radians already
    start = (*[(c + 0.5) * res for c in env.start], float(env.start_yaw or 0.0))
    goal = (*[(c + 0.5) * res for c in env.goal], float(env.goal_yaw or 0.0))
    return fine, res / upsample, start, goal


SCRIPT = '''#!/usr/bin/env python3
"""{title}: shown on a stock ROS 2 Jazzy with Nav2's planner_server alone.

In a terminal each (a sourced Jazzy in each):
  ros2 run tf2_ros static_transform_publisher --frame-id map --child-frame-id base_link
  ros2 run nav2_planner planner_server --ros-args --params-file {params}{smoother_line}
  ros2 run nav2_lifecycle_manager lifecycle_manager --ros-args -p node_names:="{node_names}" -p autostart:=true
  python3 {script}
This script publishes the map ({map_yaml}, latched on /map, as map_server would), asks
{action} through nav2_simple_commander and checks the answer on the costmap Nav2 made{smooth_words}.
If planner_server crashes, its own terminal says so, and this script waits for an answer that will
not come: stop it with Ctrl-C.
"""
import math
from pathlib import Path

import rclpy
from geometry_msgs.msg import PoseStamped
from nav2_simple_commander.robot_navigator import BasicNavigator
from nav_msgs.msg import OccupancyGrid
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

HERE = Path(__file__).resolve().parent
START, GOAL = {start}, {goal}
VIAS = {vias}  # ComputePathThroughPoses through these (x, y, yaw), in order, then GOAL; []: ComputePathToPose
RESOLUTION, INSCRIBED = {resolution}, {inscribed}
MIN_RADIUS = {min_radius}  # the planner's minimum turning radius (m); None: a 2D planner, no turning limit
SMOOTH = {smooth}  # the path also goes to smoother_server's SmoothPath (check_for_collisions false), checked too


def pose(nav, x, y, yaw):
    p = PoseStamped()
    p.header.frame_id, p.header.stamp = "map", nav.get_clock().now().to_msg()
    p.pose.position.x, p.pose.position.y = x, y
    p.pose.orientation.z, p.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return p


def tightest_turn(points):
    """(radius, index) of the tightest turn: the circle through three successive points at least half
    a cell apart (the middle one's index), or (inf, -1) when the path has none."""
    kept = [0]
    for i in range(1, len(points)):
        if math.dist(points[i], points[kept[-1]]) >= RESOLUTION / 2:
            kept.append(i)
    best = (math.inf, -1)
    for a, b, c in zip(kept, kept[1:], kept[2:]):
        (ax, ay), (bx, by), (cx, cy) = points[a], points[b], points[c]
        cross = abs((bx - ax) * (cy - ay) - (by - ay) * (cx - ax))
        if cross > 0:
            r = math.dist(points[a], points[b]) * math.dist(points[b], points[c]) * math.dist(points[c], points[a])
            best = min(best, (r / (2 * cross), b))
    return best


def read_map():
    data = (HERE / "{pgm}").read_bytes()
    head = data.split(b"\\n", 3)
    width, height = (int(v) for v in head[1].split())
    pixels = head[3][:width * height]
    rows = [pixels[r * width:(r + 1) * width] for r in range(height)][::-1]
    return width, height, [100 if v < 128 else 0 for row in rows for v in row]


def main():
    rclpy.init()
    nav = BasicNavigator()
    width, height, cells = read_map()
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
    grid = OccupancyGrid()
    grid.header.frame_id = "map"
    grid.info.resolution, grid.info.width, grid.info.height = RESOLUTION, width, height
    grid.data = cells
    nav.create_publisher(OccupancyGrid, "/map", latched).publish(grid)
    nav._waitForNodeToActivate("planner_server")  # planner_server alone: no bt_navigator, no AMCL
    for _ in range(50):  # the costmap shows this map once its static layer took it
        costmap = nav.getGlobalCostmap()
        if costmap.metadata.size_x == width and max(costmap.data) == 254:
            break
        rclpy.spin_once(nav, timeout_sec=0.1)
    if VIAS:
        path = nav.getPathThroughPoses(pose(nav, *START), [pose(nav, *v) for v in VIAS + [GOAL]], use_start=True)
    else:
        path = nav.getPath(pose(nav, *START), pose(nav, *GOAL), use_start=True)
    if path is None or not path.poses:
        print(f"no path (error {{nav.result_future.result().result.error_code if nav.result_future else '?'}})")
        return
    size_x, size_y, costs = costmap.metadata.size_x, costmap.metadata.size_y, costmap.data

    def check(what, poses):
        bad = []
        for i, p in enumerate(poses):
            mx, my = int(p.pose.position.x / RESOLUTION), int(p.pose.position.y / RESOLUTION)
            if 0 <= mx < size_x and 0 <= my < size_y and costs[my * size_x + mx] >= 253:
                bad.append((i, round(p.pose.position.x, 3), round(p.pose.position.y, 3), costs[my * size_x + mx]))
        print(f"{{what}}: {{len(poses)}} poses; {{len(bad)}} in cells of cost >= 253 (inscribed or lethal): {{bad[:10]}}")

    check("path", path.poses)
    if SMOOTH:
        smoothed = nav.smoothPath(path, check_for_collision=False)
        check("smoothed path", smoothed.poses) if smoothed is not None else print("no smoothed path")
    if MIN_RADIUS is not None:
        radius, i = tightest_turn([(p.pose.position.x, p.pose.position.y) for p in path.poses])
        print(f"tightest turn: radius {{radius:.3f}} m at pose {{i}}, against a minimum turning radius of "
              f"{{MIN_RADIUS}} m{{' (tighter by over 2 %)' if radius < 0.98 * MIN_RADIUS else ''}}")
    nav.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
'''


def write_finding(rows: Sequence[dict], name: str, problem: Any, params_file: Path, upsample: int, out: Path,
                  label: str, references: str, explanation: str, picture: Path | None = None,
                  jazzy_params: Path | None = None, min_turning_radius: float | None = None,
                  config: str = "config/robot_planner.yaml") -> Path:
    """Write the finding's files (module docstring); the path of its page. ``min_turning_radius``:
    the planner's (Hybrid-A*, Lattice), so that the script also reports the path's tightest turn;
    ``config``: the run config the rows ran with, for the page's rerun command. A scenario with vias
    is asked through them (ComputePathThroughPoses), in the script as in the rows."""
    if label not in LABELS:
        raise ValueError(f"label: {label!r} (allowed: {', '.join(LABELS)})")
    runs = [r for r in rows if r.get("scenario_name") == name]
    if not runs:
        raise ValueError(f"no row of scenario {name!r}")
    smooth = "smoother_server" in (yaml.safe_load(Path(params_file).read_text()) or {})
    if (out / f"{name}.md").exists():
        raise ValueError(f"{out / f'{name}.md'} exists: a report is never replaced (choose another -o)")
    out.mkdir(parents=True, exist_ok=True)
    first = runs[0]
    scenario = problem.parse(first["scenario"])
    occupied, res, start, goal = map_of(problem, scenario, upsample)
    vias = [tuple(round(v, 4) for v in via) for via in problem.via_poses(scenario)]
    action = "ComputePathThroughPoses" if vias else "ComputePathToPose"
    write_map(occupied, res, out / name)
    params = out / f"{name}_params.yaml"
    params.write_text(Path(params_file).read_text())
    suite = out / f"{name}_suite.json"
    suite.write_text(json.dumps({"suite": [{"name": name, "scenario": first["scenario"]}]}) + "\n")
    inscribed = 0.22 * math.cos(math.pi / 16)
    script = out / f"{name}_reproduce.py"
    script.write_text(SCRIPT.format(title=name, params=params.name, script=script.name, map_yaml=f"{name}.yaml",
                                    pgm=f"{name}.pgm", start=tuple(round(v, 4) for v in start),
                                    goal=tuple(round(v, 4) for v in goal), vias=vias, action=action,
                                    resolution=res,
                                    inscribed=round(inscribed, 4), min_radius=min_turning_radius, smooth=smooth,
                                    smoother_line=("\n  ros2 run nav2_smoother smoother_server --ros-args "
                                                   f"--params-file {params.name}") if smooth else "",
                                    node_names=str(["planner_server"] + ["smoother_server"] * smooth),
                                    smooth_words=", then smooths the path with SmoothPath and checks that too"
                                    if smooth else ""))
    kinds = Counter(r["failure_kind"] for r in runs)
    failed = sum(bool(r["failed"]) for r in runs)
    versions = first.get("versions") or {}
    lines = [
        f"# {name}", "",
        f"**Label:** {LABELS[label]} ({references}).", "",
        f"**What our oracle saw:** {first['detail']}", "",
        f"**Reproduces:** {failed} of {len(runs)} reruns on Jazzy's planner_server (" +
        ", ".join(f"{k} {v}" for k, v in sorted(kinds.items())) + ").", "",
        explanation.strip(), "",
        "## The scenario", "",
        f"- Map: [`{name}.yaml`]({name}.yaml) + [`{name}.pgm`]({name}.pgm), {occupied.shape[1]} x "
        f"{occupied.shape[0]} cells at {res:g} m, origin (0, 0).",
        f"- Start (x, y, yaw): {tuple(round(v, 4) for v in start)}; " +
        (f"vias, in order: {'; '.join(str(v) for v in vias)}; " if vias else "") +
        f"goal: {tuple(round(v, 4) for v in goal)} ({action} with `use_start: true`).",
        f"- Params: [`{name}_params.yaml`]({name}_params.yaml), `config/nav2/planners/` of AmbieGen-ROS: "
        "Jazzy's `nav2_params.yaml` global costmap (static and inflation layers; it updates and publishes "
        "at 20 Hz instead of 1 Hz) and one planner plugin with its Jazzy defaults.",
        "", "## On a stock Jazzy", "",
        f"[`{name}_reproduce.py`]({name}_reproduce.py) says how to start `planner_server` alone and asks "
        "for the path through `nav2_simple_commander`, then checks its poses on the costmap Nav2 made" +
        ("." if min_turning_radius is None else
         f" and reports its tightest turn against the minimum turning radius, {min_turning_radius:g} m."),
        "", "## Rerun with AmbieGen", "",
        f"[`{name}_suite.json`]({name}_suite.json) holds the scenario as AmbieGen runs it:", "",
        "```bash", f"ambiegen rerun {suite.name} --stack planner --params {params_file.stem}={params.name} "
        f"--config {config} --repeat {len(runs)}", "```", "",
        f"Recorded with ambiegen_ros {versions.get('ambiegen_ros', '?')}, {first.get('when', '')}.",
    ]
    if picture is not None and Path(picture).exists():
        target = out / f"{name}.png"
        target.write_bytes(Path(picture).read_bytes())
        lines[2:2] = [f"![{name}]({name}.png)", ""]
    page = out / f"{name}.md"
    page.write_text("\n".join(lines) + "\n")
    return page
