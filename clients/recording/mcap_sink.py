"""The MCAP file a recording writes.

Layout (one file per recording):

* a metadata record ``darwin`` — robot, start time, topics, layout version;
* per topic, a **JSON channel** ``/darwin/<robot>/<topic key>`` with a JSON Schema derived from
  the message dataclass (camera: ``foxglove.CompressedImage``) — what Foxglove, PlotJuggler and
  ``mcap`` readers show;
* per topic, a **msgpack channel** ``/darwin/<robot>/<topic key>/msgpack`` (no schema, message
  encoding ``msgpack``) holding the publisher's bytes unchanged — what ``darwin replay`` sends,
  so a replayed session decodes exactly as the live one did, and undecodable payloads are kept.

Both channels carry ``darwin_topic`` (``joints``, ``imu``…) and ``kind`` (``json`` | ``msgpack``)
in their channel metadata. ``log_time`` is the receive time, ``publish_time`` the message's own
``stamp``. Chunks are closed and flushed every ``flush_interval``: a killed recorder loses at most
that much, and the rest reads back with a streaming reader (see :mod:`clients.recording.reader`).
"""

from __future__ import annotations

import json
from datetime import UTC, datetime
from typing import IO, Any

from mcap.writer import CompressionType, Writer

from clients.recording.jsonify import json_schema, schema_name, to_json
from schemas.messages import Message

LAYOUT_VERSION = "1"
LIBRARY = "darwin-zenoh recorder"
RAW_ENCODING = "msgpack"


def json_topic(key: str) -> str:
    return f"/{key}"


def raw_topic(key: str) -> str:
    return f"/{key}/{RAW_ENCODING}"


class McapSink:
    def __init__(self, path: str, robot: str, topics: dict[str, str]) -> None:
        self._file: IO[bytes] = open(path, "wb")  # noqa: SIM115 — closed in close()
        self._writer = Writer(self._file, compression=CompressionType.ZSTD, chunk_size=512 * 1024)
        self._writer.start(profile="", library=LIBRARY)
        self._robot = robot
        self._keys = topics
        self._schemas: dict[str, int] = {}
        self._channels: dict[tuple[str, str], int] = {}
        self._seq: dict[int, int] = {}
        self._writer.add_metadata(
            "darwin",
            {
                "robot": robot,
                "started": datetime.now(UTC).isoformat(),
                "topics": json.dumps(topics),
                "layout": LAYOUT_VERSION,
            },
        )
        self._writer.flush()

    def _schema_id(self, cls: type[Message]) -> int:
        name = schema_name(cls)
        if name not in self._schemas:
            data = json.dumps(json_schema(cls)).encode()
            self._schemas[name] = self._writer.register_schema(name, "jsonschema", data)
        return self._schemas[name]

    def _channel(self, topic: str, kind: str, cls: type[Message]) -> int:
        cid = self._channels.get((topic, kind))
        if cid is None:
            key = self._keys[topic]
            meta = {"darwin_topic": topic, "kind": kind, "robot": self._robot, "key": key}
            if kind == RAW_ENCODING:
                cid = self._writer.register_channel(raw_topic(key), RAW_ENCODING, 0, meta)
            else:
                cid = self._writer.register_channel(
                    json_topic(key), "json", self._schema_id(cls), meta
                )
            self._channels[(topic, kind)] = cid
        return cid

    def _add(self, cid: int, log_ns: int, pub_ns: int, data: bytes) -> None:
        seq = self._seq.get(cid, 0)
        self._seq[cid] = seq + 1
        self._writer.add_message(cid, log_ns, data, pub_ns, seq)

    def write(
        self,
        topic: str,
        cls: type[Message],
        log_ns: int,
        payload: bytes,
        decoded: dict[str, Any] | None,
    ) -> None:
        pub_ns = log_ns
        if decoded is not None:
            stamp = decoded.get("stamp")
            if isinstance(stamp, int | float):
                pub_ns = int(stamp * 1e9)
            self._add(self._channel(topic, "json", cls), log_ns, pub_ns, to_json(decoded, cls))
        self._add(self._channel(topic, RAW_ENCODING, cls), log_ns, pub_ns, payload)

    def flush(self) -> None:
        self._writer.flush()

    def close(self) -> None:
        try:
            self._writer.finish()
        finally:
            self._file.close()
