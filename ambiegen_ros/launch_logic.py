"""A campaign's plan without ROS: run id, log name, node set, when it ends, its summary as a table.

``launch/campaign.launch.py`` only wraps this plan in launch / launch_ros actions, and
``ambiegen campaign`` shares its run id, log name and summary, so the logic is tested on machines
without ROS and both ways of running a campaign name and report it alike.
"""
from __future__ import annotations

import json
import os
import re
import secrets
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .ros import topics
from .nav2_params import (OVERLAY_FILE, for_namespace, goal_time_budget, merged_params, scale_nav2_rates,
                          top_speed, write_params)


SIM_EXECUTABLES = {"robot": "robot_sim", "vehicle": "car_sim", "thermostat": "thermostat_sim"}

LAUNCH_ARGUMENTS: dict[str, tuple[str, str]] = {
    "problem": ("robot", "thermostat | robot | vehicle"),
    "algorithm": ("nsga2", "ga | nsga2 | random"),
    "evaluations": ("0", "evaluation budget (0 = the paper's)"),
    "time_budget": ("0.0", "wall-clock budget in seconds (0 = none)"),
    "execution_budget": ("0.0", "wall seconds of sending scenarios, from the first (0 = none); the sent ones finish"),
    "seed": ("-1", "random seed (-1 = drawn and recorded)"),
    "mode": ("surrogate", "surrogate | in_the_loop"),
    "workers": ("1", "number of sim nodes sharing the scenarios"),
    "output_dir": (".", "where the recorder writes <run id>_<UTC time>.mcap"),
    "output": ("", "MCAP file to write ('' = <output_dir>/<run id>_<UTC time>.mcap)"),
    "overwrite": ("false", "replace an existing output file (default: the recorder refuses it and the launch ends)"),
    "keep_workers": ("false", "keep the sim workers running after the campaign (for external stacks; Ctrl-C ends them)"),
    "config_file": ("", "run config YAML ('' = the package's config/<problem>.yaml)"),
    "profile": ("", "fidelity profile of every node: replication | refined ('' = the config file's, else replication)"),
}


def new_run_id(problem: str, algorithm: str, seed: int) -> str:
    """``<problem>-<algorithm>-s<seed>-<6 hex>``: readable, and unique even for the same seed."""
    return f"{problem}-{algorithm}-s{seed}-{uuid.uuid4().hex[:6]}"


def launch_flag(name: str, text: str) -> bool:
    value = text.strip().lower()
    if value not in ("true", "false"):
        raise ValueError(f"{name}: {text!r} is not a boolean (allowed: true|false)")
    return value == "true"


def _number(name: str, text: str, kind: type, minimum: float | None = None) -> Any:
    try:
        value = kind(text)
    except ValueError:
        raise ValueError(f"{name}: {text!r} is not {'an integer' if kind is int else 'a number'}") from None
    if minimum is not None and value < minimum:
        raise ValueError(f"{name}: {text} is below {minimum}")
    return value


@dataclass
class NodeSpec:
    name: str
    executable: str
    parameters: dict[str, Any]
    package: str = "ambiegen_ros"
    params_files: list[str] = field(default_factory=list)  # ROS parameter files, before ``parameters``
    namespace: str = ""
    remappings: list[tuple[str, str]] = field(default_factory=list)


@dataclass
class CampaignPlan:
    run_id: str
    problem: str
    algorithm: str
    seed: int
    mode: str
    workers: int
    mcap: Path
    keep_workers: bool
    nodes: list[NodeSpec]
    includes: list[Any] = field(default_factory=list)  # other packages' launch files (IncludeSpec)
    notes: list[str] = field(default_factory=list)  # said when the launch starts
    nav2_params: Path | None = None  # the Nav2 params file written for the run

    def node(self, name: str) -> NodeSpec:
        """The node called ``name``, or ``<namespace>/<name>``."""
        return next(n for n in self.nodes if name in (n.name, f"{n.namespace}/{n.name}"))

    def after_generator_exit(self) -> str:
        """``shutdown``: the campaign is over, every node gets SIGINT (the recorder closes the MCAP);
        ``stop_recorder`` with ``keep_workers``: only the recorder is stopped, the workers stay."""
        return "stop_recorder" if self.keep_workers else "shutdown"

    def after_recorder_exit(self, generator_done: bool) -> bool:
        """Shut the launch down? Yes, unless the workers are kept after a finished campaign: a
        recorder that ends early (e.g. refused an existing file) would leave a run with no log."""
        return not (self.keep_workers and generator_done)


