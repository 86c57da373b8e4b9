"""The DARwIn-OP's Dynamixel cabling: which servos share a daisy chain, in cable order.

The CM-730 has five TTL Dynamixel ports (ROBOTIS e-manual, DARwIn-OP references, sub
controller: "5x TTL Ports (for DYNAMIXEL)"); each limb and the neck hang from one of them, the
servos of a limb chained from the body outwards (the DARwIn-OP assembly manual's cabling:
shoulder → upper arm → elbow, hip yaw → hip roll → hip pitch → knee → ankle pitch → ankle roll,
pan → tilt). A cable that breaks (or a servo whose board fails) after one servo hides every
servo behind it on that branch, while the other branches still answer: the first missing ID of
a branch is where to look.
"""

from __future__ import annotations

from collections.abc import Iterable

# Each branch from the CM-730 outwards.
CHAINS: dict[str, tuple[int, ...]] = {
    "right arm": (1, 3, 5),
    "left arm": (2, 4, 6),
    "right leg": (7, 9, 11, 13, 15, 17),
    "left leg": (8, 10, 12, 14, 16, 18),
    "head": (19, 20),
}


def branch_of(dxl_id: int) -> str | None:
    for name, ids in CHAINS.items():
        if dxl_id in ids:
            return name
    return None


def hidden_behind(broken_after: Iterable[int]) -> set[int]:
    """Every ID that a cable break right after each ID of ``broken_after`` cuts off."""
    hidden: set[int] = set()
    for cut in broken_after:
        name = branch_of(cut)
        if name is None:
            raise ValueError(f"ID {cut} is on no chain of the DARwIn-OP (servo IDs are 1..20)")
        ids = CHAINS[name]
        hidden.update(ids[ids.index(cut) + 1 :])
    return hidden


def first_missing(missing: Iterable[int]) -> dict[str, tuple[int, tuple[int, ...]]]:
    """Per branch with missing servos: its first missing ID (nearest the CM-730, where the
    cable or servo to check is) and every missing ID of that branch, in cable order."""
    gone = set(missing)
    out: dict[str, tuple[int, tuple[int, ...]]] = {}
    for name, ids in CHAINS.items():
        lost = tuple(i for i in ids if i in gone)
        if lost:
            out[name] = (lost[0], lost)
    return out
