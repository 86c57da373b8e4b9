"""Recording the robot's publications to MCAP (or the original's plain-text log) and replaying
them on the key space. See docs/recording.md.

    >>> from clients.recording import Recorder, read_recording
    >>> with Recorder(robot, "walk.mcap"):
    ...     robot.walk(x=0.05)
    >>> recover("killed.mcap").lines()      # a killed recorder's file → killed.recovered.mcap
"""

from clients.recording.control import ReplayControl
from clients.recording.reader import RecordedMessage, Recording, read_recording, read_session
from clients.recording.recorder import Recorder, RecorderStats
from clients.recording.recover import RecoverError, Recovery, recover
from clients.recording.replay import Replayer

__all__ = [
    "RecordedMessage",
    "Recorder",
    "RecorderStats",
    "Recording",
    "RecoverError",
    "Recovery",
    "ReplayControl",
    "Replayer",
    "read_recording",
    "read_session",
    "recover",
]
