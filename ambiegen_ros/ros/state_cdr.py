"""The world's per-step messages (odometry, TF, ``/clock``) written straight to CDR bytes.

At real time the world sends these 50 times a second to every Nav2 node; building each as nested
message objects and serialising them cost about 1 ms a step in Python, more than half of the
world's CPU beside Nav2 (issue 58). These writers give the bytes ``TypeRegistry.serialize`` gives
for ``conversions.odometry``, ``conversions.transform`` in a ``tf2_msgs/TFMessage`` and a
``rosgraph_msgs/Clock`` (little-endian CDR with its encapsulation header; a test holds them equal
byte for byte), for ``Publisher.publish_raw``.
"""
from __future__ import annotations

import math
import struct

HEADER = b"\x00\x01\x00\x00"  # CDR, little-endian
_STAMP = struct.Struct("<iI")
_U32 = struct.Struct("<I")
_ZEROS_36 = bytes(8 * 36)  # a covariance nobody filled in
_POSE = struct.Struct("<7d")
_VEC3 = struct.Struct("<3d")


class _Cdr:
    """A CDR body; alignment counts from the end of the encapsulation header."""

    __slots__ = ("parts", "size")

    def __init__(self) -> None:
        self.parts: list[bytes] = [HEADER]
        self.size = 0

    def align(self, n: int) -> None:
        pad = -self.size % n
        if pad:
            self.parts.append(bytes(pad))
            self.size += pad

    def raw(self, data: bytes, align: int = 1) -> None:
        self.align(align)
        self.parts.append(data)
        self.size += len(data)

    def stamp(self, now_ns: int) -> None:
        self.raw(_STAMP.pack(int(now_ns // 1_000_000_000), int(now_ns % 1_000_000_000)), 4)

    def string(self, text: str) -> None:
        data = text.encode() + b"\x00"
        self.raw(_U32.pack(len(data)), 4)
        self.raw(data)

    def planar_pose(self, x: float, y: float, yaw: float) -> None:
        """Point then Quaternion, as ``conversions.pose`` and ``conversions.transform`` fill them."""
        self.raw(_POSE.pack(float(x), float(y), 0.0, 0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)), 8)

    def bytes(self) -> bytes:
        return b"".join(self.parts)


def odometry(now_ns: int, x: float, y: float, yaw: float, v: float, w: float, frame_id: str,
             child_frame_id: str, vy: float = 0.0) -> bytes:
    """``nav_msgs/Odometry`` as ``conversions.odometry`` builds it (covariances zero; ``vy`` the
    sideways speed of an omnidirectional base)."""
    out = _Cdr()
    out.stamp(now_ns)
    out.string(frame_id)
    out.string(child_frame_id)
    out.planar_pose(x, y, yaw)
    out.raw(_ZEROS_36, 8)
    out.raw(_VEC3.pack(float(v), float(vy), 0.0) + _VEC3.pack(0.0, 0.0, float(w)), 8)
    out.raw(_ZEROS_36, 8)
    return out.bytes()


def tf_message(now_ns: int, transforms: list[tuple[str, str, float, float, float]]) -> bytes:
    """``tf2_msgs/TFMessage`` of planar transforms ``(parent, child, x, y, yaw)`` stamped ``now_ns``."""
    out = _Cdr()
    out.raw(_U32.pack(len(transforms)), 4)
    for parent, child, x, y, yaw in transforms:
        out.stamp(now_ns)
        out.string(parent)
        out.string(child)
        out.planar_pose(x, y, yaw)  # translation (Vector3) and rotation: the same seven doubles
    return out.bytes()


def clock(now_ns: int) -> bytes:
    """``rosgraph_msgs/Clock``."""
    out = _Cdr()
    out.stamp(now_ns)
    return out.bytes()
