"""A first robot profile from a user's Nav2 params and, where given, their URDF (issue 69), ROS-free.

What Nav2's params say about the robot, in the order it is looked for (the first found wins):

* *footprint*: the local costmap's ``footprint`` (unless ``"[]"``), else its ``robot_radius``, then
  the global costmap's the same way;
* *drive*: MPPI's ``motion_model`` (Ackermann with ``AckermannConstraints.min_turning_r``, Omni),
  else Smac Hybrid-A*'s ``motion_model_for_search`` DUBIN / REEDS_SHEPP (``minimum_turning_radius``),
  else omnidirectional when DWB or the velocity smoother allows sideways speed, else differential;
* *limits*: the velocity smoother's ``max_velocity`` and ``max_accel`` (the last word before the
  base), else the controller's (MPPI ``vx_max`` / ``wz_max`` / ``ax_max`` ..., DWB ``max_vel_x`` /
  ``acc_lim_x`` ..., Regulated Pure Pursuit's ``desired_linear_vel`` ...);
* *laser*: the costmap scan source's ``sensor_frame``, else the URDF link a Gazebo ray / lidar
  sensor is on, else a link named like a laser (``scan``, ``laser``, ``lidar``); its mount pose is
  the URDF's fixed joints from ``robot_base_frame`` to it (x, y and yaw: a planar robot), its field
  of view, beams, range and rate the Gazebo sensor's when it has one.

Whatever is not found gets a default, and ``missing`` says which and what was used.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from typing import Any

import yaml

from .robot_profile import controllers, profile_from_dict

DEFAULTS = {"footprint": {"radius": 0.1},  # Nav2's own default robot_radius
            "max_speed": {"x": 0.26, "theta": 1.0}, "max_accel": {"x": 2.5, "theta": 3.2},  # Nav2's DWB defaults
            "laser": {"fov_deg": 360.0, "beams": 360, "range": 12.0, "rate": 10.0, "noise": 0.01}}
LASER_WORDS = ("scan", "laser", "lidar")


def _ros(params: dict, *path: str) -> dict:
    node: Any = params
    for key in (*path, "ros__parameters"):
        node = node.get(key) if isinstance(node, dict) else None
    return node if isinstance(node, dict) else {}


def _num(value: Any) -> float | None:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def _costmaps(params: dict) -> list[dict]:
    return [_ros(params, "local_costmap", "local_costmap"), _ros(params, "global_costmap", "global_costmap")]


def derive_footprint(params: dict) -> tuple[dict | None, str]:
    for name, costmap in zip(("local_costmap", "global_costmap"), _costmaps(params)):
        text = costmap.get("footprint")
        if isinstance(text, str) and text.strip() not in ("", "[]"):
            try:
                pts = yaml.safe_load(text)
            except yaml.YAMLError:
                pts = None
            if isinstance(pts, list) and len(pts) >= 3:
                return {"polygon": pts}, f"{name}.footprint"
        if _num(costmap.get("robot_radius")):
            return {"radius": _num(costmap["robot_radius"])}, f"{name}.robot_radius"
    return None, ""


def derive_drive(params: dict) -> tuple[dict | None, str]:
    for name, plugin, section in controllers(params):
        model = section.get("motion_model")
        if plugin.startswith("nav2_mppi") and model == "Ackermann":
            r = _num((section.get("AckermannConstraints") or {}).get("min_turning_r"))
            return {"kind": "ackermann", "min_turning_radius": r or 0.2}, f"{name}.motion_model"  # MPPI's default
        if plugin.startswith("nav2_mppi") and model == "Omni":
            return {"kind": "omnidirectional"}, f"{name}.motion_model"
        if plugin.startswith("nav2_mppi") and model == "DiffDrive":
            return {"kind": "differential"}, f"{name}.motion_model"
    planner = _ros(params, "planner_server")
    for name in planner.get("planner_plugins") or []:
        section = planner.get(name) or {}
        if section.get("motion_model_for_search") in ("DUBIN", "REEDS_SHEPP") and _num(section.get("minimum_turning_radius")):
            return {"kind": "ackermann", "min_turning_radius": _num(section["minimum_turning_radius"])}, \
                f"planner_server.{name}.motion_model_for_search"
    sideways = [f"{n}.max_vel_y" for n, p, s in controllers(params) if p.startswith("dwb") and (_num(s.get("max_vel_y")) or 0) > 0]
    smoother = _ros(params, "velocity_smoother").get("max_velocity")
    if isinstance(smoother, list) and len(smoother) == 3 and (_num(smoother[1]) or 0) > 0:
        sideways.append("velocity_smoother.max_velocity")
    if sideways:
        return {"kind": "omnidirectional"}, sideways[0]
    return None, ""


CONTROLLER_KEYS = {  # plugin prefix -> (group, axis) -> key
    "nav2_mppi": {("max_speed", "x"): "vx_max", ("max_speed", "y"): "vy_max", ("max_speed", "theta"): "wz_max",
                  ("max_accel", "x"): "ax_max", ("max_accel", "y"): "ay_max", ("max_accel", "theta"): "az_max"},
    "dwb": {("max_speed", "x"): "max_vel_x", ("max_speed", "y"): "max_vel_y", ("max_speed", "theta"): "max_vel_theta",
            ("max_accel", "x"): "acc_lim_x", ("max_accel", "y"): "acc_lim_y", ("max_accel", "theta"): "acc_lim_theta"},
    "nav2_regulated": {("max_speed", "x"): "desired_linear_vel", ("max_speed", "theta"): "rotate_to_heading_angular_vel",
                       ("max_accel", "theta"): "max_angular_accel"},
}


def derive_limit(params: dict, group: str, axis: str) -> tuple[float | None, str]:
    """One limit: the velocity smoother's, else the first controller's that names it."""
    smoother = _ros(params, "velocity_smoother")
    key = {"max_speed": "max_velocity", "max_accel": "max_accel"}[group]
    values = smoother.get(key)
    i = "xy".find(axis) if axis != "theta" else 2
    if isinstance(values, list) and len(values) == 3 and _num(values[i]) and _num(values[i]) > 0:
        return abs(_num(values[i])), f"velocity_smoother.{key}[{i}]"
    for name, plugin, section in controllers(params):
        for prefix, keys in CONTROLLER_KEYS.items():
            found = keys.get((group, axis))
            if plugin.startswith(prefix) and found and _num(section.get(found)) and _num(section[found]) > 0:
                return _num(section[found]), f"controller_server.{name}.{found}"
    return None, ""


# --- the URDF ------------------------------------------------------------------------------------
def _yaw_pose(joint: ET.Element) -> tuple[float, float, float, float]:
    origin = joint.find("origin")
    xyz = [float(v) for v in (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()]
    rpy = [float(v) for v in (origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split()]
    return xyz[0], xyz[1], rpy[2], rpy[0]


def laser_link(root: ET.Element, hint: str = "") -> str:
    """The URDF's laser link: ``hint`` if it is a link, else the link of a Gazebo ray or lidar
    sensor, else the first link named like a laser; '' when none."""
    links = [link.get("name", "") for link in root.iter("link")]
    if hint in links:
        return hint
    for gazebo in root.iter("gazebo"):
        for sensor in gazebo.iter("sensor"):
            if sensor.get("type") in ("ray", "gpu_ray", "lidar", "gpu_lidar") and gazebo.get("reference") in links:
                return gazebo.get("reference", "")
    return next((name for name in links if any(word in name.lower() for word in LASER_WORDS)), "")


def laser_pose(root: ET.Element, base: str, link: str) -> tuple[tuple[float, float, float] | None, str]:
    """The 2D pose of ``link`` in ``base`` along the URDF's joints (None, reason when not joined)."""
    parent_of = {}
    for joint in root.iter("joint"):
        child, parent = joint.find("child"), joint.find("parent")
        if child is not None and parent is not None:
            parent_of[child.get("link")] = (parent.get("link"), joint)
    chain, at = [], link
    while at != base:
        if at not in parent_of or len(chain) > 64:
            return None, f"no chain of joints from {base} to {link}"
        at, joint = parent_of[at][0], parent_of[at][1]
        chain.append(joint)
    x = y = yaw = 0.0
    flipped = False
    for joint in chain:  # child to parent: the pose in the parent = joint origin composed with it
        jx, jy, jyaw, roll = _yaw_pose(joint)
        c, s = math.cos(jyaw), math.sin(jyaw)
        x, y, yaw = jx + c * x - s * y, jy + s * x + c * y, jyaw + yaw
        flipped ^= abs(abs(roll) - math.pi) < 1e-3
    note = " (mounted upside down: its scan is mirrored, which a profile cannot say)" if flipped else ""
    return (x, y, (yaw + math.pi) % (2 * math.pi) - math.pi), note


