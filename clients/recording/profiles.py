"""The recording profiles by name: ``darwin`` (:mod:`clients.recording.profile`) and ``ros2``
(:mod:`clients.recording.ros2_profile`, which builds on it). A new profile is one more entry."""

from __future__ import annotations

from clients.recording.profile import DARWIN, Profile
from clients.recording.ros2_profile import ROS2

PROFILES: dict[str, Profile] = {DARWIN.name: DARWIN, ROS2.name: ROS2}


def get_profile(name: str | Profile) -> Profile:
    if not isinstance(name, str):
        return name
    try:
        return PROFILES[name]
    except KeyError:
        raise ValueError(
            f"unknown recording profile {name!r}; choose among {', '.join(PROFILES)}"
        ) from None
