"""ROS 2 adapter: its CPU at 125 Hz joint_states, and the latency it adds.

Starts ``darwin up`` (emulator with wire timing, daemon, no gateway) and ``darwin ros2`` on free
loopback ports. In this process two subscribers watch the same ticks:

- the msgpack path (the baseline): the daemon's ``…/joints`` decoded with ``schemas.messages``;
- the ROS path: ``/<robot>/joint_states`` as an rmw_zenoh subscriber gets it (CDR decoded with
  rosbags, attachment parsed).

Latency is receive time minus the sample's bus-read stamp (the same stamp travels both paths), so
the difference of the two medians is what the adapter adds. CPU is the adapter process's
user+system time over the window (from /proc), as a share of one core and per message.

Run by hand:  .venv/bin/python benchmarks/ros2_benchmark.py [--seconds 10]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks.common import cpu_seconds  # noqa: E402
from schemas.keys import Keys  # noqa: E402
from schemas.messages import Joints, decode  # noqa: E402
from schemas.session import open_client  # noqa: E402
from tests.fixtures.system import darwin_command, start_system  # noqa: E402
from tests.ros2_observer import STORE, RmwObserver, read_attachment  # noqa: E402

DOMAIN = 9


def pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, int(q * len(s)))]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    args = ap.parse_args()
    with start_system(gateway=False) as system:
        adapter = subprocess.Popen(
            darwin_command(
                "ros2",
                "--connect",
                system.endpoint,
                "--robot",
                system.robot,
                "--domain",
                str(DOMAIN),
            ),
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
            cwd=REPO,
            start_new_session=True,
        )
        try:
            assert adapter.stdout is not None
            for line in adapter.stdout:
                if line.startswith("ros2: domain"):
                    break
            msgpack_lat: list[float] = []
            ros_lat: list[float] = []
            with open_client(system.endpoint) as session:
                obs = RmwObserver(session, DOMAIN)
                ros_key = obs.key(f"/{system.robot}/joint_states", "sensor_msgs/msg/JointState")

                def on_joints(sample) -> None:
                    m = decode(sample.payload.to_bytes(), Joints)
                    msgpack_lat.append(time.time() - m.stamp)

                def on_ros(sample) -> None:
                    read_attachment(sample.attachment.to_bytes())
                    m = STORE.deserialize_cdr(
                        sample.payload.to_bytes(), "sensor_msgs/msg/JointState"
                    )
                    ros_lat.append(
                        time.time() - (m.header.stamp.sec + m.header.stamp.nanosec * 1e-9)
                    )

                subs = [
                    session.declare_subscriber(Keys(system.robot).joints, on_joints),
                    session.declare_subscriber(ros_key, on_ros),
                ]
                deadline = time.monotonic() + 30
                while len(ros_lat) < 50 and time.monotonic() < deadline:
                    time.sleep(0.1)
                time.sleep(1.0)  # warm-up: caches, first allocations
                msgpack_lat.clear()
                ros_lat.clear()
                t0, c0 = time.monotonic(), cpu_seconds(adapter.pid)
                time.sleep(args.seconds)
                t1, c1 = time.monotonic(), cpu_seconds(adapter.pid)
                n = len(ros_lat)
                for sub in subs:
                    sub.undeclare()
                obs.close()
        finally:
            adapter.terminate()
            adapter.wait(timeout=10)
    wall = t1 - t0
    rate = n / wall
    cpu = (c1 - c0) / wall
    print(f"window: {wall:.1f} s, joint_states {rate:.1f} Hz (daemon tick 8 ms = 125 Hz)")
    print(
        f"adapter CPU: {100 * cpu:.1f} % of one core, "
        f"{1e6 * (c1 - c0) / max(1, n):.0f} µs per joint_states (incl. imu, tf)"
    )
    print(
        f"msgpack path (baseline) stamp→decoded: p50 {1e3 * pct(msgpack_lat, 0.5):.2f} ms, "
        f"p99 {1e3 * pct(msgpack_lat, 0.99):.2f} ms"
    )
    print(
        f"ROS path (adapter) stamp→decoded:    p50 {1e3 * pct(ros_lat, 0.5):.2f} ms, "
        f"p99 {1e3 * pct(ros_lat, 0.99):.2f} ms"
    )
    added = statistics.median(ros_lat) - statistics.median(msgpack_lat)
    print(f"added by the adapter (median): {1e3 * added:.2f} ms")
    print(f"(samples: msgpack {len(msgpack_lat)}, ros {len(ros_lat)})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
