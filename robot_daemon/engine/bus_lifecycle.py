"""The daemon's hold on the serial bus: bringing it up, the servos' power, losing the port and
getting it back, the CM-730's buttons, letting the bus go at shutdown.

Nothing here moves the robot by itself. What each event does:

* **start** (``connect(first=True)``): power the servo bus as ROBOTIS's ``CM730::Connect``
  does, scan, read, hold; torque on every servo not in alarm (``daemon.torque_on_start``).
* **DXL power lost** (the CM-730's reset button, a brown-out; it reads DXL_POWER 0): every
  module halts, one ``power`` event, and the servos stay unpowered (``status.state`` is
  ``servos_off``) until someone asks: the ``power`` verb (admin, under the lease), the START
  button (``daemon.buttons.start``), the TUI. Powering them again gives torque back only to
  the servos that had it, each holding where it is. ROBOTIS powers DXL only in
  ``Connect``/``Reinitialize`` (``Framework/src/CM730.cpp``): never by itself after a reset.
* **port lost** (the USB cable): halt, refuse what needs the bus (``unavailable``), reopen with
  back-off. When it is back nothing is powered and no torque is enabled: the servos that kept
  torque hold where they are, the others stay limp, one ``port`` event says which; if DXL
  power went meanwhile, the servos stay off as above.
* **MODE / START** (``daemon.buttons``): MODE stops every motion safely and holds (or plays
  the sit-down page, as ROBOTIS's demo does); START powers the servos when they are off.
* **shutdown**: halt, hold, paint the head LED green (``CM730::Disconnect``), close.

A part the :class:`~robot_daemon.engine.daemon.Daemon` is composed of: it sees the bus, the
motion manager, the battery and heat guard and the daemon's event and state callbacks, no more.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum
from typing import TYPE_CHECKING, Any

from config.loader import refuse_unknown
from robot_daemon.arbiter.registry import Reject, Request, needs_lease
from robot_daemon.bus.port import BlockingPortHandler
from robot_daemon.bus.preflight import HolderWatch
from robot_daemon.bus.state import cm730_field
from robot_daemon.bus.tables import CM730
from robot_daemon.engine.power_actions import SIT_PAGE
from robot_daemon.motion.action.player import ActionModule
from schemas.daemon_state import DaemonState
from schemas.errors import BusError, ConfigError, ErrorCode

if TYPE_CHECKING:
    from robot_daemon.bus.robot_bus import RobotBus
    from robot_daemon.engine.power_actions import PowerGuard
    from robot_daemon.frames import JointFrame
    from robot_daemon.motion.manager import MotionManager

# The daemon's logger: these lines were always the daemon's, and logs are read by that name.
log = logging.getLogger("robot_daemon.engine.daemon")

# CM-730 BUTTON register bits (ROBOTIS's demo: ``StatusCheck.cpp``, 1 = MODE, 2 = START).
MODE_BUTTON = 1
START_BUTTON = 2
# What still works while the servos are unpowered: nothing that would drive them.
WITHOUT_SERVOS = frozenset({"power", "led"})


class ModeAction(StrEnum):
    STOP = "stop"  # every motion stops safely (a walk ends its step), the pose is held
    SIT = "sit"  # the same, then the sit-down page (ROBOTIS's demo sits on MODE)
    NONE = "none"  # only reported


class StartAction(StrEnum):
    POWER = "power"  # servos off (reset button): power them again
    NONE = "none"  # only reported


@dataclass(frozen=True)
class Buttons:
    """What the CM-730's MODE and START buttons do (``[daemon.buttons]``)."""

    mode: ModeAction = ModeAction.STOP
    start: StartAction = StartAction.POWER

    @staticmethod
    def from_config(cfg: dict[str, Any] | None) -> Buttons:
        cfg = cfg or {}
        refuse_unknown(cfg, ("mode", "start"), "daemon.buttons")
        try:
            return Buttons(
                ModeAction(cfg.get("mode", ModeAction.STOP)),
                StartAction(cfg.get("start", StartAction.POWER)),
            )
        except ValueError as exc:
            raise ConfigError(
                f"[daemon.buttons]: {exc}: mode is one of {', '.join(ModeAction)}, start one of "
                f"{', '.join(StartAction)}"
            ) from None


