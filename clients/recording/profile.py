"""What a recording subscribes to and how each sample becomes MCAP messages: a **profile**.

The recorder and the MCAP sink know nothing of message types: a profile tells them which key
expression to subscribe for each topic, how to decode a sample (for counts and the text log),
and which channels (topic, message encoding, schema name/encoding/data, metadata, encoder) each
sample is written to. ``darwin`` (the default) writes a JSON channel with a JSON Schema and the
raw msgpack channel per topic; ``ros2`` (:mod:`clients.recording.ros2_profile`) a ROS 2 bag
(``cdr`` messages, ``ros2msg`` schemas, MCAP header profile ``ros2``). Another plugs in by adding
a :class:`Profile` to :data:`clients.recording.profiles.PROFILES`; nothing else changes.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, Protocol

from clients.recording.jsonify import json_schema, schema_name, to_json
from clients.robot import TOPICS
from schemas.errors import ProtocolError
from schemas.keys import Keys
from schemas.messages import decode_dict

RAW_ENCODING = "msgpack"
LAYOUT_VERSION = "1"

# (payload, decoded or None) → the channel's message bytes, or None to write nothing
Encoder = Callable[[bytes, dict[str, Any] | None], bytes | None]


@dataclass(frozen=True)
class SchemaSpec:
    """An MCAP schema: its name, encoding and data."""

    name: str
    encoding: str  # "jsonschema", "ros2msg", …
    data: bytes


@dataclass(frozen=True)
class ChannelSpec:
    """An MCAP channel a topic's samples are written to, and how each is encoded."""

    topic: str  # the MCAP channel topic
    message_encoding: str  # "json", "msgpack", "cdr", …
    schema: SchemaSpec | None
    encode: Encoder
    metadata: dict[str, str] = field(default_factory=dict)


class Profile(Protocol):
    name: str  # what `--profile` takes
    mcap_profile: str  # the MCAP header's profile field ("" or "ros2")
    topics: tuple[str, ...]  # every topic it can record
    default_topics: tuple[str, ...]

    def key(self, keys: Keys, topic: str) -> str:
        """The key expression to subscribe for ``topic``."""
        ...

    def decode(self, topic: str, payload: bytes) -> dict[str, Any] | None:
        """The sample as a dict, or None when it does not decode (counted as undecodable)."""
        ...

    def channels(self, topic: str, key: str, robot: str) -> tuple[ChannelSpec, ...]:
        """The MCAP channels a sample of ``topic`` is written to, in order."""
        ...

    def publish_ns(self, decoded: dict[str, Any] | None, log_ns: int) -> int:
        """The message's own time (MCAP ``publish_time``)."""
        ...

    def bind(self, session: Any, keys: Keys) -> Profile:
        """The instance one recording uses (it may ask the daemon, keep per-recording state)."""
        ...

    def latched(self) -> tuple[tuple[ChannelSpec, bytes], ...]:
        """Messages written at the start of every file (segment): latched topics."""
        ...


def json_topic(key: str) -> str:
    return f"/{key}"


def raw_topic(key: str) -> str:
    return f"/{key}/{RAW_ENCODING}"


class DarwinProfile:
    """The project's own messages: a JSON channel (JSON Schema) and the publisher's msgpack bytes
    unchanged (what ``darwin replay`` sends) per topic."""

    name = "darwin"
    mcap_profile = ""

    def __init__(self) -> None:
        self._types = TOPICS  # the one topic → message type table
        self.topics = tuple(TOPICS)
        self.default_topics = tuple(Keys().topics())

    def key(self, keys: Keys, topic: str) -> str:
        return keys.topics()[topic]

    def decode(self, topic: str, payload: bytes) -> dict[str, Any] | None:
        try:
            decoded = decode_dict(payload)
        except ProtocolError:
            return None
        return decoded if decoded.get("type") == self._types[topic].TYPE else None

    def channels(self, topic: str, key: str, robot: str) -> tuple[ChannelSpec, ...]:
        cls = self._types[topic]
        meta = {"darwin_topic": topic, "robot": robot, "key": key}
        schema = SchemaSpec(schema_name(cls), "jsonschema", json.dumps(json_schema(cls)).encode())

        def as_json(payload: bytes, decoded: dict[str, Any] | None) -> bytes | None:
            return None if decoded is None else to_json(decoded, cls)

        return (
            ChannelSpec(json_topic(key), "json", schema, as_json, {**meta, "kind": "json"}),
            ChannelSpec(
                raw_topic(key),
                RAW_ENCODING,
                None,
                lambda payload, decoded: payload,
                {**meta, "kind": RAW_ENCODING},
            ),
        )

    def publish_ns(self, decoded: dict[str, Any] | None, log_ns: int) -> int:
        stamp = decoded.get("stamp") if decoded is not None else None
        return int(stamp * 1e9) if isinstance(stamp, int | float) else log_ns

    def bind(self, session: Any, keys: Keys) -> DarwinProfile:
        return self

    def latched(self) -> tuple[tuple[ChannelSpec, bytes], ...]:
        return ()


DARWIN = DarwinProfile()


def check_topics(topics: Iterable[str] | None, profile: Profile = DARWIN) -> list[str]:
    chosen = list(profile.default_topics if topics is None else topics)
    unknown = [t for t in chosen if t not in profile.topics]
    if unknown or not chosen:
        raise ValueError(
            f"cannot record topic(s) {', '.join(map(repr, unknown)) or 'none'}; "
            f"choose among {', '.join(profile.topics)}"
        )
    return list(dict.fromkeys(chosen))
