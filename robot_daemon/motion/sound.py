"""Sounds and phrases. Where the robot has a speaker, a configured player runs in a
subprocess (``aplay``/``mpg123`` for files, ``espeak-ng`` for text) so the motion loop never
waits; in the simulator (``backend = "event"``) the sound is published as an event instead.

Text from a message never becomes a program argument: a phrase is written to the player's stdin
(``espeak-ng --stdin``), and a file name must name a file (inside ``sounds_dir`` when one is set),
is passed as an absolute path and may not start with ``-``."""

from __future__ import annotations

import logging
import shutil
import subprocess
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from config.loader import section_to

log = logging.getLogger(__name__)

Emit = Callable[..., None]


@dataclass(frozen=True)
class SoundSettings:
    """``[sound]`` (config/motion.toml)."""

    backend: str = "event"
    play_command: list[str] = field(default_factory=lambda: ["aplay", "-q", "{file}"])
    say_command: list[str] = field(default_factory=lambda: ["espeak-ng", "-v", "{lang}", "--stdin"])
    language: str = "en"
    sounds_dir: str = ""


class SoundPlayer:
    def __init__(self, section: dict[str, Any] | None = None) -> None:
        s = section_to(SoundSettings, section or {}, "sound")
        self.backend = s.backend
        if self.backend not in ("event", "command"):
            raise ValueError(f"[sound] backend must be 'event' or 'command', not {self.backend!r}")
        self.play_command = list(s.play_command)
        self.say_command = list(s.say_command)
        if any("{text}" in str(a) for a in self.say_command):
            raise ValueError(
                "[sound] say_command must not contain {text}: the phrase is written to the "
                'player\'s stdin, e.g. ["espeak-ng", "-v", "{lang}", "--stdin"]'
            )
        self.language = s.language
        self.sounds_dir = Path(s.sounds_dir) if s.sounds_dir else None
        self._proc: subprocess.Popen[bytes] | None = None
        self._stopped: list[subprocess.Popen[bytes]] = []  # terminated, reaped by polling
        self.last: dict[str, Any] | None = None

    def resolve(self, file: str) -> Path:
        """The sound file's absolute path; ``ValueError`` for a name that could read as an
        option or that leaves ``sounds_dir``."""
        if file.startswith("-") or "\x00" in file:
            raise ValueError(f"sound file name {file[:40]!r} may not start with '-'")
        p = Path(file)
        if self.sounds_dir is None:
            return p.resolve()
        base = self.sounds_dir.resolve()
        path = (base / p).resolve()
        if not path.is_relative_to(base):
            raise ValueError(f"sound file {file[:40]!r} is outside [sound] sounds_dir ({base})")
        return path

    def play(
        self, emit: Emit, file: str | None = None, say: str | None = None, lang: str | None = None
    ) -> dict[str, Any]:
        """Start a sound (a file) or a phrase (text); returns what was done. Never blocks."""
        if not file and not say:
            raise ValueError("a sound needs a file or a phrase (say)")
        lang = lang or self.language
        what = {"file": file, "say": say, "lang": lang, "backend": self.backend}
        self.last = what
        if self.backend == "event":
            text = f"sound {file}" if file else f"say {say!r}"
            emit("sound", text, **what)
            return {**what, "played": "event"}
        if file:
            path = self.resolve(file)
            if not path.is_file():
                raise ValueError(f"sound file {path} does not exist (check [sound] sounds_dir)")
            argv = [str(a).replace("{file}", str(path)) for a in self.play_command]
        else:
            argv = [str(a).replace("{lang}", lang) for a in self.say_command]
        if shutil.which(argv[0]) is None:
            raise ValueError(
                f"sound player {argv[0]!r} is not installed; set [sound] play_command/"
                'say_command, or backend = "event"'
            )
        self.stop()
        self._proc = subprocess.Popen(
            argv,
            stdin=subprocess.PIPE if say and not file else subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        if self._proc.stdin is not None:
            # A phrase is at most a few hundred bytes: the pipe buffer takes it without waiting.
            try:
                self._proc.stdin.write(str(say).encode("utf-8"))
                self._proc.stdin.close()
            except OSError as exc:  # the player exited at once
                log.warning("the say player took no text: %s", exc)
        emit("sound", f"playing {file or repr(say)}", **what)
        return {**what, "played": argv[0]}

    def playing(self) -> bool:
        self._stopped = [p for p in self._stopped if p.poll() is None]
        return self._proc is not None and self._proc.poll() is None

    def stop(self) -> None:
        proc, self._proc = self._proc, None
        if proc is not None and proc.poll() is None:
            proc.terminate()
            # Reaped later by poll(); never wait in the motion thread.
            self._stopped.append(proc)

    def close(self, timeout: float = 2.0) -> None:
        """Stop and reap every player (at shutdown, not from the motion loop)."""
        self.stop()
        for proc in self._stopped:
            try:
                proc.wait(timeout)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        self._stopped.clear()

    def status(self) -> dict[str, Any]:
        return {"backend": self.backend, "playing": self.playing(), "last": self.last}
