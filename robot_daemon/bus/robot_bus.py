"""The robot on the bus: the CM-730 and the 20 servos, their last known state, and the
per-tick transactions (sync-write goals and gains, bulk-read sensors, round-robin slow reads).

Joint angles are calibrated here and only here: ``servo = direction · joint + offset``.
A servo that misses ``offline_after`` bulk reads in a row goes offline (left out of the bulk
read so it cannot stall the others) and is probed in the round-robin until it answers again:
the bulk read and what it tells are the bus's :class:`SensorReader` (``bus/sensor_read.py``).
"""

from __future__ import annotations

import logging
import struct
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from operator import itemgetter
from typing import Any

import numpy as np

from config.loader import RobotConfig
from robot_daemon.bus.calibration import Calibration
from robot_daemon.bus.dxl import DxlBus, ReplyBudget, error_names
from robot_daemon.bus.port import BlockingPortHandler
from robot_daemon.bus.preflight import firmware_refusal
from robot_daemon.bus.scan import Identity, identify, identity_warnings, shared_id
from robot_daemon.bus.sensor_read import PROTECT_BITS, SLOW_LENGTH, SLOW_START, SensorReader
from robot_daemon.bus.servo_ram import FULL_TORQUE, reset_servo_ram
from robot_daemon.bus.state import (
    BusCounters,
    ServoState,
    cm730_status,
    imu_arrays,
    imu_raw,
)
from robot_daemon.bus.tables import (
    CM730,
    CM730_BULK_LENGTH,
    CM730_MODEL,
    MX28,
    MX28_MODEL,
    SYNC_WRITE_LENGTH,
    SYNC_WRITE_START,
)
from robot_daemon.bus.transport import Transport
from robot_daemon.frames import N_SLOTS, JointFrame, Targets
from robot_daemon.hotpath import compiled as _compiled
from schemas import units
from schemas.errors import BusError, NoReplyError, PortError

log = logging.getLogger(__name__)

# A device is asked this many times at start before it is called missing.
SCAN_TRIES = 3
# How long the daemon keeps asking the CM-730 at start before it gives up (s).
CM730_WAIT_S = 5.0


# The gyro's counts at rest until the gyro calibration module sets the frame's measured ones:
# one read-only array for every frame (the field's default made one a tick through np.full).
_AT_REST = np.full(3, float(units.IMU_CENTER))
_AT_REST.flags.writeable = False


@dataclass
class _WritePlan:
    """The sync write of one set of joints with one set of gains (RobotBus.write_targets)."""

    gains: dict[int, tuple[int, int, int]]  # the gains it was made with
    torqued: Callable[[list[bool]], tuple[bool, ...]]  # its joints' torque flags
    at: np.ndarray  # its joints' slots in the state
    flat: list[int]  # id, D, I, P, 0, goal of each row: the goals filled in each tick
    rows: struct.Struct  # packs ``flat`` into the rows' bytes


