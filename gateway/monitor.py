"""Monitor messages: the robot's latest state in legacy form, and each client's view of it.

Values are converted once per published sample (shared by every client) and rounded to the
resolution the legacy client shows, so sensor noise below it does not count as a change:

- ``motors``: ``[id, position °, speed °/s, load % of max torque (signed), torque on 1/0]``;
- ``accelerometer``: m/s², robot axes x, y, z; ``gyroscope``: °/s, robot axes x, y, z;
- ``camera``: the newest JPEG frame, base64.

A :class:`MonitorView` keeps what it last sent to one client and builds the next message with
only the requested streams and only the values that changed since (an empty ``{"monitor": {}}``
when nothing did: the message still marks the period).
"""

from __future__ import annotations

import base64
import math
from dataclasses import dataclass, field
from typing import Any

from gateway.messages import STREAMS
from schemas.messages import CameraFrame, Imu, Joints

MotorTuple = tuple[int, float, float, float, int]


def _r(value: float, digits: int) -> float:
    rounded = round(float(value), digits)
    return rounded if math.isfinite(rounded) else 0.0


def motors_from_joints(joints: Joints) -> dict[int, MotorTuple]:
    out: dict[int, MotorTuple] = {}
    for i, jid in enumerate(joints.id):
        out[int(jid)] = (
            int(jid),
            _r(math.degrees(joints.position[i]), 1),
            _r(math.degrees(joints.velocity[i]), 1),
            _r(joints.load[i] * 100.0, 1),
            1 if joints.torque_enabled[i] else 0,
        )
    return out


def accelerometer_from_imu(imu: Imu) -> tuple[float, float, float]:
    x, y, z = imu.accel[:3]
    return _r(x, 2), _r(y, 2), _r(z, 2)


def gyroscope_from_imu(imu: Imu) -> tuple[float, float, float]:
    x, y, z = (math.degrees(v) for v in imu.gyro[:3])
    return _r(x, 1), _r(y, 1), _r(z, 1)


@dataclass(frozen=True)
class CameraImage:
    """A camera frame as the legacy ``monitor`` stream sends it: base64 JPEG."""

    seq: int
    base64: str
    size: int  # bytes of the base64 text


def camera_from_frame(frame: CameraFrame) -> CameraImage:
    text = base64.b64encode(frame.jpeg).decode("ascii")
    return CameraImage(frame.seq, text, len(text))


@dataclass
class Snapshot:
    """The newest legacy values of every stream (None: nothing received yet)."""

    motors: dict[int, MotorTuple] | None = None
    accelerometer: tuple[float, float, float] | None = None
    gyroscope: tuple[float, float, float] | None = None
    camera: CameraImage | None = None


@dataclass
class MonitorView:
    """One client's monitor set and what it was last sent."""

    streams: set[str] = field(default_factory=set)
    sent_motors: dict[int, MotorTuple] = field(default_factory=dict)
    sent_accel: tuple[float, float, float] | None = None
    sent_gyro: tuple[float, float, float] | None = None
    sent_camera_seq: int | None = None

    @property
    def active(self) -> bool:
        return bool(self.streams)

    def update(self, switches: dict[str, bool]) -> None:
        """Turn streams on or off. A stream turned on starts over: its next message is full."""
        for name, on in switches.items():
            if name not in STREAMS:
                raise ValueError(f"unknown monitor stream {name!r}")
            if on and name not in self.streams:
                self._forget(name)
                self.streams.add(name)
            elif not on:
                self.streams.discard(name)

    def _forget(self, name: str) -> None:
        if name == "motors":
            self.sent_motors = {}
        elif name == "accelerometer":
            self.sent_accel = None
        elif name == "gyroscope":
            self.sent_gyro = None
        elif name == "camera":
            self.sent_camera_seq = None

    def build(self, snap: Snapshot, camera: bool = True) -> dict[str, Any]:
        """The next monitor message, recording its values as sent. ``camera=False`` leaves the
        image out (and unsent) for a client whose framing cannot carry it."""
        body: dict[str, Any] = {}
        accel, gyro, frame = snap.accelerometer, snap.gyroscope, snap.camera
        if "accelerometer" in self.streams and accel is not None and accel != self.sent_accel:
            body["accelerometer"] = list(accel)
            self.sent_accel = accel
        if "gyroscope" in self.streams and gyro is not None and gyro != self.sent_gyro:
            body["gyroscope"] = list(gyro)
            self.sent_gyro = gyro
        if "motors" in self.streams and snap.motors is not None:
            changed = [m for jid, m in snap.motors.items() if self.sent_motors.get(jid) != m]
            if changed:
                body["motors"] = [{"motor": list(m)} for m in changed]
                self.sent_motors.update({m[0]: m for m in changed})
        wants_image = camera and "camera" in self.streams
        if wants_image and frame is not None and frame.seq != self.sent_camera_seq:
            body["camera"] = frame.base64
            self.sent_camera_seq = frame.seq
        return {"monitor": body}
