"""How fast is the transport seam between two processes? (DDS backend unless AMBIEGEN_TRANSPORT says)

An echo process subscribes and answers; this process measures, with ~1 KB std_msgs/String
messages (1009 bytes of CDR):

* ping-pong: publish, spin until the echo comes back, repeat -- round trips/s and p50/p99
  latency, for the raw path (bytes in, bytes out) and the typed path (decode + encode on both
  sides with the rosbags codec in ``types.py``);
* one-way flood: publish N messages back to back; the receiver counts them (its reader keeps all
  N, so nothing is dropped by history) and reports when the last arrived -- msgs/s from first
  send to last receipt, and how many were lost (must be 0), raw and typed; then the same with
  the STREAM profile (depth 1000 on both sides) to show whether a real burst loses messages.

    .venv/bin/python bench/transport_roundtrip.py [--n-pingpong 3000] [--n-flood 20000] [--domain 42]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from ambiegen_ros.ros import transport  # noqa: E402
from ambiegen_ros.ros.qos import STREAM, Qos  # noqa: E402

STRING = "std_msgs/msg/String"
PAYLOAD = "x" * 1000
PING = Qos(reliable=True, transient_local=False, depth=10)
CTL = Qos(reliable=True, transient_local=False, depth=100)


def echo(n_flood: int) -> int:
    """The far side: echo pings, count floods, answer control requests on /bench/stats."""
    node = transport.create_node("bench_echo")
    flood_q = Qos(reliable=True, depth=max(10, n_flood))
    pong_raw = node.create_publisher(STRING, "/bench/pong_raw", PING)
    pong_typed = node.create_publisher(STRING, "/bench/pong_typed", PING)
    stats = node.create_publisher(STRING, "/bench/stats", CTL)
    counts = {"raw": 0, "typed": 0, "stream": 0, "last_ns": 0}

    def flood_raw(data, t_ns):
        counts["raw"] += 1
        counts["last_ns"] = t_ns

    def flood_stream(data, t_ns):
        counts["stream"] += 1
        counts["last_ns"] = t_ns

    def flood_typed(msg):
        counts["typed"] += 1 if len(msg.data) == len(PAYLOAD) else 0
        counts["last_ns"] = time.time_ns()

    def control(msg):
        if msg.data == "reset":
            counts.update(raw=0, typed=0, stream=0, last_ns=0)
        elif msg.data == "quit":
            node.request_shutdown()
        stats.publish(node.new_message(STRING, data=json.dumps(counts)))

    node.create_subscription(STRING, "/bench/ping_raw", lambda d, t: pong_raw.publish_raw(d), PING, raw=True)
    node.create_subscription(STRING, "/bench/ping_typed", lambda m: pong_typed.publish(m), PING)
    node.create_subscription(STRING, "/bench/flood_raw", flood_raw, flood_q, raw=True)
    node.create_subscription(STRING, "/bench/flood_typed", flood_typed, flood_q)
    node.create_subscription(STRING, "/bench/flood_stream", flood_stream, STREAM, raw=True)
    node.create_subscription(STRING, "/bench/ctl", control, CTL)
    node.spin()
    node.shutdown()
    return 0


class Client:
    def __init__(self):
        self.node = transport.create_node("bench_client")
        self.got: list = []
        self.stats: list = []
        n = self.node
        self.ping_raw = n.create_publisher(STRING, "/bench/ping_raw", PING)
        self.ping_typed = n.create_publisher(STRING, "/bench/ping_typed", PING)
        self.ctl = n.create_publisher(STRING, "/bench/ctl", CTL)
        n.create_subscription(STRING, "/bench/pong_raw", lambda d, t: self.got.append(d), PING, raw=True)
        n.create_subscription(STRING, "/bench/pong_typed", lambda m: self.got.append(m), PING)
        n.create_subscription(STRING, "/bench/stats", lambda m: self.stats.append(json.loads(m.data)), CTL)

    def request(self, what: str, until=lambda s: True, timeout: float = 30.0) -> dict:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.stats.clear()
            self.ctl.publish(self.node.new_message(STRING, data=what))
            self.node.spin_until(lambda: bool(self.stats), 1.0)
            if self.stats and until(self.stats[-1]):
                return self.stats[-1]
            time.sleep(0.05)
        raise TimeoutError(f"echo did not answer {what!r} in time: {self.stats}")

    def pingpong(self, kind: str, n: int, warmup: int = 200) -> dict:
        node = self.node
        msg = node.new_message(STRING, data=PAYLOAD)
        reg = getattr(node, "_registry", None)
        cdr = reg.serialize(msg, STRING) if reg is not None else None
        pub = self.ping_raw if kind == "raw" else self.ping_typed
        lat = []
        for i in range(warmup + n):
            self.got.clear()
            t0 = time.perf_counter_ns()
            if kind == "raw":
                pub.publish_raw(cdr)
            else:
                pub.publish(msg)
            while not self.got:
                node.spin_once(1.0)
                if time.perf_counter_ns() - t0 > 5e9:
                    raise TimeoutError(f"{kind} ping {i} lost")
            if i >= warmup:
                lat.append(time.perf_counter_ns() - t0)
        total_s = sum(lat) / 1e9
        lat.sort()
        return {
            "round_trips": n,
            "round_trips_per_s": round(n / total_s, 1),
            "latency_us_p50": round(lat[len(lat) // 2] / 1e3, 1),
            "latency_us_p99": round(lat[min(len(lat) - 1, int(len(lat) * 0.99))] / 1e3, 1),
            "latency_us_mean": round(statistics.fmean(lat) / 1e3, 1),
        }

    def flood(self, kind: str, n: int) -> dict:
        node = self.node
        qos = STREAM if kind == "stream" else Qos(reliable=True, depth=max(10, n))
        pub = node.create_publisher(STRING, f"/bench/flood_{kind}", qos)
        if not node.wait_for_subscribers(pub, 1, 10.0):
            raise TimeoutError("echo never subscribed to the flood topic")
        self.request("reset")
        msg = node.new_message(STRING, data=PAYLOAD)
        reg = getattr(node, "_registry", None)
        cdr = reg.serialize(msg, STRING) if reg is not None else None
        t0 = time.time_ns()
        if kind in ("raw", "stream"):
            for _ in range(n):
                pub.publish_raw(cdr)
        else:
            for _ in range(n):
                pub.publish(msg)
        t_sent = time.time_ns()
        try:
            st = self.request("report", until=lambda s: s[kind] >= n,
                              timeout=60.0 if kind != "stream" else 5.0)
        except TimeoutError:
            st = self.stats[-1] if self.stats else {kind: 0, "last_ns": t_sent}
        received = st[kind]
        elapsed = (st["last_ns"] - t0) / 1e9
        return {
            "messages": n,
            "received": received,
            "lost": n - received,
            "msgs_per_s": round(received / elapsed, 1) if elapsed > 0 else None,
            "publish_loop_msgs_per_s": round(n / ((t_sent - t0) / 1e9), 1),
            "mbit_per_s": round(received * 1009 * 8 / elapsed / 1e6, 1) if elapsed > 0 else None,
        }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--role", default="client", choices=["client", "echo"])
    ap.add_argument("--n-pingpong", type=int, default=3000)
    ap.add_argument("--n-flood", type=int, default=20000)
    ap.add_argument("--domain", type=int, default=int(os.environ.get("ROS_DOMAIN_ID", "42") or 42))
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "transport_roundtrip.json"))
    args = ap.parse_args(argv)
    os.environ["ROS_DOMAIN_ID"] = str(args.domain)
    if args.role == "echo":
        return echo(args.n_flood)

    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    far = subprocess.Popen([sys.executable, __file__, "--role", "echo", "--n-flood", str(args.n_flood),
                            "--domain", str(args.domain)], env=env, cwd=ROOT)
    try:
        client = Client()
        for pub in (client.ping_raw, client.ping_typed, client.ctl):
            if not client.node.wait_for_subscribers(pub, 1, 15.0):
                raise TimeoutError("echo process did not come up")
        client.request("reset")
        figures = {
            "backend": client.node.backend_name,
            "message": f"{STRING}, 1000-char data, 1009 bytes CDR",
            "pingpong_raw": client.pingpong("raw", args.n_pingpong),
            "pingpong_typed": client.pingpong("typed", max(100, args.n_pingpong // 2)),
            "flood_raw": client.flood("raw", args.n_flood),
            "flood_typed": client.flood("typed", max(1000, args.n_flood // 4)),
            "flood_raw_stream_qos": client.flood("stream", args.n_flood),
            "how": ("two processes on one host, reliable volatile QoS; ping-pong: one message in "
                    "flight, latency = publish to echo received (perf_counter); flood: back-to-back "
                    "publishes, receiver history deep enough to keep all (flood_raw_stream_qos: the "
                    "STREAM profile, depth 1000 both sides), rate = received / (last receipt - "
                    "first send) on the shared wall clock"),
        }
        client.request("quit")
        client.node.shutdown()
    finally:
        try:
            far.wait(timeout=5)
        except subprocess.TimeoutExpired:
            far.terminate()
            far.wait(timeout=5)
    try:
        sys.path.insert(0, str(ROOT / "bench"))
        from _common import write_result
        path = write_result("transport_roundtrip", figures)
        if Path(args.out).resolve() != path.resolve():
            Path(args.out).write_text(path.read_text())
    except Exception:  # keep the bench usable if the shared stamping helper changes
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps({"benchmark": "transport_roundtrip", "figures": figures},
                                             indent=2) + "\n")
    print(json.dumps(figures, indent=2))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
