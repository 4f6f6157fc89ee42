"""A robot profile (issue 69): the body, drive, limits and lasers of the robot under test, ROS-free.

Every Nav2 run used to drive Stage's Pioneer. A profile is one small YAML file
(``config/robots/<name>.yaml``) that says which robot the world, the references and ``ambiegen
nav2-params`` stand for instead:

* ``footprint``: ``radius`` (a round body about the rotation centre) or ``polygon`` (vertices in the
  base frame, x ahead, y left). The world needs a convex body (its contact is exact for one): a
  concave polygon is replaced by its convex hull, said by ``notes``; a round one by the regular
  ``ROUND_SIDES``-gon whose edges touch the circle (at most 0.5 % of the radius outside it).
* ``drive``: ``differential`` (v, w), ``omnidirectional`` (vx, vy, w) or ``ackermann``
  (``wheelbase`` and ``max_steering_deg``, or ``min_turning_radius`` directly): no turn in place.
* ``limits``: ``max_speed`` and ``max_accel``, each ``{x, y, theta}`` (m/s, m/s^2, rad/s, rad/s^2);
  ``y`` only for an omnidirectional base.
* ``frames`` (optional): links between ``base_frame`` and the lasers, each ``{parent, x, y, yaw_deg}``.
* ``lasers``: each ``{frame, parent, x, y, yaw_deg, fov_deg, beams, range, rate, noise, topic}``,
  its mount pose relative to ``parent`` (``base_frame`` or one of ``frames``).

Bad input is one ``ProfileError`` line naming the field (``lasers[0].parent: ...``): a
self-intersecting footprint, a laser outside the body's frame tree, a limit of zero, and, with
``check_controller``, a drive the Nav2 params' controller cannot serve.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np

from .robot import RobotSimConfig

DRIVES = ("differential", "omnidirectional", "ackermann")
ROUND_SIDES = 32  # a round body's polygon: edges tangent to the circle
SHIPPED = ("pioneer2dx", "turtlebot4", "turtlebot3_burger", "omni_base", "ackermann_car")
PROFILE_DIR = ("config", "robots")


class ProfileError(ValueError):
    """A bad profile: ``field`` names the key, the message is one line."""

    def __init__(self, field: str, message: str):
        super().__init__(f"{field}: {message}")
        self.field = field


@dataclasses.dataclass(frozen=True)
class Laser:
    """One planar laser: its mount pose in the base frame (``x``, ``y``, ``yaw``) after the frame chain."""

    frame: str
    parent: str
    x: float  # in the base frame [m]
    y: float
    yaw: float  # [rad]
    fov_deg: float
    beams: int
    range: float  # [m]
    rate: float  # [Hz]
    noise: float  # standard deviation of the returns [m]
    topic: str = "/scan"

    def beam_angles(self) -> np.ndarray:
        """Beam directions in the laser frame: evenly over the field of view; a full circle has no
        repeated beam (``angle_min`` -pi, ``N`` beams ``2 pi / N`` apart, as a 360-degree lidar)."""
        if self.fov_deg >= 360.0 - 1e-9:
            return -math.pi + np.arange(self.beams) * (2 * math.pi / self.beams)
        half = math.radians(self.fov_deg) / 2
        return np.linspace(-half, half, self.beams)


@dataclasses.dataclass(frozen=True)
class RobotProfile:
    name: str
    drive: str
    max_speed: tuple[float, float, float]  # x, y, theta
    max_accel: tuple[float, float, float]
    lasers: tuple[Laser, ...]
    radius: float | None = None  # a round body
    polygon: tuple[tuple[float, float], ...] | None = None
    wheelbase: float | None = None
    max_steering_deg: float | None = None
    min_turning_radius: float | None = None  # ackermann: wheelbase / tan(max steering) unless given
    base_frame: str = "base_link"
    frames: dict = dataclasses.field(default_factory=dict)  # name -> (parent, x, y, yaw)
    source: str = ""
    notes: tuple[str, ...] = ()

    @property
    def round(self) -> bool:
        return self.radius is not None

    def footprint(self) -> np.ndarray:
        """The convex body the world moves (counterclockwise vertices, rotation centre at 0)."""
        if self.radius is not None:
            k = np.arange(ROUND_SIDES)
            r = self.radius / math.cos(math.pi / ROUND_SIDES)
            a = (k + 0.5) * 2 * math.pi / ROUND_SIDES
            return np.column_stack([r * np.cos(a), r * np.sin(a)])
        from .robot_world import _convex_hull

        return _convex_hull(np.asarray(self.polygon, dtype=float))

    def circumscribed_radius(self) -> float:
        """The body's radius about the rotation centre (exact for a round one) [m]."""
        if self.radius is not None:
            return float(self.radius)
        pts = np.asarray(self.polygon, dtype=float)
        return float(np.hypot(pts[:, 0], pts[:, 1]).max())

    def nav2_footprint(self) -> str:
        """The polygon as Nav2's costmaps take it: ``"[[x, y], ...]"``."""
        return "[" + ", ".join(f"[{x:g}, {y:g}]" for x, y in self.polygon or ()) + "]"

    def world_config(self, config: Any) -> Any:
        """A ``RobotSimConfig`` with this profile's base limits and first laser."""
        laser = self.lasers[0]
        return dataclasses.replace(config, max_speed=self.max_speed[0], max_turn_rate=self.max_speed[2],
                                   cruise_speed=min(config.cruise_speed, self.max_speed[0]),
                                   max_accel=self.max_accel[0], max_turn_accel=self.max_accel[2],
                                   fov_deg=laser.fov_deg, beams=laser.beams, laser_range=laser.range,
                                   laser_noise=laser.noise)


