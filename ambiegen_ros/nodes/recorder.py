"""`recorder`: writes every topic of a run, as raw CDR bytes (no decoding), to one MCAP file.

Each message's log time is when the recorder took it and its publish time when its writer sent it
(the sample's source timestamp, as rosbag2 keeps a send time): a recorder that falls behind on a
loaded machine logs a fast run's last states after its result, but their publish times keep the
order in which they were sent.

The file follows the ROS 2 MCAP profile (schemas, ``offered_qos_profiles``, type hashes,
summary), so ``ros2 bag info/play`` and Foxglove open it. The run's config, seed and versions are
stored as MCAP metadata when the latched ``RunConfig`` arrives. The log is flushed every
``flush_period`` seconds and finalised on SIGINT/SIGTERM, once what was still on its way has
been taken (until nothing came for 0.5 s, 3 s at most; ``Node.finish_io``); after a SIGKILL,
``ambiegen recover FILE.mcap`` rebuilds a valid file with everything up to the last flush. A
scenario, a result or a stack event is flushed as it arrives (``VITAL_FLUSH_S`` later at most, so a
burst of them is one chunk): a recorder killed during a run keeps the run's scenario. A file
that can take no more (the disk is full) stops the recorder with one line saying so and exit
status 3; the log keeps everything up to the last flush.

Parameters: ``output`` (file path; default ``ambiegen_<random>_<utc time>.mcap``; the launch file
and ``ambiegen campaign`` name it ``<run id>_<utc time>.mcap``), ``overwrite`` (false: an existing
``output`` is refused with exit status 2, as rosbag2 does; true: it is replaced), ``flush_period``
(s), ``compression`` (zstd | lz4 | none), ``extra_topics`` (comma-separated ``topic`` or
``topic=pkg/msg/Type`` entries to record besides the AmbieGen topics: a robot's ``/scan``,
``/odom``, ``/tf`` ...), ``topic_wait`` (s to wait for a publisher of every extra topic),
``discover`` (also record other topics found under ``/ambiegen``).

An extra topic is subscribed once a publisher of it shows up, with that publisher's type and
reliability and durability (as ``ros2 bag record`` adapts to the offered QoS): a best-effort
laser is read best-effort, ``/tf_static`` and a map transient-local, so late samples and latched
ones are both kept. The stack that publishes them may start after the recorder, so until every
extra topic has a reader matched to a publisher the graph is looked at every ``WAIT_PERIOD``
seconds, and the recorder says on ``/ambiegen/recorder_status`` (latched) that it is still
waiting; then that it is ready, and the generator sends its first scenario (``min_recorders``),
so a bag holds every run from its first message. A topic with no publisher after ``topic_wait``
seconds is named in one warning line, the status says ready with it missing, and it is still
looked for every second (as is anything new under ``/ambiegen``).
"""
from __future__ import annotations

import json
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

from .. import __version__
from ..ros import topics
from ..ros.mcap_log import McapLog, log_file_name
from ..ros.conversions import STATUS_OK, STATUS_WARN, key_values
from ..ros.qos import DEFAULT, LATCHED, Qos
from ..ros.transport import create_node
from ..ros.types import get_registry
from . import run_node


READER_DEPTH = 5000
# Fast DDS readers whose history holds 5000 untaken samples slow down so much that the other
# topics of the same process starve: with rclpy over rmw_fastrtps_cpp, a 30,000-sample flood on one
# topic and 300 reliable samples on another gave 67 of the 300 at depth 5000 and all 300 at 1000
# and 2000 (Cyclone: all 300 at 5000). So on Fast DDS the recorder's readers are 2000 deep.
FAST_DDS_READER_DEPTH = 2000
TIMELINE_TOPICS = frozenset(topics.timeline(p) for p in topics.TIMELINE_TYPES)
CANNOT_WRITE = 3  # exit status: the disk is full (or the file may not grow): the log is kept up to the last flush
WAIT_PERIOD = 0.05  # s between two looks at the graph while an extra topic has no matched reader yet


VITAL_FLUSH_S = 0.05  # a scenario, result or stack event reaches the file this soon (SIGKILL-safe)
VITAL_TOPICS = frozenset([topics.RESULTS, topics.STACK_EVENTS, *(topics.scenarios(p) for p in topics.SCENARIO_TYPES)])


def offered_qos(offered: list) -> Qos:
    """The QoS that matches every publisher (``ros2 bag record``'s rule): reliable only if all of
    them are, transient local only if all of them are; the first one's depth."""
    if not offered:
        return DEFAULT
    return Qos(reliable=all(o.qos.reliable for o in offered),
               transient_local=all(o.qos.transient_local for o in offered), depth=offered[0].qos.depth)