def plan_campaign(values: dict[str, str], share_dir: str, seed: int | None = None) -> CampaignPlan:
    """The launch file's node set from its arguments (strings, as launch gives them).

    A drawn seed (``seed:=-1``) is drawn here, so the run id and the log name carry it; a bad
    argument raises ``ValueError`` naming it.
    """
    value = {name: values.get(name, default) for name, (default, _) in LAUNCH_ARGUMENTS.items()}
    problem = value["problem"]
    if problem not in SIM_EXECUTABLES:
        raise ValueError(f"problem: unknown {problem!r} (allowed: {'|'.join(sorted(SIM_EXECUTABLES))})")
    workers = _number("workers", value["workers"], int, 0)
    seed = _number("seed", value["seed"], int) if seed is None else seed
    seed = secrets.randbelow(2**31) if seed < 0 else seed
    run_id = new_run_id(problem, value["algorithm"], seed)
    config = value["config_file"] or os.path.join(share_dir, "config", f"{problem}.yaml")
    from .ros.mcap_log import log_file_name  # mcap and rosbags load when a campaign is planned

    mcap = Path(value["output"] or os.path.join(value["output_dir"], log_file_name(run_id))).absolute()
    nodes = [NodeSpec("recorder", "recorder",
                      {"output": str(mcap), "overwrite": launch_flag("overwrite", value["overwrite"])})]
    for k in range(workers):
        name = f"{problem}_sim_{k}"
        nodes.append(NodeSpec(name, SIM_EXECUTABLES[problem], {
            "worker_id": f"{name}_{run_id[-6:]}",  # unique per run: campaigns may share a domain
            "config_file": config, "profile": value["profile"], "min_result_subscribers": 2}))
    nodes.append(NodeSpec("generator", "generator", {
        "problem": problem,
        "algorithm": value["algorithm"],
        "evaluations": _number("evaluations", value["evaluations"], int, 0),
        "time_budget": _number("time_budget", value["time_budget"], float, 0),
        "execution_budget": _number("execution_budget", value["execution_budget"], float, 0),
        "seed": seed,
        "run_id": run_id,
        "mode": value["mode"],
        "config_file": config,
        "profile": value["profile"],
        "min_subscribers": workers + 1,
        # no scenario before the plan's recorder reads every topic it records (as ``ambiegen campaign``)
        "min_recorders": sum(n.executable == "recorder" for n in nodes),
    }))
    return CampaignPlan(run_id, problem, value["algorithm"], seed, value["mode"], workers, mcap,
                        launch_flag("keep_workers", value["keep_workers"]), nodes)


# --- Nav2 as the system under test (launch/nav2_campaign.launch.py) --------------------------------
NAV2_MODES = ("ours", "bringup", "external")
NAV2_LAUNCH_ARGUMENTS: dict[str, tuple[str, str]] = {
    **{k: v for k, v in LAUNCH_ARGUMENTS.items() if k not in ("problem", "workers", "keep_workers")},
    "nav2": ("ours", "ours: start the minimum Nav2 here (controller, planner, behaviours, BT navigator) | "
                     "bringup: include nav2_bringup's navigation_launch.py with the merged params | "
                     "external: start only our side; you start Nav2 yourself (see docs/external_sut.md)"),
    "params_file": ("", "your Nav2 params ('' = the package's config/nav2/pioneer_navfn_dwb.yaml)"),
    "params_overlay": ("", "YAML merged onto params_file ('' = the package's config/nav2/ambiegen_overlay.yaml "
                           "for a params_file of yours, none for the package's own; 'none' = none)"),
    "time_scale": ("1.0", "simulated seconds per wall second; Nav2's rates in the params file are multiplied by it"),
    "map_upsample": ("5", "each 1 m map cell goes to Nav2 as k x k cells (5 = 0.2 m)"),
    "early_verdicts": ("false", "true: the paper's stall and loitering monitors decide and cancel Nav2; false: Nav2's "
                                "own result decides (succeeded / aborted), besides collisions and the time limit"),
    "result_timeout": ("0.0", "seconds the generator waits for a scenario (0 = twice the adapter's longest run)"),
    "known_failures": ("", "YAML of known Nav2 failures, recorded as FAIL(kind, known: name) and not counted as new "
                           "('' = the package's config/nav2/known_failures.yaml; 'none' = none)"),
    "contact_fault_speed": ("", "m/s: a contact with a person is the robot's fault only when it moves towards them "
                                "faster than this ('' = the world's default, 0.01)"),
    "stacks": ("1", "K stacks of world + Nav2 + adapter fed by one generator, stack i in namespace /stack<i> "
                    "(K > 1: nav2:=ours)"),
    "robot_profile": ("", "the robot the world drives and the adapter judges: a shipped profile (turtlebot4, "
                          "turtlebot3_burger, ...) or a profile file (docs/robot_profiles.md); its body, laser and "
                          "limits go into the params too ('' = Stage's pioneer2dx)"),
    "part": ("all", "what this host runs, for a campaign across hosts: all | generator (the recorder and the "
                    "generator, for `stacks` stacks elsewhere) | stack<i> (stack i alone, in /stack<i>, serving "
                    "campaigns until Ctrl-C)"),
}
NAV2_NODES = (  # (node name, package, executable): the minimum Nav2 for navigate_to_pose with NavFn + DWB
    ("controller_server", "nav2_controller", "controller_server"),
    ("planner_server", "nav2_planner", "planner_server"),
    ("behavior_server", "nav2_behaviors", "behavior_server"),
    ("bt_navigator", "nav2_bt_navigator", "bt_navigator"),
    ("lifecycle_manager_navigation", "nav2_lifecycle_manager", "lifecycle_manager"),
)
NAV2_MANAGED = tuple(name for name, _, _ in NAV2_NODES if not name.startswith("lifecycle_manager"))


