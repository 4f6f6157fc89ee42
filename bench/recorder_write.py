"""How fast can the recorder store raw CDR messages? (McapLog.write, zstd chunks of 1 MiB)

Two payload kinds per size: real ``ScenarioResult`` CDR bytes (random trajectory poses, so about
as compressible as recorded data) and random bytes (incompressible, zstd's worst case). Every
message in a run is distinct (a pool of distinct payloads at least 4 MiB large, so no payload
repeats inside a chunk, plus a per-message counter in the first bytes). Time covers ``write``
for every message plus ``close`` (last chunk, summary, statistics).

    .venv/bin/python bench/recorder_write.py [--seconds 1.5] [--out bench/results/recorder_write.json]
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from ambiegen_ros.ros import qos  # noqa: E402
from ambiegen_ros.ros.mcap_log import McapLog  # noqa: E402
from ambiegen_ros.ros.types import get_registry  # noqa: E402

RESULT = "ambiegen_msgs/msg/ScenarioResult"
POOL_BYTES = 4 << 20


def pool_size(size: int) -> int:
    return max(64, -(-POOL_BYTES // size))


def cdr_payloads(size: int, rng: np.random.Generator) -> list[bytes]:
    """ScenarioResult messages padded with trajectory poses until they reach ``size`` bytes."""
    reg = get_registry()
    base = len(reg.serialize(reg.new(RESULT), RESULT))
    one_pose = reg.new("nav_msgs/msg/Path", poses=[reg.new("geometry_msgs/msg/PoseStamped")])
    empty = reg.new("nav_msgs/msg/Path")
    pose_bytes = len(reg.serialize(one_pose, "nav_msgs/msg/Path")) - len(reg.serialize(empty, "nav_msgs/msg/Path"))
    n_poses = max(0, (size - base - 64) // pose_bytes)
    out = []
    for k in range(pool_size(size)):
        poses = []
        for xy in rng.uniform(0, 50, size=(n_poses, 2)):
            pose = reg.new("geometry_msgs/msg/PoseStamped")
            pose.header.frame_id = "map"
            pose.pose.position.x, pose.pose.position.y = float(xy[0]), float(xy[1])
            pose.pose.orientation.w = 1.0
            poses.append(pose)
        msg = reg.new(RESULT, run_id="bench", scenario_id=k, problem="robot", worker="robot_sim",
                      objectives=[float(rng.uniform(0, 300))], failure_kind=1, failed=True)
        msg.trajectory.poses = poses
        data = reg.serialize(msg, RESULT)
        out.append(data + b"\x00" * max(0, size - len(data)))  # CDR readers ignore trailing bytes
    return out


def random_payloads(size: int, rng: np.random.Generator) -> list[bytes]:
    return [b"\x00\x01\x00\x00" + rng.bytes(size - 4) for _ in range(pool_size(size))]


def run(payloads: list[bytes], seconds: float, directory: Path) -> dict:
    size = len(payloads[0])
    path = directory / f"bench_{size}.mcap"
    buffers = [bytearray(p) for p in payloads]
    log = McapLog(path, compression="zstd", chunk_size=1 << 20)
    channel = log.add_channel("/ambiegen/results", RESULT, qos.STREAM)
    n = 0
    start = time.perf_counter()
    stop = start + seconds
    while True:
        for buf in buffers:
            buf[4:8] = n.to_bytes(4, "little")  # every message distinct
            log.write(channel, bytes(buf), n)
            n += 1
        if time.perf_counter() > stop:
            break
    log.close()
    elapsed = time.perf_counter() - start
    file_bytes = path.stat().st_size
    path.unlink()
    return {
        "payload_bytes": size,
        "messages": n,
        "seconds": round(elapsed, 3),
        "messages_per_s": round(n / elapsed),
        "MB_per_s": round(n * size / elapsed / 1e6, 1),
        "compression_ratio": round(n * size / file_bytes, 2),
    }


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=1.5, help="minimum duration of each case")
    parser.add_argument("--out", default=str(ROOT / "bench" / "results" / "recorder_write.json"))
    args = parser.parse_args(argv)
    rng = np.random.default_rng(0)
    cases = []
    with tempfile.TemporaryDirectory() as tmp:
        for size in (1024, 10240):
            for kind, make in (("cdr", cdr_payloads), ("random", random_payloads)):
                result = {"payload": kind, **run(make(size, rng), args.seconds, Path(tmp))}
                cases.append(result)
                print(
                    f"{kind:6s} {size:6d} B: {result['messages_per_s']:8d} msgs/s  "
                    f"{result['MB_per_s']:7.1f} MB/s  ratio {result['compression_ratio']}"
                )
    from importlib.metadata import version

    report = {
        "what": "McapLog.write of raw CDR bytes + close, zstd, 1 MiB chunks, one channel",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
        "mcap": version("mcap"),
        "rosbags": version("rosbags"),
        "target_messages_per_s_1KB": 20000,
        "cases": cases,
    }
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(report, indent=2) + "\n")
    print(f"wrote {args.out}")
    return report


if __name__ == "__main__":
    main()