# --- reading ---------------------------------------------------------------------------------------
def _number(data: dict, key: str, field: str, default: Any = None, positive: bool = False) -> Any:
    value = data.get(key, default)
    if value is None:
        if default is None and key not in data:
            raise ProfileError(field, "missing")
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ProfileError(field, f"must be a number, got {value!r}")
    if positive and not value > 0:
        raise ProfileError(field, f"must be > 0, got {value!r}")
    return float(value)


def _footprint(data: Any) -> tuple[float | None, tuple | None, tuple[str, ...]]:
    from shapely.geometry import Polygon
    from shapely.validation import explain_validity

    if not isinstance(data, dict) or ("radius" in data) == ("polygon" in data):
        raise ProfileError("footprint", "give either radius or polygon")
    if "radius" in data:
        return _number(data, "radius", "footprint.radius", positive=True), None, ()
    pts = data["polygon"]
    if not isinstance(pts, list) or len(pts) < 3 or not all(isinstance(p, (list, tuple)) and len(p) == 2 for p in pts):
        raise ProfileError("footprint.polygon", "must be a list of at least 3 [x, y] vertices")
    pts = tuple((float(p[0]), float(p[1])) for p in pts)
    shape = Polygon(pts)
    if not shape.is_valid:
        raise ProfileError("footprint.polygon", f"not a simple polygon ({explain_validity(shape)})")
    if shape.area <= 0:
        raise ProfileError("footprint.polygon", "has no area")
    if not shape.covers(Polygon([(0, 0), (1e-9, 0), (0, 1e-9)]).centroid):
        raise ProfileError("footprint.polygon", "must hold the rotation centre (0, 0)")
    notes = () if shape.convex_hull.area - shape.area < 1e-12 else (
        "footprint.polygon is concave: the world moves its convex hull",)
    return None, pts, notes


def _drive(data: Any) -> tuple[str, float | None, float | None, float | None]:
    if isinstance(data, str):
        data = {"kind": data}
    if not isinstance(data, dict) or data.get("kind") not in DRIVES:
        raise ProfileError("drive.kind", f"must be one of {', '.join(DRIVES)}")
    kind = data["kind"]
    if kind != "ackermann":
        return kind, None, None, None
    wheelbase = _number(data, "wheelbase", "drive.wheelbase", positive=True) if "wheelbase" in data else None
    steer = _number(data, "max_steering_deg", "drive.max_steering_deg", positive=True) \
        if "max_steering_deg" in data else None
    if steer is not None and not steer < 90:
        raise ProfileError("drive.max_steering_deg", f"must be below 90, got {steer:g}")
    r_min = _number(data, "min_turning_radius", "drive.min_turning_radius", positive=True) \
        if "min_turning_radius" in data else None
    if r_min is None:
        if wheelbase is None or steer is None:
            raise ProfileError("drive.min_turning_radius", "an ackermann drive needs it, or wheelbase and "
                                                           "max_steering_deg")
        r_min = wheelbase / math.tan(math.radians(steer))
    return kind, wheelbase, steer, r_min