class BusSupervisor:
    """The bus's bring-up, power, loss and return, and the buttons; runs in the motion thread."""

    def __init__(
        self,
        bus: RobotBus,
        manager: MotionManager,
        guard: PowerGuard,
        emit: Callable[..., None],
        set_state: Callable[[DaemonState], None],
        *,
        backoff_min: float,
        backoff_max: float,
        buttons: Buttons,
        holder_check_s: float = 2.0,
    ) -> None:
        self.bus = bus
        self.manager = manager
        self.guard = guard
        self.emit = emit
        self.set_state = set_state
        self.backoff_min = backoff_min
        self.backoff_max = backoff_max
        self.backoff = backoff_min
        self.buttons = buttons
        self.down = False  # the port is lost: commands that need the bus are refused
        self.hold_on_return = False  # the next tick holds the pose (port or power back)
        self.servos_off = False  # DXL power is off and stays off until asked
        self.stopping = False  # the daemon is stopping: nothing new may start
        self.power_request: str | None = None  # who asked to power the servos (next tick)
        self.had_torque: list[int] = []  # the servos that had torque when power went
        self._buttons_last = 0
        self.holder_check_s = holder_check_s
        self.holders: HolderWatch | None = None

    # -- start and return ------------------------------------------------------------------
    def connect(self, first: bool = True) -> None:
        """Open the port; at the first start power the servos (as ROBOTIS's ``Connect``),
        scan, read and hold, torque on per ``daemon.torque_on_start``. After a lost port,
        power nothing and enable no torque (the servos that kept it hold where they are)."""
        bus = self.bus
        self.set_state(DaemonState.STARTING)
        bus.open()
        if isinstance(bus.handler, BlockingPortHandler) and self.holder_check_s > 0:
            if self.holders is not None:
                self.holders.close()
            self.holders = HolderWatch(bus.port_name, self.holder_check_s)
        self.set_state(DaemonState.SCANNING)
        if first:  # MOVE_START_TORQUE (robot_daemon/motion_authority.py)
            bus.power_on()
        elif not bus.dxl_power():
            # Power went while the port was away: stay off until asked, as after a reset.
            if not self.servos_off:
                self.had_torque = [j for j in bus.ids if bus.state.torque[j]]
            self._unpowered()
            return
        # First start: torque per daemon.torque_on_start (None); after a lost port: none.
        self._scan_and_hold(None if first else ())

    def _scan_and_hold(self, torque: Any) -> list[int]:
        bus = self.bus
        bus.unpowered = False
        self.servos_off = False
        found = bus.scan()
        log.info("found %d devices on %s: %s", len(found), bus.port_name, sorted(found))
        alarmed = bus.initial_read(torque)
        for w in bus.warnings:
            self.emit("warning", w)
        bus.read_sensors()
        self._buttons_last = self._buttons()
        self.hold_on_return = True
        return alarmed

    def reopened(self) -> None:
        """The port is back (``connect(first=False)`` succeeded): one event saying what holds."""
        self.down = False
        bus = self.bus
        if self.servos_off:
            self.emit(
                "port",
                f"serial port {bus.port_name} is back; DXL power is off: the servos stay off "
                "until powered (`power` op=on, the START button or the TUI)",
            )
            return
        held = [j for j in bus.ids if bus.state.online[j] and bus.state.torque[j]]
        limp = [j for j in bus.ids if bus.state.online[j] and not bus.state.torque[j]]
        self.emit(
            "port",
            f"serial port {bus.port_name} is back; {len(held)} servos kept torque and hold where "
            f"they are, {len(limp)} stay limp (nothing was powered or enabled)",
            held=held,
            limp=limp,
        )

    # -- DXL power ---------------------------------------------------------------------------
    def check_power(self) -> bool:
        """After the tick's bulk read: True when DXL power has just gone (the servos are now
        off and one event said so)."""
        bus = self.bus
        if self.servos_off or not bus.cm730_valid or bus.cm730[0] != 0:
            return False
        st = bus.state
        self.had_torque = [j for j in bus.ids if st.online[j] and st.torque[j]]
        self.manager.halt()  # MOVE_POWER_LOST (robot_daemon/motion_authority.py)
        self._unpowered()
        self.emit(
            "power",
            f"DXL power went off (the CM-730 on {bus.port_name} reads DXL_POWER 0: its reset "
            "button, or a supply glitch): every servo is limp; motion halted; the servos stay "
            "off until someone powers them (`power` op=on as admin, START or the TUI)",
            had_torque=self.had_torque,
        )
        return True

    def _unpowered(self) -> None:
        bus, st = self.bus, self.bus.state
        bus.unpowered = True
        self.servos_off = True
        st.online[:] = False
        st.torque[:] = False
        st.misses[:] = 0
        self.set_state(DaemonState.SERVOS_OFF)

    def ask_power(self, on: bool, by: str) -> dict[str, Any]:
        """The ``power`` verb: on → powered at the next tick; off → cut now (every servo limp)."""
        bus = self.bus
        if on:
            if not self.servos_off:
                return {"power": True, "changed": False}
            self.power_request = by
            return {"power": True, "changed": True, "torque": list(self.had_torque)}
        if self.servos_off:
            return {"power": False, "changed": False}
        st = bus.state
        had = [j for j in bus.ids if st.online[j] and st.torque[j]]
        self.manager.halt()
        bus.write_registers(bus.cm730_id, CM730.DXL_POWER.reg.address, b"\x00")
        self.had_torque = had
        self._unpowered()
        self.emit("power", f"DXL power cut by {by}: every servo is limp", had_torque=had, by=by)
        return {"power": False, "changed": True}

    def repower(self) -> None:
        """Power the servos (asked by the verb, START or the TUI): scan, read, torque back on
        the servos that had it (not one in alarm), each holding where it is."""
        by, self.power_request = self.power_request or "?", None
        self.manager.halt()
        try:
            self.bus.power_on()
            alarmed = self._scan_and_hold(self.had_torque)
        except BusError as exc:
            log.warning("powering the servos failed: %s", exc)
            self._unpowered()
            self.emit("fault", f"powering the servos (asked by {by}) failed: {exc}")
            return
        st = self.bus.state
        back = [j for j in self.had_torque if st.online[j] and st.torque[j]]
        more = f"; in alarm, left limp: {alarmed}" if alarmed else ""
        self.emit(
            "power",
            f"servos powered again (asked by {by}): torque back on the {len(back)} that had it, "
            f"holding where they are; the others stay limp{more}",
            torque=back,
            alarmed=alarmed,
            by=by,
        )

    # -- a second master -----------------------------------------------------------------------
    def check_holders(self) -> None:
        """Each tick (a list's length when nothing changed): a process that opened the port
        while the daemon drives it halts every motion, reported once."""
        if self.holders is None:
            return
        for pid, cmd in self.holders.new():
            self.manager.halt()  # MOVE_SECOND_MASTER (robot_daemon/motion_authority.py)
            self.emit(
                "fault",
                f"PID {pid} ({cmd}) opened {self.bus.port_name} while the daemon drives it: "
                "motion halted, and commands that move the robot are refused while it holds the "
                "port (two masters garble the bus; ROBOTIS's demo starts from /etc/rc.local: "
                "remove it there, or stop it)",
                pid=pid,
            )

    # -- buttons -------------------------------------------------------------------------------
    def _buttons(self) -> int:
        bus = self.bus
        return cm730_field(bus.cm730, CM730.BUTTON) if bus.cm730_valid else self._buttons_last

    def check_buttons(self) -> None:
        """A press (the bit going 1) of MODE or START does what ``daemon.buttons`` says."""
        now = self._buttons()
        pressed, self._buttons_last = now & ~self._buttons_last, now
        if not pressed:
            return
        if pressed & MODE_BUTTON:
            self._mode()
        if pressed & START_BUTTON:
            self._start()

    def _mode(self) -> None:
        action = self.buttons.mode
        if action is ModeAction.NONE:
            self.emit("button", "MODE pressed (daemon.buttons.mode = none)", button="mode")
            return
        self.manager.stop_all()  # MOVE_MODE_BUTTON (robot_daemon/motion_authority.py)
        what = "every motion stops safely and the pose is held"
        player = self.manager.get("action")
        if action is ModeAction.SIT and not self.servos_off and isinstance(player, ActionModule):
            what = "every motion stops; sitting down"
            try:
                player.play(SIT_PAGE)
            except (KeyError, ValueError) as exc:
                what = f"every motion stops; cannot sit down ({exc})"
        self.emit("button", f"MODE pressed: {what} (daemon.buttons.mode = {action})", button="mode")

    def _start(self) -> None:
        if self.buttons.start is StartAction.POWER and self.servos_off:
            # MOVE_POWER_BACK (robot_daemon/motion_authority.py)
            self.power_request = "the START button"
            self.emit("button", "START pressed: powering the servos", button="start")
            return
        self.emit(
            "button",
            f"START pressed (daemon.buttons.start = {self.buttons.start}; servos "
            f"{'off' if self.servos_off else 'on'}): nothing to do",
            button="start",
        )

    # -- losing the port -----------------------------------------------------------------------
    def gate(self, req: Request) -> None:
        """Refuse what needs the bus or moves the robot while the port is lost or the servos
        are off (halt, lease, config and stops still work): acknowledging it would run it later."""
        bus = self.bus
        if self.down and (req.verb == "registers" or needs_lease(req.verb, req.fields)):
            raise Reject(
                ErrorCode.UNAVAILABLE,
                f"the serial port {bus.port_name} is lost (status.state is port_lost): "
                f"{req.verb} not done; send it again once the port is back",
            )
        if (
            self.servos_off
            and req.verb not in WITHOUT_SERVOS
            and (req.verb == "registers" or needs_lease(req.verb, req.fields))
        ):
            raise Reject(
                ErrorCode.UNAVAILABLE,
                f"the servos are off (DXL power, status.state is servos_off): {req.verb} not "
                "done; power them first (`power` op=on as admin, the START button or the TUI)",
            )
        if self.stopping and (req.verb == "registers" or needs_lease(req.verb, req.fields)):
            # A walk ending its last step at shutdown must not be started again.
            raise Reject(
                ErrorCode.UNAVAILABLE,
                f"the daemon is stopping (status.state is stopping): {req.verb} not done",
            )
        intruders = self.holders.current if self.holders is not None else []
        if intruders and (req.verb == "registers" or needs_lease(req.verb, req.fields)):
            pid, cmd = intruders[0]
            raise Reject(
                ErrorCode.UNAVAILABLE,
                f"PID {pid} ({cmd}) holds {bus.port_name} too: {req.verb} not done while two "
                "programs drive one bus; stop it (ROBOTIS's demo starts from /etc/rc.local)",
            )
        why = self.guard.refusal(req.verb, req.fields)
        if why is not None:
            raise Reject(ErrorCode.UNAVAILABLE, why)

    def port_lost(self, exc: Exception) -> None:
        bus = self.bus
        log.warning("serial port lost: %s", exc)
        self.emit(
            "fault", f"serial port lost: {exc}; motion halted, reopening with back-off",
            port=bus.port_name,
        )
        # Nothing that ran before the outage resumes after it: every module stops now, and
        # the first tick with the port back holds the pose the robot is in.
        self.down = True
        self.hold_on_return = True
        self.manager.halt()
        bus.close()
        bus.counters.port_reopens += 1
        self.set_state(DaemonState.PORT_LOST)
        self.backoff = self.backoff_min

    def try_reopen(self) -> float | None:
        """One attempt: None when the port is back, else how long to wait before the next."""
        try:
            self.connect(first=False)
            self.reopened()
            return None
        except BusError as exc:
            log.info("reopening %s failed: %s", self.bus.port_name, exc)
            self.bus.close()
            self.set_state(DaemonState.PORT_LOST)
        wait, self.backoff = self.backoff, min(self.backoff * 2, self.backoff_max)
        return wait

    # -- every tick and shutdown ---------------------------------------------------------------
    def hold_if_back(self, frame: JointFrame) -> None:
        if self.hold_on_return:
            # Port or power back: whatever goals the servos kept, hold the present pose.
            self.hold_on_return = False
            self.manager.hold_present(frame)

    def halt_and_hold(self, tick: int, tick_s: float) -> None:
        """Every module stops now and the present pose is written as the goal, while the bus
        is still ours: no walk or page goes on (or freezes mid-stride) once nobody drives it."""
        self.manager.halt()
        bus = self.bus
        if bus.is_open:
            try:
                bus.read_sensors()
                frame = bus.frame(tick + 1, time.monotonic(), tick_s)
                self.manager.hold_present(frame)
                bus.write_targets(self.manager.step(frame))
            except Exception as exc:  # a port already gone: nothing more to hold
                log.warning("holding the pose at shutdown failed: %s", exc)
            bus.paint_disconnected()
        if self.holders is not None:
            self.holders.close()
