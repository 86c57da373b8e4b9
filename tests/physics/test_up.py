"""`darwin up --physics mujoco`: the whole stack on the MuJoCo plant in real time — the daemon
sees the same bus, the World publication and the sim control ops work, the robot stands, walks
forward and a push knocks it over, which the daemon's fall detector reports."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from clients.robot import Robot
from schemas.errors import CommandTimeoutError
from schemas.messages import Event
from schemas.sim_control import SimControl
from tests.fixtures.system import start_system
from tests.integration.test_motion_system import WAIT, Events

REPO = Path(__file__).resolve().parents[2]


def test_up_with_physics_stands_walks_and_falls_when_pushed() -> None:
    with (
        start_system(extra_args=["--physics", "mujoco"], camera="none", gateway=False) as system,
        system.robot_client(name="physics-up") as robot,
    ):
        robot.wait_for("joints", timeout=WAIT)
        sim = SimControl(robot.session, system.robot)
        start = sim.call("get_world")
        robot.acquire()
        events = Events(robot)
        try:
            robot.walk(x=0.1)
            # Walking in physics moves the torso forward on the field (World publication).
            robot.wait_for(
                "world", lambda w: w.robot["x"] > start["robot"]["x"] + 0.1, timeout=4 * WAIT
            )
            assert sim.call("get_world")["fallen"] == "none"
            robot.walk_stop()
            # The push lands on a robot standing still: the gait ends its step first. Pushed
            # mid-step with 60 N for 0.2 s (as this test once did), the body sometimes rolled
            # right over onto its front (3 of 16 gait phases, lock-step on this plant), and the
            # detector's call and the world's first verdict then named different sides.
            events.wait(lambda e: e.kind == "walk" and e.data.get("state") == "stopped")
            # Upright: the daemon's SI IMU says +1 g up.
            try:
                imu = robot.wait_for("imu", lambda m: m.accel[2] > 8.0, WAIT)
            except CommandTimeoutError as missed:
                raise AssertionError(f"{missed}\n{_plant_and_imu(sim, robot)}") from None
            assert imu.fall == "none"
            # tests/physics/test_push.py's shove: over backward at every gait phase it was tried
            # after a walk (16 of 16, lock-step), never over and beyond.
            pushed = sim.call("push", fx=-40.0, fy=0.0, duration=0.2)
            try:
                fall: Event = events.wait(lambda e: e.kind == "fall", timeout=2 * WAIT)
            except AssertionError as missed:
                # Whether the body did not fall or the detector did not speak: the plant's
                # verdict and the daemon's last IMU reading (tilt, 1 g, its window's call).
                raise AssertionError(
                    f"{missed}\npush: {pushed}\n{_plant_and_imu(sim, robot)}"
                ) from None
            assert fall.data["state"] in ("fallen_forward", "fallen_backward")
            # The plant calls it a fall past 60° of torso tilt (config/physics.toml), which can
            # come after the daemon's detector spoke: wait for the world to agree.
            world = robot.wait_for("world", lambda w: w.fallen != "none", timeout=WAIT)
            assert world.fallen == fall.data["state"].removeprefix("fallen_")
        finally:
            robot.command("halt")
            events.close()
            robot.release()


def _plant_and_imu(sim: SimControl, robot: Robot) -> str:
    """The plant's verdict and the daemon's last IMU reading (tilt, 1 g, its window's call),
    and the events since the lease: whether the body fell or the detector did not speak."""
    state = robot.state
    imu = state.imu
    return (
        f"world now: {sim.call('get_world')}\n"
        f"last imu: accel={imu and imu.accel} raw={imu and imu.accel_raw} "
        f"fall={imu and imu.fall}\nstatus: {state.status}"
    )


def test_missing_mujoco_is_one_line_naming_the_fix(tmp_path: Path) -> None:
    # A `mujoco` that cannot be imported, ahead of the real one on the path.
    (tmp_path / "mujoco.py").write_text("raise ImportError('no mujoco here')\n")
    env = {"PYTHONPATH": f"{tmp_path}:{REPO}", "PATH": "/usr/bin:/bin"}
    for args in (["sim", "--physics", "mujoco"], ["up", "--physics", "mujoco", "--no-gateway"]):
        done = subprocess.run(
            [sys.executable, "-m", "robot_daemon.launch.cli", *args],
            capture_output=True,
            text=True,
            env=env,
            cwd=REPO,
            timeout=60,
        )
        assert done.returncode == 2, done.stderr
        assert done.stderr.strip().splitlines() == [
            f"darwin {args[0]}: the MuJoCo plant: needs the 'physics' extra: "
            "pip install -e '.[physics]' in the project's clone"
        ]
