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
    one per thread that packs."""

    def __init__(self, cls: type[Message], fixed: Mapping[str, Any]) -> None:
        packer = msgpack.Packer(use_bin_type=True)
        names = (*(f.name for f in dataclasses.fields(cls)), "v", "type")
        fixed = {**fixed, "v": SCHEMA_VERSION, "type": cls.TYPE}
        chunks = [bytearray(packer.pack_map_header(len(names)))]
        fields: list[str] = []
        for name in names:
            chunks[-1] += packer.pack(name)
            if name in fixed:
                chunks[-1] += packer.pack(fixed[name])
            else:
                fields.append(name)
                chunks.append(bytearray())
        self.fields = tuple(fields)
        self._chunks = [bytes(c) for c in chunks]
        self._pack = msgpack.Packer(use_bin_type=True).pack

    def pack(self, values: list[Any]) -> bytes:
        chunks, pack = self._chunks, self._pack
        out = [chunks[0]]
        for value, chunk in zip(values, chunks[1:], strict=True):
            out.append(pack(value))
            out.append(chunk)
        return b"".join(out)
