"""Proof that docs/robot.md installs and runs the daemon on the robot's OS: a Debian 12 i386 root
(debootstrap, cached outside the clone), the page's `recipe` block run in it word for word under
`setarch i686` + `chroot`, its `robot-run` command started there against the emulator running
outside on a pty, and a Robot client outside reading the joints and walking the robot.

Run as root (debootstrap, chroot, mounts): `bash scripts/i386-check`. The whole run happens in a
private mount namespace (`unshare --mount`), so the root's mounts go with the process on every
exit path, a kill included. One line per failure, exit status 1.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "robot.md"
CACHE = Path(os.environ.get("DARWIN_I386_CACHE", "/var/cache/darwin-zenoh/i386-bookworm"))
MIRROR = os.environ.get("DEBIAN_MIRROR", "http://deb.debian.org/debian")
SUITE, ARCH, VARIANT = "bookworm", "i386", "minbase"
HOST_CA = Path("/etc/ssl/certs/ca-certificates.crt")
ROBOT_PORT, ROBOT_LISTEN = "/dev/ttyUSB0", "tcp/0.0.0.0:7447"
# Beside the suite (scripts/test names a file in DARWIN_I386_BESIDE that exists while its tests
# run), the recipe's pip and compiler take only what the tests leave idle; once the file is gone
# they take their share again, so a machine busy with other work does not starve the check.
BESIDE_ENV = "DARWIN_I386_BESIDE"
RECIPE_NICE = 19
START_TIMEOUT = 180.0  # the daemon's first start imports numpy/zenoh from a cold disk
WAIT = 60.0


class CheckFailed(Exception):
    """One line saying what failed and where to look."""


def say(line: str) -> None:
    print(f"i386-check: {line}", flush=True)


# The page marks its blocks with a class in the attribute form of the fence, which Markdown
# (pymdownx.superfences) renders as a shell block and GitHub as a code block: an info string
# like "sh recipe" is no fence at all to Python-Markdown, and the page rendered as prose.
RECIPE = "{.sh .recipe}"
ROBOT_RUN = "{.sh .robot-run}"


def fenced_blocks(text: str, info: str) -> list[str]:
    """The bodies of the fenced blocks whose info string is exactly ``info`` (``RECIPE``)."""
    pattern = re.compile(r"^```" + re.escape(info) + r"[ \t]*\n(.*?)^```[ \t]*$", re.M | re.S)
    return [m.group(1) for m in pattern.finditer(text)]


def recipe() -> tuple[list[str], str]:
    """The page's install blocks, in order, and its daemon command."""
    text = DOC.read_text()
    install, run = fenced_blocks(text, RECIPE), fenced_blocks(text, ROBOT_RUN)
    if not install or len(run) != 1:
        raise CheckFailed(f"{DOC}: needs ```{RECIPE} blocks and one ```{ROBOT_RUN} block")
    return install, run[0].strip()


def apt_packages(blocks: list[str]) -> list[str]:
    """The packages of the recipe's `apt-get install` lines: the cached root's key."""
    found = [
        w
        for block in blocks
        for line in block.splitlines()
        if (words := shlex.split(line, comments=True))[:2] == ["apt-get", "install"]
        for w in words[2:]
        if not w.startswith("-")
    ]
    if not found:
        raise CheckFailed(f"{DOC}: the recipe has no `apt-get install` line")
    return sorted(found)


def label(block: str) -> str:
    """A block's first comment (`# the daemon`), to name it in the disk figures."""
    first = block.lstrip().splitlines()[0]
    return first.lstrip("# ").strip() if first.startswith("#") else first


def run(cmd: list[str], what: str, log: Path, **kw: Any) -> subprocess.CompletedProcess[str]:
    with log.open("a") as out:
        out.write(f"$ {shlex.join(cmd)}\n")
        out.flush()
        proc = subprocess.run(cmd, stdout=out, stderr=subprocess.STDOUT, text=True, **kw)
    if proc.returncode != 0:
        raise CheckFailed(f"{what} failed (exit {proc.returncode}); see {log}")
    return proc


def beside_suite() -> bool:
    """Whether the suite runs beside this check now (see ``BESIDE_ENV``)."""
    marker = os.environ.get(BESIDE_ENV, "")
    return bool(marker) and Path(marker).exists()


def process_tree(root: int) -> list[int]:
    """Every thread of ``root`` and of its descendants (Linux's nice is a thread's)."""
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue  # ended meanwhile
            children.setdefault(int(stat.rsplit(")", 1)[1].split()[1]), []).append(int(entry))
    threads, todo = [], [root]
    while todo:
        pid = todo.pop()
        todo.extend(children.get(pid, []))
        with contextlib.suppress(OSError):
            threads += [int(t) for t in os.listdir(f"/proc/{pid}/task")]
    return threads


