"""The MCAP file a recording (or one segment of it) writes.

Layout (one file per recording, or per segment with splitting):

* a metadata record ``darwin`` — robot, session start, topics, layout version, profile, and for
  a segment its number and the session it belongs to;
* per topic, the channels its profile names (:mod:`clients.recording.profile`). The default
  ``darwin`` profile writes a **JSON channel** ``/darwin/<robot>/<topic key>`` with a JSON Schema
  derived from the message dataclass (camera: ``foxglove.CompressedImage``) — what Foxglove,
  PlotJuggler and ``mcap`` readers show — and a **msgpack channel**
  ``/darwin/<robot>/<topic key>/msgpack`` (no schema, message encoding ``msgpack``) holding the
  publisher's bytes unchanged — what ``darwin replay`` sends, so a replayed session decodes
  exactly as the live one did, and undecodable payloads are kept. A recording of several robots
  has these channels per robot (each channel's ``robot`` metadata says whose).

Both channels carry ``darwin_topic`` (``joints``, ``imu``…) and ``kind`` (``json`` | ``msgpack``)
in their channel metadata. ``log_time`` is the receive time, ``publish_time`` the message's own
``stamp``. The open chunk is closed, written and fsynced on every ``flush()`` (the recorder's
flush interval) and whenever it reaches ``chunk_bytes``: a killed recorder loses at most that
tail, and ``darwin record recover`` makes the rest a complete file.
"""

from __future__ import annotations

import json
import os
import time
from datetime import UTC, datetime
from typing import IO

from mcap.writer import CompressionType, Writer

from clients.recording.profile import (
    DARWIN,
    LAYOUT_VERSION,
    RAW_ENCODING,
    ChannelSpec,
    Profile,
    json_topic,
    raw_topic,
)
from clients.recording.segments import Sample
from schemas.keys import Keys

LIBRARY = "darwin-zenoh recorder"
CHUNK_BYTES = 256 * 1024  # uncompressed; a chunk also closes at every flush

__all__ = ["CHUNK_BYTES", "RAW_ENCODING", "McapSink", "json_topic", "raw_topic"]


class McapSink:
    def __init__(
        self,
        path: str,
        robot: str,
        topics: dict[str, str],
        *,
        profile: Profile = DARWIN,
        chunk_bytes: int = CHUNK_BYTES,
        metadata: dict[str, str] | None = None,
    ) -> None:
        # Written as PATH.part until the header and metadata are on disk, then renamed (the open
        # file follows): a kill never leaves a file at PATH too short to recover.
        part = f"{path}.part"
        self._file: IO[bytes] = open(part, "wb")  # noqa: SIM115 — closed in close()
        self._writer = Writer(self._file, compression=CompressionType.ZSTD, chunk_size=chunk_bytes)
        self._writer.start(profile=profile.mcap_profile, library=LIBRARY)
        self._profile = profile
        self._robot = robot
        self._keys = topics
        self._specs: dict[tuple[str, str | None], tuple[ChannelSpec, ...]] = {}
        self._schemas: dict[str, int] = {}
        # one MCAP channel per (topic, encoding): two sources may feed one ROS topic (tf)
        self._channels: dict[tuple[str, str], int] = {}
        self._seq: dict[int, int] = {}
        self._writer.add_metadata(
            "darwin",
            {
                "robot": robot,
                "started": datetime.now(UTC).isoformat(),
                "topics": json.dumps(topics),
                "layout": LAYOUT_VERSION,
                "profile": profile.name,
                **(metadata or {}),
            },
        )
        for spec, data in profile.latched():
            now = time.time_ns()
            self._writer.add_message(self._channel(spec), now, data, now, 0)
        self.flush()
        os.replace(part, path)

    @property
    def size(self) -> int:
        """Bytes on disk so far (the open chunk is not counted until it is written)."""
        return self._file.tell()

    def _channel(self, spec: ChannelSpec) -> int:
        cid = self._channels.get((spec.topic, spec.message_encoding))
        if cid is None:
            sid = 0
            if spec.schema is not None:
                sid = self._schemas.get(spec.schema.name, 0)
                if not sid:
                    s = spec.schema
                    sid = self._writer.register_schema(s.name, s.encoding, s.data)
                    self._schemas[s.name] = sid
            cid = self._writer.register_channel(
                spec.topic, spec.message_encoding, sid, spec.metadata
            )
            self._channels[(spec.topic, spec.message_encoding)] = cid
        return cid

    def write(self, sample: Sample) -> None:
        topic, log_ns, payload, decoded, robot = sample
        specs = self._specs.get((topic, robot))
        if specs is None:
            # Several robots in one file: each robot's topic is a channel set of its own,
            # named by its key (``/darwin/op2/joints``) and carrying its robot in metadata.
            key = self._keys[topic] if robot is None else self._profile.key(Keys(robot), topic)
            specs = self._specs[(topic, robot)] = self._profile.channels(
                topic, key, robot or self._robot
            )
        pub_ns = self._profile.publish_ns(decoded, log_ns)
        for spec in specs:
            data = spec.encode(payload, decoded)
            if data is None:
                continue
            cid = self._channel(spec)
            seq = self._seq.get(cid, 0)
            self._seq[cid] = seq + 1
            self._writer.add_message(cid, log_ns, data, pub_ns, seq)

    def flush(self) -> None:
        self._writer.flush()
        # fsync: what was flushed survives a power cut too, not only a killed process.
        os.fsync(self._file.fileno())

    def close(self) -> None:
        try:
            self._writer.finish()
            self._file.flush()
            os.fsync(self._file.fileno())
        finally:
            self._file.close()