def sensor_numbers(root: ET.Element, link: str) -> dict:
    """The Gazebo sensor's field of view, beams, range and rate for ``link`` (what it names)."""
    out: dict = {}
    for gazebo in root.iter("gazebo"):
        if gazebo.get("reference") != link:
            continue
        for sensor in gazebo.iter("sensor"):
            rate = sensor.find("update_rate")
            if rate is not None and rate.text:
                out["rate"] = float(rate.text)
            horizontal = next(sensor.iter("horizontal"), None)
            if horizontal is not None:
                get = {child.tag: float(child.text) for child in horizontal if child.text}
                if "samples" in get:
                    out["beams"] = int(get["samples"])
                if "min_angle" in get and "max_angle" in get:
                    out["fov_deg"] = min(360.0, round(math.degrees(get["max_angle"] - get["min_angle"]), 6))
            range_max = next((r.find("max") for r in sensor.iter("range") if r.find("max") is not None), None)
            if range_max is not None and range_max.text:
                out["range"] = float(range_max.text)
    return out


# --- the profile ---------------------------------------------------------------------------------
def profile_from_params(params: dict, urdf: str | None = None, name: str = "my_robot") -> tuple[dict, list[str]]:
    """A profile mapping from Nav2 params (and a URDF's text) and the list of what was not found,
    each with the default used. The mapping is checked (``profile_from_dict``) by the caller."""
    missing: list[str] = []
    found: list[str] = []
    footprint, where = derive_footprint(params)
    if footprint is None:
        footprint = DEFAULTS["footprint"]
        missing.append(f"footprint: no footprint or robot_radius in the costmaps; used radius {footprint['radius']} m")
    else:
        found.append(f"footprint from {where}")
    drive, where = derive_drive(params)
    if drive is None:
        drive = {"kind": "differential"}
        missing.append("drive: no Omni or Ackermann model, no sideways speed; used differential")
    else:
        found.append(f"drive {drive['kind']} from {where}")
    limits: dict = {"max_speed": {}, "max_accel": {}}
    for group in limits:
        for axis in ("x", "y", "theta") if drive["kind"] == "omnidirectional" else ("x", "theta"):
            value, where = derive_limit(params, group, axis)
            if value is None:
                value = DEFAULTS[group].get(axis, DEFAULTS[group]["x"])
                missing.append(f"limits.{group}.{axis}: not in the velocity smoother or the controller; used {value:g}")
            limits[group][axis] = value
        limits[group].setdefault("y", 0.0)
    base = next((c.get("robot_base_frame") for c in _costmaps(params) if c.get("robot_base_frame")), "base_link")
    laser, notes = _laser(params, urdf, base, missing)
    data = {"name": name, "base_frame": base, "footprint": footprint, "drive": drive, "limits": limits,
            "lasers": [laser]}
    return data, missing + notes


