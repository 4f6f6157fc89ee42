"""A configuration of the stack under test: params files merged in order, with a label.

``LABEL=FILE[+FILE...]`` names one. The first file is the stack's params (Nav2: yours, or Jazzy's
``nav2_params.yaml``); each further file is merged onto it key by key (``nav2_params.merge_overlay``:
mappings merge, anything else is replaced, ``*`` keys are patterns), so a fix is a small overlay:
``jazzy=nav2_params.yaml`` against ``people=nav2_params.yaml+fix:people_approach``. ``fix:NAME``
is the package's ``config/nav2/fixes/NAME.yaml``. On a Nav2 stack our world's overlay
(``config/nav2/ambiegen_overlay.yaml``: frames, footprint, laser, base limits) goes on the first
file before the fixes, so a fix has the last word, and every file's loop rates are scaled to the
time scale.

One file serves every node of the stack: each node reads its own section. So a fix may also change
the world (``robot_world: {ros__parameters: {sim: {fov_deg: 360.0, beams: 361}}}``: the robot whose
laser sees all round) or, on our ND stack, the driver (``nd_driver: ...``). A relative path to a
behaviour tree (a string ending in ``.xml``) is taken from the file's own folder, so a fix and its
tree travel together; a fix that changes Nav2's own tree says how (``trees``), and the tree is
derived from the installed one. A fix may be made of fixes (``ambiegen_fixes: [NAME, ...]``,
merged in order before its own keys): ``fix:hardened`` is the stack Nav2's engineers would ship
for our robot, the fixes that worked and nothing else.

The merged file is written once per content (``<label>.<digest>.params.yaml``) and its digest is
recorded in every row: a label run with other params is refused, never mixed.
"""
from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core.errors import BadInput

FIX_PREFIX = "fix:"
FIXES_KEY = "ambiegen_fixes"  # a fix made of the package's fixes, by name
FIXES_DIR = ("config", "nav2", "fixes")  # under the package's share dir (or the repo)
LABEL = re.compile(r"[A-Za-z0-9_.+-]{1,60}")
NAV2_STACKS = ("bringup", "ours", "external", "planner")  # planner: planner_server alone (launch_logic.planner_stack)
STACKS = ("nd",) + NAV2_STACKS
BT_KEYS = ("default_nav_to_pose_bt_xml", "default_nav_through_poses_bt_xml")


@dataclass(frozen=True)
class StackConfig:
    label: str
    files: tuple[str, ...]  # as given (resolved to paths by ``prepare``)


@dataclass
class Prepared:
    """A configuration made ready to run: its merged params, written, and what every row records."""

    config: StackConfig
    params: dict
    path: Path | None  # the written params file (None: no params, our ND stack's defaults)
    digest: str
    world: dict  # robot_world's sim.* options from the params (e.g. fov_deg)
    behavior_tree: str | None
    speed: float | None  # the controller's top speed (Nav2), for the time limit

    def record(self) -> dict[str, Any]:
        return {"label": self.config.label, "config_files": list(self.config.files), "config_digest": self.digest,
                "params_file": str(self.path) if self.path else None, "world": self.world,
                "behavior_tree": self.behavior_tree}


def fixes_dir() -> Path | None:
    from ..nav2_params import package_file

    return package_file(*FIXES_DIR, folder=True)


def parse_config(spec: str) -> StackConfig:
    """``[LABEL=]FILE[+FILE...]``; without a label, the files' stems joined by '+' (one word per fix)."""
    label, _, files = spec.rpartition("=") if "=" in spec else ("", "", spec)
    parts = tuple(f.strip() for f in files.split("+")) if files.strip() else ()
    if any(not p for p in parts):
        raise BadInput(f"--params {spec!r}: an empty file name between '+'")
    if not label:
        label = "+".join(Path(p[len(FIX_PREFIX):] if p.startswith(FIX_PREFIX) else p).stem for p in parts) or "default"
    if not LABEL.fullmatch(label):
        raise BadInput(f"--params {spec!r}: label {label!r} must be 1-60 letters, digits and _ . + -")
    return StackConfig(label, parts)


def resolve(name: str) -> Path:
    """A config file: a path, or ``fix:NAME`` (the package's fixes)."""
    if name.startswith(FIX_PREFIX):
        folder = fixes_dir()
        path = folder / f"{name[len(FIX_PREFIX):]}.yaml" if folder else None
        if path is None or not path.is_file():
            known = sorted(p.stem for p in folder.glob("*.yaml")) if folder else []
            raise BadInput(f"{name}: no such fix (the package's fixes: {', '.join(known) or 'none installed'})")
        return path
    path = Path(name).expanduser()
    if not path.is_file():
        raise BadInput(f"{name}: no such params file")
    return path.resolve()


def _with_trees(tree: Any, folder: Path) -> Any:
    """``tree`` with relative paths to existing ``.xml`` files made absolute (from ``folder``)."""
    if isinstance(tree, dict):
        return {k: _with_trees(v, folder) for k, v in tree.items()}
    if isinstance(tree, list):
        return [_with_trees(v, folder) for v in tree]
    if isinstance(tree, str) and tree.endswith(".xml") and not Path(tree).is_absolute() and (folder / tree).is_file():
        return str((folder / tree).resolve())
    return tree


