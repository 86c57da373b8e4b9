from __future__ import annotations

from functools import cached_property
from typing import Any

from lerobot.robots.robot import Robot

from clients.learn.dataset import FEATURES
from clients.learn.stream import PolicyStream
from clients.robot import Robot as DarwinClient
from lerobot_robot_darwin.config_darwin import DarwinConfig
from schemas.joints import JOINT_NAMES

STATE_NAMES: list[str] = FEATURES["observation.state"]["names"]


class Darwin(Robot):
    config_class = DarwinConfig
    name = "darwin"

    def __init__(self, config: DarwinConfig) -> None:
        super().__init__(config)
        self.config = config
        self.client: DarwinClient | None = None
        self.stream: PolicyStream | None = None
        self._tick = -1

    @cached_property
    def observation_features(self) -> dict[str, type]:
        return dict.fromkeys(STATE_NAMES, float)

    @cached_property
    def action_features(self) -> dict[str, type]:
        return {f"{j}.pos": float for j in JOINT_NAMES}

    @property
    def is_connected(self) -> bool:
        return self.stream is not None

    @property
    def is_calibrated(self) -> bool:
        return True  # calibration (offsets) lives in the daemon's config

    def calibrate(self) -> None:
        pass

    def configure(self) -> None:
        pass

    def connect(self, calibrate: bool = True) -> None:
        self.client = DarwinClient(self.config.endpoint, self.config.robot, name="lerobot")
        self.client.acquire()
        self.stream = PolicyStream(self.client).start(rate_hz=self.config.rate_hz)

    def get_observation(self) -> dict[str, Any]:
        assert self.stream is not None, "connect() first"
        obs = self.stream.next_observation(self._tick)
        if obs is None:
            raise TimeoutError("no observation from the darwin daemon")
        self._tick = obs.tick
        return dict(zip(STATE_NAMES, obs.vector(), strict=True))

    def send_action(self, action: dict[str, Any]) -> dict[str, Any]:
        assert self.stream is not None, "connect() first"
        values = [float(action[f"{j}.pos"]) for j in JOINT_NAMES]
        applied = self.stream.send(values, max(self._tick, 0), wait=True)
        if applied is None or applied.refused:
            why = applied.refused if applied else "no answer from the daemon"
            raise RuntimeError(f"darwin refused the action: {why}")
        return {f"{j}.pos": a for j, a in zip(JOINT_NAMES, applied.action, strict=True)}

    def disconnect(self) -> None:
        if self.stream is not None:
            self.stream.stop()
            self.stream.close()
            self.stream = None
        if self.client is not None:
            self.client.release()
            self.client.close()
            self.client = None
