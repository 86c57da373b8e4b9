"""Message text never becomes a program argument of the sound player."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from robot_daemon.motion.sound import SoundPlayer

# A stand-in player that records its argv and stdin (a real subprocess).
RECORDER = (
    "import json, sys; "
    "json.dump({'argv': sys.argv[1:], 'stdin': sys.stdin.read()}, open(sys.argv[1], 'w'))"
)


def _emit(*_a: object, **_k: object) -> None:
    pass


def test_a_phrase_goes_on_stdin_never_into_argv(tmp_path: Path) -> None:
    import json

    out = tmp_path / "call.json"
    player = SoundPlayer(
        {"backend": "command", "say_command": [sys.executable, "-c", RECORDER, str(out), "{lang}"]}
    )
    evil = "-w/tmp/owned --stdout"
    player.play(_emit, say=evil, lang="en")
    assert player._proc is not None and player._proc.wait(timeout=30) == 0  # it has finished
    player.close()
    call = json.loads(out.read_text())
    assert call["stdin"] == evil
    assert call["argv"] == [str(out), "en"]


def test_a_say_command_with_text_in_its_arguments_is_refused() -> None:
    with pytest.raises(ValueError, match="stdin"):
        SoundPlayer({"backend": "command", "say_command": ["espeak-ng", "{text}"]})


@pytest.mark.parametrize("name", ["-w/tmp/x", "--help", "../../etc/passwd"])
def test_file_names_cannot_be_options_or_leave_the_sounds_dir(tmp_path: Path, name: str) -> None:
    (tmp_path / "ok.wav").write_bytes(b"RIFF")
    player = SoundPlayer(
        {"backend": "command", "play_command": [sys.executable, "-c", "pass", "{file}"],
         "sounds_dir": str(tmp_path)}
    )
    with pytest.raises(ValueError):
        player.play(_emit, file=name)
    assert player.play(_emit, file="ok.wav")["played"] == sys.executable
    player.close()
