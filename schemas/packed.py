"""A message's msgpack bytes from a layout packed once: the same bytes ``encode`` gives, for the
messages the loop sends every tick.

``encode`` builds the message, turns it into a dict and has msgpack walk that: for the joints
message (12 columns of 20) the building and the dict cost more than the packing. A
:class:`Prepacked` is made once from the message's definition (``schemas.messages``: its field
order and names are the dataclass's) with what never changes (ids, names, the version and the
type, every key) packed already; per call each other field is packed by msgpack's C packer
straight from the value given (a list of floats, an int) and the pieces joined.
``tests/unit/test_packed.py`` checks the bytes equal ``encode``'s for random messages.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import msgpack

from schemas import SCHEMA_VERSION
from schemas.messages import Message


class Prepacked:
    """``pack(values)`` → the bytes of ``encode(cls(**fixed, **values))``; ``values`` in the
    order of :attr:`fields` (the message's fields that are not ``fixed``). Not thread-safe:
    one per thread that packs.

    Each run of consecutive fields given per call is packed by one C call, as a map of just
    those fields whose header is left off: a map's pairs are its keys and values packed one
    after the other, so the bytes are those of packing each key and value alone, without a
    Python step per field."""

    def __init__(self, cls: type[Message], fixed: Mapping[str, Any]) -> None:
        packer = msgpack.Packer(use_bin_type=True)
        names = (*(f.name for f in dataclasses.fields(cls)), "v", "type")
        fixed = {**fixed, "v": SCHEMA_VERSION, "type": cls.TYPE}
        chunks = [bytearray(packer.pack_map_header(len(names)))]
        runs: list[list[str]] = []
        fields: list[str] = []
        for name in names:
            if name in fixed:
                if runs and len(chunks) == len(runs):
                    chunks.append(bytearray())  # the fixed bytes after a run
                chunks[-1] += packer.pack(name)
                chunks[-1] += packer.pack(fixed[name])
            else:
                fields.append(name)
                if len(runs) < len(chunks):
                    runs.append([])  # a run starts after fixed bytes
                runs[-1].append(name)
        if len(chunks) == len(runs):
            chunks.append(bytearray())
        self.fields = tuple(fields)
        self._chunks = [bytes(c) for c in chunks]
        # (names, the length of a map header of that many, where its values start)
        self._runs = [
            (tuple(r), len(packer.pack_map_header(len(r))), fields.index(r[0])) for r in runs
        ]
        self._pack = msgpack.Packer(use_bin_type=True).pack
        # A layout of one run (joints, IMU): its fixed bytes before and after the run and the
        # run's keys packed, for a packer that writes the run's values between them itself
        # (robot_daemon/_hotpath.c's pack_fields: the same bytes, tests/unit/test_hotpath.py).
        self.single: tuple[bytes, tuple[bytes, ...], bytes] | None = None
        if len(self._runs) == 1:
            keys = tuple(packer.pack(name) for name in self._runs[0][0])
            self.single = (self._chunks[0], keys, self._chunks[1])

    def pack(self, values: list[Any]) -> bytes:
        if len(values) != len(self.fields):
            raise ValueError(f"{len(values)} values for the {len(self.fields)} fields "
                             f"{', '.join(self.fields)}")
        chunks, pack = self._chunks, self._pack
        if len(self._runs) == 1:  # joints and IMU: one C call
            names, header, _ = self._runs[0]
            body = pack(dict(zip(names, values, strict=True)))
            return b"".join((chunks[0], memoryview(body)[header:], chunks[1]))
        out: list[bytes | memoryview] = [chunks[0]]
        for (names, header, at), chunk in zip(self._runs, chunks[1:], strict=True):
            body = pack(dict(zip(names, values[at : at + len(names)], strict=True)))
            out.append(memoryview(body)[header:])
            out.append(chunk)
        return b"".join(out)