def _laser(params: dict, urdf: str | None, base: str, missing: list[str]) -> tuple[dict, list[str]]:
    """The laser's frame, mount and numbers (module docstring), what was missing appended."""
    frame = ""
    for costmap in _costmaps(params):
        for layer in costmap.values():
            source = layer.get("scan") if isinstance(layer, dict) else None
            if isinstance(source, dict) and source.get("sensor_frame"):
                frame = str(source["sensor_frame"])
    laser = {"frame": frame or "base_scan", "parent": base, "x": 0.0, "y": 0.0, "yaw_deg": 0.0, **DEFAULTS["laser"]}
    notes: list[str] = []
    root = ET.fromstring(urdf) if urdf else None
    link = laser_link(root, frame) if root is not None else ""
    if link:
        laser["frame"] = link
        pose, note = laser_pose(root, base, link)
        if pose is None:
            missing.append(f"lasers[0] mount: {note} in the URDF; used the base's origin")
        else:
            laser.update(x=round(pose[0], 9), y=round(pose[1], 9), yaw_deg=round(math.degrees(pose[2]), 9))
            notes += [f"lasers[0]{note}"] if note else []
        numbers = sensor_numbers(root, link)
        laser.update(numbers)
    else:
        numbers = {}
        missing.append(f"lasers[0] mount: {'no URDF given' if root is None else 'no laser link in the URDF'}; "
                       f"used {laser['frame']} on the base's origin")
    if not frame and not link:
        missing.append("lasers[0].frame: no sensor_frame in the costmaps' scan sources; used base_scan")
    for key in ("fov_deg", "beams", "range", "rate"):
        if key not in numbers:
            missing.append(f"lasers[0].{key}: no Gazebo sensor says it; used {DEFAULTS['laser'][key]:g}")
    missing.append(f"lasers[0].noise: neither params nor URDF say it; used {DEFAULTS['laser']['noise']:g} m")
    return laser, notes


def derive(params: dict, urdf: str | None = None, name: str = "my_robot") -> tuple[Any, dict, list[str]]:
    """``profile_from_params`` checked: (RobotProfile, its mapping, what was not found)."""
    data, missing = profile_from_params(params, urdf, name)
    return profile_from_dict(data), data, missing


__all__ = ["DEFAULTS", "derive", "derive_drive", "derive_footprint", "derive_limit", "laser_link", "laser_pose",
           "profile_from_params", "sensor_numbers"]
