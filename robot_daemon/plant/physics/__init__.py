"""The MuJoCo plant under the emulator (`--physics mujoco`): the model, the world, the camera;
and its public face for code that steps it without an emulator (:class:`DirectPlant`: the
learning backend, clients/learn/fast.py). Imported lazily: the model generator needs no MuJoCo."""

from __future__ import annotations

from typing import Any

__all__ = ["DirectPlant", "PhysicsSettings"]


def __getattr__(name: str) -> Any:
    if name == "DirectPlant":
        from robot_daemon.plant.physics.direct_plant import DirectPlant

        return DirectPlant
    if name == "PhysicsSettings":
        from robot_daemon.plant.physics.mjcf_model import PhysicsSettings

        return PhysicsSettings
    raise AttributeError(name)
