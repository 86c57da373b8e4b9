"""The tick's bulk read and what it tells: present position, speed and load of the servos, the
slow block (torque … temperature) of one servo in turn, the CM-730's sensors, alarms, and servos
going offline after ``offline_after`` missed reads in a row and coming back when a probe answers.

:class:`SensorReader` is a part the :class:`~robot_daemon.bus.robot_bus.RobotBus` has, made with
what it writes (the servos' state, the counters, events) and a way to turn a servo's torque off
(the firmware's alarm shutdown, mirrored); each read is handed the open bus and who the bus keeps
offline, and returns what it read of the CM-730 (:class:`Cm730Read`).
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from operator import itemgetter
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from robot_daemon.bus.dxl import error_names
from robot_daemon.bus.read_plan import servos_to_read
from robot_daemon.bus.state import BusCounters, ServoState, word
from robot_daemon.bus.tables import (
    CM730_BULK_LENGTH,
    CM730_BULK_START,
    MX28,
    SERVO_BULK_LENGTH,
    SERVO_BULK_START,
    ErrorBit,
)
from robot_daemon.hotpath import compiled as _compiled
from schemas import units

if TYPE_CHECKING:
    from config.loader import RobotConfig
    from robot_daemon.bus.bulk_receive import BulkResult
    from robot_daemon.bus.dxl import DxlBus

# Round-robin slow block: torque enable (24) … present temperature (43).
SLOW_START = MX28.TORQUE_ENABLE.reg.address
SLOW_LENGTH = MX28.PRESENT_TEMPERATURE.reg.address + 1 - SLOW_START
_FAST_BLOCK = (SERVO_BULK_START, SERVO_BULK_LENGTH)
# Which word of the per-tick block (SERVO_BULK_START…) each present value is.
_FAST_POSITION = (MX28.PRESENT_POSITION.reg.address - SERVO_BULK_START) // 2
_FAST_SPEED = (MX28.PRESENT_SPEED.reg.address - SERVO_BULK_START) // 2
_FAST_LOAD = (MX28.PRESENT_LOAD.reg.address - SERVO_BULK_START) // 2
# Where each register is in the slow block.
_TORQUE = MX28.TORQUE_ENABLE.reg.address - SLOW_START
_GOAL = MX28.GOAL_POSITION.reg.address - SLOW_START
_TORQUE_LIMIT = MX28.TORQUE_LIMIT.reg.address - SLOW_START
_POSITION = MX28.PRESENT_POSITION.reg.address - SLOW_START
_SPEED = MX28.PRESENT_SPEED.reg.address - SLOW_START
_LOAD = MX28.PRESENT_LOAD.reg.address - SLOW_START
_VOLTAGE = MX28.PRESENT_VOLTAGE.reg.address - SLOW_START
_TEMPERATURE = MX28.PRESENT_TEMPERATURE.reg.address - SLOW_START
# Alarms the firmware protects against by dropping torque (the MX-28's default shutdown mask).
PROTECT_BITS = ErrorBit.OVERHEATING | ErrorBit.OVERLOAD


class _Layout(NamedTuple):
    blocks: list[tuple[int, int, int]]  # (id, start, length) in bus order
    fast: list[int]  # the servos read for position, speed and load, in that order
    at: slice | np.ndarray  # the same, as an index of the state's arrays
    pick: Callable[[dict[int, bytes]], Any]  # their replies out of the data, in one call


class Cm730Read(NamedTuple):
    """What a bulk read got of the CM-730: its block (None: no reply, keep the last), whether
    this tick's came error-free, and whether it is online (answering, in its place first in
    the chain)."""

    data: bytes | None
    valid: bool
    online: bool


class SensorReader:
    """The bulk read each tick; ``settings`` the daemon's ``[daemon]`` table (offline_after_misses,
    slow_reads_per_tick, servo_reads_per_tick) and ``probe_every`` ([bus] probe_offline_every)."""

    def __init__(
        self,
        robot: RobotConfig,
        state: ServoState,
        counters: BusCounters,
        emit: Callable[..., Any],
        torque_off: Callable[[list[int], bool], Any],
        daemon: dict[str, Any],
        probe_every: int,
    ) -> None:
        self.robot = robot
        self.ids = robot.ids
        self.cm730_id = robot.cm730_id
        self.state = state
        self.counters = counters
        self.emit = emit  # emit(kind, message, **data)
        self._set_torque = torque_off  # (ids, False): the bus's set_torque
        self.offline_after = int(daemon.get("offline_after_misses", 5))
        self.slow_per_tick = int(daemon.get("slow_reads_per_tick", 1))
        self.servo_share = int(daemon.get("servo_reads_per_tick", 0))  # 0: every servo
        # An offline servo is probed once every this many ticks (a silent probe costs a wait).
        self.probe_every = max(1, probe_every)
        self._cm730_misses = 0
        self._rr = 0
        self._who_key: tuple[bytes, int, bool] | None = None
        self._who_cache: tuple[list[int], list[int]] = ([], [])
        self._layouts: dict[tuple[Any, ...], _Layout] = {}
        # The servos whose last status had alarm bits (what ``state.alarm`` holds non-zero): a
        # tick without errors or alarms skips the per-servo alarm pass without asking numpy.
        self._alarmed: set[int] = set()

    def _who(self, refused: Collection[int], unpowered: bool) -> tuple[list[int], list[int]]:
        """The online servos and the offline ones worth probing, in bus order: remade only
        when who is online (or refused) changes, not every tick."""
        st = self.state
        key = (st.online.tobytes(), len(refused), unpowered)
        if key != self._who_key:
            on = st.online.tolist()
            # DXL power off: only the CM-730 is read, and no servo is probed.
            self._who_cache = (
                [j for j in self.ids if on[j]],
                [j for j in self.ids if not on[j] and j not in refused and not unpowered],
            )
            self._who_key = key
            self._layouts = {}
        return self._who_cache

    def _layout(
        self, online: list[int], slow: set[int], probe: int | None, cm730_online: bool
    ) -> _Layout:
        """The bulk read's blocks for this tick, and which of them are the fast block of a
        servo (decoded all at once): made once per combination, then reused."""
        share = self.servo_share
        turn = (self._rr * share) % len(online) if 0 < share < len(online) else -1
        key = (tuple(sorted(slow)), turn, cm730_online, probe)
        layout = self._layouts.get(key)
        if layout is None:
            blocks: list[tuple[int, int, int]] = [
                (j, SLOW_START, SLOW_LENGTH) if j in slow else (j, *_FAST_BLOCK)
                for j in servos_to_read(online, slow, self._rr, share)
            ]
            # The CM-730 first, as ROBOTIS's CM730::MakeBulkReadPacket (framework r47), Bold
            # Hearts and NimbRo-OP; last while it has not answered, so a silent CM-730 (the
            # chain waits for its status packet) silences nobody.
            cm = (self.cm730_id, CM730_BULK_START, CM730_BULK_LENGTH)
            blocks.insert(len(blocks) if not cm730_online else 0, cm)
            if probe is not None:
                blocks.append((probe, SLOW_START, SLOW_LENGTH))
            fast = [
                j
                for j, start, _ in blocks
                if start == SERVO_BULK_START and j not in (self.cm730_id, probe)
            ]
            # A run of IDs (the usual 1…20) indexes the state's arrays as a slice: several
            # times cheaper than an index array, five times a tick.
            run = bool(fast) and fast == list(range(fast[0], fast[0] + len(fast)))
            at = slice(fast[0], fast[0] + len(fast)) if run else np.array(fast, np.intp)
            # itemgetter of one key gives the value, not a 1-tuple: the join wants a sequence.
            pick = itemgetter(*fast) if len(fast) > 1 else lambda data: [data[j] for j in fast]
            layout = self._layouts[key] = _Layout(blocks, fast, at, pick)
        return layout

    def read(
        self, dxl: DxlBus, refused: Collection[int], unpowered: bool, cm730_online: bool
    ) -> Cm730Read:
        """One bulk read: the CM-730's sensors, position/speed/load of the online servos, the
        slow block (torque … temperature) of one servo in turn, and now and then a probe of
        an offline servo (last, so a silent one delays nobody). ``refused``: servos kept
        offline (never probed); ``unpowered``: DXL power off (only the CM-730 is read)."""
        online, offline = self._who(refused, unpowered)
        n = min(self.slow_per_tick, len(online))
        slow = {online[(self._rr * n + k) % len(online)] for k in range(n)}
        self._rr += 1
        probe = None
        if offline and self._rr % self.probe_every == 0:
            probe = offline[(self._rr // self.probe_every) % len(offline)]
        layout = self._layout(online, slow, probe, cm730_online)
        res = dxl.bulk_read(layout.blocks)
        read = self._cm730(res, cm730_online)
        self._count(res, probe)
        # Every reply in: the fast servos are the layout's (the usual tick, no per-servo
        # test); else those of them that answered.
        whole = len(res.data) == len(layout.blocks)
        for jid in slow if whole else res.data:
            data = res.data.get(jid)
            if data is not None and jid in slow:
                self.apply_slow(jid, data, res.errors.get(jid, 0))
                self.state.misses[jid] = 0
        if probe is not None and probe in res.data:
            self._back(probe, res.data[probe], res.errors.get(probe, 0))
        self._apply_fast(layout, res, whole)
        if res.stalled:
            self.counters.bus_stalls += 1
        else:
            self._blame(res, probe)
        return read

    def _cm730(self, res: BulkResult, online: bool) -> Cm730Read:
        cm730 = res.data.get(self.cm730_id)
        valid = cm730 is not None and not res.errors.get(self.cm730_id)
        self._cm730_misses = 0 if cm730 is not None else self._cm730_misses + 1
        if cm730 is not None:
            online = True
        elif self._cm730_misses >= self.offline_after:
            online = False  # back to the end of the chain until it answers again
        return Cm730Read(cm730, valid, online)

    def _count(self, res: BulkResult, probe: int | None) -> None:
        c = self.counters
        c.bulk_reads += 1
        # The probed servo's silence is expected: not a missing reply nor a stale tick.
        lost = [j for j in res.missing if j != probe] if res.missing else []
        c.missing_replies += len(lost)
        c.corrupt_replies += res.corrupt
        c.retries += int(res.retried)
        if lost or res.corrupt:
            c.stale_ticks += 1

    def _back(self, probe: int, data: bytes, error: int) -> None:
        """An offline servo answered its probe: online again."""
        st = self.state
        self.apply_slow(probe, data, error)
        st.misses[probe] = 0
        st.online[probe] = True
        self.emit(
            "servo_online",
            f"servo {probe} ({self.robot.by_id[probe].name}) answers again",
            id=probe,
        )

    def _apply_fast(self, layout: _Layout, res: BulkResult, whole: bool) -> None:
        st = self.state
        if whole and _compiled is not None and _compiled.apply_fast(
            res.data, layout.fast, st.position, st.speed, st.load, st.misses,
            _FAST_POSITION, _FAST_SPEED, _FAST_LOAD, SERVO_BULK_LENGTH,
        ) is True:
            # The same words into the same slots as below (tests/unit/test_hotpath.py).
            if res.errors or self._alarmed:
                for jid in layout.fast:
                    self._alarm(jid, res.errors.get(jid, 0))
            return
        if whole:
            fast, at = layout.fast, layout.at
            replies = layout.pick(res.data)
        else:
            fast = [j for j in layout.fast if j in res.data]
            at = np.array(fast, np.intp)
            replies = [res.data[j] for j in fast]
        if not fast:
            return
        words = np.frombuffer(b"".join(replies), "<u2")
        words = words.reshape(-1, SERVO_BULK_LENGTH // 2)
        st.position[at] = words[:, _FAST_POSITION]
        st.speed[at] = words[:, _FAST_SPEED]
        st.load[at] = words[:, _FAST_LOAD]
        st.misses[at] = 0
        if res.errors or self._alarmed:
            for jid in fast:
                self._alarm(jid, res.errors.get(jid, 0))

    def _blame(self, res: BulkResult, probe: int | None) -> None:
        """A servo blamed for a missing reply: offline after ``offline_after`` in a row."""
        st = self.state
        for jid in res.blamed:
            if jid in (self.cm730_id, probe):
                continue
            st.misses[jid] += 1
            if st.misses[jid] >= self.offline_after and st.online[jid]:
                st.online[jid] = False
                self.emit(
                    "servo_offline",
                    f"servo {jid} ({self.robot.by_id[jid].name}) missed {st.misses[jid]} reads "
                    "in a row: offline (check its cable; it comes back when it answers)",
                    id=jid,
                )

    def apply_slow(self, jid: int, data: bytes, error: int) -> None:
        """A servo's slow block (torque … temperature) into the state, its alarm bits too."""
        st = self.state
        # An MX-28 in alarm shutdown has TORQUE_LIMIT 0 and TORQUE_ENABLE still 1: limp.
        limit = word(data, _TORQUE_LIMIT)
        arrays = (st.torque_limit, st.torque, st.goal, st.position, st.speed, st.load,
                  st.voltage, st.temperature)
        values = (limit, bool(data[_TORQUE]) and limit > 0, word(data, _GOAL),
                  word(data, _POSITION), word(data, _SPEED), word(data, _LOAD),
                  units.voltage_raw_to_v(data[_VOLTAGE]), float(data[_TEMPERATURE]))
        # Eight numpy item writes in one compiled call where it is built (the same values:
        # tests/unit/test_hotpath.py), else one by one.
        if _compiled is None or _compiled.put_row(arrays, jid, values) is not True:
            for array, value in zip(arrays, values, strict=True):
                array[jid] = value
        self._alarm(jid, error)

    def _alarm(self, jid: int, bits: int) -> None:
        st = self.state
        if bits == st.alarm[jid]:
            return
        old, st.alarm[jid] = int(st.alarm[jid]), bits
        if bits:
            self._alarmed.add(jid)
        else:
            self._alarmed.discard(jid)
        if not bits:
            self.emit("servo_alarm_cleared", f"servo {jid} alarm cleared", id=jid, bits=0)
            return
        names = error_names(bits)
        protect = bool(bits & PROTECT_BITS) and not old & PROTECT_BITS
        if bits & PROTECT_BITS:
            # The firmware's alarm shutdown has zeroed TORQUE_LIMIT with the same status packet
            # (e-manual, "Torque Limit (34)"); the slow read says so only when its turn comes,
            # and a torque-on before then must know to re-arm the limit (RobotBus.set_torque).
            st.torque_limit[jid] = 0
        self.emit(
            "servo_alarm",
            f"servo {jid} ({self.robot.by_id[jid].name}) alarm: {', '.join(names)}"
            + ("; torque off to protect it" if protect else ""),
            id=jid,
            bits=bits,
            alarms=names,
        )
        if protect and st.torque[jid]:
            # As the firmware's alarm shutdown does: no torque until someone re-enables it
            # (MOVE_SERVO_SHUTDOWN in robot_daemon/motion_authority.py).
            self._set_torque([jid], False)
