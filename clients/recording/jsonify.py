"""msgpack messages → JSON that Foxglove, PlotJuggler and plain Python read, with JSON Schemas
derived from the message dataclasses in :mod:`schemas.messages` (so they never drift).

Bytes become base64 strings (``contentEncoding: base64``). Camera frames are written as
``foxglove.CompressedImage`` so Foxglove shows them as images.
"""

from __future__ import annotations

import base64
import dataclasses
import json
import math
import types
import typing
from typing import Any

from schemas.messages import CameraFrame, Message

CAMERA_SCHEMA_NAME = "foxglove.CompressedImage"

_CAMERA_SCHEMA: dict[str, Any] = {
    "title": CAMERA_SCHEMA_NAME,
    "description": "A compressed image (JPEG) from the robot's camera",
    "type": "object",
    "properties": {
        "timestamp": {
            "type": "object",
            "title": "time",
            "properties": {
                "sec": {"type": "integer", "minimum": 0},
                "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999},
            },
        },
        "frame_id": {"type": "string"},
        "data": {"type": "string", "contentEncoding": "base64"},
        "format": {"type": "string"},
    },
}


def _type_schema(tp: Any) -> dict[str, Any]:
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        options = [_type_schema(a) for a in args if a is not type(None)]
        schema = options[0] if len(options) == 1 else {"anyOf": options}
        if type(None) in args:
            return {"anyOf": [schema, {"type": "null"}]}
        return schema
    if origin is list:
        return {"type": "array", "items": _type_schema(args[0]) if args else {}}
    if typing.is_typeddict(tp):  # the typed status sub-maps (schemas.messages)
        hints = typing.get_type_hints(tp)
        return {"type": "object", "properties": {k: _type_schema(v) for k, v in hints.items()}}
    if origin is dict or tp is dict:
        return {"type": "object"}
    if tp is bool:
        return {"type": "boolean"}
    if tp is int:
        return {"type": "integer"}
    if tp is float:
        return {"type": "number"}
    if tp is str:
        return {"type": "string"}
    if tp is bytes:
        return {"type": "string", "contentEncoding": "base64"}
    return {}


def json_schema(cls: type[Message]) -> dict[str, Any]:
    """The JSON Schema of one message type (``camera_frame`` gets foxglove.CompressedImage)."""
    if cls is CameraFrame:
        return _CAMERA_SCHEMA
    hints = typing.get_type_hints(cls)
    props = {f.name: _type_schema(hints[f.name]) for f in dataclasses.fields(cls)}
    props["v"] = {"type": "integer", "description": "schema version"}
    props["type"] = {"type": "string", "const": cls.TYPE}
    return {
        "title": f"darwin.{cls.TYPE}",
        "description": (cls.__doc__ or "").strip().splitlines()[0] if cls.__doc__ else "",
        "type": "object",
        "properties": props,
    }


def schema_name(cls: type[Message]) -> str:
    return CAMERA_SCHEMA_NAME if cls is CameraFrame else f"darwin.{cls.TYPE}"


def _plain(value: Any) -> Any:
    if isinstance(value, bytes | bytearray | memoryview):
        return base64.b64encode(bytes(value)).decode("ascii")
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        # JSON has no NaN/inf; null keeps the sample visible instead of breaking the file.
        return None
    return value


def to_json(d: dict[str, Any], cls: type[Message]) -> bytes:
    """One decoded msgpack map as the JSON bytes of its channel."""
    if cls is CameraFrame:
        stamp = float(d.get("stamp", 0.0))
        sec = int(stamp)
        d = {
            "timestamp": {"sec": sec, "nsec": min(int(round((stamp - sec) * 1e9)), 999_999_999)},
            "frame_id": "camera",
            "data": d.get("jpeg", b""),
            "format": "jpeg",
        }
    return json.dumps(_plain(d), separators=(",", ":"), allow_nan=False).encode()