def nav2_node_parameters(name: str) -> dict:
    """What our Nav2 node set fixes whatever the params file says: sim time, and the lifecycle
    manager's node list (Jazzy's nav2_params.yaml has none: navigation_launch.py passes its own)."""
    if name.startswith("lifecycle_manager"):
        return {"use_sim_time": True, "autostart": True, "node_names": list(NAV2_MANAGED)}
    return {"use_sim_time": True}


NAV2_TOPICS = ("/map", "/initialpose", "/scan", "/odom", "/tf", "/tf_static", "/cmd_vel", "/plan", "/collision",
               "/ambiegen/world/obstacles", "/ambiegen/world/markers")
"""What a Nav2 campaign records besides the AmbieGen topics: a robot bag (types and QoS: the publishers')."""
EXTERNAL_START_TIMEOUT = 600.0  # s the adapter waits for a Nav2 the user starts by hand


@dataclass
class IncludeSpec:
    """Another package's launch file, included with ``arguments`` (``nav2:=bringup``)."""
    package: str
    launch_file: str  # under the package's share dir
    arguments: dict[str, str]


def file_argument(value: str, default: str | None) -> str | None:
    """A file launch argument: 'none' = no file, '' = ``default``, else the path given."""
    if value.strip().lower() == "none":
        return None
    return value or default


def nav2_overlay(value: str, params_file: str, share_dir: str) -> str | None:
    """The overlay file a Nav2 campaign merges on: the package's for a user's params file."""
    return file_argument(value, os.path.join(share_dir, *OVERLAY_FILE) if params_file else None)


# Nav2 error codes that our side causes, since our world publishes the scan, TF and clock: 107,
# FollowPath's CONTROLLER_TIMED_OUT, is thrown only when the controller's costmap got no current data
# within costmap_update_timeout; 102 and 202, FollowPath's and ComputePathToPose's TF_ERROR, when a
# transform of ours was too old ("Transform data too old when converting from map to odom"). All seen
# on a machine running two stacks (docs/results/nav2/hardened.md)
NAV2_OURS_ERROR_CODES = "102,107,202"


