"""`ambiegen doctor`: is this machine fit to run AmbieGen-ROS? One line per check.

Checks the transport backend that nodes would use (and why: rclpy's import error, if any), the
ROS environment (RMW_IMPLEMENTATION, ROS_DOMAIN_ID, ROS_AUTOMATIC_DISCOVERY_RANGE: both what it
gives nodes and what ``ambiegen campaign`` uses, ROS_STATIC_PEERS), every dependency against its
minimum (``deps``), whether numba loads, and whether an installed ``ambiegen_msgs`` (``share/ambiegen_msgs/msg`` on AMENT_PREFIX_PATH) has the
message definitions and type hashes our nodes use; on the rclpy backend, also whether the Python
classes of ``ambiegen_msgs`` import (a plain ``colcon build`` skips that package). Exit status 0
when nothing is broken, 1 when something is (warnings alone keep 0); ``--json`` prints the same as
one JSON object.

It imports nothing that a broken environment could break before the checks run, so
``python -m ambiegen_ros.doctor`` (``main``) works even where ``ambiegen`` itself cannot start;
``ambiegen doctor`` is the same checks as a subcommand (``ambiegen_ros.cli.doctor``).
"""
from __future__ import annotations

import json
import os
import sys
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable

OK, WARN, FAIL = "ok", "warn", "fail"
# RMWs whose nodes speak DDS, so they meet nodes on our DDS backend (Cyclone)
DDS_RMWS = ("rmw_fastrtps_cpp", "rmw_fastrtps_dynamic_cpp", "rmw_cyclonedds_cpp", "rmw_connextdds")
SAFE_DOMAIN_MAX = 101  # above this the DDS ports of a participant may fall into Linux's ephemeral range


@dataclass
class Check:
    name: str
    status: str  # ok | warn | fail
    detail: str
    data: dict[str, Any] = field(default_factory=dict)


def check_backend() -> Check:
    """The backend ``create_node`` would pick, and why the other one is not used."""
    from ..ros import transport
    from ..ros.transport import dds_backend, rclpy_backend

    env_choice = os.environ.get(transport.ENV_VAR, "").strip()
    data: dict[str, Any] = {
        "requested": env_choice or "auto",
        "rclpy_error": None if rclpy_backend.is_available() else rclpy_backend.unavailable_reason(),
        "dds_error": None if dds_backend.is_available() else dds_backend.unavailable_reason(),
    }
    try:
        chosen = transport.select_backend()
    except (transport.BackendUnavailable, ValueError) as exc:
        data["chosen"] = None
        return Check("backend", FAIL, str(exc), data)
    data["chosen"] = chosen
    if env_choice and env_choice.lower() != "auto":
        why = f"{transport.ENV_VAR}={env_choice}"
    elif chosen == "rclpy":
        why = "rclpy imports"
    else:
        why = f"rclpy does not import ({data['rclpy_error']})"
    return Check("backend", OK, f"{chosen} ({why})", data)


def check_rmw(backend: str | None) -> Check:
    rmw = os.environ.get("RMW_IMPLEMENTATION", "").strip()
    data = {"RMW_IMPLEMENTATION": rmw or None}
    shown = rmw or "unset (Jazzy default: rmw_fastrtps_cpp)"
    if backend == "dds":
        shown += "; this process speaks DDS through Cyclone DDS itself (the RMW applies to rclpy processes)"
    if rmw and rmw not in DDS_RMWS:
        return Check("rmw", WARN, f"{shown}: {rmw} is not a DDS RMW, so its nodes may not meet nodes on the DDS "
                                  f"backend (DDS RMWs: {', '.join(DDS_RMWS)})", data)
    return Check("rmw", OK, shown, data)


def check_domain() -> Check:
    from ..ros.transport import TransportError
    from ..ros.transport.dds_backend import domain_id_from_env

    raw = os.environ.get("ROS_DOMAIN_ID", "").strip()
    try:
        domain = domain_id_from_env()
    except TransportError as exc:
        return Check("domain_id", FAIL, str(exc), {"ROS_DOMAIN_ID": raw})
    shown = f"{domain}" + ("" if raw else " (ROS_DOMAIN_ID unset)")
    if domain > SAFE_DOMAIN_MAX:
        return Check("domain_id", WARN, f"{shown}: above {SAFE_DOMAIN_MAX} its ports may collide with Linux's "
                                        "ephemeral ports (use 0..101)", {"domain_id": domain})
    return Check("domain_id", OK, shown, {"domain_id": domain})


