"""A Nav2 parameter file for AmbieGen's world: the user's own params, our overlay on top, loop rates scaled.

A Nav2 user keeps their bringup and their robot's params file. What our world needs from Nav2
is small and lives in an overlay (``config/nav2/ambiegen_overlay.yaml``): the frames robot_world
publishes, the pioneer's footprint, laser returns of +inf as free space, the base's acceleration
limits. ``merged_params`` lays it over theirs; ``scale_nav2_rates`` makes Jazzy's wall-clock loops
keep pace with a world running ``time_scale`` times faster than real time. ``ambiegen nav2-params``
writes the result for ``ros2 launch nav2_bringup navigation_launch.py params_file:=...``, and
``nav2_campaign.launch.py`` does the same for the Nav2 it starts itself.

Overlay keys merge into the user's mappings key by key. A key that begins with ``*`` is a
pattern: its mapping is merged into every mapping at that level that already has all of the
pattern's own keys, so ``"*scan": {scan: {inf_is_valid: true}}`` reaches each costmap layer with a
``scan`` source whatever the user named the layer, and ``"*mppi": {ax_max: ..., ax_min: ...}``
reaches an MPPI controller and nothing else.
"""
from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

OVERLAY_FILE = ("config", "nav2", "ambiegen_overlay.yaml")  # under the package's share dir (or the repo)
RATES = {  # parameter name -> "rate" (multiplied by k) | "period" (divided by k)
    "controller_frequency": "rate", "expected_planner_frequency": "rate", "update_frequency": "rate",
    "publish_frequency": "rate", "cycle_frequency": "rate", "bt_loop_duration": "period",
    "smoothing_frequency": "rate",
}
SPEED_KEYS = ("max_vel_x", "max_speed_xy", "vx_max")  # DWB, DWB, MPPI / others: the controller's top speed


def scale_nav2_rates(params: Any, k: float) -> Any:
    """A Nav2 parameter tree with every loop rate multiplied by ``k`` (and loop periods divided):
    Jazzy's controller, planner, costmap, smoother and behaviour-tree loops run on wall-clock
    rates, so a world ``k`` times faster than real time needs them ``k`` times faster too.
    Timeouts stay: they count in sim time (``use_sim_time``)."""
    if isinstance(params, dict):
        out = {}
        for key, value in params.items():
            kind = RATES.get(key)
            if kind and isinstance(value, (int, float)) and not isinstance(value, bool):
                value = value * k if kind == "rate" else max(1, int(round(value / k)))
            out[key] = scale_nav2_rates(value, k)
        return out
    return params


def merge_overlay(base: Any, overlay: Any) -> Any:
    """``base`` with ``overlay`` merged in (a new tree; see the module docstring for ``*`` keys)."""
    if not isinstance(base, dict) or not isinstance(overlay, dict):
        return copy.deepcopy(overlay)
    out = copy.deepcopy(base)
    for key, value in overlay.items():
        if isinstance(key, str) and key.startswith("*"):
            if not isinstance(value, dict):
                raise ValueError(f"overlay pattern {key!r}: must be a mapping")
            for name, child in out.items():
                if isinstance(child, dict) and all(k in child for k in value):
                    out[name] = merge_overlay(child, value)
        else:
            out[key] = merge_overlay(out.get(key), value)
    return out


def top_speed(params: dict) -> float | None:
    """The controller's top forward speed [m/s] from a Nav2 params tree (the largest of its
    controller plugins' ``max_vel_x`` / ``max_speed_xy`` / ``vx_max``), None if it names none."""
    server = (params.get("controller_server") or {}).get("ros__parameters") or {}
    speeds = []
    for plugin in server.get("controller_plugins") or []:
        section = server.get(plugin) or {}
        speeds += [float(section[k]) for k in SPEED_KEYS if isinstance(section.get(k), (int, float))]
    return max(speeds) if speeds else None


WORLD_TOPICS = ("/scan", "/odom", "/map", "/cmd_vel")  # robot_world's, named absolutely in Nav2 params


