"""Settings of the simulated world: the ``[world]`` config section (config/world.toml)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from dataclasses import field as dc_field
from typing import Any

from config.loader import load_all
from robot_daemon.sim.world.render import CameraModel, FieldGeometry
from schemas.errors import ConfigError


@dataclass(frozen=True)
class BallSettings:
    radius: float = 0.035
    color: tuple[int, int, int] = (210, 28, 28)  # RGB
    rolling_decel: float = 0.5  # m/s²
    restitution: float = 0.6
    rest_speed: float = 0.01  # m/s


@dataclass(frozen=True)
class FeetSettings:
    length: float = 0.104
    width: float = 0.066
    height: float = 0.03


@dataclass(frozen=True)
class FallSettings:
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
    gyro_lag_s: float = 0.05


@dataclass(frozen=True)
class RenderSettings:
    camera: CameraModel = dc_field(default_factory=CameraModel)
    noise: float = 3.0
    light_variation: float = 0.12
    blur: bool = True
    fps: float = 30.0


@dataclass(frozen=True)
class WorldSettings:
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
        try:
            rx, ry, ryaw = (float(v) for v in world.get("robot_start", (-1.0, 0.0, 0.0)))
            ball_start = world.get("ball_start", (-0.4, 0.0))
            b = dict(world.get("ball", {}))
            if "color" in b:
                b["color"] = tuple(int(c) for c in b["color"])
            f = dict(world.get("falls", {}))
            falls = FallSettings(
                tilt_limit=math.radians(float(f.pop("tilt_limit_deg", 40.0))),
                stand_tilt=math.radians(float(f.pop("stand_tilt_deg", 20.0))),
                com_offset=tuple(float(v) for v in f.pop("com_offset", (-0.005, 0.0, -0.045))),
                **{k: float(v) for k, v in f.items()},
            )
            c = dict(world.get("camera", {}))
            render = RenderSettings(
                camera=CameraModel(
                    int(c.pop("width", 320)),
                    int(c.pop("height", 240)),
                    float(c.pop("fov_h_deg", 58.0)),
                    float(c.pop("fov_v_deg", 46.0)),
                ),
                blur=bool(c.pop("blur", True)),
                **{k: float(v) for k, v in c.items()},
            )
            return cls(
                robot_start=(rx, ry, math.radians(ryaw)),
                ball_start=(float(ball_start[0]), float(ball_start[1])) if ball_start else None,
                publish_hz=float(world.get("publish_hz", 20.0)),
                field=FieldGeometry.from_config(world.get("field", {})),
                ball=BallSettings(**b),
                feet=FeetSettings(**{k: float(v) for k, v in world.get("feet", {}).items()}),
                falls=falls,
                render=render,
                imu=ImuSettings(
                    gyro_lag_s=float(world.get("imu", {}).get("gyro_lag_s", 0.05)),
                ),
            )
        except (TypeError, ValueError) as exc:
            raise ConfigError(
                f"[world] in config/world.toml or the user file is wrong: {exc}"
            ) from exc

    @classmethod
    def load(cls, path: str | None = None) -> WorldSettings:
        return cls.from_config(load_all(path).get("world", {}))
