"""The service and action types we call without rclpy, as rosidl derives them from .srv/.action files.

rosbags' Jazzy type store has messages only. A service ``pkg/srv/S`` puts ``pkg/srv/S_Request`` and
``pkg/srv/S_Response`` on the wire; an action ``pkg/action/A`` its ``A_Goal``, ``A_Result``,
``A_Feedback`` and the wrappers rosidl_parser (``definition.Action``) builds around them:
``A_SendGoal_Request {UUID goal_id; A_Goal goal}``, ``A_SendGoal_Response {bool accepted; Time
stamp}``, ``A_GetResult_Request {UUID goal_id}``, ``A_GetResult_Response {int8 status; A_Result
result}`` and ``A_FeedbackMessage {UUID goal_id; A_Feedback feedback}``. ``ensure`` registers them
in a ``TypeRegistry`` on first use.

The texts are the Jazzy files' definitions (``share/<pkg>/{srv,action}/*``) without their comments;
test/ros/test_dds_services.py checks them, and the RIHS01 hashes, against a Jazzy build when one is
found. An empty section gets rosidl's ``uint8 structure_needs_at_least_one_member``: it is on the
wire (one byte), as in std_msgs/Empty.
"""
from __future__ import annotations

import threading
from typing import Any

from rosbags.typesys import get_types_from_msg

EMPTY = "uint8 structure_needs_at_least_one_member"

SERVICES: dict[str, str] = {
    "lifecycle_msgs/srv/GetState": "---\nState current_state\n",
    "nav2_msgs/srv/ClearEntireCostmap": "std_msgs/Empty request\n---\nstd_msgs/Empty response\n",
    "nav2_msgs/srv/ManageLifecycleNodes": (
        "uint8 STARTUP=0\nuint8 PAUSE=1\nuint8 RESUME=2\nuint8 RESET=3\nuint8 SHUTDOWN=4\nuint8 CONFIGURE=5\n"
        "uint8 CLEANUP=6\nuint8 command\n---\nbool success\n"),
    "std_srvs/srv/Trigger": "---\nbool success\nstring message\n",
    "action_msgs/srv/CancelGoal": (
        "GoalInfo goal_info\n---\n"
        "int8 ERROR_NONE=0\nint8 ERROR_REJECTED=1\nint8 ERROR_UNKNOWN_GOAL_ID=2\nint8 ERROR_GOAL_TERMINATED=3\n"
        "int8 return_code\nGoalInfo[] goals_canceling\n"),
}
ACTIONS: dict[str, str] = {
    "nav2_msgs/action/NavigateToPose": (
        "geometry_msgs/PoseStamped pose\nstring behavior_tree\n---\n"
        "uint16 NONE=0\nuint16 error_code\nstring error_msg\n---\n"
        "geometry_msgs/PoseStamped current_pose\nbuiltin_interfaces/Duration navigation_time\n"
        "builtin_interfaces/Duration estimated_time_remaining\nint16 number_of_recoveries\n"
        "float32 distance_remaining\n"),
    "nav2_msgs/action/ComputePathToPose": (
        "geometry_msgs/PoseStamped goal\ngeometry_msgs/PoseStamped start\nstring planner_id\nbool use_start\n---\n"
        "uint16 NONE=0\nuint16 UNKNOWN=200\nuint16 INVALID_PLANNER=201\nuint16 TF_ERROR=202\n"
        "uint16 START_OUTSIDE_MAP=203\nuint16 GOAL_OUTSIDE_MAP=204\nuint16 START_OCCUPIED=205\n"
        "uint16 GOAL_OCCUPIED=206\nuint16 TIMEOUT=207\nuint16 NO_VALID_PATH=208\n"
        "nav_msgs/Path path\nbuiltin_interfaces/Duration planning_time\nuint16 error_code\nstring error_msg\n---\n"),
    "nav2_msgs/action/ComputePathThroughPoses": (
        "geometry_msgs/PoseStamped[] goals\ngeometry_msgs/PoseStamped start\nstring planner_id\nbool use_start\n---\n"
        "uint16 NONE=0\nuint16 UNKNOWN=300\nuint16 INVALID_PLANNER=301\nuint16 TF_ERROR=302\n"
        "uint16 START_OUTSIDE_MAP=303\nuint16 GOAL_OUTSIDE_MAP=304\nuint16 START_OCCUPIED=305\n"
        "uint16 GOAL_OCCUPIED=306\nuint16 TIMEOUT=307\nuint16 NO_VALID_PATH=308\nuint16 NO_VIAPOINTS_GIVEN=309\n"
        "nav_msgs/Path path\nbuiltin_interfaces/Duration planning_time\nuint16 error_code\nstring error_msg\n---\n"),
    "nav2_msgs/action/SmoothPath": (
        "nav_msgs/Path path\nstring smoother_id\nbuiltin_interfaces/Duration max_smoothing_duration\n"
        "bool check_for_collisions\n---\n"
        "uint16 NONE=0\nuint16 UNKNOWN=500\nuint16 INVALID_SMOOTHER=501\nuint16 TIMEOUT=502\n"
        "uint16 SMOOTHED_PATH_IN_COLLISION=503\nuint16 FAILED_TO_SMOOTH_PATH=504\nuint16 INVALID_PATH=505\n"
        "nav_msgs/Path path\nbuiltin_interfaces/Duration smoothing_duration\nbool was_completed\n"
        "uint16 error_code\nstring error_msg\n---\n"),
}
UUID = "unique_identifier_msgs/msg/UUID"

