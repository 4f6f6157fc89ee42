"""The transport seam's DDS backend between real processes on real DDS (each test its own
ROS_DOMAIN_ID, ``ros_domain``): typed and raw bytes exchanged exactly, a latched late joiner,
discovery, SIGINT and SIGTERM. Every wait ends on an event; ``PATIENCE`` bounds it as a safety net,
and no test asserts how fast anything is. The seam's other tests: ``test_transport_params.py``
(parameters, names), ``test_transport_rclpy.py`` (the rclpy backend without rclpy),
``test_transport_dds.py`` (the DDS backend's tables and one process).

This file is also the helper program for its multi-process tests:
``python test_transport.py ROLE ARGS...`` runs one node role (see ``_ROLES``).
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PATIENCE = 120.0  # s: the bound of every wait that ends on an event (a hung child, not a slow machine)
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from ambiegen_ros.ros import transport  # noqa: E402
from ambiegen_ros.ros.qos import LATCHED, STREAM  # noqa: E402

STRING = "std_msgs/msg/String"
GRID = "nav_msgs/msg/OccupancyGrid"


# ---------------------------------------------------------------------------------------------
# messages both sides build identically


def _grid_fields(i: int) -> dict:
    import numpy as np
    return dict(
        header={"frame_id": f"map{i}", "sec": 100 + i, "nanosec": 7},
        width=7, height=3, resolution=0.05 * (i + 1),
        data=np.arange(21, dtype=np.int16).astype(np.int8) * (i + 1) - 50,
    )


def make_grid(reg, i: int):
    f = _grid_fields(i)
    stamp = reg.new("builtin_interfaces/msg/Time", sec=f["header"]["sec"], nanosec=f["header"]["nanosec"])
    header = reg.new("std_msgs/msg/Header", stamp=stamp, frame_id=f["header"]["frame_id"])
    origin = reg.new("geometry_msgs/msg/Pose",
                     position=reg.new("geometry_msgs/msg/Point", x=-1.5, y=2.25, z=0.0),
                     orientation=reg.new("geometry_msgs/msg/Quaternion", x=0.0, y=0.0, z=0.0, w=1.0))
    info = reg.new("nav_msgs/msg/MapMetaData", map_load_time=stamp, resolution=f["resolution"],
                   width=f["width"], height=f["height"], origin=origin)
    return reg.new(GRID, header=header, info=info, data=f["data"])


STRINGS = ["hello", "", "ünïcödé ✓", "x" * 1000]


def expected_bytes(reg) -> dict[str, list[str]]:
    return {
        "/chat": [reg.serialize(reg.new(STRING, data=s), STRING).hex() for s in STRINGS],
        "/grid": [reg.serialize(make_grid(reg, i), GRID).hex() for i in range(2)],
    }


# ---------------------------------------------------------------------------------------------
# helper roles (run in child processes)


def _role_sub(out: str) -> int:
    node = transport.create_node("typed_sub")
    reg = node._registry
    got: dict[str, list] = {"raw": [], "typed": [], "threads": []}
    main = threading.get_ident()

    def typed(topic, typename):
        def cb(msg):
            got["threads"].append(threading.get_ident() == main)
            got["typed"].append([topic, reg.serialize(msg, typename).hex()])
        return cb

    def raw(topic):
        def cb(data, t_ns):
            got["raw"].append([topic, bytes(data).hex(), abs(time.time_ns() - t_ns) < 5e9])
        return cb

    for topic, typename in (("/chat", STRING), ("/grid", GRID)):
        node.create_subscription(typename, topic, typed(topic, typename), STREAM)
        node.create_subscription(typename, topic, raw(topic), STREAM, raw=True)
    print("READY", flush=True)
    total = len(STRINGS) + 2
    node.spin_until(lambda: len(got["raw"]) >= total and len(got["typed"]) >= total, PATIENCE)
    node.shutdown()
    Path(out).write_text(json.dumps(got))
    return 0


def _role_pub(out: str) -> int:
    node = transport.create_node("typed_pub")
    reg = node._registry
    chat = node.create_publisher(STRING, "chat", STREAM)
    grid = node.create_publisher(GRID, "/grid", STREAM)
    report = {"matched": [node.wait_for_subscribers(chat, 2, PATIENCE), node.wait_for_subscribers(grid, 2, PATIENCE)]}
    for s in STRINGS:
        chat.publish(node.new_message(STRING, data=s))
    for i in range(2):
        grid.publish(make_grid(reg, i))
    # stay until the subscriber has everything and leaves (reliable delivery needs us alive)
    deadline = time.monotonic() + PATIENCE
    while (chat.subscription_count() or grid.subscription_count()) and time.monotonic() < deadline:
        time.sleep(0.01)
    report["left"] = chat.subscription_count() == 0
    node.shutdown()
    Path(out).write_text(json.dumps(report))
    return 0


def _role_latched(out: str) -> int:
    node = transport.create_node("latched_pub", namespace="/demo")
    reg = node._registry
    pub = node.create_publisher(GRID, "latched_map", LATCHED)
    for i in range(3):
        pub.publish(make_grid(reg, i))
    ticks = []
    node.create_timer(0.02, lambda: ticks.append(1))
    print("READY", flush=True)
    node.spin()  # until SIGINT/SIGTERM
    # finalising after a signal must still work
    Path(out).write_text(json.dumps({"ok_after": node.ok(), "ticks": len(ticks)}))
    node.shutdown()
    return 0


def _role_late(out: str) -> int:
    node = transport.create_node("late_sub")
    got = []
    node.create_subscription(GRID, "/demo/latched_map", lambda d, t: got.append(bytes(d).hex()),
                             LATCHED, raw=True)
    node.spin_until(lambda: len(got) >= 1, PATIENCE)
    node.spin_until(lambda: False, 0.3)  # would a second (older) sample arrive?
    node.shutdown()
    Path(out).write_text(json.dumps(got))
    return 0


_ROLES = {"sub": _role_sub, "pub": _role_pub, "latched": _role_latched, "late": _role_late}


# ---------------------------------------------------------------------------------------------
# process helpers


def _spawn(role: str, domain: int, *args: str) -> subprocess.Popen:
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), AMBIEGEN_TRANSPORT="dds",
               PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.Popen([sys.executable, __file__, role, *args], cwd=REPO, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_ready(proc: subprocess.Popen, timeout: float = PATIENCE) -> None:
    box: list[str] = []
    t = threading.Thread(target=lambda: box.append(proc.stdout.readline()), daemon=True)
    t.start()
    t.join(timeout)
    if not box or "READY" not in box[0]:
        proc.kill()
        raise AssertionError(f"child not ready: {box!r} {proc.stderr.read()[-2000:]}")


def _finish(proc: subprocess.Popen, timeout: float = PATIENCE) -> None:
    try:
        _, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise
    assert proc.returncode == 0, err[-3000:]

# ---------------------------------------------------------------------------------------------
# DDS backend between processes


def test_two_processes_exchange_typed_and_raw_bytes_exactly(tmp_path, ros_domain):
    from ambiegen_ros.ros import types
    sub = _spawn("sub", ros_domain, str(tmp_path / "sub.json"))
    _wait_ready(sub)
    pub = _spawn("pub", ros_domain, str(tmp_path / "pub.json"))
    _finish(sub)
    _finish(pub)
    report = json.loads((tmp_path / "pub.json").read_text())
    assert report == {"matched": [True, True], "left": True}
    got = json.loads((tmp_path / "sub.json").read_text())
    want = expected_bytes(types.get_registry())
    for kind in ("raw", "typed"):
        for topic, hexes in want.items():
            assert [h for t, h, *_ in got[kind] if t == topic] == hexes, (kind, topic)
    assert all(ok for *_, ok in got["raw"])  # receive times are wall-clock ns
    assert got["threads"] and all(got["threads"])  # callbacks ran on the spinning thread


def test_latched_late_joiner_discovery_and_sigint(tmp_path, dds_env, ros_domain):
    from ambiegen_ros.ros import types
    reg = types.get_registry()
    latched = _spawn("latched", ros_domain, str(tmp_path / "final.json"))
    try:
        _wait_ready(latched)
        late = _spawn("late", ros_domain, str(tmp_path / "late.json"))
        _finish(late)
        got = json.loads((tmp_path / "late.json").read_text())
        assert got == [reg.serialize(make_grid(reg, 2), GRID).hex()]  # only the last, depth 1

        node = dds_env(ros_domain, "observer")
        node.spin_until(lambda: ("/demo/latched_map", [GRID]) in node.topic_names_and_types(), PATIENCE)
        assert ("/demo/latched_map", [GRID]) in node.topic_names_and_types()
        info = []
        node.spin_until(lambda: bool(info.extend(node.publishers_info("/demo/latched_map"))
                                     or (info and info[-1].node_name)), PATIENCE)
        ep = info[-1]
        assert (ep.typename, ep.qos, ep.keep_all) == (GRID, LATCHED, False)
        assert ep.type_hash == reg.type_hash(GRID)
        assert (ep.node_namespace, ep.node_name) == ("/demo", "latched_pub")

        t0 = time.monotonic()
        latched.send_signal(signal.SIGINT)
        _finish(latched)  # ends on the signal; how fast is not checked
        print(f"SIGINT to exit: {time.monotonic() - t0:.2f} s")
        final = json.loads((tmp_path / "final.json").read_text())
        assert final["ok_after"] is False and final["ticks"] > 0
    finally:
        if latched.poll() is None:
            latched.kill()


def test_sigterm_ends_spin_cleanly(tmp_path, ros_domain):
    proc = _spawn("latched", ros_domain, str(tmp_path / "final.json"))
    try:
        _wait_ready(proc)
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        _finish(proc)  # ends on the signal; how fast is not checked
        print(f"SIGTERM to exit: {time.monotonic() - t0:.2f} s")
        assert json.loads((tmp_path / "final.json").read_text())["ok_after"] is False
    finally:
        if proc.poll() is None:
            proc.kill()


if __name__ == "__main__":
    sys.exit(_ROLES[sys.argv[1]](*sys.argv[2:]))