def nav2_stack(ns: str, mode: str, params: dict, scaled: Path, seed: int, tag: str, k: float, upsample: int,
               start_timeout: float, early: bool, speed: float | None, config_file: str, profile: str) -> list[NodeSpec]:
    """One stack: ``robot_world``, Nav2 (with ``nav2:=ours``) and ``sut_adapter``. In the root
    namespace (``ns`` = '') as one stack runs; else every node of it in ``/<ns>``, on its own
    world's clock (``/<ns>/clock``) and TF (``/<ns>/tf``), with the params nested under ``ns``
    (``nav2_params.for_namespace``) in a file of its own beside the log. ``seed``: the world's (laser
    noise); ``tag``: makes the adapter's worker id unique (the run id's last characters)."""
    at = (lambda topic: f"/{ns}{topic}") if ns else (lambda topic: topic)  # noqa: E731
    suffix = f"_{ns}" if ns else ""
    world = NodeSpec("robot_world", "robot_world", {
        "time_scale": k, "seed": seed, "paired_start": True,
        **{f"{name}_topic": at(f"/{name}") for name in ("map", "initialpose", "cmd_vel", "odom", "scan", "collision",
                                                         "clock")},
        "obstacles_topic": at(topics.WORLD_OBSTACLES), "markers_topic": at(topics.WORLD_MARKERS)}, namespace=ns)
    nav2 = []
    if mode == "ours":
        files = [str(scaled)]
        if ns:
            files = [str(write_params(for_namespace(params, ns), scaled.with_name(f"{scaled.stem}.{ns}.yaml"),
                                      f"{scaled.name} for the stack in /{ns}", overwrite=True))]
        remap = [("/tf", "tf"), ("/tf_static", "tf_static"), ("/clock", at("/clock"))] if ns else []
        nav2 = [NodeSpec(name, executable, nav2_node_parameters(name), package=package, params_files=files,
                         namespace=ns, remappings=remap) for name, package, executable in NAV2_NODES]
    lifecycle = ",".join(f"{ns}/{n}" if ns else n for n in ("planner_server", "controller_server", "bt_navigator"))
    adapter = NodeSpec(f"sut_adapter{suffix}", "sut_adapter", {
        "problem": "robot", "worker_id": f"nav2{suffix}_{tag}", "goal_mode": "action", "time_scale": k,
        "map_topic": at("/map"), "initialpose_topic": at("/initialpose"), "odom_topic": at("/odom"),
        "collision_topic": at("/collision"), "plan_topic": at("/plan"), "action_name": at("/navigate_to_pose"),
        "obstacles_topic": at(topics.WORLD_OBSTACLES),
        "nav2_lifecycle_nodes": lifecycle,
        # a bringup that gave up is started again: ours and nav2_bringup's stacks, never a user's own
        "nav2_lifecycle_manager": "" if mode == "external" else "/".join(filter(None, (ns, "lifecycle_manager_navigation"))),
        "nav2_clear_costmaps": ",".join(at(f"/{c}_costmap/clear_entirely_{c}_costmap") for c in ("global", "local")),
        "timing_scan_topic": at("/scan"), "timing_clock_topic": at("/clock"),  # its own world's silences
        "map_upsample": upsample,
        "tick_period": 0.05,  # a turn every 50 ms (Nav2 controls at 20 Hz): its verdict follows stamps, not turns
        "settle_time": 1.0, "start_timeout": start_timeout,
        "early_verdicts": early, "time_limit_speed": speed or 0.0,
        "goal_time_budget": goal_time_budget(params, k),
        "ours_error_codes": NAV2_OURS_ERROR_CODES,
        "config_file": config_file, "profile": profile, "min_result_subscribers": 2})
    return [world, *nav2, adapter]


def nd_stack(seed: int, tag: str, profile: str | None, config_file: str | None) -> list[NodeSpec]:
    """Our ROS-free navigation stack: ``robot_world`` in lockstep with ``nd_driver`` (the full
    model's route and Nearness Diagram on Nav2's topics) behind ``sut_adapter``, so every verdict is
    the in-process full model's for the world's ``seed`` (the world's collision report included: a
    robot stopped by a person it drove into is a collision, not a stall)."""
    return [
        NodeSpec("robot_world", "robot_world", {"lockstep": True, "time_scale": 0.0, "scan_rate": 10.0, "seed": seed,
                                                "cmd_vel_stamped": True, "paired_start": True, "sim.dt": 0.1}),
        NodeSpec("nd_driver", "nd_driver", {"cmd_vel_stamped": True, "paired_start": True}),
        NodeSpec("sut_adapter", "sut_adapter", {
            "problem": "robot", "worker_id": f"sut_{tag}", "profile": profile, "config_file": config_file,
            "stall_topic": "/nd_driver/stall", "plan_topic": "/plan", "collision_topic": "/collision",
            "min_result_subscribers": 2, "settle_time": 0.1}),
    ]


PLANNER_NODES = (  # (node name, package, executable): Nav2's planner alone (``--stack planner``, issue 68)
    ("planner_server", "nav2_planner", "planner_server"),
    ("smoother_server", "nav2_smoother", "smoother_server"),
    ("lifecycle_manager_planner", "nav2_lifecycle_manager", "lifecycle_manager"),
)
PLANNER_PLUGINS = {  # a planner_server plugin -> its rules in ambiegen_ros/sims/plans/rules.py
    "nav2_navfn_planner/NavfnPlanner": "navfn", "nav2_navfn_planner::NavfnPlanner": "navfn",
    "nav2_smac_planner/SmacPlanner2D": "smac_2d", "nav2_smac_planner::SmacPlanner2D": "smac_2d",
    "nav2_smac_planner/SmacPlannerHybrid": "smac_hybrid", "nav2_smac_planner::SmacPlannerHybrid": "smac_hybrid",
    "nav2_smac_planner/SmacPlannerLattice": "smac_lattice", "nav2_smac_planner::SmacPlannerLattice": "smac_lattice",
    "nav2_theta_star_planner/ThetaStarPlanner": "theta_star",
    "nav2_theta_star_planner::ThetaStarPlanner": "theta_star",
}
PLANNER_RULE_KEYS = {  # the plugin's params the rules take (rules.py's argument names)
    "navfn": ("tolerance", "allow_unknown"), "smac_2d": ("tolerance", "allow_unknown", "max_planning_time"),
    "theta_star": ("allow_unknown",),
    "smac_hybrid": ("tolerance", "allow_unknown", "max_planning_time", "minimum_turning_radius"),
    "smac_lattice": ("tolerance", "allow_unknown", "max_planning_time", "allow_reverse_expansion"),
}
PLANNER_TOPICS = ("/map", "/tf_static", "/plan", "/global_costmap/costmap")
"""What a planner stack records besides the AmbieGen topics: the map asked, the costmap the planner saw."""


