"""The recorder node end to end: messages/s it writes to MCAP over DDS, and how many are lost.

Starts ``ambiegen_ros.nodes.recorder`` as a subprocess recording an extra topic, floods it from
this process with N messages of ~1 KB (std_msgs/String, reliable, paced at a fixed offered rate
or as fast as the publisher can go), stops the recorder with SIGINT and counts the messages in the finished MCAP with the mcap
reader. Rate = recorded / (last - first log time in the file). Target (issue 3): >= 20,000/s for
1 KB with no loss.

Usage: python bench/recorder_node.py [--messages 50000] [--domain 81]
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_result  # noqa: E402

from mcap.reader import make_reader  # noqa: E402

from ambiegen_ros.ros.qos import STREAM  # noqa: E402
from ambiegen_ros.ros.transport import create_node  # noqa: E402

TOPIC = "/ambiegen/bench"
TYPE = "std_msgs/msg/String"


def run(messages: int, domain: int, payload: int, rate: float | None) -> dict:
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "bench.mcap"
        rec = subprocess.Popen(
            [sys.executable, "-m", "ambiegen_ros.nodes.recorder", "--ros-args", "-p", f"output:={out}",
             "-p", f"extra_topics:={TOPIC}={TYPE}", "-p", "discover:=false"],
            env=dict(os.environ), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        )
        node = create_node("recorder_bench", argv=[])
        pub = node.create_publisher(TYPE, TOPIC, STREAM)
        if not node.wait_for_subscribers(pub, 1, 30.0):
            raise SystemExit("the recorder never subscribed")
        time.sleep(0.5)
        msg = node.new_message(TYPE, data="x" * payload)
        start = time.perf_counter()
        for i in range(messages):
            pub.publish(msg)
            if rate and i % 100 == 99:  # pace: never ahead of the offered rate
                ahead = start + (i + 1) / rate - time.perf_counter()
                if ahead > 0:
                    time.sleep(ahead)
        publish_s = time.perf_counter() - start
        time.sleep(2.0)  # let the recorder drain its queue
        rec.send_signal(signal.SIGINT)
        rec.wait(timeout=30)
        node.shutdown()
        with open(out, "rb") as fh:
            times = [m.log_time for _, c, m in make_reader(fh).iter_messages(topics=[TOPIC])]
    span = (max(times) - min(times)) / 1e9 if len(times) > 1 else float("nan")
    return {
        "messages_sent": messages,
        "messages_recorded": len(times),
        "lost": messages - len(times),
        "payload_bytes": payload,
        "offered_msgs_per_s": rate or "unpaced",
        "publish_loop_msgs_per_s": round(messages / publish_s, 1),
        "recorded_msgs_per_s": round(len(times) / span, 1) if span == span and span > 0 else None,
        "recorder_exit": rec.returncode,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--messages", type=int, default=50_000)
    parser.add_argument("--domain", type=int, default=81)
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args()
    figures = {"how": __doc__.strip().splitlines()[0], "target_msgs_per_s_1KB": 20_000, "cases": []}
    for payload, rate in ((1000, 20_000), (1000, 30_000), (1000, None), (10_000, 5_000), (10_000, None)):
        n = args.messages if payload == 1000 else args.messages // 5
        case = run(n, args.domain, payload, rate)
        figures["cases"].append(case)
        print(case)
    lossless = [c["recorded_msgs_per_s"] for c in figures["cases"] if c["payload_bytes"] == 1000 and c["lost"] == 0]
    figures["best_lossless_msgs_per_s_1KB"] = max(lossless) if lossless else None
    if not args.no_write:
        print("wrote", write_result("recorder_node", figures))


if __name__ == "__main__":
    main()
