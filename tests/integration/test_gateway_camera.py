"""The camera through the gateway: base64 JPEG, subscribed only while some client monitors it,
and left out (with one error saying why) for a client whose framing cannot carry an image."""

from __future__ import annotations

import base64

from tests.legacy_client import LegacyClient


def test_camera_only_while_monitored(system_factory, tmp_path) -> None:
    # Full-size fine images: far more than the 9999 bytes four ASCII digits can announce.
    config = tmp_path / "camera.toml"
    config.write_text("[daemon.camera]\nwidth = 640\nheight = 480\njpeg_quality = 95\n")
    system = system_factory(camera="sim", extra_args=["--config", str(config)])
    assert system.gateway is not None
    with system.robot_client(name="observer") as robot:
        robot.wait_for("status", lambda s: s.camera.get("subscribed") is False, 30.0, fresh=False)
        with (
            LegacyClient(*system.gateway, order="little", timeout=30.0) as c,
            LegacyClient(*system.gateway, order="ascii", timeout=30.0) as small,
        ):
            c.send({"monitor": {"camera": 1}})
            msg = c.recv_until(lambda m: "camera" in m.get("monitor", {}))
            assert set(msg["monitor"]) == {"camera"}
            assert base64.b64decode(msg["monitor"]["camera"]).startswith(b"\xff\xd8")  # JPEG
            robot.wait_for("status", lambda s: s.camera.get("subscribed") is True, 30.0)

            # A second client shares the one subscription, but four ASCII digits cannot say
            # the size of an image: one error says why, and the other streams still come.
            small.send({"monitor": {"camera": 1, "gyroscope": 1}})
            err = small.recv_error()
            assert err["code"] == "out_of_range" and "camera images left out" in err["message"]
            for _ in range(3):
                got = small.recv_until(lambda m: "monitor" in m)
                assert "camera" not in got["monitor"]
            assert len([m for m in small.received if "error" in m]) == 1

            # The last client watching switches it off: the gateway unsubscribes.
            small.send({"monitor": {"camera": 0}})
            c.send({"monitor": {"camera": 0}})
            robot.wait_for("status", lambda s: s.camera.get("subscribed") is False, 30.0)