def _limits(data: Any, drive: str) -> tuple[tuple, tuple]:
    if not isinstance(data, dict):
        raise ProfileError("limits", "must hold max_speed and max_accel")
    out = []
    for group in ("max_speed", "max_accel"):
        values = data.get(group)
        if not isinstance(values, dict):
            raise ProfileError(f"limits.{group}", "must be a mapping {x, y, theta}")
        x = _number(values, "x", f"limits.{group}.x", positive=True)
        theta = _number(values, "theta", f"limits.{group}.theta", positive=True)
        y = _number(values, "y", f"limits.{group}.y", default=0.0)
        if drive == "omnidirectional" and not y > 0:
            raise ProfileError(f"limits.{group}.y", f"an omnidirectional base needs it > 0, got {y:g}")
        if drive != "omnidirectional" and y != 0:
            raise ProfileError(f"limits.{group}.y", f"a {drive} base cannot move sideways: must be 0, got {y:g}")
        out.append((x, y, theta))
    return out[0], out[1]


def _frames(data: Any, base: str) -> dict:
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ProfileError("frames", "must be a mapping name -> {parent, x, y, yaw_deg}")
    out = {}
    for name, f in data.items():
        field = f"frames.{name}"
        if not isinstance(f, dict) or not isinstance(f.get("parent"), str):
            raise ProfileError(f"{field}.parent", "missing")
        out[str(name)] = (f["parent"], _number(f, "x", f"{field}.x", 0.0), _number(f, "y", f"{field}.y", 0.0),
                          math.radians(_number(f, "yaw_deg", f"{field}.yaw_deg", 0.0)))
    for name in out:  # every frame reaches the base, without a loop
        seen, at = {name}, out[name][0]
        while at != base:
            if at not in out:
                raise ProfileError(f"frames.{name}.parent", f"{at!r} is neither {base!r} nor a frame of the profile")
            if at in seen:
                raise ProfileError(f"frames.{name}.parent", "the frames form a loop")
            seen.add(at)
            at = out[at][0]
    return out


def _in_base(frames: dict, parent: str, x: float, y: float, yaw: float, base: str) -> tuple[float, float, float]:
    """A pose relative to ``parent`` expressed in the base frame (the chain of ``frames``)."""
    while parent != base:
        p, fx, fy, fyaw = frames[parent]
        c, s = math.cos(fyaw), math.sin(fyaw)
        x, y, yaw = fx + c * x - s * y, fy + s * x + c * y, fyaw + yaw
        parent = p
    return x, y, (yaw + math.pi) % (2 * math.pi) - math.pi


def _lasers(data: Any, frames: dict, base: str, polygon: np.ndarray) -> tuple[Laser, ...]:
    if not isinstance(data, list) or not data:
        raise ProfileError("lasers", "at least one laser")
    out = []
    for i, d in enumerate(data):
        field = f"lasers[{i}]"
        if not isinstance(d, dict) or not isinstance(d.get("frame"), str) or not d["frame"]:
            raise ProfileError(f"{field}.frame", "missing")
        parent = d.get("parent", base)
        if parent != base and parent not in frames:
            raise ProfileError(f"{field}.parent", f"{parent!r} is outside the body's frame tree (neither {base!r} "
                                                  f"nor one of frames)")
        if d["frame"] == base or d["frame"] in frames:
            raise ProfileError(f"{field}.frame", f"{d['frame']!r} is already a frame of the body")
        x, y, yaw = _in_base(frames, parent, _number(d, "x", f"{field}.x", 0.0), _number(d, "y", f"{field}.y", 0.0),
                             math.radians(_number(d, "yaw_deg", f"{field}.yaw_deg", 0.0)), base)
        from .robot_world import _polygon_signed_distance

        if _polygon_signed_distance(np.array([x]), np.array([y]), polygon)[0] > 1e-9:
            raise ProfileError(f"{field}.x", f"the mount ({x:.3f}, {y:.3f}) in {base} lies outside the footprint")
        fov = _number(d, "fov_deg", f"{field}.fov_deg", positive=True)
        if fov > 360:
            raise ProfileError(f"{field}.fov_deg", f"at most 360, got {fov:g}")
        beams = d.get("beams")
        if isinstance(beams, bool) or not isinstance(beams, int) or beams < 2:
            raise ProfileError(f"{field}.beams", f"must be a whole number >= 2, got {beams!r}")
        noise = _number(d, "noise", f"{field}.noise", 0.0)
        if noise < 0:
            raise ProfileError(f"{field}.noise", f"must be >= 0, got {noise:g}")
        out.append(Laser(d["frame"], parent, x, y, yaw, fov, beams, _number(d, "range", f"{field}.range", positive=True),
                         _number(d, "rate", f"{field}.rate", positive=True), noise,
                         str(d.get("topic", "/scan" if i == 0 else f"/scan_{i}"))))
    topics = [laser.topic for laser in out]
    if len(set(topics)) != len(topics):
        raise ProfileError("lasers", "two lasers on one topic")
    return tuple(out)