def run_recipe(cmd: list[str], what: str, log: Path) -> None:
    """``cmd`` at nice ``RECIPE_NICE`` while the suite runs beside it, at normal priority from
    the moment it ends (checked each second: the tree is reniced again, so a process started
    meanwhile is caught too)."""
    niced = beside_suite()
    with log.open("a") as out:
        out.write(f"$ {shlex.join(cmd)}\n")
        out.flush()
        proc = subprocess.Popen(
            ["nice", "-n", str(RECIPE_NICE), *cmd] if niced else cmd,
            stdout=out, stderr=subprocess.STDOUT, text=True,
        )
        while True:
            try:
                code = proc.wait(timeout=1.0 if niced else None)
                break
            except subprocess.TimeoutExpired:
                if not beside_suite():
                    for tid in process_tree(proc.pid):
                        with contextlib.suppress(OSError):  # ended meanwhile
                            os.setpriority(os.PRIO_PROCESS, tid, 0)
    if code != 0:
        raise CheckFailed(f"{what} failed (exit {code}); see {log}")


def core_requirements() -> list[str]:
    return tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["dependencies"]


def dry_run(log: Path) -> None:
    """pip resolves, for 32-bit Linux and CPython 3.11, every core requirement the recipe lets
    pip fetch. numpy is left out: PyPI has no i686 numpy wheel since 1.22, so the robot takes
    Debian's (python3-numpy 1.24.2), which the install in the root below proves."""
    reqs = [r for r in core_requirements() if not r.startswith("numpy")]
    with tempfile.TemporaryDirectory() as target:
        run(
            [sys.executable, "-m", "pip", "install", "--dry-run", "--only-binary=:all:",
             "--platform", "manylinux2014_i686", "--python-version", "3.11",
             "--target", target, *reqs],
            "pip install --dry-run for manylinux2014_i686 / 3.11 of the core",
            log,
        )


def ensure_debootstrap(log: Path) -> None:
    if shutil.which("debootstrap"):
        return
    run(["apt-get", "update", "-qq"], "apt-get update (to install debootstrap)", log)
    run(["apt-get", "install", "-y", "-qq", "debootstrap"], "apt-get install debootstrap", log)


def cached_root(packages: list[str], log: Path) -> tuple[Path, bool]:
    """The debootstrapped root, rebuilt when missing or when the recipe's apt list changed.
    Returns it and whether it was built now."""
    key = f"{SUITE} {ARCH} {VARIANT} {MIRROR}\n{' '.join(packages)}\n"
    root, stamp = CACHE / "root", CACHE / "recipe.key"
    if root.is_dir() and stamp.is_file() and stamp.read_text() == key:
        return root, False
    ensure_debootstrap(log)
    building = CACHE / "root.building"
    shutil.rmtree(building, ignore_errors=True)
    shutil.rmtree(root, ignore_errors=True)
    stamp.unlink(missing_ok=True)
    run(
        ["debootstrap", f"--arch={ARCH}", f"--variant={VARIANT}", SUITE, str(building), MIRROR],
        f"debootstrap --arch={ARCH} {SUITE}",
        log,
    )
    building.rename(root)
    stamp.write_text(key)
    return root, True


@contextlib.contextmanager
def mounted(root: Path) -> Iterator[None]:
    """/proc, /sys, /dev and /dev/pts (the emulator's pty) inside the root."""
    done: list[Path] = []
    try:
        for kind, source, place in [
            ("proc", "proc", "proc"),
            ("sysfs", "sysfs", "sys"),
            ("bind", "/dev", "dev"),
            ("bind", "/dev/pts", "dev/pts"),
        ]:
            where = root / place
            where.mkdir(parents=True, exist_ok=True)
            opts = ["--bind", source] if kind == "bind" else ["-t", kind, source]
            subprocess.run(["mount", *opts, str(where)], check=True)
            done.append(where)
        yield
    finally:
        for where in reversed(done):
            subprocess.run(["umount", "-l", str(where)], check=False)


def chroot_cmd(root: Path, *cmd: str) -> list[str]:
    env = {
        "HOME": "/root",
        "PATH": "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin",
        "LANG": "C.UTF-8",
        "DEBIAN_FRONTEND": "noninteractive",
        "PIP_DISABLE_PIP_VERSION_CHECK": "1",
        "PYTHONUNBUFFERED": "1",
    }
    if HOST_CA.is_file():  # this machine's CAs, copied in by prepare() (a TLS proxy may intercept)
        env["PIP_CERT"] = "/etc/ssl/host-ca.crt"
    env_args = [f"{k}={v}" for k, v in env.items()]
    return ["setarch", "i686", "chroot", str(root), "/usr/bin/env", "-i", *env_args, *cmd]


