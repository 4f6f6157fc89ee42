"""ROS nodes: thin wrappers over the core (each module has main())."""
from __future__ import annotations

import sys
from typing import Any, Callable


def run_node(label: str, make: Callable[[], Any], finish: Callable[[Any], int | None] | None = None) -> int:
    """The shared ``main()`` of every node: build it, spin until SIGINT/SIGTERM or done, clean up.

    ``make`` returns an object with a ``node``; a bad parameter or config exits with status 2 and
    one line. ``finish`` runs before the node shuts down (close files, stop threads) and may
    return the exit code.
    """
    from ..core.attributes import ScenarioError
    from ..core.config import ConfigError
    from ..ros.transport import TransportError

    try:
        obj = make()
    except (ConfigError, ScenarioError, ValueError, TransportError, OSError) as exc:
        print(f"{label}: error: {exc}", file=sys.stderr)
        return 2
    code: int | None = 0
    try:
        obj.node.spin()
    finally:
        if finish is not None:
            code = finish(obj)
        obj.node.shutdown()
    return code or 0