KEYS = {"name", "base_frame", "footprint", "drive", "limits", "frames", "lasers"}


def profile_from_dict(data: Any, source: str = "") -> RobotProfile:
    """A checked profile from a parsed YAML mapping (``ProfileError`` naming the field otherwise)."""
    if not isinstance(data, dict):
        raise ProfileError("profile", "must be a YAML mapping")
    unknown = sorted(set(data) - KEYS)
    if unknown:
        raise ProfileError(unknown[0], f"unknown key (known: {', '.join(sorted(KEYS))})")
    name = data.get("name")
    if not isinstance(name, str) or not name:
        raise ProfileError("name", "missing")
    base = data.get("base_frame", "base_link")
    radius, polygon, notes = _footprint(data.get("footprint"))
    drive, wheelbase, steer, r_min = _drive(data.get("drive"))
    speed, accel = _limits(data.get("limits"), drive)
    frames = _frames(data.get("frames"), base)
    partial = RobotProfile(name, drive, speed, accel, (), radius, polygon)
    lasers = _lasers(data.get("lasers"), frames, base, partial.footprint())
    return RobotProfile(name, drive, speed, accel, lasers, radius, polygon, wheelbase, steer, r_min, base, frames,
                        source, notes)


def profile_path(name_or_path: str | Path) -> Path:
    """A shipped profile's file (a bare name: ``turtlebot4``) or a path as given."""
    text = str(name_or_path)
    return _shipped(text) if "/" not in text and not text.endswith((".yaml", ".yml")) else Path(text)


def _shipped(name: str) -> Path:
    here = Path(__file__).resolve().parents[2] / Path(*PROFILE_DIR) / f"{name}.yaml"
    if here.is_file():
        return here
    import os
    import sys

    for prefix in [sys.prefix, *os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)]:
        path = Path(prefix) / "share" / "ambiegen_ros" / Path(*PROFILE_DIR) / f"{name}.yaml"
        if prefix and path.is_file():
            return path
    raise ProfileError("robot_profile", f"no shipped profile {name!r} (shipped: {', '.join(SHIPPED)}; or give a path)")


def load_profile(name_or_path: str | Path) -> RobotProfile:
    """A shipped profile by name or a profile file by path, checked."""
    import yaml

    path = profile_path(name_or_path)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ProfileError("robot_profile", f"cannot read {path}: {str(exc).splitlines()[0]}") from None
    return profile_from_dict(data, str(path))


def profile_to_dict(p: RobotProfile) -> dict:
    """The YAML mapping of a profile (what ``profile_from_dict`` reads back to the same profile)."""
    out: dict = {"name": p.name, "base_frame": p.base_frame}
    out["footprint"] = {"radius": p.radius} if p.round else {"polygon": [list(v) for v in p.polygon or ()]}
    drive: dict = {"kind": p.drive}
    if p.drive == "ackermann":
        if p.wheelbase is not None and p.max_steering_deg is not None:
            drive.update(wheelbase=p.wheelbase, max_steering_deg=p.max_steering_deg)
        else:
            drive["min_turning_radius"] = p.min_turning_radius
    out["drive"] = drive
    out["limits"] = {g: dict(zip(("x", "y", "theta"), v)) for g, v in (("max_speed", p.max_speed),
                                                                      ("max_accel", p.max_accel))}
    if p.frames:
        out["frames"] = {k: {"parent": v[0], "x": v[1], "y": v[2], "yaw_deg": math.degrees(v[3])}
                         for k, v in p.frames.items()}
    out["lasers"] = [{"frame": las.frame, "parent": p.base_frame, "x": las.x, "y": las.y,
                      "yaw_deg": round(math.degrees(las.yaw), 9), "fov_deg": las.fov_deg, "beams": las.beams,
                      "range": las.range, "rate": las.rate, "noise": las.noise, "topic": las.topic}
                     for las in p.lasers]
    return out


