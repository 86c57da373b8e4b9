"""``darwin doctor``: one line per check of the robot, each failing line with its fix.

With the daemon running it asks the daemon over Zenoh (read-only); with the port free it scans
the bus itself. ``--json`` prints one object: ``{"ok": bool, "source": …, "checks": [...]}``.
Exit status 0 when nothing failed (warnings allowed), 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from config.loader import load_all, robot_from_dict, section_to
from config.robotis_offsets import ROBOTIS_CONFIG_INI, offsets_not_imported
from robot_daemon.bus.preflight import MIN_MX28_FIRMWARE
from robot_daemon.bus.tables import SERVO_IDS
from robot_daemon.doctor import checks as C
from robot_daemon.doctor.daemon_link import DaemonLink
from robot_daemon.doctor.probe import Facts, from_bus, from_daemon
from robot_daemon.power_policy import load_settings as load_power_settings
from schemas.errors import DarwinError, PortError
from schemas.session import add_target_arguments, resolve_args


@dataclass
class DoctorSettings:
    """The ``[doctor]`` section: the thresholds of its checks."""

    disk_min_mb: float = 500.0
    recordings_dir: str = ""
    loop_headroom_min: float = 0.25
    clock_min_year: int = 2024
    clock_skew_s: float = 2.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--port", help="serial port (config daemon.port)")
    parser.add_argument("--baud", type=int, help="baud rate (config daemon.baud)")
    parser.add_argument("--config", metavar="FILE", help="user config file")
    parser.add_argument("--json", action="store_true", help="one JSON object, for scripts")
    parser.add_argument(
        "--no-daemon", action="store_true", help="do not look for a daemon; scan the bus"
    )
    parser.add_argument("--sysfs", default="/sys", help=argparse.SUPPRESS)  # tests: a fake FTDI
    add_target_arguments(parser)


def client_version() -> str:
    try:
        return metadata.version("darwin-zenoh")
    except metadata.PackageNotFoundError:
        return "unknown"


def _daemon_facts(args: argparse.Namespace, ids: list[int]) -> tuple[Facts | None, str, str]:
    target = resolve_args(args)
    if args.no_daemon:
        return None, target.endpoint, target.robot
    try:
        with DaemonLink(target) as link:
            if not link.alive(timeout=1.5):
                return None, target.endpoint, target.robot
            return from_daemon(link, ids), target.endpoint, target.robot
    except DarwinError:
        return None, target.endpoint, target.robot


def gather(args: argparse.Namespace) -> tuple[list[C.Check], str]:
    data = load_all(args.config)
    s = section_to(DoctorSettings, data.get("doctor", {}), "doctor")
    # The battery and heat thresholds are the policy's own ([power], [heat]): the doctor warns
    # where the robot warns and fails where it would sit down.
    power, heat = load_power_settings(data)
    dcfg, bus_cfg = data.get("daemon", {}), data.get("bus", {})
    port = args.port or dcfg.get("port", "/dev/ttyUSB0")
    baud = int(args.baud or dcfg.get("baud", 1_000_000))
    ids = [j["id"] for j in data.get("robot", {}).get("joints", {}).values()] or list(SERVO_IDS)
    ids.sort()
    out: list[C.Check] = []
    facts, endpoint, robot = _daemon_facts(args, ids)
    running = facts is not None
    local = os.path.exists(port)
    if facts is not None and not local:
        where = facts.port or port
        out.append(C.Check("serial", C.SKIP, f"{where} is on the daemon's computer"))
    else:
        out.append(C.serial_device(port))
    if local:
        out.append(C.port_holder_check(port, C.port_holders(port), running))
        out.append(C.latency_timer(port, Path(args.sysfs)))
    if facts is None and local and out[-2].status != C.FAIL:
        try:
            facts = from_bus(
                port,
                baud,
                ids,
                margin_ms=float(bus_cfg.get("start_reply_margin_ms", 20.0)),
                power_on_s=float(bus_cfg.get("power_on_delay_ms", 300.0)) / 1000,
            )
        except PortError as exc:
            out.append(C.Check("bus", C.FAIL, str(exc), "stop whatever holds the port"))
    if facts is not None:
        if facts.source == "bus":
            out.append(C.bus_answers(port, baud, facts.answered_at, facts.devices))
        else:
            out.append(C.Check("bus", C.OK, f"the daemon runs the bus ({facts.devices} devices)"))
        if facts.source == "daemon" or facts.answered_at == baud:
            out += C.servos(ids, facts.servos, MIN_MX28_FIRMWARE)
            out.append(C.voltage(facts.voltage, power.warn_v, power.sit_v))
            out.append(C.temperatures(facts.temperatures, heat.warn_c, heat.sit_c))
    out.append(
        C.clock(
            time.time(), s.clock_min_year, facts.daemon_stamp if facts else None, s.clock_skew_s
        )
    )
    out.append(C.disk(Path(s.recordings_dir or "."), s.disk_min_mb))
    ini = str(dcfg.get("robotis_config_ini", ROBOTIS_CONFIG_INI) or "")
    if ini and os.path.isfile(ini):  # a robot with ROBOTIS's files on it
        robot_cfg = robot_from_dict(data["robot"])
        out.append(C.robotis_offsets(ini, offsets_not_imported(ini, robot_cfg)))
    out.append(C.loop_headroom(facts.loop if facts else None, s.loop_headroom_min))
    out.append(C.zenoh_reach(endpoint, robot, running, facts.state if facts else None))
    out.append(C.versions(client_version(), facts.daemon_version if facts else None))
    return out, facts.source if facts else "none"


def run(args: argparse.Namespace) -> int:
    results, source = gather(args)
    failed = any(c.status == C.FAIL for c in results)
    if args.json:
        print(
            json.dumps(
                {"ok": not failed, "source": source, "checks": [c.as_dict() for c in results]}
            )
        )
    else:
        for c in results:
            print(c.line())
    return 1 if failed else 0
