"""`ambiegen nav2-params` and `ambiegen robot-profile`: your Nav2 params and your robot, made ready
for AmbieGen's world.

``robot-profile --from-params`` derives a first robot profile (issue 69) from the params (and a
URDF); ``nav2-params --robot`` writes a profile's robot into the params. The first of the two commands of a "bring your own Nav2" campaign (docs/external_sut.md): it
writes the file that ``ros2 launch nav2_bringup navigation_launch.py params_file:=...`` takes.
The work is ``ambiegen_ros.nav2_params``; this module only reads flags and says what it did.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from ..core.errors import BadInput


def cmd_nav2_params(args: argparse.Namespace) -> int:
    from ..nav2_params import OVERLAY_FILE, merged_params, package_file, top_speed, write_params

    if not args.time_scale > 0:
        raise BadInput("--time-scale: must be > 0")
    overlay = None if args.overlay == "none" else args.overlay or package_file(*OVERLAY_FILE)
    if args.overlay == "" and overlay is None:
        raise BadInput(f"the package's overlay {'/'.join(OVERLAY_FILE)} is not installed here: name one with --overlay")
    first, *fixes = args.params.split("+")
    tree = None
    profile, notes = _robot(args.robot), []
    try:
        if fixes:  # the merge and the tree of `ambiegen compare --params`, so both run the same stack
            from ..trials.configs import StackConfig, merged
            from ..trials.trees import with_tree

            if Path(args.output).exists() and not args.overwrite:
                raise FileExistsError(f"{args.output} exists (not overwritten)")
            params, trees = merged(StackConfig("nav2-params", (first, *fixes)), "bringup", overlay, args.time_scale)
            if trees:
                params, tree = with_tree(params, trees, Path(args.output).parent, Path(args.output).stem)
        else:
            params = merged_params(first, overlay, args.time_scale)
        if profile is not None:  # checked on the merged params: a fix may set the controller (a car's set-up)
            from ..nav2_params import with_robot

            notes = _check_controller(args.robot, profile, params)
            params = with_robot(params, profile)
        out = write_params(params, args.output, f"{first}" + (f" + {overlay}" if overlay else "")
                           + "".join(f" + {fix}" for fix in fixes)
                           + (f" + robot {profile.name} ({profile.source})" if profile is not None else "")
                           + f", Nav2's loop rates x {args.time_scale:g} (time_scale)\n"
                           "written by `ambiegen nav2-params`", overwrite=args.overwrite)
    except (ValueError, FileExistsError) as exc:
        raise BadInput(f"{exc}{' (--overwrite replaces it)' if isinstance(exc, FileExistsError) else ''}") from None
    speed = top_speed(params)
    print(out)
    if tree:
        print(f"behaviour tree: {tree} (bt_navigator's default_nav_to_pose_bt_xml)")
    server = (params.get("controller_server") or {}).get("ros__parameters") or {}
    plugins = [str((server.get(name) or {}).get("plugin", "?")) for name in server.get("controller_plugins") or []]
    print(f"controller{'s' * (len(plugins) != 1)}: {', '.join(plugins) or 'none named'}; top speed "
          + (f"{speed:g} m/s (the time limit divides routes by it)" if speed else "not found (the time limit uses 0.3 m/s)"))
    if profile is not None:
        print(f"{robot_summary(profile)}; give robot_world and sut_adapter robot_profile:={args.robot} (the Nav2 "
              f"campaign launch: robot_profile:={args.robot})")
    for note in notes:
        print(f"note: {note}")
    print(f"start Nav2: ros2 launch nav2_bringup navigation_launch.py use_sim_time:=true params_file:={out}")
    return 0


def _robot(name: str):
    """The ``--robot`` profile (None: the overlay's Pioneer); a bad one is one line naming the field."""
    if not name:
        return None
    from ..sims.robot_profile import ProfileError, load_profile

    try:
        return load_profile(name)
    except ProfileError as exc:
        raise BadInput(f"--robot {name}: {exc}") from None


def _check_controller(name: str, profile, params: dict) -> list[str]:
    """``check_controller`` on the params as merged, its refusal one line naming the field."""
    from ..sims.robot_profile import ProfileError, check_controller

    try:
        return check_controller(profile, params)
    except ProfileError as exc:
        raise BadInput(f"--robot {name}: {exc}") from None


def cmd_robot_profile(args: argparse.Namespace) -> int:
    from ..nav2_params import load_yaml
    from ..sims.robot_profile import ProfileError
    from ..sims.robot_profile_derive import derive

    try:
        params = load_yaml(args.from_params, "--from-params")
        urdf = Path(args.urdf).read_text() if args.urdf else None
        profile, data, missing = derive(params, urdf, args.name or Path(args.output).stem)
    except OSError as exc:
        raise BadInput(f"--urdf: cannot read {args.urdf}: {exc.strerror}") from None
    except ProfileError as exc:
        raise BadInput(f"the derived profile: {exc} (edit the params or the URDF)") from None
    except ValueError as exc:  # an unreadable YAML file or a URDF that is no XML
        raise BadInput(str(exc).splitlines()[0]) from None
    out = Path(args.output)
    if out.exists() and not args.overwrite:
        raise BadInput(f"{out} exists (not overwritten; --overwrite replaces it)")
    import yaml

    header = [f"A first robot profile, derived by `ambiegen robot-profile` from {args.from_params}"
              + (f" and {args.urdf}" if args.urdf else "") + ".", "Not found there (check these):"]
    header += [f"  {line}" for line in missing] or ["  nothing"]
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("".join(f"# {line}\n" for line in header) + yaml.safe_dump(data, sort_keys=False))
    print(out)
    print(robot_summary(profile))
    for line in missing:
        print(f"not found: {line}")
    print(f"next: ambiegen nav2-params {args.from_params} --robot {out} -o merged.yaml")
    return 0


def register(sub) -> None:
    p = sub.add_parser("nav2-params", help="your Nav2 params + AmbieGen's overlay (frames, footprint, laser, base "
                                           "limits), loop rates x time scale: the params_file for your Nav2 bringup")
    p.add_argument("params", metavar="PARAMS.yaml[+FIX...]",
                   help="your Nav2 params (e.g. Jazzy's nav2_bringup/params/nav2_params.yaml), then any fixes merged "
                        "after the overlay, as `ambiegen compare --params` takes them: +FILE.yaml or +fix:NAME (the "
                        "package's config/nav2/fixes; fix:hardened = the stack Nav2's engineers would ship for our "
                        "robot); a fix that changes the behaviour tree writes the derived tree beside OUT.yaml")
    p.add_argument("-o", "--output", required=True, metavar="OUT.yaml", help="the file to write (never overwritten "
                                                                             "without --overwrite)")
    p.add_argument("--overlay", default="", metavar="FILE.yaml|none",
                   help="merged onto PARAMS (default: the package's config/nav2/ambiegen_overlay.yaml; none: no overlay)")
    p.add_argument("--time-scale", type=float, default=1.0,
                   help="the campaign's time_scale: Nav2's wall-clock loop rates are multiplied by it (default 1)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing OUT.yaml")
    p.add_argument("--robot", default="", metavar="NAME|PROFILE.yaml",
                   help="the robot: a shipped profile (pioneer2dx, turtlebot4, turtlebot3_burger, omni_base, "
                        "ackermann_car) or your own (ambiegen robot-profile); its footprint, laser and limits replace "
                        "the Pioneer's, and a controller that cannot drive it is refused (default: the overlay's Pioneer)")
    p.set_defaults(func=cmd_nav2_params)

    p = sub.add_parser("robot-profile", help="a first robot profile from your Nav2 params (footprint, drive, limits) "
                                             "and URDF (laser pose), saying what it could not find")
    p.add_argument("--from-params", required=True, metavar="PARAMS.yaml", help="your Nav2 params")
    p.add_argument("--urdf", default="", metavar="ROBOT.urdf", help="your robot's URDF (expanded, not xacro): the "
                                                                   "laser's mount pose and its Gazebo sensor")
    p.add_argument("--name", default="", help="the profile's name (default: OUT's file name)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.yaml", help="the profile to write (never "
                                                                             "overwritten without --overwrite)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing OUT.yaml")
    p.set_defaults(func=cmd_robot_profile)


def robot_summary(profile) -> str:
    """One line of what a robot profile says: its drive, body, top speed and first laser."""
    body = f"robot_radius {profile.radius:g} m" if profile.round else f"footprint {profile.nav2_footprint()}"
    laser = profile.lasers[0]
    return (f"robot {profile.name}: {profile.drive}, {body}, {profile.max_speed[0]:g} m/s, laser {laser.frame} at "
            f"({laser.x:g}, {laser.y:g})")