# --- a simulator config that carries its robot ------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class ProfiledConfig(RobotSimConfig):
    """A ``RobotSimConfig`` that carries its robot: the references and the judge take it
    (``sims.reference.robot.robot_profile``). The world's limits stay the config's: ``RobotWorld``
    takes the profile itself."""

    robot_profile: Any = None


def profiled(config: Any, profile: RobotProfile | str | None) -> ProfiledConfig:
    """``config`` with ``profile`` (a ``RobotProfile``, or a shipped name or path, loaded)."""
    if isinstance(profile, (str, Path)):
        profile = load_profile(profile) if str(profile) else None
    values = {f.name: getattr(config, f.name) for f in dataclasses.fields(config) if f.name != "robot_profile"}
    return ProfiledConfig(**values, robot_profile=profile)


# --- the controller that drives it -----------------------------------------------------------------
CAR_LIKE = {"nav2_mppi_controller::MPPIController": "motion_model: Ackermann",
            "nav2_regulated_pure_pursuit_controller::RegulatedPurePursuitController": "use_rotate_to_heading: false"}
"""Nav2's controllers with a car-like mode, and the setting that turns it on (Nav2's docs: MPPI's
Ackermann motion model; Regulated Pure Pursuit, documented for Ackermann robots without its rotate
to heading). DWB, Rotation Shim, Graceful and the rest turn in place: they cannot drive a car."""


def controllers(params: dict) -> list[tuple[str, str, dict]]:
    """(name, plugin, section) of each controller plugin in a Nav2 params tree."""
    server = (params.get("controller_server") or {}).get("ros__parameters") or {}
    out = []
    for name in server.get("controller_plugins") or []:
        section = server.get(name) or {}
        out.append((str(name), str(section.get("plugin", "")).replace("/", "::"), section))
    return out


def check_controller(profile: RobotProfile, params: dict) -> list[str]:
    """Refuse (``ProfileError`` naming the params' field) a controller that cannot drive the
    profile's base: an Ackermann robot under one without a car-like model, a differential or
    car-like one under a controller that commands sideways motion. Returns notes on what is
    allowed but unused (an omnidirectional base under a controller that never moves sideways)."""
    notes = []
    for name, plugin, section in controllers(params):
        field = f"controller_server.{name}"
        model = str(section.get("motion_model", "DiffDrive"))
        if profile.drive == "ackermann":
            if plugin not in CAR_LIKE:
                raise ProfileError(f"{field}.plugin", f"{plugin or '?'} has no car-like model: it cannot drive the "
                                                      f"Ackermann robot {profile.name} (MPPI with motion_model "
                                                      f"Ackermann, or Regulated Pure Pursuit, can)")
            if plugin.startswith("nav2_mppi") and model != "Ackermann":
                raise ProfileError(f"{field}.motion_model", f"{model} turns in place: the Ackermann robot "
                                                            f"{profile.name} needs motion_model Ackermann")
            if plugin.startswith("nav2_regulated") and section.get("use_rotate_to_heading", True) is not False:
                raise ProfileError(f"{field}.use_rotate_to_heading", f"true (Nav2's default) turns in place: the "
                                                                     f"Ackermann robot {profile.name} needs false")
        sideways = model == "Omni" if plugin.startswith("nav2_mppi") else \
            _positive(section.get("max_vel_y")) or _positive(section.get("vy_max"))
        if sideways and profile.drive != "omnidirectional":
            what = "motion_model" if plugin.startswith("nav2_mppi") else "max_vel_y"
            raise ProfileError(f"{field}.{what}", f"commands sideways motion the {profile.drive} robot "
                                                  f"{profile.name} cannot make")
        if profile.drive == "omnidirectional" and not sideways:
            notes.append(f"{field}: never moves sideways; the omnidirectional {profile.name} is driven as a "
                         f"differential one")
    return notes


def _positive(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and value > 0


__all__ = ["CAR_LIKE", "DRIVES", "Laser", "ProfileError", "ProfiledConfig", "ROUND_SIDES", "RobotProfile", "SHIPPED", "check_controller",
           "controllers", "load_profile", "profile_from_dict", "profile_path", "profile_to_dict", "profiled"]
