"""The MuJoCo plant against the kinematic one, measured in the same run.

    .venv/bin/python benchmarks/physics_benchmark.py [--seconds 10] [--stack-seconds 15]
                                                     [--frames 200] [--skip-stack]

1. The plant alone, lock-step: the emulator's servo model and the world (``Emulator.advance``
   in 8 ms slices, no daemon), robot standing with torque on: simulated seconds per wall
   second, kinematic (the baseline) and MuJoCo; and bare ``mj_step`` steps per second.
2. The lock-step rig (``SimRig``: the daemon's bus code and motion modules over the in-process
   link, the ball finder on camera frames at 30 simulated fps): simulated s per wall s, both.
3. The whole stack in real time: ``darwin up --physics mujoco`` against ``darwin up``, each run
   for ``--stack-seconds``: simulated time over wall time (from the World message's
   ``sim_time``), the motion loop's tick rate, p99 period and overruns (from ``status.loop``).
4. The camera at the world's resolution (320×240): MuJoCo offscreen (EGL/OSMesa on the CPU,
   shadows and reflections off) against the OpenCV renderer, frames per second.

Needs the physics extra (``pip install -e '.[physics]'``). Ratios are MuJoCo / kinematic.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from config.loader import load_all
from tests.fixtures.sim_rig import SimRig

PLANTS = ("kinematic", "mujoco")
SLICE_S = 0.008


def rig(plant: str) -> SimRig:
    r = SimRig(seed=1, settings=load_all(), physics=plant)
    r.world.place_robot(0.0, 0.0, 0.0)
    r.run(0.5)  # the daemon holds its pose, torque on: the plant settles
    return r


def plant_speed(plant: str, seconds: float) -> float:
    r = rig(plant)
    n = round(seconds / SLICE_S)
    start = time.perf_counter()
    for _ in range(n):
        r.emulator.advance(SLICE_S)
    return n * SLICE_S / (time.perf_counter() - start)


def mj_steps_per_s(seconds: float) -> tuple[float, float]:
    """Bare ``mj_step`` calls per wall second on the world's model, and its timestep (s)."""
    world = rig("mujoco").world
    mj, m, d = world.mj, world.model, world.data
    n = round(seconds / m.opt.timestep)
    start = time.perf_counter()
    for _ in range(n):
        mj.mj_step(m, d)
    return n / (time.perf_counter() - start), float(m.opt.timestep)


def rig_speed(plant: str, seconds: float) -> float:
    r = rig(plant)
    t0, start = r.time, time.perf_counter()
    r.run(seconds)
    return (r.time - t0) / (time.perf_counter() - start)


def stack(plant: str, seconds: float) -> dict[str, float]:
    from tests.fixtures.system import start_system

    extra = ["--physics", plant] if plant != "kinematic" else []
    with (
        start_system(gateway=False, camera="none", extra_args=extra) as system,
        system.robot_client() as robot,
    ):
        robot.wait_for("status", lambda s: s.loop["ticks"] > 50, timeout=60)
        w0 = robot.wait_for("world", timeout=30)
        s0 = robot.wait_for("status", timeout=10)
        time.sleep(seconds)  # the measurement window: real time is what is measured
        w1 = robot.wait_for("world", timeout=10)
        s1 = robot.wait_for("status", timeout=10)
    loop0, loop1 = s0.loop, s1.loop
    return {
        "sim_per_wall": (w1.sim_time - w0.sim_time) / (w1.stamp - w0.stamp),
        "ticks_per_s": (loop1["ticks"] - loop0["ticks"]) / (s1.stamp - s0.stamp),
        "p99_ms": loop1["period_p99_ms"],
        "overruns": loop1["overruns"] - loop0["overruns"],
    }


def camera_fps(frames: int) -> dict[str, float]:
    from robot_daemon.plant.physics.mujoco_camera import GLUnavailableError, MujocoCamera

    world = rig("mujoco").world
    cam_model = world.settings.render.camera
    out: dict[str, float] = {}
    pose, ball = world.camera_view()
    start = time.perf_counter()
    for _ in range(frames):
        world.renderer().render(pose, ball)
    out["opencv"] = frames / (time.perf_counter() - start)
    try:
        cam = MujocoCamera(world.model, cam_model.width, cam_model.height)
    except GLUnavailableError as exc:
        print(f"  (no MuJoCo camera: {exc})")
        out["mujoco"] = float("nan")
        return out
    with cam:
        cam.render(world.data)  # the first frame compiles llvmpipe's shaders
        start = time.perf_counter()
        for _ in range(frames):
            cam.render(world.data)
        out["mujoco"] = frames / (time.perf_counter() - start)
        out["backend"] = cam.backend  # type: ignore[assignment]
    return out


def row(name: str, base: float, mine: float, unit: str) -> None:
    ratio = mine / base if base else float("nan")
    print(f"{name:34}{base:>12.2f}{mine:>12.2f}{ratio:>10.2f}  {unit}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="simulated s per lock-step run")
    parser.add_argument("--stack-seconds", type=float, default=15.0, help="wall s per darwin up")
    parser.add_argument("--frames", type=int, default=200)
    parser.add_argument("--skip-stack", action="store_true", help="no darwin up runs")
    args = parser.parse_args()

    print(f"lock-step runs of {args.seconds:.0f} simulated s …", flush=True)
    plant = {p: plant_speed(p, args.seconds) for p in PLANTS}
    rigs = {p: rig_speed(p, args.seconds) for p in PLANTS}
    steps, dt = mj_steps_per_s(min(args.seconds, 5.0))
    cams = camera_fps(args.frames)
    stacks: dict[str, dict[str, Any]] = {}
    if not args.skip_stack:
        for p in PLANTS:
            print(f"darwin up ({p}) for {args.stack_seconds:.0f} s …", flush=True)
            try:
                stacks[p] = stack(p, args.stack_seconds)
            except RuntimeError as exc:  # it did not start: its output says why
                print(f"  darwin up ({p}) did not start: {str(exc).splitlines()[-1]}")
                stacks.clear()
                break

    print()
    print(f"{'':34}{'kinematic':>12}{'mujoco':>12}{'ratio':>10}")
    row("plant alone (emulator + world)", plant["kinematic"], plant["mujoco"], "sim s / wall s")
    row("lock-step rig (daemon code)", rigs["kinematic"], rigs["mujoco"], "sim s / wall s")
    if stacks:
        k, m = stacks["kinematic"], stacks["mujoco"]
        row("darwin up: sim time / wall time", k["sim_per_wall"], m["sim_per_wall"], "")
        row("darwin up: loop ticks", k["ticks_per_s"], m["ticks_per_s"], "per s (125 due)")
        row("darwin up: loop period p99", k["p99_ms"], m["p99_ms"], "ms")
        row("darwin up: overruns", k["overruns"], m["overruns"], f"in {args.stack_seconds:.0f} s")
    print(f"{'':34}{'opencv':>12}{'mujoco':>12}{'ratio':>10}")
    backend = cams.get("backend", "no GL")
    row("camera 320×240", cams["opencv"], cams["mujoco"], f"frames/s (MuJoCo on {backend})")
    print()
    print(f"bare mj_step: {steps:,.0f} steps/s = {steps * dt:.1f}× real time at {dt * 1e3:g} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