def goal_time_budget(params: dict, k: float = 1.0) -> float:
    """The simulated seconds bt_navigator's NavigateToPose tree allows one goal: a ``Timeout`` at the
    root of its main tree (``fix:doorway_patient`` wraps Jazzy's tree in one), times ``k`` (BT.CPP
    times it by the wall clock). 0 when the tree has none, or names no file that can be read."""
    import xml.etree.ElementTree as ET

    bt = ((params.get("bt_navigator") or {}).get("ros__parameters") or {}).get("default_nav_to_pose_bt_xml")
    try:
        root = ET.parse(str(bt)).getroot() if bt else None
    except (OSError, ET.ParseError):
        return 0.0
    if root is None:
        return 0.0
    trees = root.findall("BehaviorTree")
    main = next((t for t in trees if t.get("ID") == root.get("main_tree_to_execute")), trees[0] if trees else None)
    top = list(main) if main is not None else []
    if len(top) != 1 or top[0].tag != "Timeout":
        return 0.0
    try:
        return float(top[0].get("msec", 0)) / 1000.0 * k
    except ValueError:
        return 0.0


def for_namespace(params: dict, namespace: str) -> dict:
    """The params of a Nav2 run in ``namespace`` (one of several stacks on one host): nested under
    it, as ROS parameter files address namespaced nodes, with robot_world's topics that the file
    names absolutely (``/scan``, ``/odom``, ...) and every static layer's map moved into it."""
    ns = "/" + namespace.strip("/")

    def walk(value: Any) -> Any:
        if isinstance(value, dict):
            out = {k: walk(v) for k, v in value.items()}
            if out.get("plugin") == "nav2_costmap_2d::StaticLayer":
                out["map_topic"] = f"{ns}/map"
            return out
        if isinstance(value, list):
            return [walk(v) for v in value]
        return f"{ns}{value}" if isinstance(value, str) and value in WORLD_TOPICS else value

    return {namespace.strip("/"): walk(params)}


def package_file(*parts: str, folder: bool = False) -> Path | None:
    """A file (``folder``: a folder) the package ships under ``share/ambiegen_ros`` (a colcon or pip
    install) or in its source checkout; None where neither has it."""
    import os
    import sys

    roots = [Path(__file__).resolve().parents[1]]  # a source checkout / editable install
    roots += [Path(prefix) / "share" / "ambiegen_ros"
              for prefix in [sys.prefix, *os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)] if prefix]
    for root in roots:
        path = root / Path(*parts)
        if path.is_dir() if folder else path.is_file():
            return path
    return None


def load_yaml(path: str | Path, what: str) -> dict:
    """A YAML mapping from ``path``; ``ValueError`` naming ``what`` and the reason otherwise."""
    import yaml

    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f"{what}: cannot read {path}: {exc}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{what}: {path} is not a YAML mapping")
    return data


def merged_params(params_file: str | Path, overlay_file: str | Path | None, time_scale: float) -> dict:
    """The user's params, the overlay merged on (None: none), rates x ``time_scale``."""
    params = load_yaml(params_file, "params_file")
    if overlay_file:
        params = merge_overlay(params, load_yaml(overlay_file, "params_overlay"))
    return scale_nav2_rates(params, time_scale)


def write_params(params: dict, out: str | Path, header: str, overwrite: bool = False) -> Path:
    """Write a params tree; an existing file is refused (``FileExistsError``) unless ``overwrite``."""
    import yaml

    out = Path(out)
    if out.exists() and not overwrite:
        raise FileExistsError(f"{out} exists (not overwritten)")
    out.parent.mkdir(parents=True, exist_ok=True)
    text = "".join(f"# {line}\n" for line in header.splitlines()) + yaml.safe_dump(params, sort_keys=False)
    out.write_text(text)
    return out


# --- the robot (issue 69) ----------------------------------------------------------------------------
COSTMAPS = (("local_costmap", "local_costmap"), ("global_costmap", "global_costmap"))


def _section(params: dict, *path: str) -> dict | None:
    node = params
    for key in (*path, "ros__parameters"):
        node = node.get(key) if isinstance(node, dict) else None
    return node if isinstance(node, dict) else None


def _cap(section: dict, key: str, limit: float, negative: bool = False) -> None:
    """``section[key]`` not beyond the base's ``limit`` (never raised; set when absent)."""
    value = section.get(key)
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    section[key] = (max(value, -limit) if ok else -limit) if negative else (min(value, limit) if ok else limit)


