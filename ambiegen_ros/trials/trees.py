"""A behaviour tree derived from one Nav2 ships: the change a fix makes, written as a change.

A fix's params may hold ``ambiegen_behavior_tree`` (not a node's section: taken out before the
params are written)::

    ambiegen_behavior_tree:
      from: navigate_to_pose_w_replanning_and_recovery.xml   # nav2_bt_navigator's, as installed
      remove: [BackUp]                                        # every node of these types
      set: {NavigateRecovery.number_of_retries: 1000}         # NAME_OR_TYPE.attribute: value
      wrap: {Timeout: {msec: 180000}}                         # the tree's root inside this node

``from`` is a tree of the installed ``nav2_bt_navigator`` (found through ``AMENT_PREFIX_PATH``) or
a path, relative to the fix's folder. So the tree a fix runs is the user's own Nav2's, changed
only where the fix says, and it becomes ``bt_navigator``'s ``default_nav_to_pose_bt_xml``.
"""
from __future__ import annotations

import hashlib
import json
import os
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

from ..core.errors import BadInput

KEY = "ambiegen_behavior_tree"
SHIPPED = ("nav2_bt_navigator", "behavior_trees")


def shipped_tree(name: str) -> Path | None:
    """A tree of the installed nav2_bt_navigator (``<prefix>/share/nav2_bt_navigator/behavior_trees``)."""
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            path = Path(prefix, "share", *SHIPPED, name)
            if path.is_file():
                return path
    return None


def _source(spec: dict, folder: Path) -> Path:
    name = str(spec.get("from") or "")
    if not name:
        raise BadInput(f"{KEY}: 'from' names the tree to start from")
    local = folder / name
    if local.is_file():
        return local
    found = shipped_tree(name)
    if found is None:
        raise BadInput(f"{KEY}: no tree {name!r} beside the fix nor in an installed nav2_bt_navigator "
                       "(source your ROS 2 setup, or give a path)")
    return found


def _check(spec: Any) -> dict:
    if not isinstance(spec, dict) or set(spec) - {"from", "remove", "set", "wrap"}:
        raise BadInput(f"{KEY}: a mapping of from / remove / set / wrap")
    return spec


def derive(specs: list[tuple[Any, Path]]) -> tuple[str, str]:
    """(the derived tree's XML text, the source it came from) for the specs of a configuration's
    files, applied in order to the first one's ``from`` (a later ``from`` must name the same tree)."""
    specs = [(_check(spec), folder) for spec, folder in specs]
    first, folder = specs[0]
    source = _source(first, folder)
    for spec, where in specs[1:]:
        if spec.get("from") and _source(spec, where) != source:
            raise BadInput(f"{KEY}: two fixes start from different trees ({source.name}, {spec['from']}): "
                           "one tree per configuration")
    try:
        root = ET.parse(source).getroot()
    except ET.ParseError as exc:
        raise BadInput(f"{source}: not a behaviour tree ({exc})")
    for spec, _ in specs:
        _apply(root, spec, source.name)
    ET.indent(root)
    said = json.dumps([spec for spec, _ in specs], sort_keys=True)
    return f"<!-- derived by AmbieGen from {source} : {said} -->\n" + ET.tostring(root, encoding="unicode") + "\n", \
        str(source)


def _apply(root: ET.Element, spec: dict, name: str) -> None:
    for kind in spec.get("remove") or []:
        removed = 0
        for parent in list(root.iter()):
            for child in [c for c in parent if c.tag == kind]:
                parent.remove(child)
                removed += 1
        if not removed:
            raise BadInput(f"{KEY}: remove: no {kind} node in {name}")
    for target, value in (spec.get("set") or {}).items():
        who, _, attribute = str(target).rpartition(".")
        hits = [e for e in root.iter() if who in (e.get("name"), e.tag)]
        if not who or not attribute or not hits:
            raise BadInput(f"{KEY}: set: no node named or of type {who!r} in {name}")
        for element in hits:
            element.set(attribute, str(value))
    for kind, attributes in (spec.get("wrap") or {}).items():
        for tree in root.iter("BehaviorTree"):
            inner = list(tree)
            wrapper = ET.Element(kind, {k: str(v) for k, v in (attributes or {}).items()})
            for child in inner:
                tree.remove(child)
                wrapper.append(child)
            tree.append(wrapper)


def with_tree(params: dict, specs: list[tuple[Any, Path]], out_dir: Path, label: str) -> tuple[dict, str | None]:
    """``params`` without the fix key, and with the tree the specs derive (written once per content in
    ``out_dir``) as bt_navigator's ``default_nav_to_pose_bt_xml``; the tree's path, or None."""
    params = {k: v for k, v in params.items() if k != KEY}
    if not specs:
        return params, None
    text, _ = derive(specs)
    digest = hashlib.sha1(text.encode()).hexdigest()[:12]
    path = Path(out_dir) / f"{label}.{digest}.tree.xml"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    bt = dict((params.get("bt_navigator") or {}).get("ros__parameters") or {})
    bt["default_nav_to_pose_bt_xml"] = str(path)
    params["bt_navigator"] = {**(params.get("bt_navigator") or {}), "ros__parameters": bt}
    return params, str(path)


__all__ = ["KEY", "derive", "shipped_tree", "with_tree"]
