"""The recorder's core: raw CDR bytes in, an MCAP file that ROS 2 tools open out.

No ROS and no decoding on the hot path: ``write`` hands the bytes received from DDS (4-byte CDR
header included) to the ``mcap`` writer, which packs them into compressed chunks. What makes the
file a rosbag2-compatible bag is the metadata around the messages: profile ``ros2``, one schema
per type (``pkg/msg/Type``, ``ros2msg`` text as rosbag2 writes it), and channels carrying
``offered_qos_profiles`` (so ``ros2 bag play`` republishes latched topics as latched) and
``topic_type_hash``.

A recorder killed with SIGKILL leaves a file without summary and perhaps with half a chunk at the
end; everything up to the last ``flush()`` is in complete chunks, and :func:`recover` rewrites
such a file into a valid one.
"""
from __future__ import annotations

import io
import os
import secrets
import struct
import threading
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, BinaryIO, Callable

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Attachment, Channel, Chunk, Header, Message, Metadata, Schema
from mcap.stream_reader import breakup_chunk
from mcap.writer import CompressionType, Writer

from .qos import Qos, to_offered_qos_yaml
from .types import TypeRegistry, get_registry

PROFILE = "ros2"
MAGIC = b"\x89MCAP0\r\n"
_COMPRESSION = {
    "zstd": CompressionType.ZSTD,
    "lz4": CompressionType.LZ4,
    "none": CompressionType.NONE,
}


def _default_library() -> str:
    try:
        from .. import __version__
    except ImportError:  # pragma: no cover - only when vendored without the package
        __version__ = "unknown"
    return f"ambiegen-ros {__version__}"


def create_file(path: str | os.PathLike, overwrite: bool = False) -> BinaryIO:
    """Open a new file for writing; an existing one is refused (``FileExistsError``) unless ``overwrite``.

    Check and creation are one system call (``O_EXCL``), so a writer started on the same name at
    the same moment cannot truncate what another one wrote (as ``rosbag2`` refuses an existing bag).
    """
    try:
        return open(path, "wb" if overwrite else "xb")
    except FileExistsError:
        raise FileExistsError(f"{path} already exists; refusing to overwrite it") from None


def log_file_name(run_id: str | None = None, when: datetime | None = None) -> str:
    """``<run id>_<UTC time>.mcap`` (``ambiegen_<random>_<UTC time>.mcap`` without a run id).

    A default name that differs for every recording, so no run lands on an earlier run's log.
    """
    stamp = (when or datetime.now(timezone.utc)).strftime("%Y%m%dT%H%M%SZ")
    return f"{run_id or 'ambiegen_' + secrets.token_hex(3)}_{stamp}.mcap"