def _controller_limits(section: dict, plugin: str, profile: Any) -> None:
    """A controller's speed caps within the base's, its accelerations the base's."""
    (vx, vy, wz), (ax, ay, az) = profile.max_speed, profile.max_accel
    omni = profile.drive == "omnidirectional"
    if plugin.startswith("nav2_mppi"):
        for key, limit, negative in (("vx_max", vx, False), ("vx_min", vx, True), ("wz_max", wz, False)):
            _cap(section, key, limit, negative)
        section.update(ax_max=ax, ax_min=-ax, az_max=az)
        critic = section.get("CostCritic")
        if isinstance(critic, dict):  # the overlay's footprint check is for a body that is no disc; a disc's
            critic["consider_footprint"] = not profile.round  # is its centre's cost (Nav2's default, its docs)
        if omni:
            _cap(section, "vy_max", vy)
            section["ay_max"] = ay
        if profile.drive == "ackermann":
            section.setdefault("AckermannConstraints", {})["min_turning_r"] = profile.min_turning_radius
    elif plugin.startswith("dwb"):
        caps = [("max_vel_x", vx, False), ("min_vel_x", vx, True), ("max_vel_theta", wz, False),
                ("max_speed_xy", math.hypot(vx, vy), False)]
        for key, limit, negative in caps + ([("max_vel_y", vy, False), ("min_vel_y", vy, True)] if omni else []):
            _cap(section, key, limit, negative)
        section.update(acc_lim_x=ax, decel_lim_x=-ax, acc_lim_theta=az, decel_lim_theta=-az)
        if omni:
            section.update(acc_lim_y=ay, decel_lim_y=-ay)
    elif plugin.startswith("nav2_regulated"):
        for key, limit in (("desired_linear_vel", vx), ("rotate_to_heading_angular_vel", wz)):
            _cap(section, key, limit)
        section["max_angular_accel"] = az


def _scan_source(source: dict, laser: Any) -> dict:
    """A costmap's scan source seen from ``laser``: its frame, and ranges no farther than it reaches."""
    source["sensor_frame"] = laser.frame
    for key in ("obstacle_max_range", "raytrace_max_range"):
        if isinstance(source.get(key), (int, float)):
            source[key] = min(source[key], laser.range)
    return source


def with_robot(params: dict, profile: Any) -> dict:
    """The params with the robot's footprint (or ``robot_radius``), laser and limits in place of
    the Pioneer's the overlay wrote: each costmap's body and scan sources (``sensor_frame``, ranges
    no farther than the laser's; a profile's further lasers each as a source like the first, named
    after its topic), each controller's speed caps (never raised) and accelerations,
    the velocity smoother's, and an Ackermann robot's turning radius in MPPI and Smac's planners."""
    out = copy.deepcopy(params)
    laser = profile.lasers[0]
    for path in COSTMAPS:
        costmap = _section(out, *path)
        if costmap is None:
            continue
        costmap.pop("footprint", None) if profile.round else costmap.pop("robot_radius", None)
        if profile.round:
            costmap["robot_radius"] = profile.radius
        else:
            costmap["footprint"] = profile.nav2_footprint()
        for layer in costmap.values():
            source = layer.get("scan") if isinstance(layer, dict) else None
            if isinstance(source, dict):
                _scan_source(source, laser)
                for other in profile.lasers[1:]:  # each further laser: a source of its own, set as the first
                    name = other.topic.strip("/").replace("/", "_")
                    layer[name] = _scan_source({**copy.deepcopy(source), "topic": other.topic}, other)
                    sources = str(layer.get("observation_sources", "scan")).split()
                    layer["observation_sources"] = " ".join(sources + [name] * (name not in sources))
    from .sims.robot_profile import controllers

    for name, plugin, section in controllers(out):
        _controller_limits(out["controller_server"]["ros__parameters"][name], plugin, profile)
    smoother = _section(out, "velocity_smoother")
    if smoother is not None:
        limits = list(profile.max_speed)
        top = smoother.get("max_velocity") if isinstance(smoother.get("max_velocity"), list) else limits
        low = smoother.get("min_velocity") if isinstance(smoother.get("min_velocity"), list) else [-v for v in limits]
        smoother["max_velocity"] = [min(float(t), v) for t, v in zip(top, limits)]
        smoother["min_velocity"] = [max(float(t), -v) for t, v in zip(low, limits)]
        smoother["max_accel"] = list(profile.max_accel)
        smoother["max_decel"] = [-a for a in profile.max_accel]
    planner = _section(out, "planner_server") or {}
    for name in planner.get("planner_plugins") or []:
        section = planner.get(name)
        if profile.drive == "ackermann" and isinstance(section, dict) and "Smac" in str(section.get("plugin", "")):
            section["minimum_turning_radius"] = profile.min_turning_radius
    return out


__all__ = ["OVERLAY_FILE", "RATES", "WORLD_TOPICS", "for_namespace", "load_yaml", "package_file", "merge_overlay", "merged_params", "scale_nav2_rates", "top_speed",
           "with_robot", "write_params"]
