"""The shape of an argparse parser as plain data: every subcommand, option, default, choice and help.

Comparing shapes instead of ``--help`` text keeps the check independent of terminal width and of
the Python version's help formatting, while still catching a renamed, dropped or changed option.
"""
from __future__ import annotations

import argparse
from typing import Any


def _plain(value: Any) -> Any:
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if callable(value):
        return getattr(value, "__name__", repr(value))
    return repr(value)


def parser_shape(parser: argparse.ArgumentParser) -> dict[str, Any]:
    """``{prog, description, actions: [...], commands: {name: shape}}`` of a parser, recursively."""
    actions: list[dict[str, Any]] = []
    commands: dict[str, Any] = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {choice.dest: choice.help for choice in action._choices_actions}
            for name, sub in action.choices.items():
                shape = parser_shape(sub)
                shape["help"] = helps.get(name)
                commands[name] = shape
            continue
        actions.append({
            "options": list(action.option_strings), "dest": action.dest, "kind": type(action).__name__,
            "default": _plain(action.default) if action.default is not argparse.SUPPRESS else "==SUPPRESS==",
            "choices": _plain(list(action.choices)) if action.choices is not None else None,
            "type": _plain(action.type), "nargs": _plain(action.nargs), "required": action.required,
            "metavar": _plain(action.metavar), "help": action.help,
        })
    groups = [sorted(a.dest for a in g._group_actions) for g in parser._mutually_exclusive_groups]
    return {"prog": parser.prog, "description": parser.description, "actions": actions,
            "exclusive": sorted(groups), "commands": commands}
