"""The boot service: systemd units for the daemon (and optionally the gateway and a router) and a
udev rule for the CM-730's USB serial adapter. Pure text and file placement here; the command
(``darwin service``) is :mod:`robot_daemon.launch.service_cli`.

The CM-730 reaches the PC through an FTDI FT232R USB-UART, USB id 0403:6001 (the chip on the
CM-730 board; ROBOTIS's Linux demos open it as ``LinuxCM730 linux_cm730("/dev/ttyUSB0")``, and
the NimbRo-OP setup scripts match it by its FTDI ``FT…`` serial). The rule gives it a stable name,
sets the FTDI latency timer to 1 ms (the default 16 ms delays every status packet by up to
16 ms: ``hardware.md``, packet timeout) and keeps ModemManager off it (``ID_MM_DEVICE_IGNORE``).
brltty claims every 0403:6001 adapter from its own udev rules (Ubuntu, Debian with brltty
installed), which no later rule can undo: ``install`` masks its two units instead
(``brltty-udev.service``, ``brltty.path``: symlinks to /dev/null), ``remove`` unmasks them.
"""

from __future__ import annotations

import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path

from schemas.errors import DarwinError

FTDI_VENDOR = "0403"
FTDI_PRODUCT = "6001"
DEVICE_NAME = "darwin-cm730"  # /dev/darwin-cm730
UDEV_RULE = "99-darwin-cm730.rules"
UNIT_DIR = "etc/systemd/system"
UDEV_DIR = "etc/udev/rules.d"
# The daemon's stop (halt, hold the pose, close the session) takes well under a second; the
# margin covers a slow Atom and a recorder flushing its last chunk.
STOP_TIMEOUT_S = 15
COMPONENTS = ("daemon", "gateway", "router")
BRLTTY_UNITS = ("brltty-udev.service", "brltty.path")


class ServiceError(DarwinError):
    """The boot service cannot be installed, removed or read here."""


def unit_name(component: str) -> str:
    return f"darwin-{component}.service"


@dataclass(frozen=True)
class ServicePlan:
    """What ``darwin service install`` writes."""

    darwin: str  # absolute path of the `darwin` program
    config: str | None  # absolute path of the user's config, baked into every ExecStart
    user: str
    components: tuple[str, ...] = ("daemon",)
    port: str = f"/dev/{DEVICE_NAME}"
    extra: dict[str, list[str]] = field(default_factory=dict)

    def command(self, component: str) -> str:
        args = [self.darwin, component]
        if self.config:
            args += ["--config", self.config]
        if component == "daemon":
            args += ["--port", self.port]
        args += self.extra.get(component, [])
        return " ".join(_quote(a) for a in args)

    def unit(self, component: str) -> str:
        after = ["network-online.target"]
        wants = ["network-online.target"]
        if component == "daemon" and "router" in self.components:
            after.append(unit_name("router"))
        if component == "gateway":
            after.append(unit_name("daemon"))
            wants.append(unit_name("daemon"))
        lines = [
            "# Written by `darwin service install`; `darwin service remove` deletes it.",
            "[Unit]",
            f"Description=darwin-zenoh {component}",
            "Documentation=https://github.com/darwin-zenoh/darwin-zenoh/blob/main/docs/service.md",
            f"After={' '.join(after)}",
            f"Wants={' '.join(wants)}",
            "",
            "[Service]",
            "Type=simple",
            f"User={self.user}",
            f"ExecStart={self.command(component)}",
            "Environment=PYTHONUNBUFFERED=1",
            "Restart=on-failure",
            "RestartSec=2",
            # SIGTERM to the main process only: the daemon halts, holds the pose and stops its
            # children itself; whatever is left after the timeout gets SIGKILL.
            "KillSignal=SIGTERM",
            "KillMode=mixed",
            f"TimeoutStopSec={STOP_TIMEOUT_S}",
            "StandardOutput=journal",
            "StandardError=journal",
            f"SyslogIdentifier=darwin-{component}",
        ]
        if component == "daemon":
            lines += ["SupplementaryGroups=dialout"]
        lines += ["", "[Install]", "WantedBy=multi-user.target", ""]
        return "\n".join(lines)