def prepare(root: Path) -> None:
    """A fresh start for the recipe: the host's DNS and CAs, the source as ~/darwin-zenoh, no
    venv from an earlier run."""
    shutil.copyfile("/etc/resolv.conf", root / "etc" / "resolv.conf")
    if HOST_CA.is_file():
        (root / "etc" / "ssl").mkdir(exist_ok=True)
        shutil.copyfile(HOST_CA, root / "etc" / "ssl" / "host-ca.crt")
    shutil.rmtree(root / "opt" / "darwin", ignore_errors=True)
    src = root / "root" / "darwin-zenoh"
    shutil.rmtree(src, ignore_errors=True)
    files = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=REPO, capture_output=True, check=True,
    ).stdout.split(b"\0")
    for name in filter(None, files):
        path = REPO / os.fsdecode(name)
        if path.is_file():
            dest = src / os.fsdecode(name)
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(path, dest)


def du_mb(*paths: Path) -> float:
    out = subprocess.run(["du", "-sxb", *map(str, paths)], capture_output=True, text=True)
    return sum(int(line.split()[0]) for line in out.stdout.splitlines()) / 1e6


def used_mb(root: Path) -> float:
    """The root's size as the robot keeps it: without apt's downloaded .debs, pip's cache and
    the source copy."""
    caches = [root / "var/cache/apt/archives", root / "root/.cache", root / "root/darwin-zenoh"]
    return du_mb(root) - du_mb(*[c for c in caches if c.exists()])


def install(root: Path, blocks: list[str], built: bool, log: Path) -> None:
    """Run the recipe's blocks in order. On a root built now, measure what each adds and keep
    the figures with the cache (later runs find the apt packages there already)."""
    sizes = [used_mb(root)]
    for block in blocks:
        t0 = time.monotonic()
        # Beside the suite the recipe's pip and compiler (~25 s of CPU) wait for what the tests
        # leave idle (run_recipe); the daemon's run afterwards keeps normal priority, as its
        # loop would on the robot.
        run_recipe(chroot_cmd(root, "/bin/bash", "-euxo", "pipefail", "-c", block),
                   f"the recipe of docs/robot.md ({label(block)})", log)
        say(f"recipe: {label(block)}: {time.monotonic() - t0:.0f} s")
        sizes.append(used_mb(root))
    figures = CACHE / "footprint.txt"
    if built:
        lines = [f"disk: minimal Debian 12 i386 root {sizes[0]:.0f} MB"]
        lines += [f"disk: + {after - before:.0f} MB for {label(block)}"
                  for block, before, after in zip(blocks, sizes[:-1], sizes[1:], strict=True)]
        lines.append(f"disk: {sizes[-1]:.0f} MB in all")
        figures.write_text("\n".join(lines) + "\n")
    if figures.is_file():
        for line in figures.read_text().splitlines():
            say(line)
    else:
        say(f"disk: no figures kept from the build (remove {CACHE} to measure them)")
    say(f"disk: of which the venv /opt/darwin {du_mb(root / 'opt/darwin'):.0f} MB")


def start_emulator(log: Path) -> tuple[subprocess.Popen[str], str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "robot_daemon.launch.cli", "sim"],
        stdout=subprocess.PIPE, stderr=log.open("a"), text=True, cwd=REPO,
        start_new_session=True,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    if not line.startswith("port: "):
        raise CheckFailed(f"the emulator printed {line!r} instead of 'port: …'; see {log}")
    return proc, line.removeprefix("port: ").strip()


def start_daemon(
    root: Path, command: str, pty: str, endpoint: str, robot: str, log: Path
) -> subprocess.Popen[str]:
    if ROBOT_PORT not in command or ROBOT_LISTEN not in command:
        raise CheckFailed(f"{DOC}: the robot-run command lost {ROBOT_PORT} or {ROBOT_LISTEN}")
    words = shlex.split(command.replace(ROBOT_PORT, pty).replace(ROBOT_LISTEN, endpoint))
    proc = subprocess.Popen(
        chroot_cmd(root, *words, "--robot", robot),
        stdout=subprocess.PIPE, stderr=log.open("a"), text=True, start_new_session=True,
    )
    assert proc.stdout is not None
    deadline = time.monotonic() + START_TIMEOUT
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            raise CheckFailed(f"darwin daemon in the i386 root exited ({proc.wait()}); see {log}")
        if line.startswith("zenoh: "):
            return proc
    raise CheckFailed(f"darwin daemon in the i386 root did not start in {START_TIMEOUT:.0f} s")