_lock = threading.Lock()


def split_sections(text: str) -> list[str]:
    """The sections of a .srv/.action text (lines of three dashes separate them)."""
    sections, current = [], []
    for line in text.splitlines():
        if line.strip() == "---":
            sections.append("\n".join(current))
            current = []
        else:
            current.append(line)
    sections.append("\n".join(current))
    return sections


def _has_fields(text: str) -> bool:
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if line and "=" not in line:  # constants have one
            return True
    return False


def derived_types(typename: str, text: str) -> dict[str, str]:
    """``pkg/kind/Name_Suffix`` -> its .msg text, for a service or action ``typename``."""
    pkg, kind, name = typename.split("/")
    base = f"{pkg}/{kind}/{name}"
    sections = split_sections(text)

    def body(section: str) -> str:
        return section if _has_fields(section) else (section + "\n" + EMPTY).strip("\n")

    if kind == "srv":
        if len(sections) != 2:
            raise ValueError(f"{typename}: a service has 2 sections, found {len(sections)}")
        return {f"{base}_Request": body(sections[0]), f"{base}_Response": body(sections[1])}
    if kind == "action":
        if len(sections) != 3:
            raise ValueError(f"{typename}: an action has 3 sections, found {len(sections)}")
        uuid = "unique_identifier_msgs/UUID goal_id"
        return {
            f"{base}_Goal": body(sections[0]), f"{base}_Result": body(sections[1]),
            f"{base}_Feedback": body(sections[2]),
            f"{base}_SendGoal_Request": f"{uuid}\n{base}_Goal goal",
            f"{base}_SendGoal_Response": "bool accepted\nbuiltin_interfaces/Time stamp",
            f"{base}_GetResult_Request": uuid,
            f"{base}_GetResult_Response": f"int8 status\n{base}_Result result",
            f"{base}_FeedbackMessage": f"{uuid}\n{base}_Feedback feedback",
        }
    raise ValueError(f"{typename}: not a service (pkg/srv/Name) or an action (pkg/action/Name)")


def ensure(registry: Any, typename: str) -> None:
    """Register the wire types of service or action ``typename`` (one of ``SERVICES``/``ACTIONS``)."""
    text = SERVICES.get(typename) or ACTIONS.get(typename)
    if text is None:
        raise KeyError(f"no definition of {typename!r} here (known: {', '.join(sorted({**SERVICES, **ACTIONS}))})")
    with _lock:
        types = derived_types(typename, text)
        if all(registry.has(name) for name in types):
            return
        typedefs: dict = {}
        for name, msg in types.items():
            pkg, _kind, short = name.split("/")
            # parsed as pkg/msg/short: rosbags would file a pkg/srv/ type under pkg/srv/msg/ and resolve
            # its unqualified field types (State, GoalInfo) to pkg/srv/, where rosidl looks in pkg/msg/
            (_, (consts, fields)), = get_types_from_msg(msg, f"{pkg}/msg/{short}").items()
            typedefs[name] = (consts, fields)
        registry.store.register(typedefs)
