"""A listener on ``/ambiegen/results`` that prints one line per result: ``<worker> <scenario id>``.

Tests start it beside a campaign (test/helpers/netns.py) to see progress as it happens, so that
faults fire on events (k results seen, every worker answered) instead of at wall-clock offsets.
It only subscribes: the campaign's nodes see one more result subscriber and nothing else.
"""
from __future__ import annotations

import sys


def main() -> int:
    from ambiegen_ros.ros import topics
    from ambiegen_ros.ros.qos import STREAM
    from ambiegen_ros.ros.transport import create_node

    node = create_node("result_probe", argv=["result_probe"])

    def on_result(msg) -> None:
        sys.stdout.write(f"{msg.worker} {int(msg.scenario_id)}\n")
        sys.stdout.flush()

    node.create_subscription(topics.RESULT_TYPE, topics.RESULTS, on_result, STREAM)
    try:
        while node.ok():
            node.spin_once(0.1)
    except KeyboardInterrupt:
        pass
    finally:
        node.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
