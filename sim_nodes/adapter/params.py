"""The adapter's parameters as typed tables: one for the node, one per judge, one for the oracle.

Each entry says its name, type, default, the values it may take and its help; ``declare`` reads a
table through the node (``-p NAME:=VALUE`` or a params file) and checks each value against its
entry, so a bad value stops the node with one ``ConfigError`` line naming the parameter. The same
tables print the node's ``--help`` (``help_text``), so the help cannot drift from what is read.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Iterable

from ambiegen_ros.core.config import ConfigError


@dataclass(frozen=True)
class Param:
    """One parameter. ``default`` may be a function of the values read before it (``early_verdicts``
    follows ``goal_mode``); ``default_text`` then says so in the help. ``minimum`` with ``above``
    says "> minimum", without it ">= minimum". ``parse`` turns the raw value into what the node
    uses (a ``ValueError`` from it is a bad value, ``parse_text`` says what was expected)."""

    name: str
    type: type
    default: Any
    help: str = ""
    allowed: tuple = ()
    minimum: float | None = None
    above: bool = False
    parse: Callable[[Any], Any] | None = None
    parse_text: str = ""
    default_text: str = ""

    def check(self, value: Any) -> Any:
        """The value as the node uses it, or a ConfigError naming this parameter."""
        if self.allowed and value not in self.allowed:
            raise ConfigError(f"{self.name}: unknown {value!r} (allowed: {'|'.join(map(str, self.allowed))})")
        if self.minimum is not None:
            bad = not value > self.minimum if self.above else not value >= self.minimum
            if bad or (isinstance(value, float) and math.isnan(value)):
                raise ConfigError(f"{self.name}: must be {'>' if self.above else '>='} {self.minimum:g}")
        if self.parse is not None:
            try:
                return self.parse(value)
            except ValueError:
                raise ConfigError(f"{self.name}: {self.parse_text}, not {value!r}") from None
        return value


class Settings(dict):
    """Values read from the tables, by name (``settings.time_scale`` or ``settings["oracle.radius"]``)."""

    def __getattr__(self, name: str) -> Any:
        try:
            return self[name]
        except KeyError:
            raise AttributeError(name) from None


def declare(declare_parameter: Callable[..., Any], table: Iterable[Param], into: Settings | None = None) -> Settings:
    """Declare every parameter of ``table`` (``node.declare_parameter``) and check it; the values, added to ``into``."""
    values = Settings() if into is None else into
    for param in table:
        default = param.default(values) if callable(param.default) else param.default
        raw = declare_parameter(param.name, default, param.help)
        values[param.name] = param.check(param.type(raw))
    return values


def merged(*tables: Iterable[Param]) -> tuple[Param, ...]:
    """Several tables as one, each name once (the first entry wins: ``odom_topic`` of two judges)."""
    seen: dict[str, Param] = {}
    for table in tables:
        for param in table:
            seen.setdefault(param.name, param)
    return tuple(seen.values())


def help_text(sections: Iterable[tuple[str, Iterable[Param]]]) -> str:
    """The ``--help`` listing: per section, each parameter with its type, default, allowed values and help."""
    lines = []
    for title, table in sections:
        lines += ["", f"{title}:"]
        for param in table:
            default = param.default_text or repr(param.default)
            allowed = f", one of {' | '.join(map(str, param.allowed))}" if param.allowed else ""
            if param.minimum is not None:
                allowed += f", {'>' if param.above else '>='} {param.minimum:g}"
            lines.append(f"  {param.name} ({param.type.__name__}, default {default}{allowed})")
            if param.help:
                lines.append(f"      {param.help}")
    return "\n".join(lines)
