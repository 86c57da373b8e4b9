"""The project's messages as Foxglove messages: plottable JSON maps and Foxglove schemas."""

from __future__ import annotations

import math
from typing import Any

from foxglove.messages import (
    CircleAnnotation,
    Color,
    CompressedImage,
    FrameTransform,
    FrameTransforms,
    ImageAnnotations,
    Log,
    LogLevel,
    Point2,
    Quaternion,
    TextAnnotation,
    Timestamp,
    Vector3,
)

from schemas.kinematics import quaternion
from schemas.messages import BallDetection, CameraFrame, Event, Joints, Message, Status

# Event kinds that mean something went wrong (the rest are informational).
WARNING_KINDS = frozenset({"fall", "servo_alarm", "warning", "port", "halt"})
ERROR_KINDS = frozenset({"fault"})
BALL_COLOUR = Color(r=1.0, g=0.1, b=0.1, a=1.0)


def nanos(stamp: float) -> int:
    return int(stamp * 1e9)


def stamp_of(stamp: float) -> Timestamp:
    return Timestamp.from_epoch_secs(stamp)


def plain(msg: Message) -> dict[str, Any]:
    """The message's fields as a JSON map (without the wire's ``v``/``type``)."""
    d = msg.to_dict()
    d.pop("v", None)
    d.pop("type", None)
    return d


def joints_json(msg: Joints) -> dict[str, Any]:
    """Every column as sent, plus ``by_name.<joint>.<field>`` for readable plot paths."""
    d = plain(msg)
    columns = [c for c in Joints.COLUMNS if c != "name"]
    d["by_name"] = {
        name: {c: d[c][i] for c in columns if i < len(d[c])} for i, name in enumerate(msg.name)
    }
    return d


def loop_json(msg: Status) -> dict[str, Any]:
    return {"stamp": msg.stamp, **(msg.loop or {})}


def transforms(frames: list[tuple[str, str, Any]], stamp: float) -> FrameTransforms:
    ts = stamp_of(stamp)
    out = []
    for parent, child, pose in frames:
        x, y, z, w = quaternion(pose)
        t = pose[:3, 3]
        out.append(
            FrameTransform(
                timestamp=ts,
                parent_frame_id=parent,
                child_frame_id=child,
                translation=Vector3(x=float(t[0]), y=float(t[1]), z=float(t[2])),
                rotation=Quaternion(x=float(x), y=float(y), z=float(z), w=float(w)),
            )
        )
    return FrameTransforms(transforms=out)


def log_entry(event: Event) -> Log:
    if event.kind in ERROR_KINDS:
        level = LogLevel.Error
    elif event.kind in WARNING_KINDS:
        level = LogLevel.Warning
    else:
        level = LogLevel.Info
    return Log(timestamp=stamp_of(event.stamp), level=level, message=event.message, name=event.kind)


def image(frame: CameraFrame) -> CompressedImage:
    return CompressedImage(
        timestamp=stamp_of(frame.stamp), frame_id="camera", data=bytes(frame.jpeg), format="jpeg"
    )


def ball_annotations(det: BallDetection) -> ImageAnnotations:
    """A circle round the detected ball (its area as a disc) and the ball play phase; empty
    when no ball is seen, so the overlay clears."""
    ts = stamp_of(det.stamp)
    if not det.found:
        texts = []
        if det.phase:
            texts = [_label(ts, det, 8.0, 16.0)]
        return ImageAnnotations(timestamp=ts, circles=[], texts=texts)
    diameter = 2.0 * math.sqrt(max(det.size, 0.0) * det.width * det.height / math.pi)
    circle = CircleAnnotation(
        timestamp=ts,
        position=Point2(x=float(det.x), y=float(det.y)),
        diameter=max(diameter, 4.0),
        thickness=2.0,
        outline_color=BALL_COLOUR,
        fill_color=Color(r=0.0, g=0.0, b=0.0, a=0.0),
    )
    texts = [_label(ts, det, float(det.x) + diameter / 2 + 4, float(det.y))]
    return ImageAnnotations(timestamp=ts, circles=[circle], texts=texts)


def _label(ts: Timestamp, det: BallDetection, x: float, y: float) -> TextAnnotation:
    text = "ball" + (f" ({det.phase})" if det.phase else "")
    return TextAnnotation(
        timestamp=ts,
        position=Point2(x=x, y=y),
        text=text,
        font_size=14.0,
        text_color=BALL_COLOUR,
        background_color=Color(r=0.0, g=0.0, b=0.0, a=0.5),
    )