class RobotBus:
    """Owns the transport; every method runs in the motion thread.

    ``transport`` makes the transport at each :meth:`open`: by default the serial port
    ``port_name`` (:class:`BlockingPortHandler`); the simulated rig passes an in-process link to
    the emulator (:class:`robot_daemon.emulator.inprocess_link.EmulatorLink`)."""

    def __init__(
        self,
        port_name: str,
        robot: RobotConfig,
        settings: dict[str, Any],
        emit: Any,
        transport: Callable[[], Transport] | None = None,
    ) -> None:
        daemon = settings.get("daemon", {})
        bus_cfg = settings.get("bus", {})
        self.port_name = port_name
        self.robot = robot
        self.baud = int(daemon.get("baud", 1_000_000))
        self.reply_margin_ms = float(bus_cfg.get("reply_margin_ms", 1.5))
        # Power-on, scan and the first read are not timed by the loop: a busy machine must not
        # make a servo look absent there.
        self.start_margin_ms = float(bus_cfg.get("start_reply_margin_ms", 20.0))
        self.power_on_delay = float(bus_cfg.get("power_on_delay_ms", 300.0)) / 1000.0
        self.torque_on_start = bool(daemon.get("torque_on_start", True))
        # A torqued servo found at start keeps its goal only this close to where it is.
        sag_deg = float(bus_cfg.get("hold_sag_limit_deg", 5.0))
        self.hold_sag_raw = sag_deg * units.UNITS_PER_REV / 360.0
        # DXL power off (the reset button): only the CM-730 is read until it is powered again.
        self.unpowered = False
        # The TORQUE_LIMIT each servo runs with (MAX_TORQUE, bus/servo_ram.py): what a re-arm
        # writes back.
        self.torque_limits: dict[int, int] = {}
        imu = settings.get("imu", {})
        self.gyro_dps = float(imu.get("gyro_full_scale_dps", units.GYRO_DPS_FULL_SCALE))
        self.emit = emit  # emit(kind, message, **data)
        self.cm730_id = robot.cm730_id
        self.ids = robot.ids
        self.state = ServoState()
        self.cm730: bytes = bytes(CM730_BULK_LENGTH)
        self.cm730_online = False
        self._cm730_misses = 0
        self.cm730_valid = False  # this tick's CM-730 block came, error-free (frame.imu_valid)
        self.counters = BusCounters()
        self.warnings: list[str] = []
        # Found before the bus (the robot's configuration): every scan keeps saying them.
        self.config_warnings: list[str] = []
        self.refused: dict[int, str] = {}  # id → why it is kept offline (old firmware)
        self.make_transport = transport or (lambda: BlockingPortHandler(self.port_name))
        self.handler: Transport | None = None
        self.dxl: DxlBus | None = None
        # The tick's bulk read; an alarm shutdown it sees turns the servo's torque off here.
        self.sensors = SensorReader(
            robot, self.state, self.counters, emit, self.set_torque, daemon,
            int(bus_cfg.get("probe_offline_every", 25)),
        )
        self.calibration = Calibration(robot)
        # Each joint's configured (D, I, P): the sync write's gain bytes unless a module sets
        # others this tick.
        self._gain_rows = [(0, 0, 0)] * N_SLOTS
        for j in robot.joints:
            self._gain_rows[j.id] = (j.d, j.i, j.p)
        # The goals' slots of the state by the joints written (a handful of sets in use): an
        # index array made once, not a list turned into one every tick.
        self._goal_at: dict[tuple[int, ...], np.ndarray] = {}
        self._write_plans: dict[tuple[int, ...], _WritePlan] = {}

    # -- calibration ---------------------------------------------------------------------------
    def raw_to_joint(self, jid: int, raw: int | float) -> float:
        return self.calibration.to_joint(jid, raw)

    def joint_to_raw(self, jid: int, rad: float) -> int:
        return self.calibration.to_raw(jid, rad)

    # -- port lifecycle ------------------------------------------------------------------------
    @property
    def is_open(self) -> bool:
        return self.dxl is not None

    def open(self) -> None:
        handler = self.make_transport()
        handler.open(self.baud)
        self.handler = handler
        self.dxl = DxlBus(handler, ReplyBudget(self.start_margin_ms))

    def close(self) -> None:
        if self.handler is not None:
            self.handler.close()
        self.handler = self.dxl = None

    def read_sensors(self) -> None:
        """The tick's bulk read (:meth:`SensorReader.read`); the CM-730's block kept here."""
        got = self.sensors.read(self._bus(), self.refused, self.unpowered, self.cm730_online)
        if got.data is not None:
            self.cm730 = got.data
        self.cm730_valid, self.cm730_online = got.valid, got.online

    def _bus(self) -> DxlBus:
        if self.dxl is None:
            raise BusError(f"serial port {self.port_name} is not open (lost; reopening)")
        return self.dxl

    def power_on(self) -> None:
        """Power the servo bus (CM-730 DXL_POWER = 1), paint the head LED orange, and wait."""
        head = units.rgb_to_color_word(255, 128, 0)
        # The CM-730 may still be booting (or the machine busy): keep asking for a while.
        deadline = time.monotonic() + CM730_WAIT_S
        while True:
            try:
                self._write_retry(self.cm730_id, CM730.DXL_POWER.reg.address, b"\x01")
                break
            except PortError:
                raise
            except BusError as exc:
                if time.monotonic() > deadline:
                    raise NoReplyError(
                        f"the CM-730 (id {self.cm730_id}) on {self.port_name} did not answer "
                        f"for {CM730_WAIT_S:.0f} s: is the robot switched on, and is this its "
                        f"port? ({exc})"
                    ) from exc
        try:  # the framework's "connected" colour: nice to have, not worth failing for
            self._write_retry(self.cm730_id, CM730.LED_HEAD.reg.address, head.to_bytes(2, "little"))
        except PortError:
            raise
        except BusError as exc:
            log.info("could not paint the head LED: %s", exc)
        # A little past the nominal delay: a servo asked too early looks absent.
        assert self.handler is not None
        self.handler.pause(self.power_on_delay * 1.2)

    def scan(self) -> dict[int, int]:
        """Ping the CM-730 and every joint; check model, firmware and return delay (a servo with
        firmware < 27 is kept offline). Returns id → model number of what answered."""
        bus = self._bus()
        # Bring-up's patience until initial_read ends (the servos powered again mid-run too).
        bus.budget.margin_ms = self.start_margin_ms
        found: dict[int, int] = {}
        self.warnings = list(self.config_warnings)
        self.refused = {}
        # Two passes: a servo that powered up late (or a busy host that missed its replies)
        # is asked again after the others, rather than left offline without torque.
        ids = [self.cm730_id, *self.ids]
        for dxl_id in self._scan_order(ids, found):
            ident = identify(bus, dxl_id, SCAN_TRIES)
            if ident is None:
                continue
            found[dxl_id] = ident.model
            self.state.firmware[dxl_id] = ident.firmware
            bus.budget.set_return_delay(dxl_id, ident.return_delay)
            expected = CM730_MODEL if dxl_id == self.cm730_id else MX28_MODEL
            for line in identity_warnings(ident, dxl_id, expected, self.port_name):
                self._warn(line)
            joint = self.robot.by_id.get(dxl_id)
            refusal = firmware_refusal(dxl_id, joint.name, ident.firmware) if joint else None
            if joint is not None and refusal is None:
                refusal = self._angle_limits(dxl_id, ident)
            if joint is not None and refusal is None and shared_id(bus, dxl_id):
                # Goals and torque written to this ID would drive both servos, one of them
                # somewhere else in the body (MOVE_* in robot_daemon/motion_authority.py: none).
                refusal = (
                    f"servo {dxl_id} ({joint.name}): two servos answer as ID {dxl_id} (their "
                    "replies collide: a replaced or firmware-recovered servo given an ID in "
                    "use?); left offline, torque refused; find the second by scanning one "
                    "chain at a time (`darwin scan`) and give it its own ID "
                    "(docs/servo-replacement.md)"
                )
            if refusal is not None:  # kept offline, probes included
                self.refused[dxl_id] = refusal
                self._warn(refusal)
        missing = [i for i in self.ids if i not in found]
        if missing:
            self._warn(f"servos {missing} do not answer on {self.port_name}; they stay offline")
        self.cm730_online = self.cm730_id in found
        for jid in self.ids:
            self.state.online[jid] = jid in found and jid not in self.refused
            self.state.misses[jid] = 0
        return found

    def _angle_limits(self, dxl_id: int, ident: Identity) -> str | None:
        """A servo in wheel mode (CW and CCW limits 0) is refused: it would turn, not hold. One
        whose own limits are narrower than the joint's configured range is a warning: goals
        past them are refused by the servo (ANGLE_LIMIT error) and the joint stops short."""
        name = self.robot.by_id[dxl_id].name
        cw, ccw = ident.cw_limit, ident.ccw_limit
        if cw == 0 and ccw == 0:
            return (
                f"servo {dxl_id} ({name}) is in wheel mode (CW and CCW angle limits 0): it would "
                "turn, not hold a position; left offline, torque refused; set its limits back "
                "(0 and 4095) with an admin's `registers` write (--allow-hardware-writes "
                "--allow-eeprom) or RoboPlus"
            )
        j = self.robot.by_id[dxl_id]
        ends = (self.joint_to_raw(dxl_id, j.min_rad), self.joint_to_raw(dxl_id, j.max_rad))
        lo, hi = sorted(ends)
        if lo < cw or hi > ccw:
            self._warn(
                f"servo {dxl_id} ({name}) limits its own angle to {cw}..{ccw} (raw), narrower "
                f"than the joint's configured {j.min_deg:g}°..{j.max_deg:g}° ({lo}..{hi}): the "
                "servo refuses goals past its limits and the joint stops short"
            )
        return None

    @staticmethod
    def _scan_order(ids: list[int], found: dict[int, int]) -> Iterator[int]:
        yield from ids
        yield from [i for i in ids if i not in found]

    def _write_retry(self, dxl_id: int, address: int, data: bytes) -> None:
        # The first try at the loop's margin; a status that missed it (a busy host, an
        # emulator's pace) is waited for with bring-up's patience, since a command that fails
        # for want of 4 ms is worse than a loop that runs late once.
        self._bus().write(
            dxl_id, address, data, tries=SCAN_TRIES, retry_margin_ms=self.start_margin_ms
        )

    def _read_retry(self, bus: DxlBus, dxl_id: int, address: int, length: int) -> bytes | None:
        try:
            return bus.read(
                dxl_id, address, length, tries=SCAN_TRIES, retry_margin_ms=self.start_margin_ms
            )[0]
        except PortError:
            raise
        except BusError:
            return None

    def _warn(self, text: str) -> None:
        log.warning(text)
        self.warnings.append(text)

    def initial_read(self, torque: Iterable[int] | None = None) -> list[int]:
        """Read every online servo's slow block once (its alarm bits kept), then hold:

        * a servo in alarm shutdown (an OVERLOAD or OVERHEATING bit, or TORQUE_LIMIT 0 with
          torque enabled: the MX-28's shutdown, e-manual "Torque Limit (34)") is reported and
          left alone: its RAM is not reset (writing TORQUE_LIMIT would re-arm it) and it gets
          no torque;
        * a servo with torque on keeps its goal when that is within ``hold_sag_limit_deg`` of
          where it is (its present position under load is below the goal: re-commanding that
          would make the joint sink), else it holds where it is (a goal left far away would
          be a jump the moment the RAM reset lifts a slow MOVING_SPEED);
        * the others' goal is their present position, so enabling torque moves nothing;
        * then the RAM a previous program may have left (bus/servo_ram.py) is reset on the
          servos not in alarm, and torque is enabled on ``torque`` (not the alarmed ones;
          None: every servo when ``daemon.torque_on_start``, none otherwise).

        Returns the servos left limp for an alarm."""
        st = self.state
        enabled: dict[int, bool] = {}
        for jid in self.ids:
            if st.online[jid]:
                read = self._read_with_error(jid, SLOW_START, SLOW_LENGTH)
                if read is None:
                    st.online[jid] = False
                    self._warn(f"servo {jid} stopped answering after the scan; offline")
                else:
                    data, error = read
                    enabled[jid] = bool(data[0])
                    self.sensors.apply_slow(jid, data, error)
        online = [j for j in self.ids if st.online[j]]
        alarmed = [j for j in online if self._shut_down(j, enabled.get(j, False))]
        for jid in alarmed:
            names = ", ".join(error_names(int(st.alarm[jid]))) or "torque limit 0"
            self._warn(
                f"servo {jid} ({self.robot.by_id[jid].name}) is in alarm shutdown ({names}): "
                "left limp, its torque limit untouched; `torque` enable=true re-arms it once "
                "the alarm is gone (let it cool, take the load off)"
            )
            st.torque[jid] = False
        sag = self.hold_sag_raw
        for jid in self.ids:
            far = abs(int(st.goal[jid]) - int(st.position[jid])) > sag
            if far or not (st.online[jid] and st.torque[jid]):
                st.goal[jid] = st.position[jid]
        rows = {j: self._sync_row(j, int(st.goal[j])) for j in online if j not in alarmed}
        if rows:
            self._bus().sync_write(SYNC_WRITE_START, SYNC_WRITE_LENGTH, rows)
        # After the goals: the reset lifts any slow MOVING_SPEED, so the goal must be near.
        healthy = [j for j in online if j not in alarmed]
        self.torque_limits.update(
            reset_servo_ram(self._bus(), healthy, lambda *a: self._read_retry(self._bus(), *a))
        )
        if torque is None:
            torque = self.ids if self.torque_on_start else ()
        wanted = [j for j in torque if j in healthy]
        if wanted:
            self.set_torque(wanted, True)
        self._bus().budget.margin_ms = self.reply_margin_ms  # from now on the loop is timed
        return alarmed

    def _shut_down(self, jid: int, enabled: bool) -> bool:
        """In alarm shutdown: a protecting alarm stands, or torque enabled with a limit of 0."""
        st = self.state
        return bool(st.alarm[jid] & PROTECT_BITS) or (enabled and st.torque_limit[jid] == 0)

    def _read_with_error(self, jid: int, address: int, length: int) -> tuple[bytes, int] | None:
        try:
            return self._bus().read(
                jid, address, length, tries=SCAN_TRIES, retry_margin_ms=self.start_margin_ms
            )
        except PortError:
            raise
        except BusError:
            return None

    def dxl_power(self) -> bool:
        """Whether the CM-730 says the servo bus is powered (a read: nothing is switched)."""
        data = self._read_retry(self._bus(), self.cm730_id, CM730.DXL_POWER.reg.address, 1)
        if data is None:
            raise NoReplyError(
                f"the CM-730 (id {self.cm730_id}) on {self.port_name} does not answer"
            )
        return bool(data[0])

    def paint_disconnected(self) -> None:
        """The head LED green, as ROBOTIS's ``CM730::Disconnect`` leaves it
        (``Framework/src/CM730.cpp``): the orange of a connected daemon must not stay after it
        exits. Sent without waiting for the status; best effort."""
        if self.dxl is None:
            return
        green = units.rgb_to_color_word(0, 255, 0)
        try:
            self.dxl.write_unanswered(
                self.cm730_id, CM730.LED_HEAD.reg.address, green.to_bytes(2, "little")
            )
            assert self.handler is not None
            self.handler.pause(0.002)  # the 9 bytes on the wire before the port closes
        except (BusError, OSError) as exc:
            log.info("could not paint the head LED green: %s", exc)

    # -- per tick ----------------------------------------------------------------------------
    def _sync_row(self, jid: int, goal_raw: int) -> bytes:
        """A joint's sync-write row with its configured gains (writes outside the tick)."""
        d, i, p = self._gain_rows[jid]
        return bytes((d, i, p, 0, goal_raw & 0xFF, goal_raw >> 8))

    def write_targets(self, targets: Targets) -> None:
        """Sync-write gains and goals of the joints the motion layer drives this tick."""
        goal = targets.goal
        if not goal:
            return
        # The usual tick: the same joints as a tick before, with the same gains, every one
        # torqued and within its limits. Their rows are a template made once (ids and gains)
        # and the goals converted as one batch: the same bytes as the loop below, at a third
        # of its cost.
        ids = tuple(goal)
        plan = self._write_plans.get(ids)
        if plan is None or plan.gains != targets.gains:
            plan = self._write_plan(ids, targets.gains)
        if plan is not None and all(plan.torqued(self.state.torque.tolist())):
            raws = self.calibration.goals_raw(ids, list(goal.values()))
            if raws is not None:
                flat = plan.flat
                flat[5::6] = raws
                if _compiled is None or _compiled.put_ints(self.state.goal, ids, raws) is not True:
                    self.state.goal[plan.at] = raws  # (what put_ints does, in numpy)
                self._bus().sync_write_rows(SYNC_WRITE_START, SYNC_WRITE_LENGTH,
                                            plan.rows.pack(*flat))
                c = self.counters
                c.sync_writes += 1
                c.goal_writes += len(ids)
                return
        self._write_each(targets)

    def _write_plan(self, ids: tuple[int, ...], gains: dict[int, tuple[int, int, int]]
                    ) -> _WritePlan | None:
        """The rows' template of a set of joints with these gains (None for one joint, or a
        gain that is not a byte: the loop says what is wrong with it)."""
        flat: list[int] = []
        for jid in ids:
            pid = gains.get(jid)
            if pid is None:
                d, i, p = self._gain_rows[jid]
            else:
                p, i, d = pid
            flat += (jid, d, i, p, 0, 0)
        if len(ids) < 2 or not all(type(v) is int and 0 <= v <= 0xFF for v in flat):
            return None
        if len(self._write_plans) > 64:
            self._write_plans.clear()
        plan = self._write_plans[ids] = _WritePlan(
            gains=dict(gains),
            torqued=itemgetter(*ids),
            at=np.array(ids, np.intp),
            flat=flat,
            rows=struct.Struct("<" + "5BH" * len(ids)),
        )
        return plan

    def _write_each(self, targets: Targets) -> None:
        """:meth:`write_targets` a goal at a time: joints without torque skipped, goals
        outside their limits clamped and counted."""
        st = self.state
        torque = st.torque.tolist()
        goal_raw = self.calibration.goal_raw
        default, gains = self._gain_rows, targets.gains
        row: list[int] = []  # the packet's rows: id, D, I, P, 0, goal low, goal high
        written: dict[int, int] = {}
        clamps = 0
        for jid, rad in targets.goal.items():
            # An offline joint that had torque keeps getting its goal, as ROBOTIS's framework
            # writes every enabled joint every tick whatever the replies: a servo whose replies
            # are lost may still hear, and fed no goal it jumped to the newest one on return.
            if not torque[jid]:
                continue
            # The arbiter rejects out-of-range commands; the clamp guards module bugs.
            raw, clamped = goal_raw(jid, rad)
            clamps += clamped
            written[jid] = raw
            pid = gains.get(jid)
            if pid is None:
                d, i, p = default[jid]
            else:
                p, i, d = pid
            row += (jid, d, i, p, 0, raw & 0xFF, raw >> 8)
        c = self.counters
        c.skipped_goals += len(targets.goal) - len(written)
        c.limit_clamps += clamps
        if not written:
            return
        at = self._goal_at.get(tuple(written))
        if at is None:
            if len(self._goal_at) > 64:
                self._goal_at.clear()
            at = self._goal_at[tuple(written)] = np.array(list(written), np.intp)
        st.goal[at] = np.fromiter(written.values(), st.goal.dtype, len(written))
        self._bus().sync_write_rows(SYNC_WRITE_START, SYNC_WRITE_LENGTH, bytes(row))
        c.sync_writes += 1
        c.goal_writes += len(written)

    # -- frame ---------------------------------------------------------------------------------
    def frame(self, tick: int, now: float, dt: float) -> JointFrame:
        st = self.state
        # Whole arrays at once, handed to the frame as made (slot 0 is unused and stays
        # meaningless): this runs every tick.
        cal = self.calibration
        gyro_raw, accel_raw, gyro, accel = imu_arrays(self.cm730, self.gyro_dps)
        position, velocity, load = cal.joint_arrays(st.position, st.speed, st.load)
        return JointFrame(
            tick=tick,
            time=now,
            dt=dt,
            position=position,
            goal_raw=st.goal.copy(),
            to_joint=cal.to_joint,
            velocity=velocity,
            load=load,
            online=st.online.copy(),
            torque_enabled=st.torque.copy(),
            gyro=gyro,
            accel=accel,
            gyro_raw=gyro_raw,
            accel_raw=accel_raw,
            imu_valid=self.cm730_valid,
            gyro_centre=_AT_REST,
        )

    def imu_raw(self) -> tuple[list[int], list[int]]:
        return imu_raw(self.cm730)

    def cm730_status(self) -> dict[str, Any]:
        return cm730_status(self.cm730) if self.cm730_online else cm730_status(b"")

    # -- BusCommands (registry.py), run by verb handlers in the motion thread ---------------------
    def set_leds(self, head: int | None, eye: int | None, panel: int | None) -> None:
        cm = self.cm730_id
        if panel is not None:
            self._write_retry(cm, CM730.LED_PANEL.reg.address, bytes((panel,)))
        if head is not None:
            self._write_retry(cm, CM730.LED_HEAD.reg.address, head.to_bytes(2, "little"))
        if eye is not None:
            self._write_retry(cm, CM730.LED_EYE.reg.address, eye.to_bytes(2, "little"))

    def set_torque(self, ids: list[int], enable: bool) -> dict[int, str]:
        """Torque on or off; returns the servos refused (id → why): enabling skips a servo in
        alarm shutdown, since writing its TORQUE_LIMIT would re-arm it into the same fault."""
        st = self.state
        ids = [j for j in ids if st.online[j]]
        refused: dict[int, str] = {}
        if enable:
            for j in ids:
                if st.alarm[j] & PROTECT_BITS:
                    names = ", ".join(error_names(int(st.alarm[j])))
                    refused[j] = f"servo {j} ({self.robot.by_id[j].name}) is in alarm ({names})"
            ids = [j for j in ids if j not in refused]
        if not ids:
            return refused
        bus = self._bus()
        off = [j for j in ids if not st.torque[j]]
        if enable and off:
            # Hold where the servo is now, so enabling torque never makes it jump (one already
            # on keeps its goal).
            rows = {j: self._sync_row(j, int(st.position[j])) for j in off}
            bus.sync_write(SYNC_WRITE_START, SYNC_WRITE_LENGTH, rows)
            for j in off:
                st.goal[j] = st.position[j]
            # A servo shut down by an alarm that has since gone (cooled, unloaded) has
            # TORQUE_LIMIT 0: re-armed with the limit it runs with, goal already at present.
            rearm = {
                j: self.torque_limits.get(j, FULL_TORQUE).to_bytes(2, "little")
                for j in off
                if st.torque_limit[j] == 0
            }
            if rearm:
                bus.sync_write(MX28.TORQUE_LIMIT.reg.address, 2, rearm)
                for j in rearm:
                    st.torque_limit[j] = self.torque_limits.get(j, FULL_TORQUE)
        flag = bytes((1 if enable else 0,))
        bus.sync_write(MX28.TORQUE_ENABLE.reg.address, 1, dict.fromkeys(ids, flag))
        for j in ids:
            st.torque[j] = enable
        return refused

    def read_registers(self, dxl_id: int, address: int, length: int) -> bytes:
        # A read has no side effect: asked again, patiently, like a write (_write_retry).
        return self._bus().read(
            dxl_id, address, length, tries=SCAN_TRIES, retry_margin_ms=self.start_margin_ms
        )[0]

    def write_registers(self, dxl_id: int, address: int, data: bytes) -> None:
        # Writing the same bytes again is harmless, so a lost status packet is retried.
        enable_at = MX28.TORQUE_ENABLE.reg.address
        goal_at = MX28.GOAL_POSITION.reg.address
        st = self.state
        if (
            dxl_id in self.ids
            and address <= enable_at < address + len(data)
            and data[enable_at - address]
            and not address <= goal_at < address + len(data)
            and st.online[dxl_id]
            and not st.torque[dxl_id]
        ):
            # Torque on by a raw write: the goal the servo holds may be anything a previous
            # program left; hold where it is first, as `torque` does. Where it is now, read
            # from the servo: the tick's bulk read may predate a push that came after it.
            raw = self._read_retry(self._bus(), dxl_id, MX28.PRESENT_POSITION.reg.address, 2)
            present = int.from_bytes(raw, "little") if raw else int(st.position[dxl_id])
            self._write_retry(dxl_id, goal_at, present.to_bytes(2, "little"))
            st.goal[dxl_id] = present
        self._write_retry(dxl_id, address, data)
        if dxl_id in self.ids and address <= enable_at < address + len(data):
            st.torque[dxl_id] = bool(data[enable_at - address])

    def status(self) -> dict[str, Any]:
        # As lists: forty numpy scalars looked at one by one cost most of a status message.
        online, torque = self.state.online.tolist(), self.state.torque.tolist()
        return {
            "port": self.port_name,
            "open": self.is_open,
            **self.counters.to_dict(),
            "offline": [j for j in self.ids if not online[j]],
            "torque_off": [j for j in self.ids if online[j] and not torque[j]],
            "cm730_online": self.cm730_online,
            "warnings": list(self.warnings),
            "bytes_written": self.handler.bytes_written if self.handler else 0,
            "bytes_read": self.handler.bytes_read if self.handler else 0,
        }