def udev_rule() -> str:
    match = (
        f'SUBSYSTEM=="tty", ATTRS{{idVendor}}=="{FTDI_VENDOR}", '
        f'ATTRS{{idProduct}}=="{FTDI_PRODUCT}"'
    )
    return "\n".join(
        [
            "# Written by `darwin service install`: the CM-730's FTDI FT232R (0403:6001).",
            f'{match}, SYMLINK+="{DEVICE_NAME}", GROUP="dialout", MODE="0660", '
            'ENV{ID_MM_DEVICE_IGNORE}="1"',
            # The latency timer is an attribute of the usb-serial device, the tty's parent.
            f'{match}, ATTR{{device/latency_timer}}="1"',
            "",
        ]
    )


def rule_fields(text: str) -> list[dict[str, tuple[str, str]]]:
    """Each rule line as {key: (operator, value)}: what the tests check when udevadm cannot."""
    rules = []
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        entry: dict[str, tuple[str, str]] = {}
        for part in line.split(", "):
            for op in ("==", "+=", ":=", "!=", "="):
                key, sep, value = part.partition(op)
                if sep:
                    if not (value.startswith('"') and value.endswith('"')):
                        raise ValueError(f"{part!r}: the value must be in double quotes")
                    entry[key] = (op, value[1:-1])
                    break
            else:
                raise ValueError(f'{part!r} is not KEY OP "VALUE"')
        rules.append(entry)
    return rules


SYSTEMD_RUNNING = Path("/run/systemd/system")  # sd_booted(3): present when systemd is PID 1


def has_systemd(root: Path) -> bool:
    """systemd runs here (the live system only; a temp root always can hold units)."""
    if root != Path("/"):
        return True
    return SYSTEMD_RUNNING.is_dir()


def refuse_without_systemd(root: Path) -> None:
    if not has_systemd(root):
        raise ServiceError(
            "systemd is not running on this machine (no /run/systemd/system): start the daemon "
            "another way (an init script running `darwin daemon`), or use --root DIR to write "
            "the files for another system"
        )


def paths(root: Path, components: tuple[str, ...]) -> dict[str, Path]:
    out = {c: root / UNIT_DIR / unit_name(c) for c in components}
    out["udev"] = root / UDEV_DIR / UDEV_RULE
    return out


def darwin_program() -> str:
    here = Path(sys.executable).parent / "darwin"
    if here.exists():
        return str(here.absolute())
    found = shutil.which("darwin")
    if found is None:
        raise ServiceError(
            "cannot find the `darwin` program: install the package (pip install -e .) or run "
            "`darwin service` from the environment it is installed in"
        )
    return str(Path(found).absolute())


def install(plan: ServicePlan, root: Path, dry_run: bool = False) -> list[tuple[Path, str]]:
    """The files to write (written unless ``dry_run``), as (path, text)."""
    refuse_without_systemd(root)
    where = paths(root, plan.components)
    files = [(where[c], plan.unit(c)) for c in plan.components]
    files.append((where["udev"], udev_rule()))
    masks = [root / UNIT_DIR / u for u in BRLTTY_UNITS]
    files += [(m, "-> /dev/null") for m in masks if not m.is_symlink()]
    if not dry_run:
        for path, text in files:
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                if path in masks:
                    path.symlink_to("/dev/null")
                else:
                    path.write_text(text)
            except PermissionError:
                raise ServiceError(
                    f"cannot write {path}: permission denied; run with sudo (or --root DIR)"
                ) from None
    return files


def installed(root: Path) -> dict[str, Path]:
    """The files of ours present under ``root`` (the brltty masks: symlinks to /dev/null)."""
    found = {k: p for k, p in paths(root, COMPONENTS).items() if p.exists()}
    for unit in BRLTTY_UNITS:
        mask = root / UNIT_DIR / unit
        if mask.is_symlink() and str(mask.readlink()) == "/dev/null":
            found[unit] = mask
    return found


def remove(root: Path, dry_run: bool = False) -> list[Path]:
    refuse_without_systemd(root)
    found = list(installed(root).values())
    if not dry_run:
        for path in found:
            try:
                path.unlink()
            except PermissionError:
                raise ServiceError(
                    f"cannot remove {path}: permission denied; run with sudo (or --root DIR)"
                ) from None
    return found


def _quote(arg: str) -> str:
    # systemd's ExecStart splits on whitespace and honours double quotes.
    if not arg or any(c in arg for c in ' \t"\\$%'):
        escaped = arg.replace("\\", "\\\\").replace('"', '\\"').replace("$", "$$")
        return f'"{escaped.replace("%", "%%")}"'
    return arg