def planner_under_test(params: dict) -> tuple[str, str, str]:
    """(planner_id, rules key, rules overrides ``key=value,...``) of the params' first planner plugin,
    with the global costmap's ``robot_radius``; ``ValueError`` naming the field when it is none we judge."""
    server = ((params.get("planner_server") or {}).get("ros__parameters")) or {}
    ids = server.get("planner_plugins") or ["GridBased"]
    planner_id = str(ids[0])
    section = server.get(planner_id) or {}
    plugin = str(section.get("plugin", ""))
    key = PLANNER_PLUGINS.get(plugin)
    if key is None:
        raise ValueError(f"planner_server.{planner_id}.plugin: {plugin or 'none'!r} is no planner we judge "
                         f"(known: {', '.join(sorted({p.replace('::', '/') for p in PLANNER_PLUGINS}))})")
    rules = {name: section[name] for name in PLANNER_RULE_KEYS[key] if name in section}
    if key == "smac_hybrid" and section.get("motion_model_for_search"):
        rules["motion_model"] = section["motion_model_for_search"]
    if key == "smac_lattice" and section.get("lattice_filepath"):
        rules.update(lattice_metadata(f"planner_server.{planner_id}.lattice_filepath", section["lattice_filepath"]))
    costmap = (((params.get("global_costmap") or {}).get("global_costmap") or {}).get("ros__parameters")) or {}
    if "robot_radius" in costmap:
        rules["robot_radius"] = costmap["robot_radius"]
    text = ",".join(f"{k}={str(v).lower() if isinstance(v, bool) else v}" for k, v in rules.items())
    return planner_id, key, text


def lattice_metadata(where: str, path: str) -> dict:
    """The rules a Smac Lattice primitives file sets (``turning_radius``, ``motion_model`` of its
    ``lattice_metadata``); ``ValueError`` naming ``where`` (the param) when the file cannot tell."""
    try:
        meta = json.loads(Path(path).read_text())["lattice_metadata"]
        return {"minimum_turning_radius": float(meta["turning_radius"]), "motion_model": str(meta["motion_model"])}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{where}: {path!r} gives no lattice_metadata turning_radius and motion_model "
                         f"({type(exc).__name__}: {exc})") from None


def planner_stack(params: dict, params_file: Path | None, tag: str, upsample: int, start_timeout: float,
                  config_file: str, profile: str) -> list[NodeSpec]:
    """Nav2's ``planner_server`` (and ``smoother_server`` when the params have one) under their own
    lifecycle manager, each by ``ros2 run`` with the user's params on wall time (no world, no /clock,
    no controller), and ``sut_adapter`` in ``goal_mode:=plan``, which publishes each scenario's map,
    the static transforms map -> odom -> base_link the global costmap needs, and asks the planner."""
    planner_id, rules, overrides = planner_under_test(params)
    smooth = "smoother_server" in params
    names = ["planner_server"] + (["smoother_server"] if smooth else [])
    files = [str(params_file)] if params_file else []
    nodes = []
    for name, package, executable in PLANNER_NODES:
        if name in names:
            nodes.append(NodeSpec(name, executable, {"use_sim_time": False}, package=package, params_files=files))
        elif name.startswith("lifecycle_manager"):
            nodes.append(NodeSpec(name, executable, {"use_sim_time": False, "autostart": True, "node_names": names},
                                  package=package))
    adapter = NodeSpec("sut_adapter", "sut_adapter", {
        "problem": "robot", "worker_id": f"planner_{tag}", "goal_mode": "plan", "map_upsample": upsample,
        "planner_plugin": rules, "planner_rules": overrides, "planner_id": planner_id, "smooth": smooth,
        "plan_lifecycle_nodes": ",".join(names), "settle_time": 0.0, "tick_period": 0.01,
        "start_timeout": start_timeout, "config_file": config_file, "profile": profile,
        "min_result_subscribers": 2})
    return [*nodes, adapter]