def check_discovery() -> list[Check]:
    from ..ros.transport import TransportError
    from ..ros.transport.discovery import (LOCALHOST_ONLY_VAR, PEERS_VAR, RANGE_VAR, check_peers_resolve,
                                          options_from_env)

    raw_range = os.environ.get(RANGE_VAR, "").strip()
    try:
        options = options_from_env()
    except TransportError as exc:
        return [Check("discovery_range", FAIL, str(exc), {RANGE_VAR: raw_range or None})]
    shown = options.range + ("" if raw_range else " (unset: SUBNET)")
    if os.environ.get(LOCALHOST_ONLY_VAR, "").strip() == "1":
        shown += f" ({LOCALHOST_ONLY_VAR}=1 wins; it is deprecated in Jazzy)"
    campaign = campaign_range()
    data: dict[str, Any] = {"range": options.range, "campaign_range": campaign}
    # the two differ by design (a campaign defaults to LOCALHOST): say both, so neither surprises
    shown = f"{shown} for nodes started by hand or by ros2 launch; `ambiegen campaign` uses {campaign or '?'}"
    if campaign and not raw_range and campaign == "LOCALHOST":
        shown += " (its default; --discovery-range subnet for workers on other machines)"
    checks = [Check("discovery_range", OK, shown, data)]
    peers = list(options.static_peers)
    raw_peers = os.environ.get(PEERS_VAR, "").strip()
    if not peers:
        ignored = " (ignored: range is not SUBNET/LOCALHOST)" if raw_peers else ""
        checks.append(Check("static_peers", OK, "none" + ignored, {"peers": []}))
        return checks
    try:
        check_peers_resolve(options)
    except TransportError as exc:
        checks.append(Check("static_peers", FAIL, str(exc), {"peers": peers}))
    else:
        checks.append(Check("static_peers", OK, "; ".join(peers), {"peers": peers}))
    return checks


def campaign_range() -> str | None:
    """The discovery range ``ambiegen campaign`` gives its nodes here without --discovery-range
    (``campaign.discovery_scope``: the environment's if set, else LOCALHOST); None if unknown."""
    try:
        from ..campaign import discovery_scope
    except ImportError:  # a broken dependency is the dependency checks' to report
        return None
    return discovery_scope(None, dict(os.environ))


def check_dependencies() -> list[Check]:
    from .. import deps

    out = []
    for s in deps.statuses():
        d = s.dependency
        data = {"installed": s.installed, "minimum": d.minimum, "optional": bool(d.optional)}
        problem = s.problem()
        if problem:
            out.append(Check(d.name, FAIL, problem, data))
        elif s.installed is None:
            out.append(Check(d.name, WARN, f"not installed (optional: {d.optional})", data))
        else:
            out.append(Check(d.name, OK, f"{s.installed} (>= {d.minimum})", data))
    return out


def check_numba() -> Check:
    from ..core import accel

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # the error is this check's detail
        error = accel.numba_error()
    if error:
        return Check("numba_loads", WARN, f"no: {error}; the numpy paths run instead (same results, slower)",
                     {"loads": False, "error": error})
    return Check("numba_loads", OK, "yes", {"loads": True})


def installed_msgs_dir() -> Path | None:
    """``share/ambiegen_msgs/msg`` of the first AMENT_PREFIX_PATH entry that has .msg files."""
    from ..ros.types import MSGS_PACKAGE

    for prefix in filter(None, os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)):
        path = Path(prefix) / "share" / MSGS_PACKAGE / "msg"
        if any(path.glob("*.msg")):
            return path
    return None


def _rosidl_hash(msg_dir: Path, typename: str) -> str | None:
    """The RIHS01 hash rosidl wrote next to an installed .msg (``Type.json``), if present."""
    path = msg_dir / (typename.rsplit("/", 1)[-1] + ".json")
    try:
        for entry in json.loads(path.read_text()).get("type_hashes", []):
            if entry.get("type_name") == typename:
                return entry.get("hash_string")
    except (OSError, ValueError, AttributeError):
        return None
    return None