def _layers(path: Path, within: tuple[Path, ...] = ()) -> list[tuple[dict, Path]]:
    """A further file's layers, in merge order: the fixes it is made of (``FIXES_KEY``), each expanded,
    then its own keys; with the folder each came from."""
    from ..nav2_params import load_yaml

    layer = load_yaml(path, "params file")
    names = layer.pop(FIXES_KEY, None) or []
    if not isinstance(names, list) or not all(isinstance(n, str) and n for n in names):
        raise BadInput(f"{path}: {FIXES_KEY} is a list of the package's fix names")
    out: list[tuple[dict, Path]] = []
    for name in names:
        part = resolve(name if name.startswith(FIX_PREFIX) else FIX_PREFIX + name)
        if part == path or part in within:
            raise BadInput(f"{path}: {FIXES_KEY} names {name}, which contains it")
        out += _layers(part, within + (path,))
    return out + ([(layer, path.parent)] if layer else [])


def _flat(tree: dict, prefix: str = "") -> dict:
    out: dict = {}
    for key, value in tree.items():
        if isinstance(value, dict):
            out.update(_flat(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def merged(config: StackConfig, stack: str, overlay: str | None, time_scale: float) -> tuple[dict, list]:
    """The configuration's params tree (see the module docstring for the order), and the behaviour-tree
    changes its files ask for (``trees.KEY``: (spec, the file's folder), in order)."""
    from ..nav2_params import merge_overlay, merged_params, scale_nav2_rates
    from .trees import KEY

    paths = [resolve(f) for f in config.files]
    trees: list = []

    def take(layer: dict, folder: Path) -> dict:
        if KEY in layer:
            trees.append((layer[KEY], folder))
        return _with_trees({k: v for k, v in layer.items() if k != KEY}, folder)

    try:
        if not paths:
            return {}, trees
        if stack in NAV2_STACKS:
            params = take(merged_params(paths[0], overlay, time_scale), paths[0].parent)
            rest = paths[1:]
        else:
            params, rest = {}, paths
        for path in rest:
            for own, folder in _layers(path):
                layer = take(own, folder)
                params = merge_overlay(params, scale_nav2_rates(layer, time_scale) if stack in NAV2_STACKS else layer)
        return params, trees
    except ValueError as exc:
        raise BadInput(str(exc)) from None


def with_stack_robot(config: StackConfig, stack: str, params: dict, robot: str) -> dict:
    """The params with the robot's body and limits (``launch_logic.campaign_robot``, as the Nav2
    campaign launch does), once the params' controller is known to drive it; our ND driver turns
    in place, so no car. A refusal is one line naming the configuration and the field."""
    from ..launch_logic import campaign_robot, node_robot

    try:
        if stack in NAV2_STACKS:
            return campaign_robot(robot, params)[1]
        profile = node_robot(robot)[1]
    except ValueError as exc:
        raise BadInput(f"--params {config.label} with --robot {robot}: {exc}") from None
    if stack == "nd" and profile.drive == "ackermann":
        raise BadInput(f"--params {config.label} with --robot {robot}: drive.kind: our ND driver turns in place: it "
                       f"cannot drive the Ackermann robot {profile.name} (a Nav2 stack with a car-like controller can)")
    return params


def prepare(config: StackConfig, stack: str, overlay: str | None, time_scale: float, out_dir: Path,
            robot: str = "") -> Prepared:
    """Merge, write (once per content, never over another file) and describe one configuration;
    ``robot`` (a profile, '' = the Pioneer) is in its params and its digest."""
    from ..nav2_params import top_speed, write_params

    if stack in NAV2_STACKS and not config.files:
        raise BadInput(f"--params {config.label}: a Nav2 stack needs a params file (e.g. Jazzy's "
                       "nav2_bringup/params/nav2_params.yaml)")
    params, trees = merged(config, stack, overlay, time_scale)
    if trees:
        from .trees import with_tree

        params, _ = with_tree(params, trees, out_dir, config.label)
    if robot:
        params = with_stack_robot(config, stack, params, robot)
    content = [params, robot] if robot else params  # a label run on another robot is refused, never mixed
    digest = hashlib.sha1(json.dumps(content, sort_keys=True, default=str).encode()).hexdigest()[:12]
    path = None
    if params:
        path = Path(out_dir) / f"{config.label}.{digest}.params.yaml"
        if not path.exists():
            header = " + ".join(config.files) + (f" (+ {overlay} after the first)" if overlay and stack in NAV2_STACKS
                                                  else "") + f", loop rates x {time_scale:g}" + (
                f", robot {robot}" if robot else "")
            write_params(params, path, header)
    world = _flat(((params.get("robot_world") or {}).get("ros__parameters") or {}).get("sim") or {})
    bt = (params.get("bt_navigator") or {}).get("ros__parameters") or {}
    tree = next((str(bt[k]) for k in BT_KEYS[:1] if bt.get(k)), None)
    return Prepared(config, params, path, digest, world, tree, top_speed(params) if stack in NAV2_STACKS else None)


__all__ = ["FIXES_KEY", "FIX_PREFIX", "NAV2_STACKS", "STACKS", "Prepared", "StackConfig", "fixes_dir", "merged", "parse_config",
           "prepare", "resolve", "with_stack_robot"]