def drive(endpoint: str, robot_name: str) -> str:
    """Read the joints and walk a few steps through the daemon in the root."""
    from clients.robot import Robot

    with Robot(endpoint, robot_name, name="i386-check", timeout=10.0) as robot:
        robot.wait_for("joints", lambda j: len(j.online) == 20 and all(j.online), WAIT)
        with robot.control():
            robot.walk(x=0.03)
            status = robot.wait_for(
                "status",
                lambda s: s.motion.get("walking", {}).get("steps", 0) >= 4,
                WAIT,
            )
            robot.walk_stop()
    loop = status.loop
    hz = loop.get("telemetry_hz", 0.0)
    return (
        f"client: read 20 joints and walked {status.motion['walking']['steps']} steps; loop "
        f"period p50 {loop.get('period_p50_ms', 0):.1f} ms, p99 {loop.get('period_p99_ms', 0):.1f}"
        f" ms, {loop.get('overruns', 0)} overruns in {loop.get('ticks', 0)} ticks; joints and IMU"
        f" {f'at {hz:g} Hz' if hz else 'every tick'}"
    )


def stop(proc: subprocess.Popen[str] | None) -> None:
    if proc is None or proc.poll() is not None:
        return
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, 15)
    try:
        proc.wait(20)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, 9)
        proc.wait()


def check(log: Path) -> None:
    t0 = time.monotonic()
    blocks, command = recipe()
    dry_run(log)
    say("pip: every core requirement pip fetches has a manylinux2014_i686 wheel for 3.11")
    CACHE.mkdir(parents=True, exist_ok=True)
    with (CACHE / "lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # one check at a time uses the cached root
        root, built = cached_root(apt_packages(blocks), log)
        say(f"root: {root} ({'built' if built else 'cached'}, {time.monotonic() - t0:.0f} s)")
        prepare(root)
        emulator = daemon = None
        with mounted(root):
            try:
                install(root, blocks, built, log)
                info = subprocess.run(
                    chroot_cmd(root, "/opt/darwin/bin/python", "-c",
                               "import platform, struct, numpy, zenoh; print(platform.machine(),"
                               " struct.calcsize('P') * 8, platform.python_version(),"
                               " 'numpy', numpy.__version__)"),
                    capture_output=True, text=True,
                )
                if info.returncode != 0 or " 32 " not in info.stdout:
                    got = (info.stdout + info.stderr).strip().splitlines()[-1:]
                    raise CheckFailed(f"the root's Python is not 32-bit i686: {got}")
                say(f"python in the root: {info.stdout.strip()}")
                hot = subprocess.run(
                    chroot_cmd(root, "/opt/darwin/bin/python", "-c",
                               "from robot_daemon import hotpath; print(hotpath.status)"),
                    capture_output=True, text=True,
                )
                if "compiled" not in hot.stdout:
                    got = (hot.stdout + hot.stderr).strip().splitlines()[-1:]
                    raise CheckFailed(f"the recipe's compiled hot path is not in use: {got}")
                say(hot.stdout.strip())
                emulator, pty = start_emulator(log)
                from schemas.session import free_tcp_port

                endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
                robot = f"i386check{uuid.uuid4().hex[:6]}"
                daemon = start_daemon(root, command, pty, endpoint, robot, log)
                say(f"daemon: running in the root on {pty}, {endpoint}")
                say(drive(endpoint, robot))
            finally:
                stop(daemon)
                stop(emulator)
    say(f"passed in {time.monotonic() - t0:.0f} s")


def main() -> int:
    if os.geteuid() != 0:
        say("needs root (debootstrap, chroot, mounts): run it as root")
        return 2
    if os.environ.get("DARWIN_I386_NS") != "1":
        # Re-run in a private mount namespace: its mounts vanish with it, however it ends.
        env = dict(os.environ, DARWIN_I386_NS="1")
        cmd = ["unshare", "--mount", "--propagation", "private", sys.executable, *sys.argv]
        return subprocess.run(cmd, env=env).returncode
    log = Path(tempfile.mkdtemp(prefix="i386-check-")) / "log.txt"
    sys.path.insert(0, str(REPO))
    try:
        check(log)
    except CheckFailed as exc:
        say(f"FAILED: {exc}")
        return 1
    except KeyboardInterrupt:
        say("interrupted")
        return 130
    except Exception as exc:  # anything else is still one line, with the log for the rest
        say(f"FAILED: {type(exc).__name__}: {exc}; see {log}")
        return 1
    shutil.rmtree(log.parent, ignore_errors=True)  # kept only when something failed
    return 0


if __name__ == "__main__":
    sys.exit(main())