def campaign_part(value: str) -> str:
    """``all``, ``generator`` or ``stack<i>`` (i >= 0): what one host of a campaign runs."""
    if value in ("all", "generator") or re.fullmatch(r"stack(0|[1-9][0-9]*)", value):
        return value
    raise ValueError(f"part: unknown {value!r} (allowed: all | generator | stack<i>, e.g. stack0)")


def nav2_result_timeout(cfg: Any, speed: float | None, time_scale: float, start_timeout: float) -> float:
    """How long the generator waits for a scenario: a safety net for an adapter that died, beyond
    the adapter's own guard (``wall_slack`` 2 x the time limit / time_scale + start_timeout) for a
    route ten 50 m map sides long (the longest routes searches have found are about nine)."""
    return 2.0 * cfg.time_limit(10 * 50.0, speed) / time_scale + start_timeout + 60.0


def node_robot(robot: str) -> tuple[str, Any]:
    """The robot as the world and the adapter take it (``robot_profile``), and its checked profile
    (``ProfileError`` naming the field otherwise). A shipped name stays a name; a file becomes an
    absolute path, so every node reads the file checked here, whatever its working directory. The
    Nav2 campaign launch and the supervised trials (``ambiegen rerun --robot``) both resolve it here."""
    from .sims.robot_profile import load_profile, profile_path

    profile = load_profile(robot)
    path = profile_path(robot)
    return (str(path.absolute()) if path == Path(robot) else robot), profile


def campaign_robot(robot: str, params: dict) -> tuple[str, dict]:
    """``node_robot``'s robot, and the params with its body and limits (``nav2_params.with_robot``),
    once it is known that the params' controller can drive it (``ValueError`` naming the field otherwise)."""
    from .nav2_params import with_robot
    from .sims.robot_profile import check_controller

    value, profile = node_robot(robot)
    check_controller(profile, params)
    return value, with_robot(params, profile)


def plan_nav2_campaign(values: dict[str, str], share_dir: str, seed: int | None = None) -> CampaignPlan:
    """``nav2_campaign.launch.py``'s node set: recorder, ``robot_world`` (free-running at
    ``time_scale``, publishing ``/clock``), Nav2 (``nav2``: ours, nav2_bringup's, or the user's
    own), ``sut_adapter`` (``goal_mode:=action``, collisions from the world) as the campaign's one
    worker, and the generator. The params file (the user's, the overlay merged on, rates scaled:
    ``nav2_params``) is written next to the log; its controller's top speed sets the time limit."""
    value = {name: values.get(name, default) for name, (default, _) in NAV2_LAUNCH_ARGUMENTS.items()}
    base = plan_campaign({**{k: v for k, v in value.items() if k in LAUNCH_ARGUMENTS}, "problem": "robot",
                          "workers": "0"}, share_dir, seed)
    mode = value["nav2"]
    if mode not in NAV2_MODES:
        raise ValueError(f"nav2: unknown {mode!r} (allowed: {'|'.join(NAV2_MODES)})")
    k = _number("time_scale", value["time_scale"], float, 0.0)
    if not k > 0:
        raise ValueError("time_scale: must be > 0")
    upsample = _number("map_upsample", value["map_upsample"], int, 1)
    early = launch_flag("early_verdicts", value["early_verdicts"])
    source = value["params_file"] or os.path.join(share_dir, "config", "nav2", "pioneer_navfn_dwb.yaml")
    overlay = nav2_overlay(value["params_overlay"], value["params_file"], share_dir)
    params = merged_params(source, overlay, k)
    robot = value.get("robot_profile", "")
    if robot:  # issue 69: the robot of the world and the adapter's judge, and its body and limits in Nav2's params
        robot, params = campaign_robot(robot, params)
    scaled = base.mcap.with_name(base.mcap.stem + ".nav2_params.yaml")
    write_params(params, scaled, f"{source}" + (f" + {overlay}" if overlay else "")
                 + f", Nav2's loop rates x {k:g} (time_scale)", overwrite=True)  # named after the run: ours
    speed = top_speed(params)
    start_timeout = EXTERNAL_START_TIMEOUT if mode == "external" else 120.0
    from .sims.robot import RobotSimConfig

    result_timeout = (_number("result_timeout", value["result_timeout"], float, 0.0)
                      or nav2_result_timeout(RobotSimConfig(), speed, k, start_timeout))
    known = file_argument(value["known_failures"], os.path.join(share_dir, "config", "nav2", "known_failures.yaml")) or ""
    stacks = _number("stacks", value["stacks"], int, 1)
    part = campaign_part(value["part"])
    if (stacks > 1 or part != "all") and mode != "ours":
        raise ValueError(f"stacks: {stacks} stacks (part {part}) need nav2:=ours (each stack's Nav2 runs on its own "
                         "world's clock, /<ns>/clock, which navigation_launch.py cannot remap)")
    recorder, generator = base.node("recorder"), base.node("generator")
    groups = [""] if stacks == 1 and part == "all" else [f"stack{i}" for i in range(stacks)]
    recorder.parameters["extra_topics"] = ",".join(
        topic if not ns else f"/{ns}{topic}" for ns in groups for topic in NAV2_TOPICS)
    generator.parameters.update(min_subscribers=1 + stacks, min_workers=stacks, max_in_flight=1,
                                result_timeout=result_timeout)
    here = {"all": groups, "generator": []}.get(part, [part])
    nodes = [] if part.startswith("stack") else [recorder]
    for ns in here:
        stack = nav2_stack(ns, mode, params, scaled, base.seed, base.run_id[-6:], k, upsample, start_timeout, early,
                           speed, generator.parameters["config_file"], value["profile"])
        world, adapter = stack[0], stack[-1]
        if robot:  # the world drives it, the adapter judges it
            world.parameters["robot_profile"] = adapter.parameters["robot_profile"] = robot
        adapter.parameters["known_failures"] = known
        if value["contact_fault_speed"]:
            charge = _number("contact_fault_speed", value["contact_fault_speed"], float, 0.0)
            world.parameters["sim.contact_fault_speed"] = charge  # the world decides who ran into whom
            adapter.parameters["oracle.contact_fault_speed"] = charge  # ... and the reference, alike
        nodes += stack
    base.nodes = nodes + ([] if part.startswith("stack") else [generator])
    base.workers = stacks if part == "all" else len(here)
    if part.startswith("stack"):
        base.notes.append(f"part:={part}: stack {part[5:]} alone, in /{part}, serving the generator of "
                          "part:=generator on another host (same ROS domain) until Ctrl-C")
    base.nav2_params = scaled
    if mode == "bringup":
        base.includes = [IncludeSpec("nav2_bringup", "launch/navigation_launch.py", {
            "params_file": str(scaled), "use_sim_time": "true", "autostart": "true", "use_composition": "False"})]
    if mode == "external":
        base.notes.append(f"nav2:=external: start Nav2 within {start_timeout:.0f} s, in this ROS domain: ros2 launch "
                          f"nav2_bringup navigation_launch.py use_sim_time:=true params_file:={scaled}")
    return base


