"""Limits on what a node accepts from the graph, and the counters that show what it refused.

Every subscription of every node receives through ``InputGuard`` (built by the transport seam):
a sample larger than the node's ``max_message_bytes`` parameter, one that does not decode, or one
whose handler raises is dropped, counted and logged, and the node keeps serving. Semantic checks
that name the offending field (scenario JSON depth, non-finite numbers, identifiers that end up in
file names) live next to the conversions that read the fields (``conversions.py``) and use the
helpers here.
"""
from __future__ import annotations

import inspect
import re
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

MAX_MESSAGE_BYTES_PARAM = "max_message_bytes"
DEFAULT_MAX_MESSAGE_BYTES = 4 * 1024 * 1024  # a 2000 x 2000 OccupancyGrid fits; 100 MB does not
MAX_JSON_DEPTH = 32  # a scenario is {"elements": [{...}]}: depth 3; metadata may nest a little
MAX_NAME_LENGTH = 128
LOGGED_DROPS = 10  # the first drops are logged one by one, then one line per LOG_EVERY
LOG_EVERY = 1000

_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.+@=-]*$")
NAME_RULE = (f"1..{MAX_NAME_LENGTH} characters from letters, digits and _ . + @ = -, not starting with "
             "'.', without '..', '/', '\\\\', spaces or control characters")


class UnsafeName(ValueError):
    """An identifier that would be unsafe in a file name (path traversal, control characters)."""


def check_name(value: Any, field: str, allow_empty: bool = False) -> str:
    """``value`` if it is a safe identifier (run id, worker id) else ``UnsafeName`` naming ``field``.

    Run and worker ids travel in messages and end up in file names (run directories, logs,
    reports), so anything that could climb out of a directory or hide in a terminal is refused.
    """
    if not isinstance(value, str):
        raise UnsafeName(f"{field}: must be a string, got {type(value).__name__}")
    if value == "" and allow_empty:
        return value
    if len(value) > MAX_NAME_LENGTH or not _NAME.match(value) or ".." in value:
        raise UnsafeName(f"{field}: unsafe name {value[:MAX_NAME_LENGTH]!r} (allowed: {NAME_RULE})")
    return value


_JSON_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.DOTALL)
_NOT_BRACKET = re.compile(r"[^\[\]{}]+")


def json_depth(text: str) -> int:
    """Deepest nesting of ``[``/``{`` in JSON text, without parsing it (linear, no recursion).

    Python's ``json`` recurses once per level, so a deep enough text raises ``RecursionError``
    (or worse) before any field can be named; this is checked first.
    """
    brackets = _NOT_BRACKET.sub("", _JSON_STRING.sub("", text))
    if not brackets:
        return 0
    steps = np.frombuffer(brackets.encode("ascii"), dtype=np.uint8)
    opens = (steps == ord("[")) | (steps == ord("{"))
    return int(np.cumsum(np.where(opens, 1, -1)).max(initial=0))


@dataclass
class InputStats:
    """What a node's subscriptions received and what they dropped, by reason."""

    taken: int = 0
    oversize: int = 0
    malformed: int = 0
    handler_errors: int = 0
    by_topic: dict[str, int] = field(default_factory=dict)  # dropped samples per topic

    @property
    def dropped(self) -> int:
        return self.oversize + self.malformed + self.handler_errors

    def as_dict(self) -> dict[str, int]:
        return {"taken": self.taken, "dropped": self.dropped, "oversize": self.oversize,
                "malformed": self.malformed, "handler_errors": self.handler_errors}

    def summary(self) -> str:
        return (f"input: {self.taken} samples taken, {self.dropped} dropped (oversize {self.oversize}, "
                f"malformed {self.malformed}, handler errors {self.handler_errors})")


class InputGuard:
    """The one place received samples pass: size limit, decoding, handler; failures are counted.

    ``wrap`` returns ``deliver(data, receive_ns)`` for a backend to call with each sample's
    serialised bytes. Nothing from a sample is evaluated: it is decoded by the type's codec and
    handed to the node's handler, whose exceptions are logged (with the topic), not propagated,
    so one hostile sample cannot stop the node.
    """

    def __init__(self, logger: Any, max_bytes: int):
        if int(max_bytes) <= 0:
            raise ValueError(f"{MAX_MESSAGE_BYTES_PARAM}: must be > 0, got {max_bytes}")
        self.logger = logger
        self.max_bytes = int(max_bytes)
        self.stats = InputStats()
        self._last_log = 0.0

    def _drop(self, topic: str, reason: str, what: str) -> None:
        s = self.stats
        setattr(s, reason, getattr(s, reason) + 1)
        s.by_topic[topic] = s.by_topic.get(topic, 0) + 1
        n = s.dropped
        if n <= LOGGED_DROPS or n % LOG_EVERY == 0:
            self.logger.warning(f"dropped a sample on {topic}: {what} ({s.summary()})")

    def wrap(self, topic: str, callback: Callable, raw: bool,
             decode: Callable[[bytes], Any]) -> Callable[..., None]:
        timed = raw and takes_source_time(callback)

        def deliver(data, receive_ns: int | None = None, source_ns: int | None = None) -> None:
            self.stats.taken += 1
            size = len(data)
            if size > self.max_bytes:
                self._drop(topic, "oversize", f"{size} bytes > {MAX_MESSAGE_BYTES_PARAM} {self.max_bytes}")
                return
            if raw:
                args = (data, time.time_ns() if receive_ns is None else receive_ns)
                if timed:  # the writer's clock when it sent the sample (the receive time when unknown)
                    args += (args[1] if not source_ns else source_ns,)
            else:
                try:
                    args = (decode(data),)
                except Exception as exc:  # truncated CDR, bad header, lengths past the end, ...
                    self._drop(topic, "malformed", f"cannot decode {size} bytes: {type(exc).__name__}: {exc}")
                    return
            try:
                callback(*args)
            except (KeyboardInterrupt, SystemExit):
                raise
            except Exception as exc:  # MemoryError and RecursionError included: the node keeps serving
                self._drop(topic, "handler_errors", f"handler raised {type(exc).__name__}: {str(exc)[:300]}")

        return deliver


def takes_source_time(callback: Callable) -> bool:
    """A raw callback whose third positional argument has no default gets the sample's source
    timestamp there (rclpy's rule: a callback that takes the message info gets it; a default, as in
    ``lambda d, t, name=name: ...``, is the caller's own)."""
    try:
        params = inspect.signature(callback).parameters.values()
    except (TypeError, ValueError):  # no signature to read (a builtin): as before
        return False
    positional = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    required = [p for p in params if p.kind in positional and p.default is inspect.Parameter.empty]
    return len(required) >= 3
