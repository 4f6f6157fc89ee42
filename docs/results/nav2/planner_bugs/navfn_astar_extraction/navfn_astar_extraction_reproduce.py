#!/usr/bin/env python3
"""navfn_astar_extraction: shown on a stock ROS 2 Jazzy with Nav2's planner_server alone.

In a terminal each (a sourced Jazzy in each):
  ros2 run tf2_ros static_transform_publisher --frame-id map --child-frame-id base_link
  ros2 run nav2_planner planner_server --ros-args --params-file navfn_astar_extraction_params.yaml
  ros2 run nav2_lifecycle_manager lifecycle_manager --ros-args -p node_names:="['planner_server']" -p autostart:=true
  python3 navfn_astar_extraction_reproduce.py
This script publishes the map (navfn_astar_extraction.yaml, latched on /map, as map_server would), asks
ComputePathToPose through nav2_simple_commander and checks the answer on the costmap Nav2 made.
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
START, GOAL = (3.375, 0.875, 1.8326), (2.375, 8.625, 4.7124)
RESOLUTION, INSCRIBED = 0.05, 0.2158
MIN_RADIUS = None  # the planner's minimum turning radius (m); None: a 2D planner, no turning limit
SMOOTH = False  # the path also goes to smoother_server's SmoothPath (check_for_collisions false), checked too


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
    data = (HERE / "navfn_astar_extraction.pgm").read_bytes()
    head = data.split(b"\n", 3)
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
    path = nav.getPath(pose(nav, *START), pose(nav, *GOAL), use_start=True)
    if path is None or not path.poses:
        print(f"no path (error {nav.result_future.result().result.error_code if nav.result_future else '?'})")
        return
    size_x, size_y, costs = costmap.metadata.size_x, costmap.metadata.size_y, costmap.data

    def check(what, poses):
        bad = []
        for i, p in enumerate(poses):
            mx, my = int(p.pose.position.x / RESOLUTION), int(p.pose.position.y / RESOLUTION)
            if 0 <= mx < size_x and 0 <= my < size_y and costs[my * size_x + mx] >= 253:
                bad.append((i, round(p.pose.position.x, 3), round(p.pose.position.y, 3), costs[my * size_x + mx]))
        print(f"{what}: {len(poses)} poses; {len(bad)} in cells of cost >= 253 (inscribed or lethal): {bad[:10]}")

    check("path", path.poses)
    if SMOOTH:
        smoothed = nav.smoothPath(path, check_for_collision=False)
        check("smoothed path", smoothed.poses) if smoothed is not None else print("no smoothed path")
    if MIN_RADIUS is not None:
        radius, i = tightest_turn([(p.pose.position.x, p.pose.position.y) for p in path.poses])
        print(f"tightest turn: radius {radius:.3f} m at pose {i}, against a minimum turning radius of "
              f"{MIN_RADIUS} m{' (tighter by over 2 %)' if radius < 0.98 * MIN_RADIUS else ''}")
    nav.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