class Recorder:
    def __init__(self, argv: list[str] | None = None, node=None):
        self.node = node or create_node("recorder", argv=argv)
        n = self.node
        stamp = datetime.now(timezone.utc).strftime("%Y%m%d_%H%M%S")
        output = n.declare_parameter("output", "", "MCAP file to write ('' = ambiegen_<random>_<utc time>.mcap)")
        overwrite = n.declare_parameter("overwrite", False, "replace an existing output file (default: refuse it)")
        flush_period = n.declare_parameter("flush_period", 1.0, "seconds between flushes (data safe from SIGKILL)")
        compression = n.declare_parameter("compression", "zstd", "zstd | lz4 | none")
        extra = n.declare_parameter("extra_topics", "", "extra 'topic=pkg/msg/Type' entries to record, comma-separated")
        self.topic_wait = n.declare_parameter(
            "topic_wait", 30.0, "seconds to wait for a publisher of every extra topic before saying ready without it")
        self.discover = n.declare_parameter("discover", True, "also record other topics under /ambiegen")
        default_depth = FAST_DDS_READER_DEPTH if (n.rmw or "").startswith("rmw_fastrtps") else READER_DEPTH
        self.reader_depth = n.declare_parameter(
            "reader_depth", default_depth, "samples each reader queues while the recorder is busy (min: the topic's depth)")
        self.path = Path(output or log_file_name())
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.registry = get_registry()
        try:
            self.log = McapLog(self.path, self.registry, compression=compression,
                               library=f"ambiegen-ros {__version__} recorder", overwrite=overwrite)
        except FileExistsError as exc:  # one line and exit status 2 (run_node), the old log untouched
            raise FileExistsError(f"{exc} (choose another output, or set overwrite:=true to replace it)") from None
        self.log.add_metadata("ambiegen_recorder", {"version": __version__, "started": stamp,
                                                     "middleware": n.middleware})
        self._config_seen = False
        self.cannot_write: OSError | None = None  # set once the file takes no more (the recorder stops)
        self.flushed_at: datetime | None = None
        # said first (before the run topics are read): a generator that sees this recorder sees it waiting
        self.pub_status = n.create_publisher(topics.RECORDER_STATUS_TYPE, topics.RECORDER_STATUS, LATCHED)
        self.waiting_since = time.monotonic()
        self.readers: dict[str, object] = {}  # extra topic -> its subscription
        self.pending: dict[str, str] = {}  # extra topics not subscribed yet -> type ('' = the publisher's)
        for entry in extra.split(","):
            if entry.strip():
                topic, _, typename = entry.partition("=")
                self.pending[topic.strip()] = typename.strip()
        self.wanted = list(self.pending)  # every extra topic, in the order given
        self.publish_status(ready=not self.wanted, missing=self.wanted)
        for topic, typename, qos in topics.run_topics():
            self.record(topic, typename, qos)
            self.pending.pop(topic, None)  # an extra topic that is a run topic is read already
        n.create_timer(flush_period, self.flush)
        self.vital_unflushed = False  # a scenario, result or stack event written since the last flush
        n.create_timer(VITAL_FLUSH_S, lambda: self.flush() if self.vital_unflushed else None)
        if self.discover or self.pending:
            n.create_timer(1.0, self.discover_topics)
        if self.wanted:
            self.wait_timer = n.create_timer(WAIT_PERIOD, self.await_topics)
        n.logger.info(f"recording to {self.path} ({n.middleware})")

    def record(self, topic: str, typename: str, qos: Qos):
        """Read ``topic`` into its own channel; its subscription (None: read already, or a type unknown here)."""
        if self.log.channel_id(topic) is not None:
            return None
        if not self.registry.has(typename):
            self.node.logger.warning(f"not recording {topic}: unknown type {typename}")
            return None
        channel = self.log.add_channel(topic, typename, qos)
        is_config = topic == topics.RUN_CONFIG
        vital = topic in VITAL_TOPICS

        def on_bytes(data: bytes, receive_ns: int, source_ns: int) -> None:
            if self.cannot_write is not None:
                return
            try:  # log time: when taken here; publish time: when its writer sent it (rosbag2's send time)
                self.log.write(channel, data, receive_ns, source_ns)
            except OSError as exc:  # the disk is full (or the file may grow no more): stop, keep what is written
                self.stop_writing(exc)
                return
            if is_config:
                self.store_run_config(data)
            self.vital_unflushed = self.vital_unflushed or vital

        # the reader's queue is local (it does not affect matching): keep it deep so bursts are not lost.
        # Timelines (hundreds of samples per full-model run, in bursts) are read best-effort, so a
        # recorder that falls behind loses timeline samples, never scenarios or results (see
        # FAST_DDS_READER_DEPTH: on Fast DDS a reliable flood starves the other readers)
        reliable = qos.reliable and topic not in TIMELINE_TOPICS
        reader_qos = Qos(reliable=reliable, transient_local=qos.transient_local, depth=max(qos.depth, self.reader_depth))
        return self.node.create_subscription(typename, topic, on_bytes, reader_qos, raw=True)

    def store_run_config(self, data: bytes) -> None:
        msg = self.registry.deserialize(data, topics.RUN_CONFIG_TYPE)
        config = json.loads(msg.config_json)
        self.log.add_metadata(
            "ambiegen_run",
            {
                "run_id": msg.run_id,
                "package_version": msg.package_version,
                "seed": str(config.get("seed")),
                "problem": str(config.get("problem")),
                "config_json": msg.config_json,
            },
        )

    def discover_topics(self) -> None:
        for topic, types in self.node.topic_names_and_types():
            if not types or self.log.channel_id(topic) is not None or topic == topics.RECORDER_STATUS:
                continue  # recorders' statuses steer the start; they are not part of the run
            wanted = topic in self.pending
            if not (wanted or (self.discover and topic.startswith(topics.NAMESPACE + "/"))):
                continue
            offered = self.node.publishers_info(topic)
            if wanted and not offered:
                continue  # only subscribers so far: wait for a publisher and its QoS
            typename = self.pending.pop(topic, "") or types[0]
            reader = self.record(topic, typename, offered_qos(offered))
            if reader is not None and topic in self.wanted:
                self.readers[topic] = reader

    def missing(self) -> list[str]:
        """Extra topics not read yet: no publisher so far, or a reader not matched to one yet
        (a backend that cannot tell counts a reader made for a publisher it saw as matched)."""
        def unmatched(reader) -> bool:
            count = getattr(reader, "publisher_count", None)
            return count is not None and count() == 0

        return [t for t in self.wanted if t in self.pending or (t in self.readers and unmatched(self.readers[t]))]

    def await_topics(self) -> None:
        """Until every extra topic is read (or ``topic_wait`` ran out): subscribe what has a
        publisher now, then say ready once none is missing."""
        if self.pending:
            self.discover_topics()
        missing = self.missing()
        waited = time.monotonic() - self.waiting_since
        if missing and waited < self.topic_wait:
            return
        self.wait_timer.cancel()
        if missing:
            self.node.logger.warning(
                f"no publisher of {', '.join(missing)} after {self.topic_wait:g} s: recording without "
                f"{'it' if len(missing) == 1 else 'them'} (still looked for every second)")
        else:
            self.node.logger.info(f"reading all {len(self.wanted)} extra topics after {waited:.2f} s: ready")
        self.publish_status(ready=True, missing=missing)

    def publish_status(self, ready: bool, missing: list[str]) -> None:
        n = self.node
        text = ("waiting for " if not ready else "ready without " if missing else "ready") + ", ".join(missing)
        self.pub_status.publish(n.new_message(
            topics.RECORDER_STATUS_TYPE, level=STATUS_WARN if ready and missing else STATUS_OK,
            name=n.fully_qualified_name, message=text, hardware_id=str(self.path),
            values=key_values(n.new_message, {"state": "ready" if ready else "waiting", "missing": ",".join(missing)})))

    def flush(self) -> None:
        if self.cannot_write is not None:
            return
        try:
            self.vital_unflushed = False
            self.log.flush()
            self.flushed_at = datetime.now(timezone.utc)
        except OSError as exc:
            self.stop_writing(exc)

    def stop_writing(self, exc: OSError) -> None:
        """The file can take no more (disk full, a size limit): one clear line, and the node stops; the
        log holds everything up to the last flush (``ambiegen recover`` makes it whole)."""
        self.cannot_write = exc
        when = self.flushed_at.strftime("%H:%M:%S UTC") if self.flushed_at else "its start"
        self.node.logger.error(f"cannot write {self.path}: {exc.strerror or exc} (disk full?); recording stopped. "
                               f"The log is readable up to {when}: ambiegen recover {self.path}")
        self.node.request_shutdown()

    def close(self) -> int:
        if self.cannot_write is not None:
            try:
                self.log.close()
            except (OSError, ValueError):
                pass  # no room for the summary: the chunks flushed before are what recover reads
            return CANNOT_WRITE
        self.log.close()
        counts = self.log.counts()
        self.node.logger.info(f"closed {self.path}: {sum(counts.values())} messages")
        return 0


def main(argv: list[str] | None = None) -> int:
    return run_node("recorder", lambda: Recorder(argv), Recorder.close, doc=__doc__, drain=True)


if __name__ == "__main__":
    sys.exit(main())
