"""Settings of the simulated world: the ``[world]`` config section (config/world.toml)."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from dataclasses import field as dc_field
from typing import Any

from config.loader import load_all, refuse_unknown, section_to
from robot_daemon.plant.camera_model import CameraModel, FieldGeometry
from schemas.errors import ConfigError


@dataclass(frozen=True)
class BallSettings:
    """``[world.ball]``: the ball's size, colour and how it rolls and bounces."""

    radius: float = 0.035
    color: tuple[int, int, int] = (210, 28, 28)  # RGB
    rolling_decel: float = 0.5  # m/s²
    restitution: float = 0.6
    rest_speed: float = 0.01  # m/s


@dataclass(frozen=True)
class FeetSettings:
    """``[world.feet]``: the size of a foot (m): what touches the ball and the ground."""

    length: float = 0.104
    width: float = 0.066
    height: float = 0.03


@dataclass(frozen=True)
class FallSettings:
    """``[world.falls]``: when the kinematic body falls, and its stand and crouch heights."""

    tilt_limit: float = math.radians(40.0)
    com_margin: float = 0.012
    com_outside_s: float = 0.35
    com_offset: tuple[float, float, float] = (-0.005, 0.0, -0.045)
    crouch_height: float = 0.195
    stand_height: float = 0.23
    stand_tilt: float = math.radians(20.0)
    push_fall_impulse: float = 0.5  # N·s: a push this strong tips the kinematic body over


@dataclass(frozen=True)
class ImuSettings:
    """``[world.imu]``: how late the simulated gyro follows the body."""

    gyro_lag_s: float = 0.05


@dataclass(frozen=True)
class RenderSettings:
    """``[world.camera]``: the simulated camera's lens, noise, lighting, blur and rate."""

    camera: CameraModel = dc_field(default_factory=CameraModel)
    noise: float = 3.0
    light_variation: float = 0.12
    blur: bool = True
    fps: float = 30.0


@dataclass(frozen=True)
class _WorldTable:
    """The top of ``[world]`` as written (yaw in degrees); its sub-tables are read one by one."""

    robot_start: tuple[float, float, float] = (-1.0, 0.0, 0.0)
    ball_start: tuple[float, ...] = (-0.4, 0.0)  # [] for no ball
    publish_hz: float = 20.0


_READ_HERE = ("field", "ball", "feet", "falls", "camera", "imu")
_CAMERA_MODEL = [f.name for f in fields(CameraModel)]


@dataclass(frozen=True)
class WorldSettings:
    """The ``[world]`` section: where the robot and the ball start, the field and each part's
    settings."""

    robot_start: tuple[float, float, float] = (-1.0, 0.0, 0.0)  # x, y, yaw (rad)
    ball_start: tuple[float, float] | None = (-0.4, 0.0)
    publish_hz: float = 20.0
    field: FieldGeometry = dc_field(default_factory=FieldGeometry)
    ball: BallSettings = dc_field(default_factory=BallSettings)
    feet: FeetSettings = dc_field(default_factory=FeetSettings)
    falls: FallSettings = dc_field(default_factory=FallSettings)
    render: RenderSettings = dc_field(default_factory=RenderSettings)
    imu: ImuSettings = dc_field(default_factory=ImuSettings)

    @classmethod
    def from_config(cls, world: dict[str, Any]) -> WorldSettings:
        """From the ``[world]`` table: angles there are in degrees (``robot_start``'s yaw,
        ``*_deg``), and ``[world.camera]`` holds both the camera model and the rendering."""
        start = section_to(_WorldTable, world, "world", skip=_READ_HERE)
        if len(start.ball_start) not in (0, 2):
            wrong = list(start.ball_start)
            raise ConfigError(f"[world] ball_start = {wrong} should be [x, y] or [] (no ball)")
        falls = dict(world.get("falls", {}))
        for deg in ("tilt_limit", "stand_tilt"):
            if f"{deg}_deg" in falls:
                falls[deg] = math.radians(falls.pop(f"{deg}_deg"))
        camera = dict(world.get("camera", {}))
        rendering = [f.name for f in fields(RenderSettings) if f.name != "camera"]
        refuse_unknown(camera, [*_CAMERA_MODEL, *rendering], "world.camera")
        model = {k: camera.pop(k) for k in _CAMERA_MODEL if k in camera}
        x, y, yaw_deg = start.robot_start
        return cls(
            robot_start=(x, y, math.radians(yaw_deg)),
            ball_start=(start.ball_start[0], start.ball_start[1]) if start.ball_start else None,
            publish_hz=start.publish_hz,
            field=FieldGeometry.from_config(world.get("field", {})),
            ball=section_to(BallSettings, world.get("ball", {}), "world.ball"),
            feet=section_to(FeetSettings, world.get("feet", {}), "world.feet"),
            falls=section_to(FallSettings, falls, "world.falls"),
            render=section_to(
                RenderSettings,
                camera,
                "world.camera",
                camera=section_to(CameraModel, model, "world.camera"),
            ),
            imu=section_to(ImuSettings, world.get("imu", {}), "world.imu"),
        )

    @classmethod
    def load(cls, path: str | None = None) -> WorldSettings:
        return cls.from_config(load_all(path).get("world", {}))
