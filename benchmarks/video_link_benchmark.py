"""Video never delays control: halt and lease round trips on a link shaped like busy Wi-Fi, with
and without two camera viewers on it (same run, same link).

The network is ``tests/fixtures/netns.py``'s: ``darwin up --camera sim`` in a ``robot``
namespace, and on the shaped ``operator`` link (``tc netem``, or the TUN forwarder on a kernel
without netem: ~10 Mbit/s, 20 ms ± 5 ms each way, 1 % loss) the operator — a notebook ``Robot``
holding the lease and renewing it — and a second viewer. The camera runs at 320×240,
quality 100 (~50 kB a frame, as a UVC camera's 640×480 MJPEG), 30 fps (the simulated world's
JPEG, passed through): two viewers ask for more than the link carries, so the daemon must drop
frames.

Figures: round trips (p50 / p90 / max, ms) of ``halt`` and of a lease renewal, quiet and while
both viewers watch, beside the link's own round trip (2 × delay); the viewers' frame rate,
Mbit/s, frames skipped (dropped by the daemon), and their backlog in frames (frames the daemon
had captured beyond the one arriving: queued or in flight ahead of the viewer); the frames that
reached the operator during each halt's round trip; the daemon's memory before and after.

Needs root (network namespaces).  Run by hand:
    sudo .venv/bin/python benchmarks/video_link_benchmark.py [--n 40] [--interval 0.25]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.fixtures.netns import Agent, AgentError, unavailable  # noqa: E402
from tests.fixtures.video_link import WIFI, shaped_link, udp_rtts  # noqa: E402


def round_trips(agent: Agent, verb: str, n: int, interval: float, **fields: Any) -> dict[str, Any]:
    return agent.request("rtt", verb=verb, n=n, interval=interval, fields=fields, timeout=n * 6.0)


def summary(xs: list[float]) -> str:
    if not xs:
        return "none"
    ms = sorted(x * 1000 for x in xs)
    p90 = ms[min(len(ms) - 1, int(len(ms) * 0.9))]
    return f"p50 {statistics.median(ms):6.1f}  p90 {p90:6.1f}  max {ms[-1]:6.1f} ms"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=40, help="round trips per figure")
    parser.add_argument("--interval", type=float, default=0.25, help="s between commands")
    args = parser.parse_args()
    if (why := unavailable()) is not None:
        print(f"error: {why}")
        return 1
    with shaped_link() as link:
        quiet_halt = round_trips(link.operator, "halt", args.n, args.interval)
        quiet_lease = round_trips(link.operator, "lease", args.n, args.interval, op="renew")
        rss0 = link.rss_kib()
        link.operator.request("camera", start=True)
        link.viewer.request("camera", start=True)
        time.sleep(3.0)  # let the viewers fill the link (a measurement window, not a sync)
        ping = udp_rtts(link.net)
        busy_halt = round_trips(link.operator, "halt", args.n, args.interval)
        busy_lease = round_trips(link.operator, "lease", args.n, args.interval, op="renew")
        rss1 = link.rss_kib()
        time.sleep(5.0)  # five seconds more of video: does anything keep growing?
        rss2 = link.rss_kib()
        op_view = link.operator.request("camera", stop=True)
        second = link.viewer.request("camera", stop=True)
        try:
            held = link.operator.call("command", "lease", op="renew")
        except AgentError as exc:
            held = {"error": str(exc)}
        impairment = link.net.impairment
    link_rtt = 2 * WIFI["delay_ms"]
    print(f"link: {WIFI['rate_mbit']:g} Mbit/s, {WIFI['delay_ms']:g} ± {WIFI['jitter_ms']:g} ms "
          f"each way, {WIFI['loss_pct']:g} % loss ({impairment}); its own round trip "
          f"{link_rtt:g} ms")  # fmt: skip
    print(f"UDP echo across the link while the viewers watch: {summary(ping)}")
    print(f"halt, quiet link:           {summary(quiet_halt['rtt'])}")
    print(f"halt, two viewers:          {summary(busy_halt['rtt'])}")
    print(f"lease renewal, quiet link:  {summary(quiet_lease['rtt'])}")
    print(f"lease renewal, two viewers: {summary(busy_lease['rtt'])}")
    errors = (
        quiet_halt["errors"] + quiet_lease["errors"] + busy_halt["errors"] + busy_lease["errors"]
    )
    print(f"commands without a reply: {len(errors)}{': ' + errors[0] if errors else ''}")
    print(f"lease after the run: {held.get('error') or 'still held'}")
    for who, v in (("operator's viewer", op_view), ("second viewer", second)):
        if not v.get("n"):
            print(f"{who}: no frames")
            continue
        print(
            f"{who}: {v['rate']:.1f} frames/s, {v['mbit']:.1f} Mbit/s, "
            f"{v['mean_bytes'] / 1000:.0f} kB/frame, {v['skipped']} skipped, backlog (frames) "
            f"first/last third {v['backlog_first']}/{v['backlog_last']} (max "
            f"{v['backlog_max']}), in order: {v['in_order']}"
        )
    during = busy_halt["frames_during"]
    if during:
        print(f"frames reaching the operator during a halt's round trip: max {max(during)}, "
              f"mean {statistics.mean(during):.1f}")  # fmt: skip
    print(f"daemon memory: {rss0 / 1024:.1f} MiB before the viewers, {rss1 / 1024:.1f} MiB after "
          f"the round trips, {rss2 / 1024:.1f} MiB 5 s later")  # fmt: skip
    for name, quiet, busy in (("halt", quiet_halt, busy_halt), ("lease", quiet_lease, busy_lease)):
        if quiet["rtt"] and busy["rtt"]:
            q, b = statistics.median(quiet["rtt"]) * 1000, statistics.median(busy["rtt"]) * 1000
            print(f"ratio {name} p50 with viewers / quiet: {b / q:.2f}; beyond the link's "
                  f"round trip: +{b - link_rtt:.1f} ms")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
