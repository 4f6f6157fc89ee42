"""`ambiegen nav2-params`: your Nav2 params file made ready for AmbieGen's world.

The first of the two commands of a "bring your own Nav2" campaign (docs/external_sut.md): it
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
        out = write_params(params, args.output, f"{first}" + (f" + {overlay}" if overlay else "")
                           + "".join(f" + {fix}" for fix in fixes)
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
    print(f"start Nav2: ros2 launch nav2_bringup navigation_launch.py use_sim_time:=true params_file:={out}")
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
    p.set_defaults(func=cmd_nav2_params)