class McapLog:
    """Append-only MCAP writer for one recording (thread-safe; one lock around each call).

    The file must not exist yet (``FileExistsError``) unless ``overwrite``.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        registry: TypeRegistry | None = None,
        compression: str = "zstd",
        chunk_size: int = 1 << 20,
        library: str | None = None,
        overwrite: bool = False,
    ):
        if compression not in _COMPRESSION:
            raise ValueError(f"compression must be one of zstd, lz4, none; got {compression!r}")
        self.path = Path(path)
        self.registry = registry
        self._file = create_file(self.path, overwrite)
        self._writer = Writer(self._file, chunk_size=chunk_size, compression=_COMPRESSION[compression])
        self._writer.start(profile=PROFILE, library=library or _default_library())
        self._lock = threading.Lock()
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, tuple[int, str, Qos]] = {}
        self._counts: dict[int, int] = {}
        self.message_count = 0
        self.closed = False

    # --- structure -------------------------------------------------------------------------
    def add_channel(self, topic: str, typename: str, qos: Qos) -> int:
        """Register a topic (once) and return its channel id; the schema is shared per type.

        Adding the same topic again with the same type and QoS returns the existing id.
        """
        with self._lock:
            self._check_open()
            known = self._channels.get(topic)
            if known is not None:
                if known[1:] != (typename, qos):
                    raise ValueError(f"topic {topic} already recorded as {known[1]} with {known[2]}")
                return known[0]
            registry = self.registry or get_registry()
            self.registry = registry
            schema_id = self._schemas.get(typename)
            if schema_id is None:
                schema_id = self._writer.register_schema(
                    name=typename, encoding="ros2msg", data=registry.msgdef(typename).encode("utf-8")
                )
                self._schemas[typename] = schema_id
            channel_id = self._writer.register_channel(
                topic=topic,
                message_encoding="cdr",
                schema_id=schema_id,
                metadata={
                    "offered_qos_profiles": to_offered_qos_yaml(qos),
                    "topic_type_hash": registry.type_hash(typename),
                },
            )
            self._channels[topic] = (channel_id, typename, qos)
            self._counts[channel_id] = 0
            return channel_id

    def channel_id(self, topic: str) -> int | None:
        known = self._channels.get(topic)
        return known[0] if known else None

    # --- hot path --------------------------------------------------------------------------
    def write(
        self,
        channel_id: int,
        data: bytes | bytearray | memoryview,
        log_time_ns: int,
        publish_time_ns: int | None = None,
    ) -> None:
        """Append one message: CDR bytes exactly as received (encapsulation header included)."""
        with self._lock:
            if self.closed:
                raise ValueError(f"{self.path} is closed")
            count = self._counts.get(channel_id)
            if count is None:
                raise KeyError(f"unknown channel id {channel_id}")
            self._writer.add_message(
                channel_id,
                log_time_ns,
                data,
                log_time_ns if publish_time_ns is None else publish_time_ns,
            )
            self._counts[channel_id] = count + 1
            self.message_count += 1

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """A named key/value record (e.g. the run config); values must be strings."""
        bad = [k for k, v in data.items() if not isinstance(k, str) or not isinstance(v, str)]
        if bad:
            raise TypeError(f"metadata {name!r}: keys and values must be str (bad key {bad[0]!r})")
        with self._lock:
            self._check_open()
            self._writer.add_metadata(name, dict(data))

    def counts(self) -> dict[str, int]:
        """Messages written per topic so far."""
        with self._lock:
            return {topic: self._counts[cid] for topic, (cid, _, _) in self._channels.items()}

    # --- durability ------------------------------------------------------------------------
    def flush(self, fsync: bool = False) -> None:
        """Close the current chunk and hand it to the OS: it survives a SIGKILL from here on.

        ``fsync=True`` also survives a power loss, at the cost of a disk sync.
        Each flush ends a chunk, so flushing very often lowers the compression ratio.
        """
        with self._lock:
            self._check_open()
            self._writer.flush()
            if fsync:
                os.fsync(self._file.fileno())

    def close(self) -> None:
        """Write the summary (schemas, channels, statistics, indexes) and the footer. Idempotent."""
        with self._lock:
            if self.closed:
                return
            self.closed = True
            try:
                self._writer.finish()
            finally:
                self._file.close()

    def _check_open(self) -> None:
        if self.closed:
            raise ValueError(f"{self.path} is closed")

    def __enter__(self) -> "McapLog":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __del__(self) -> None:  # best effort: a forgotten log still gets its summary
        try:
            if not self.closed:
                self.close()
        except Exception:
            pass


# --- recovery --------------------------------------------------------------------------------
_RECORD_HEADER = struct.Struct("<BQ")


def _read_body(body: bytes, reader: Callable[[ReadDataStream], Any], length: int | None = None) -> Any:
    stream = ReadDataStream(io.BytesIO(body))
    return reader(stream) if length is None else reader(stream, length)


def recover(src: str | os.PathLike, dst: str | os.PathLike, compression: str = "zstd", overwrite: bool = False) -> dict:
    """Rewrite a (possibly truncated) MCAP file into a valid one holding every complete message.

    Reads records one by one and stops at the first record that does not fit in the file (a
    write cut short by SIGKILL or a full disk). A complete chunk whose CRC or decompression fails
    is skipped and counted. Schemas, channels, metadata and attachments are carried over; the
    output gets a fresh summary and statistics. Returns a small report.

    The input is never written; an existing ``dst`` is refused (``FileExistsError``) unless
    ``overwrite``, and a ``dst`` that is the input (same path, link) always is (``ValueError``).
    """
    src, dst = Path(src), Path(dst)
    if src.resolve() == dst.resolve() or (dst.exists() and os.path.samefile(src, dst)):
        raise ValueError(f"recover writes a new file: the output {dst} is the input {src}")
    report = {
        "messages": 0,
        "channels": 0,
        "schemas": 0,
        "metadata": 0,
        "attachments": 0,
        "chunks": 0,
        "bad_chunks": 0,
        "complete": False,
        "truncated_bytes": 0,
    }
    size = src.stat().st_size
    with open(src, "rb") as f:
        if f.read(len(MAGIC)) != MAGIC:
            raise McapError(f"{src} is not an MCAP file (bad magic)")
        out_file = create_file(dst, overwrite)  # before any work: an existing output is refused at once
        pos = len(MAGIC)
        header: Header | None = None
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        out_schema: dict[int, int] = {}
        out_channel: dict[int, int] = {}
        writer: Writer | None = None

        def ensure_writer() -> Writer:
            nonlocal writer
            if writer is None:
                writer = Writer(out_file, compression=_COMPRESSION[compression])
                writer.start(
                    profile=header.profile if header else PROFILE,
                    library=header.library if header else _default_library(),
                )
            return writer

        def channel_for(old_id: int) -> int | None:
            if old_id in out_channel:
                return out_channel[old_id]
            channel = channels.get(old_id)
            if channel is None:
                return None
            w = ensure_writer()
            schema_id = 0
            if channel.schema_id:
                schema = schemas.get(channel.schema_id)
                if schema is None:
                    return None
                if schema.id not in out_schema:
                    out_schema[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
                    report["schemas"] += 1
                schema_id = out_schema[schema.id]
            out_channel[old_id] = w.register_channel(
                channel.topic, channel.message_encoding, schema_id, dict(channel.metadata)
            )
            report["channels"] += 1
            return out_channel[old_id]

        def handle(record: Any) -> None:
            if isinstance(record, Schema):
                schemas.setdefault(record.id, record)
            elif isinstance(record, Channel):
                channels.setdefault(record.id, record)
            elif isinstance(record, Message):
                cid = channel_for(record.channel_id)
                if cid is not None:
                    ensure_writer().add_message(
                        cid, record.log_time, record.data, record.publish_time, record.sequence
                    )
                    report["messages"] += 1

        try:
            while True:
                head = f.read(_RECORD_HEADER.size)
                if len(head) < _RECORD_HEADER.size:
                    break
                opcode, length = _RECORD_HEADER.unpack(head)
                if pos + _RECORD_HEADER.size + length > size:
                    break  # the record was being written when the process died
                body = f.read(length)
                pos += _RECORD_HEADER.size + length
                if opcode == Opcode.HEADER:
                    header = _read_body(body, Header.read)
                elif opcode == Opcode.SCHEMA:
                    handle(_read_body(body, Schema.read))
                elif opcode == Opcode.CHANNEL:
                    handle(_read_body(body, Channel.read))
                elif opcode == Opcode.MESSAGE:
                    handle(_read_body(body, Message.read, length))
                elif opcode == Opcode.CHUNK:
                    try:
                        chunk = _read_body(body, Chunk.read)
                        inner = breakup_chunk(chunk, validate_crc=True)
                    except Exception:  # corrupt chunk: skip it, keep going
                        report["bad_chunks"] += 1
                        continue
                    report["chunks"] += 1
                    for record in inner:
                        handle(record)
                elif opcode == Opcode.METADATA:
                    meta = _read_body(body, Metadata.read)
                    ensure_writer().add_metadata(meta.name, dict(meta.metadata))
                    report["metadata"] += 1
                elif opcode == Opcode.ATTACHMENT:
                    att = _read_body(body, Attachment.read)
                    ensure_writer().add_attachment(att.create_time, att.log_time, att.name, att.media_type, att.data)
                    report["attachments"] += 1
                elif opcode in (Opcode.DATA_END, Opcode.FOOTER):
                    report["complete"] = True
                    break
                # message indexes and summary records are rebuilt by the writer
            report["truncated_bytes"] = 0 if report["complete"] else size - pos
            w = ensure_writer()
            # channels that were declared but never received a message still belong in the file
            for old_id in sorted(channels):
                channel_for(old_id)
            w.finish()
        finally:
            out_file.close()
    return report


__all__ = ["McapLog", "PROFILE", "create_file", "log_file_name", "recover"]
