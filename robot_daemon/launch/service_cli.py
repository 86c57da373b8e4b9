"""`darwin service install|remove|status`: the daemon (and optionally the gateway and a router)
as systemd units started at boot, and the CM-730's udev rule (docs/service.md).

Every file written or removed is printed as ``file: PATH``; ``status`` prints ``UNIT: state``.
``--root DIR`` writes under DIR instead of / (an image being built, a test); ``--dry-run``
prints without writing.
"""

from __future__ import annotations

import argparse
import getpass
import shutil
import subprocess
from pathlib import Path

from robot_daemon.launch import service as svc
from schemas.errors import ConfigError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=("install", "remove", "status"))
    parser.add_argument(
        "--config", help="the user config file every unit runs with (its absolute path is kept)"
    )
    parser.add_argument("--gateway", action="store_true", help="also a unit for the gateway")
    parser.add_argument("--router", action="store_true", help="also a unit for a Zenoh router")
    parser.add_argument("--user", help="the account the units run as (default: you)")
    parser.add_argument(
        "--port",
        default=f"/dev/{svc.DEVICE_NAME}",
        help=f"the daemon's serial port (default /dev/{svc.DEVICE_NAME}, the udev rule's name)",
    )
    parser.add_argument("--root", default="/", help="write under this directory instead of /")
    parser.add_argument("--dry-run", action="store_true", help="print, write nothing")
    parser.add_argument("--now", action="store_true", help="install: also start the units")


def run(args: argparse.Namespace) -> int:
    root = Path(args.root)
    live = root == Path("/") and not args.dry_run
    if args.action == "install":
        return _install(args, root, live)
    if args.action == "remove":
        if live:
            _systemctl("disable", "--now", *_units(svc.installed(root)))
        for path in svc.remove(root, args.dry_run):
            print(f"file: {path}")
        if live:
            _reload(root)
        return 0
    return _status(root)


def _install(args: argparse.Namespace, root: Path, live: bool) -> int:
    config = None
    if args.config:
        path = Path(args.config).expanduser().absolute()
        if not path.is_file():
            raise ConfigError(f"--config {args.config}: no such file; give the config to run with")
        config = str(path)
    components = (
        ("daemon",) + (("gateway",) if args.gateway else ()) + (("router",) if args.router else ())
    )
    plan = svc.ServicePlan(
        darwin=svc.darwin_program(),
        config=config,
        user=args.user or getpass.getuser(),
        components=components,
        port=args.port,
    )
    for path, text in svc.install(plan, root, args.dry_run):
        print(f"file: {path}")
        if args.dry_run:
            print(text)
    if live:
        _reload(root)
        _systemctl("enable", *(["--now"] if args.now else []), *map(svc.unit_name, components))
    return 0


def _status(root: Path) -> int:
    svc.refuse_without_systemd(root)
    found = svc.installed(root)
    for component in svc.COMPONENTS:
        if component not in found:
            print(f"{svc.unit_name(component)}: not installed")
            continue
        state = "installed"
        if root == Path("/") and shutil.which("systemctl"):
            unit = svc.unit_name(component)
            enabled = _query("is-enabled", unit)
            active = _query("is-active", unit)
            state = f"{enabled}, {active}"
        print(f"{svc.unit_name(component)}: {state} ({found[component]})")
    udev = "installed" if "udev" in found else "not installed"
    print(f"udev rule: {udev} ({svc.paths(root, ()).get('udev')})")
    device = Path(f"/dev/{svc.DEVICE_NAME}")
    print(f"device: {device if device.exists() else 'not present (CM-730 unplugged?)'}")
    return 0


def _units(found: dict[str, Path]) -> list[str]:
    return [svc.unit_name(c) for c in svc.COMPONENTS if c in found]


def _query(verb: str, unit: str) -> str:
    done = subprocess.run(
        ["systemctl", verb, unit], capture_output=True, text=True, check=False, timeout=10
    )
    return done.stdout.strip() or "unknown"


def _systemctl(*argv: str) -> None:
    if len(argv) > 1 and not argv[-1].startswith("-"):
        subprocess.run(["systemctl", *argv], check=False, timeout=60)


def _reload(root: Path) -> None:
    subprocess.run(["systemctl", "daemon-reload"], check=False, timeout=60)
    if shutil.which("udevadm"):
        subprocess.run(["udevadm", "control", "--reload-rules"], check=False, timeout=30)
        subprocess.run(["udevadm", "trigger", "--subsystem-match=tty"], check=False, timeout=30)