def check_messages() -> Check:
    """Do our message definitions match the installed ambiegen_msgs (names, text, type hashes)?"""
    from ..ros.types import TypeRegistry, get_registry

    installed = installed_msgs_dir()
    if installed is None:
        return Check("ambiegen_msgs", OK, "not installed (no share/ambiegen_msgs/msg on AMENT_PREFIX_PATH): "
                                          "nothing to compare", {"installed": None})
    ours = get_registry()
    data: dict[str, Any] = {"installed": str(installed), "ours": str(ours.msg_dir)}
    if ours.msg_dir.resolve() == installed.resolve():
        return Check("ambiegen_msgs", OK, f"{installed} (our nodes use these very files)", data)
    try:
        theirs = TypeRegistry(installed)
    except Exception as exc:  # unparsable or incomplete definitions
        return Check("ambiegen_msgs", FAIL, f"{installed}: cannot read ({type(exc).__name__}: {exc})", data)
    problems = []
    for name in sorted(set(ours.own_types) | set(theirs.own_types)):
        if name not in theirs.own_types:
            problems.append(f"{name} missing from the installed package")
        elif name not in ours.own_types:
            problems.append(f"{name} is installed but unknown to our nodes")
        elif ours.type_hash(name) != theirs.type_hash(name):
            problems.append(f"{name} differs (hash {theirs.type_hash(name)[:15]}... installed, "
                            f"{ours.type_hash(name)[:15]}... ours)")
        else:
            built = _rosidl_hash(installed, name)
            if built is not None and built != ours.type_hash(name):
                problems.append(f"{name}: rosidl built hash {built[:15]}..., ours {ours.type_hash(name)[:15]}...")
    data["problems"] = problems
    if problems:
        return Check("ambiegen_msgs", FAIL, f"{installed} does not match ours ({ours.msg_dir}): "
                                            + "; ".join(problems) + " (rebuild/re-source the workspace)", data)
    return Check("ambiegen_msgs", OK, f"{installed}: {len(ours.own_types)} types, same type hashes", data)


def check_message_classes() -> Check:
    """rclpy backend: do the Python classes colcon generates for ambiegen_msgs import? (The same
    check every node makes before it starts, with the same one line.)"""
    from ..ros.transport.rclpy_backend import message_classes, missing_messages

    missing = missing_messages()
    if missing:
        return Check("ambiegen_msgs_python", FAIL, missing, {"importable": False})
    return Check("ambiegen_msgs_python", OK, f"ambiegen_msgs.msg has {', '.join(message_classes())}",
                 {"importable": True})


def _safely(name: str, fn: Callable[[], Any]) -> list[Check]:
    """A check that crashes is itself a broken environment, reported as one line."""
    try:
        got = fn()
    except Exception as exc:
        return [Check(name, FAIL, f"check crashed: {type(exc).__name__}: {exc}")]
    return got if isinstance(got, list) else [got]


def run_checks() -> list[Check]:
    backend_checks = _safely("backend", check_backend)
    backend = backend_checks[0].data.get("chosen")
    checks = backend_checks + _safely("rmw", lambda: check_rmw(backend)) + _safely("domain_id", check_domain)
    checks += _safely("discovery", check_discovery) + _safely("dependencies", check_dependencies)
    checks += _safely("numba_loads", check_numba) + _safely("ambiegen_msgs", check_messages)
    if backend == "rclpy":
        checks += _safely("ambiegen_msgs_python", check_message_classes)
    return checks


def report(checks: list[Check], as_json: bool = False) -> int:
    """Print the checks; 1 when any failed, else 0."""
    broken = any(c.status == FAIL for c in checks)
    if as_json:
        print(json.dumps({"ok": not broken, "checks": [asdict(c) for c in checks]}, indent=2))
    else:
        width = max(len(c.name) for c in checks)
        for c in checks:
            print(f"[{c.status:>4}] {c.name:<{width}}  {c.detail}")
        print("all fine" if not broken else f"{sum(c.status == FAIL for c in checks)} problem(s) found")
    return 1 if broken else 0


USAGE = "usage: {prog} [-h] [--json]"


def main(argv: list[str] | None = None, prog: str = "python -m ambiegen_ros.doctor") -> int:
    """Run the checks and print them (``--json``: one JSON object); exit status as ``report``.

    Parses its one option by hand: argparse belongs to the command line (``cli``), which imports
    this module, never the other way round. A wrong argument is two lines and exit status 2, as
    argparse would print them.
    """
    args = sys.argv[1:] if argv is None else list(argv)
    if any(a in ("-h", "--help") for a in args):
        print(USAGE.format(prog=prog) + "\n\n" + (__doc__ or "").split("\n")[0] + "\n\noptions:\n"
              "  -h, --help  show this help message and exit\n"
              "  --json      print one JSON object (ok, checks[])")
        return 0
    unknown = [a for a in args if a != "--json"]
    if unknown:
        print(USAGE.format(prog=prog), file=sys.stderr)
        print(f"{prog}: error: unrecognized arguments: {' '.join(unknown)}", file=sys.stderr)
        return 2
    return report(run_checks(), as_json="--json" in args)