# --- the end of a run ------------------------------------------------------------------------------
def log_summary(mcap: Path, run_id: str, recorder_log: str) -> dict[str, Any]:
    """``summarize()`` of the finished log and the profile it recorded, and a picture of each
    distinct certified failure in ``failures/`` beside it (``nodes.gallery``); a missing or damaged
    log is reported under ``log_error`` (with what to do), never raised."""
    from .nodes.execution import run_profile
    from .nodes.gallery import draw_failures
    from .ros.runlog import read_metadata, summarize

    if not Path(mcap).exists():
        return {"mcap": str(mcap), "log_error": f"no MCAP written (see {recorder_log})"}
    try:
        out = summarize(mcap, run_id)
        metadata = read_metadata(mcap)
        out["metadata"] = sorted(metadata)
        recorded = run_profile(metadata.get("ambiegen_run", {}).get("config_json", ""))
        if recorded:
            out["profile"] = recorded  # what the run used, as recorded
        if out.get("failures"):
            out.update(draw_failures(mcap, Path(mcap).parent / "failures"))
        return out
    except Exception as exc:  # a damaged log is reported, not hidden
        return {"mcap": str(mcap), "log_error": f"{type(exc).__name__}: {exc} (try: ambiegen recover {mcap})"}


def plan_summary(plan: CampaignPlan, elapsed: float, exit_codes: dict[str, int | None]) -> dict[str, Any]:
    """What ``ambiegen campaign`` reports, for a launched campaign."""
    summary: dict[str, Any] = {
        "run_id": plan.run_id, "problem": plan.problem, "algorithm": plan.algorithm, "mode": plan.mode,
        "seed": plan.seed, "workers": plan.workers, "elapsed_s": round(elapsed, 2), "exit_codes": exit_codes,
    }
    if exit_codes.get("recorder") == 2:  # refused its file or a parameter: the file there is not this run's
        summary.update(mcap=str(plan.mcap), log_error="the recorder did not start (exit status 2, see its error above)")
    else:
        summary.update(log_summary(plan.mcap, plan.run_id, "the recorder's output above"))
    return summary


def search_line(summary: dict[str, Any]) -> str:
    """How the search's evaluations became published scenarios, so 2000 evaluations next to 3
    scenarios is not read as lost work: in surrogate mode the search runs on the surrogate and
    only its final suite is published to the sims; in the loop the sims give every F1, but for the
    scenarios the problem calls invalid (not sent: F1 0, as the search's constraint says)."""
    evaluations, published = summary["evaluations"], summary.get("scenarios_published", 0)
    plural = "s" * (published != 1)
    not_sent = summary.get("not_sent", 0)
    unsent = f", {not_sent} not sent (invalid)" if not_sent else ""
    if summary.get("mode", "surrogate") == "surrogate":
        return f"{evaluations} evaluations -> suite of {published} scenario{plural} published{unsent}"
    return (f"{evaluations} evaluations -> {published} scenario{plural} published (in the loop: the sims give every "
            f"F1){unsent}")


def summary_table(summary: dict[str, Any]) -> str:
    """The campaign summary for people: scenarios, results, failures by kind, timeouts, errors,
    MCAP path, wall time (``ambiegen campaign --json`` prints the dict itself)."""
    rows: list[tuple[str, str]] = []
    workers = summary.get("workers")
    run = f"{summary.get('problem')} / {summary.get('algorithm')}, seed {summary.get('seed')}"
    run += f", {summary.get('mode', 'surrogate')} mode" + (f", {workers} worker{'s' * (workers != 1)}" if workers is not None else "")
    rows.append(("run", run))
    if "scenarios_published" in summary:
        unresolved = summary.get("unresolved") or []
        rows.append(("scenarios", f"{summary['scenarios_published']} published, {summary['results_received']} results, "
                                  f"{len(unresolved)} unresolved" + (f" (ids {unresolved[:10]})" if unresolved else "")))
        if summary.get("not_sent"):
            rules = ", ".join(f"{rule} {n}" for rule, n in list(summary.get("not_sent_rules", {}).items())[:3])
            rows.append(("not sent", f"{summary['not_sent']}  (the problem calls them invalid, never executed; "
                                     f"logged with the rule they break: {rules})"))
        kinds = {k: v for k, v in summary.get("outcomes", {}).items() if k != "none"}
        by_kind = ", ".join(f"{k} {v}" for k, v in sorted(kinds.items(), key=lambda kv: (-kv[1], kv[0])))
        rows.append(("failures", f"{summary['failures']}" + (f"  (outcomes: {by_kind})" if by_kind else "")))
        if summary.get("failures"):
            pictures = summary.get("failure_pictures") or []
            known = summary.get("known_failures") or 0
            rows.append(("distinct", f"{summary.get('distinct_failures', '?')} distinct failures (by what failed and "
                                     f"where), {len(pictures)} drawn" + (f"; {known} known failures (not counted)"
                                                                        if known else "")))
            for picture in pictures[:3]:
                rows.append(("picture", f"{picture['path']}  ({picture['signature']})"))
            if len(pictures) > 3:
                rows.append(("pictures", f"{len(pictures) - 3} more in {Path(pictures[0]['path']).parent}"))
            if summary.get("same_failure_pair"):
                rows.append(("same failure", f"{summary['same_failure_pair']['path']}  (two failures counted as one)"))
        if summary.get("near_misses"):
            rows.append(("near misses", f"{summary['near_misses']}  (passes that needed Nav2's recoveries: "
                                        "nav2_recoveries in their metrics)"))
        if summary.get("invalid_tests"):
            rows.append(("invalid tests", f"{summary['invalid_tests']}  (no reference passes them either: "
                                          "not failures of the system under test)"))
        rows.append(("timeouts", str(summary["timeouts"])))
        rows.append(("errors", f"{summary['errors']}, invalid scenarios {summary.get('invalid', 0)}"))
        if "evaluations" in summary:
            rows.append(("search", f"{search_line(summary)}, best F1 {summary['best_f1']:.4g}, "
                                   f"state {summary.get('final_state')}"))
    if "log_error" in summary:
        rows.append(("log error", summary["log_error"]))
    rows.append(("MCAP", str(summary.get("mcap", "-"))))
    if "suite" in summary:
        rows.append(("suite", str(summary["suite"])))
    rows.append(("wall time", f"{summary.get('elapsed_s', 0.0):.1f} s"))
    codes = summary.get("exit_codes") or {}
    if codes:
        rows.append(("exit codes", ", ".join(f"{name} {code}" for name, code in codes.items())))
    if summary.get("interrupted"):
        rows.append(("interrupted", f"yes ({summary.get('stopped_by') or 'Ctrl-C'})"))
    width = max(len(label) for label, _ in rows)
    return "\n".join([f"campaign {summary.get('run_id')}"] + [f"  {label:<{width}}  {text}" for label, text in rows])
