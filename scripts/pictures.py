"""Draw the documentation's pictures from what they show, so a picture cannot drift from the code:

- ``docs/pictures/servo-chains.svg``: the servo IDs and joint names of the shipped robot config
  (``config/robot.toml``) on the CM-730's five chains in cable order
  (``robot_daemon/bus/chains.py``), seen from the front;
- ``docs/pictures/ros2-arrangements.svg``: the two ways a ROS 2 system and the robot meet
  (docs/ros2.md), with the adapter's options and the endpoints;
- ``docs/pictures/foxglove-layout.svg``: the panels of the shipped Foxglove layout
  (``clients/foxglove/layout.json``) where the layout puts them, with their topics and series;
- ``docs/pictures/calibration-pose.png``: the MuJoCo model (``robot_daemon/plant/physics``) in
  the calibration posture of docs/calibration.md (every joint at servo zero), drawn offscreen on
  the CPU (EGL, else OSMesa).

    python scripts/pictures.py           # rewrite them
    python scripts/pictures.py --check   # exit 1 when an SVG is out of step (the PNG: see below)

tests/unit/test_docs_pictures.py runs the check. The SVGs are text and compared whole; the PNG
is compared pixel by pixel within a tolerance, since GL drivers differ in their last bits.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from html import escape
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np

REPO = Path(__file__).resolve().parent.parent
OUT = REPO / "docs" / "pictures"
CHAINS_SVG = OUT / "servo-chains.svg"
ROS2_SVG = OUT / "ros2-arrangements.svg"
FOXGLOVE_SVG = OUT / "foxglove-layout.svg"
CALIBRATION_PNG = OUT / "calibration-pose.png"
LAYOUT = REPO / "clients" / "foxglove" / "layout.json"

FONT = "font-family:'DejaVu Sans',Verdana,Arial,sans-serif"
INK = "#1f2933"
MUTED = "#52606d"


# -- a few SVG primitives -----------------------------------------------------------------------
def _svg(width: int, height: int, title: str, body: Iterable[str]) -> str:
    # width/height give the natural size; the site scales it down to the column, never up.
    return (
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
        f'viewBox="0 0 {width} {height}" role="img" style="{FONT}">\n'
        f"<title>{escape(title)}</title>\n"
        f'<rect width="{width}" height="{height}" fill="#ffffff"/>\n'
        + "".join(f"{line}\n" for line in body)
        + "</svg>\n"
    )


def _text(x: float, y: float, text: str, size: int = 13, anchor: str = "middle",
          weight: str = "normal", fill: str = INK, mono: bool = False) -> str:
    family = ' font-family="DejaVu Sans Mono,Menlo,Consolas,monospace"' if mono else ""
    return (f'<text x="{x:g}" y="{y:g}" font-size="{size}" text-anchor="{anchor}" '
            f'font-weight="{weight}" fill="{fill}"{family}>{escape(text)}</text>')


def _box(x: float, y: float, w: float, h: float, fill: str, stroke: str, radius: int = 6,
         dash: bool = False) -> str:
    extra = ' stroke-dasharray="6 4"' if dash else ""
    return (f'<rect x="{x:g}" y="{y:g}" width="{w:g}" height="{h:g}" rx="{radius}" '
            f'fill="{fill}" stroke="{stroke}" stroke-width="1.5"{extra}/>')


def _line(points: Iterable[tuple[float, float]], stroke: str, width: float = 2.5,
          arrow: bool = False, dash: bool = False) -> str:
    path = " ".join(f"{x:g},{y:g}" for x, y in points)
    extra = ' marker-end="url(#arrow)"' if arrow else ""
    extra += ' stroke-dasharray="6 4"' if dash else ""
    return (f'<polyline points="{path}" fill="none" stroke="{stroke}" '
            f'stroke-width="{width:g}"{extra}/>')


ARROW_DEF = ('<defs><marker id="arrow" viewBox="0 0 10 10" refX="9" refY="5" markerWidth="7" '
             'markerHeight="7" orient="auto-start-reverse"><path d="M0,0 L10,5 L0,10 z" '
             f'fill="{MUTED}"/></marker></defs>')


# -- the servo chains ---------------------------------------------------------------------------
CHAIN_COLOURS = {
    "head": ("#fff4d6", "#b7791f"),
    "right arm": ("#e3f2fd", "#1e6bb8"),
    "left arm": ("#e3f2fd", "#1e6bb8"),
    "right leg": ("#e6f4ea", "#2f7d32"),
    "left leg": ("#e6f4ea", "#2f7d32"),
}


def chains_svg() -> str:
    """The five chains with each servo's ID and joint name, from the shipped config."""
    sys.path.insert(0, str(REPO))
    from config.loader import robot_from_dict, shipped
    from robot_daemon.bus.chains import CHAINS

    robot = robot_from_dict(shipped()["robot"])
    names = {j.id: j.name for j in robot.joints}
    missing = sorted(set(names) - {i for ids in CHAINS.values() for i in ids})
    if missing:
        raise SystemExit(f"pictures: servo IDs {missing} of config/robot.toml are on no chain "
                         "of robot_daemon/bus/chains.py; add them there first")
    width, height = 780, 690
    bw, bh, step = 176, 36, 50
    cm_x, cm_y, cm_w, cm_h = width / 2, 228, 170, 64
    # Seen from the front: the robot's right is on the viewer's left.
    columns = {"right arm": 100, "right leg": 290, "left leg": 490, "left arm": 680}
    top = {"right arm": 228 - bh / 2, "left arm": 228 - bh / 2,
           "right leg": 350, "left leg": 350}
    body = [ARROW_DEF]
    body.append(_text(width / 2, 26, "The servo chains, seen from the front", 17, weight="bold"))
    body.append(_text(width / 2, 46, "the robot's right is on your left; each chain is cabled "
                      "from the CM-730 outwards", 12, fill=MUTED))

    def servo(cx: float, y: float, dxl_id: int, chain: str) -> list[str]:
        fill, stroke = CHAIN_COLOURS[chain]
        return [_box(cx - bw / 2, y, bw, bh, fill, stroke),
                _text(cx - bw / 2 + 10, y + bh / 2 + 5, f"{dxl_id}", 15, "start", "bold",
                      stroke),
                _text(cx - bw / 2 + 40, y + bh / 2 + 5, names.get(dxl_id, "?"), 13, "start",
                      mono=True)]

    # The CM-730 and its ports.
    body.append(_box(cm_x - cm_w / 2, cm_y - cm_h / 2, cm_w, cm_h, "#f0f0f3", INK, 8))
    body.append(_text(cm_x, cm_y - 4, "CM-730", 16, weight="bold"))
    body.append(_text(cm_x, cm_y + 16, f"ID {robot.cm730_id} · 5 TTL ports", 12, fill=MUTED))
    for chain, ids in CHAINS.items():
        stroke = CHAIN_COLOURS[chain][1]
        if chain == "head":
            # Upwards from the top of the CM-730.
            ys = [cm_y - cm_h / 2 - 30 - bh - i * step for i in range(len(ids))]
            body.append(_line([(cm_x, cm_y - cm_h / 2), (cm_x, ys[0] + bh)], stroke))
            for a, b in itertools.pairwise(ys):
                body.append(_line([(cm_x, a), (cm_x, b + bh)], stroke))
            body.append(_text(cm_x + bw / 2 + 10, ys[-1] + bh / 2 + 5, "head", 13, "start",
                              "bold", stroke))
            for y, i in zip(ys, ids, strict=True):
                body += servo(cm_x, y, i, chain)
            continue
        cx = columns[chain]
        ys = [top[chain] + i * step for i in range(len(ids))]
        left = cx < cm_x
        port_x = cm_x - cm_w / 2 if left else cm_x + cm_w / 2
        if chain.endswith("arm"):
            edge = cx + bw / 2 if left else cx - bw / 2
            body.append(_line([(port_x, cm_y - 12), (edge, cm_y - 12)], stroke))
        else:
            port_y = cm_y + 12 if "leg" in chain else cm_y
            body.append(_line([(port_x, port_y), (cx, port_y), (cx, ys[0])], stroke))
        for a, b in itertools.pairwise(ys):
            body.append(_line([(cx, a + bh), (cx, b)], stroke))
        label_y = ys[0] - 10 if chain.endswith("arm") else ys[-1] + bh + 22
        body.append(_text(cx, label_y, chain, 13, weight="bold", fill=stroke))
        for y, i in zip(ys, ids, strict=True):
            body += servo(cx, y, i, chain)
    body.append(_text(width / 2, height - 14, "Generated from config/robot.toml and "
                      "robot_daemon/bus/chains.py by scripts/pictures.py", 11, fill=MUTED))
    return _svg(width, height, "The DARwIn-OP's servo chains and IDs", body)


# -- the ROS 2 arrangements ---------------------------------------------------------------------
@dataclass
class _Node:
    x: float
    y: float
    w: float
    h: float
    title: str
    lines: tuple[str, ...]
    fill: str = "#f0f0f3"
    stroke: str = INK

    def draw(self) -> list[str]:
        out = [_box(self.x, self.y, self.w, self.h, self.fill, self.stroke),
               _text(self.x + self.w / 2, self.y + 22, self.title, 14, weight="bold")]
        out += [_text(self.x + 12, self.y + 44 + 18 * k, line, 12, "start", mono=True)
                for k, line in enumerate(self.lines)]
        return out


ROBOT = ("#e3f2fd", "#1e6bb8")
ROS = ("#e6f4ea", "#2f7d32")


def ros2_svg() -> str:
    """The two arrangements of docs/ros2.md, one above the other."""
    width, height = 780, 650
    body = [ARROW_DEF]

    def machine(x: float, y: float, w: float, h: float, name: str, colours: tuple[str, str]
                ) -> list[str]:
        return [_box(x, y, w, h, colours[0], colours[1], 10, dash=True),
                _text(x + 12, y + 20, name, 13, "start", "bold", colours[1])]

    def link(a: tuple[float, float], b: tuple[float, float], label: str, dash: bool = False
             ) -> list[str]:
        mid = ((a[0] + b[0]) / 2, (a[1] + b[1]) / 2 - 8)
        return [_line([a, b], MUTED, 2, arrow=True, dash=dash),
                _text(mid[0], mid[1], label, 11, fill=MUTED, mono=True)]

    # 1. ROS machines join the robot: the robot's endpoint is a Zenoh router.
    y0 = 20
    body.append(_text(20, y0 + 16, "1. ROS machines join the robot", 16, "start", "bold"))
    body.append(_text(20, y0 + 36, "one robot; ROS on a laptop without its own rmw_zenohd", 12,
                      "start", fill=MUTED))
    body += machine(20, y0 + 50, 350, 220, "the robot", ROBOT)
    robot1 = _Node(40, y0 + 84, 310, 170, "darwin up --ros2",
                   ("--listen tcp/0.0.0.0:7447", "--config router.toml",
                    '  [zenoh] mode = "router"', "daemon: darwin/op1/…",
                    "ros2 adapter: /op1/joint_states,", "  /op1/cmd_vel, /op1/halt …"))
    body += robot1.draw()
    body += machine(450, y0 + 50, 310, 220, "ROS 2 machine (Jazzy)", ROS)
    ros1 = _Node(470, y0 + 84, 270, 170, "ros2 / rviz2 / teleop",
                 ("RMW_IMPLEMENTATION=", "  rmw_zenoh_cpp", "ZENOH_CONFIG_OVERRIDE=",
                  '  mode="client";', "  connect/endpoints=", '  ["tcp/ROBOT_IP:7447"]'))
    body += ros1.draw()
    body += link((470, y0 + 170), (350, y0 + 170), "tcp/ROBOT_IP:7447")

    # 2. The robot joins an existing ROS system: the adapter connects to rmw_zenohd.
    y1 = 330
    body.append(_text(20, y1 + 16, "2. The robot joins an existing ROS system", 16, "start",
                      "bold"))
    body.append(_text(20, y1 + 36, "a ROS network already runs rmw_zenohd; ROS nodes keep "
                      "their defaults", 12, "start", fill=MUTED))
    body += machine(20, y1 + 50, 350, 240, "the robot", ROBOT)
    daemon = _Node(40, y1 + 84, 310, 62, "darwin up", ("daemon: darwin/op1/… on :7447",))
    adapter = _Node(40, y1 + 166, 310, 108, "darwin ros2",
                    ("--router tcp/ROS_HOST:7447", "[--ros-user U", " --ros-password-file F]"))
    body += daemon.draw() + adapter.draw()
    body += link((195, y1 + 166), (195, y1 + 146), "")
    body.append(_text(205, y1 + 161, "the key space", 11, "start", fill=MUTED))
    body += machine(450, y1 + 50, 310, 240, "ROS host", ROS)
    router = _Node(470, y1 + 84, 270, 62, "rmw_zenohd", ("listens on tcp/[::]:7447",))
    nodes = _Node(470, y1 + 166, 270, 108, "ROS 2 nodes",
                  ("RMW_IMPLEMENTATION=", "  rmw_zenoh_cpp", "(default router)"))
    body += router.draw() + nodes.draw()
    body += link((350, y1 + 220), (470, y1 + 115), "tcp/ROS_HOST:7447")
    body += link((605, y1 + 166), (605, y1 + 146), "")
    body.append(_text(width / 2, height - 12, "Topics and services: docs/ros2.md · drawn by "
                      "scripts/pictures.py", 11, fill=MUTED))
    return _svg(width, height, "The two ROS 2 arrangements", body)


# -- the Foxglove layout ------------------------------------------------------------------------
PLOT_COLOURS = ("#4e98e2", "#f5774d", "#f7df71", "#5cd6a9", "#dc5bb9", "#9e8df0")


def _split(node: Any, x: float, y: float, w: float, h: float
           ) -> list[tuple[str, float, float, float, float]]:
    """The panels of a layout tree (react-mosaic's: direction, first, second, splitPercentage)
    with their rectangles."""
    if isinstance(node, str):
        return [(node, x, y, w, h)]
    share = float(node.get("splitPercentage", 50)) / 100
    if node["direction"] == "row":
        return (_split(node["first"], x, y, w * share, h)
                + _split(node["second"], x + w * share, y, w * (1 - share), h))
    return (_split(node["first"], x, y, w, h * share)
            + _split(node["second"], x, y + h * share, w, h * (1 - share)))


def _panel(kind: str, config: dict[str, Any], x: float, y: float, w: float, h: float
           ) -> list[str]:
    pad = 3
    x, y, w, h = x + pad, y + pad, w - 2 * pad, h - 2 * pad
    title = config.get("title") or {"3D": "3D", "Image": "Image", "Teleop": "Teleop",
                                    "RosOut": "Log", "Plot": "Plot"}.get(kind, kind)
    out = [f'<rect x="{x:g}" y="{y:g}" width="{w:g}" height="{h:g}" fill="#15151c" '
           'stroke="#2e2e3a"/>',
           f'<rect x="{x:g}" y="{y:g}" width="{w:g}" height="22" fill="#23232d"/>',
           _text(x + 8, y + 16, title, 13, "start", "bold", "#e8e8ee"),
           _text(x + w - 8, y + 16, kind, 11, "end", fill="#9a9aab")]
    cx, cy = x + 10, y + 38
    lines: list[tuple[str, str]] = []  # (text, colour)
    grey = "#c8c8d4"
    if kind == "3D":
        layers = config.get("layers", {})
        kinds: dict[str, dict[str, Any]] = {la.get("layerId", ""): la for la in layers.values()}
        urdf, grid = kinds.get("foxglove.Urdf", {}), kinds.get("foxglove.Grid", {})
        lines += [(f"URDF layer: {urdf.get('topic', '?')}", grey),
                  (f"grid in frame {grid.get('frameId', '?')}", grey),
                  ("topics: " + ", ".join(t for t, v in config.get("topics", {}).items()
                                          if v.get("visible")), grey),
                  (f"follows {config.get('followTf', '?')}", grey)]
        # A stick figure on the field grid, where the 3D view draws the robot.
        gx, gy = x + w / 2 - 120, y + h / 2 + 90
        for k in range(7):
            out.append(_line([(gx + 30 * k, gy), (gx + 60 + 30 * k, gy - 90)], "#248eff", 1))
        for k in range(4):
            out.append(_line([(gx + 20 * k, gy - 30 * k), (gx + 180 + 20 * k, gy - 30 * k)],
                             "#248eff", 1))
        out.append(_text(gx + 120, gy + 22, "the robot and the ball on the field grid", 11,
                         fill="#9a9aab"))
    elif kind == "Image":
        mode = config.get("imageMode", {})
        lines += [(f"image: {mode.get('imageTopic', '?')}", grey)]
        lines += [(f"overlay: {t}", grey) for t in mode.get("annotations", {})]
    elif kind == "Teleop":
        lines += [(f"publishes {config.get('topic', '?')}", grey),
                  (f"at {config.get('publishRate', '?')} Hz", grey)]
        for key, arrow in (("upButton", "↑"), ("downButton", "↓"), ("leftButton", "←"),
                           ("rightButton", "→")):
            b = config.get(key, {})
            lines.append((f"{arrow} {b.get('field', '?')} {b.get('value', '?'):+g}", grey))
    elif kind == "Plot":
        for k, path in enumerate(config.get("paths", [])):
            colour = path.get("color") or PLOT_COLOURS[k % len(PLOT_COLOURS)]
            lines.append((f"— {path.get('label') or path.get('value')}", colour))
    elif kind == "RosOut":
        lines += [(f"log of {config.get('topicToRender', '?')}", grey)]
    # A short panel lists its lines in as many columns as it takes.
    rows = max(1, int((y + h - 4 - cy) // 14) + 1)
    column = (w - 10) / -(-len(lines) // rows) if lines else w
    for k, (text, colour) in enumerate(lines):
        col, row = divmod(k, rows)
        out.append(_text(cx + col * column, cy + row * 14, text, 12, "start", fill=colour))
    return out


def foxglove_svg() -> str:
    """The shipped layout's panels at the places the layout gives them, in a window about as
    wide as the site's column (so its text stays readable there)."""
    layout = json.loads(LAYOUT.read_text())
    width, height = 880, 660
    top = 48
    body = [f'<rect width="{width}" height="{height}" fill="#0e0e13"/>',
            f'<rect width="{width}" height="{top}" fill="#1c1c24"/>',
            _text(12, 20, "Foxglove — ws://127.0.0.1:8765 — layout: clients/foxglove/layout.json",
                  13, "start", "bold", "#e8e8ee"),
            _text(12, 38, "a drawing of the layout's panels generated from the file by "
                  "scripts/pictures.py, not a screenshot", 11, "start", fill="#9a9aab")]
    for panel, x, y, w, h in _split(layout["layout"], 0, top, width, height - top):
        kind = panel.split("!", 1)[0]
        body += _panel(kind, layout["configById"].get(panel, {}), x, y, w, h)
    return _svg(width, height, "The shipped Foxglove layout's panels", body)


# -- the calibration posture --------------------------------------------------------------------
VIEW_W, VIEW_H = 360, 480
# MuJoCo azimuths: the robot faces +x, its left is +y.
VIEWS = (("front", 180.0), ("front left", 225.0), ("left side", 270.0))


def calibration_image() -> np.ndarray:
    """The model with every servo at zero (raw 2048, the offset tuner's posture), front and
    side, as one RGB image."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    sys.path.insert(0, str(REPO))
    import xml.etree.ElementTree as ET

    import cv2
    import mujoco
    import numpy as np

    from config.loader import robot_from_dict, shipped
    from robot_daemon.plant.physics.mjcf_model import BALL, world_mjcf
    from schemas.body import build_body, limits_from_config

    robot = robot_from_dict(shipped()["robot"])
    xml = ET.fromstring(world_mjcf(build_body(limits_from_config(robot), robot.max_speed)))
    # A light sky behind the robot (the world's own has none: the head camera looks down).
    asset = xml.find("asset")
    assert asset is not None
    ET.SubElement(asset, "texture", type="skybox", builtin="gradient", rgb1="0.93 0.95 0.98",
                  rgb2="0.72 0.8 0.9", width="64", height="64")
    model = mujoco.MjModel.from_xml_string(ET.tostring(xml, encoding="unicode"))
    model.vis.headlight.ambient[:] = 0.35
    model.vis.headlight.diffuse[:] = 0.6
    model.vis.global_.offwidth, model.vis.global_.offheight = VIEW_W, VIEW_H
    data = mujoco.MjData(model)
    # Every joint at 0 (servo zero): the qpos of the hinges is left at its default 0. The ball
    # goes out of sight; the body stands with its soles on the floor.
    ball = model.body(BALL).jntadr[0]
    data.qpos[model.jnt_qposadr[ball]:model.jnt_qposadr[ball] + 3] = (40.0, 40.0, 0.0)
    mujoco.mj_kinematics(model, data)
    soles = [data.site(name).xpos[2] for name in ("l_sole", "r_sole")]
    data.qpos[2] -= min(soles)
    mujoco.mj_kinematics(model, data)
    frames = []
    try:
        renderer = mujoco.Renderer(model, VIEW_H, VIEW_W)
    except Exception as exc:  # no EGL/OSMesa library, no display driver
        raise SystemExit(
            f"pictures: MuJoCo cannot draw offscreen with MUJOCO_GL={os.environ['MUJOCO_GL']} "
            f"({exc}); install libegl1 libgl1-mesa-dri libosmesa6, or set MUJOCO_GL=osmesa"
        ) from None
    with renderer:
        for label, azimuth in VIEWS:
            cam = mujoco.MjvCamera()
            cam.type = mujoco.mjtCamera.mjCAMERA_FREE
            cam.lookat[:] = (data.qpos[0], data.qpos[1], 0.2)
            cam.distance, cam.azimuth, cam.elevation = 0.8, azimuth, -12.0
            renderer.update_scene(data, cam)
            frame = np.ascontiguousarray(renderer.render())
            cv2.putText(frame, label, (14, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.8, (20, 30, 40), 2,
                        cv2.LINE_AA)
            frames.append(frame)
    return np.hstack(frames)


def write_png(path: Path, rgb: np.ndarray) -> None:
    import cv2

    ok, png = cv2.imencode(".png", rgb[:, :, ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 9])
    if not ok:
        raise SystemExit(f"pictures: could not encode {path.name}")
    path.write_bytes(png.tobytes())


def read_png(path: Path) -> np.ndarray:
    import cv2
    import numpy as np

    bgr = cv2.imdecode(np.frombuffer(path.read_bytes(), np.uint8), cv2.IMREAD_COLOR)
    if bgr is None:
        raise SystemExit(f"pictures: {path} is not a PNG")
    return bgr[:, :, ::-1]


def differs(a: np.ndarray, b: np.ndarray) -> float:
    """The share of pixels that differ by more than GL drivers' rounding (0..1)."""
    import numpy as np

    if a.shape != b.shape:
        return 1.0
    return float((np.abs(a.astype(int) - b.astype(int)).max(axis=2) > 24).mean())


SVGS = {CHAINS_SVG: chains_svg, ROS2_SVG: ros2_svg, FOXGLOVE_SVG: foxglove_svg}
# Pixels allowed to differ between two GL drivers' pictures of the same scene.
PNG_TOLERANCE = 0.01


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="exit 1 when a picture is out of step")
    ap.add_argument("--no-png", action="store_true", help="leave the MuJoCo picture alone")
    args = ap.parse_args(argv)
    OUT.mkdir(parents=True, exist_ok=True)
    stale = []
    for path, draw in SVGS.items():
        text = draw()
        if args.check:
            if not path.exists() or path.read_text() != text:
                stale.append(path.relative_to(REPO))
        else:
            path.write_text(text)
    if not args.no_png:
        image = calibration_image()
        if args.check:
            if not CALIBRATION_PNG.exists() or differs(read_png(CALIBRATION_PNG), image) > (
                    PNG_TOLERANCE):
                stale.append(CALIBRATION_PNG.relative_to(REPO))
        else:
            write_png(CALIBRATION_PNG, image)
    if stale:
        print(f"pictures: out of step: {', '.join(map(str, stale))}; run "
              "`python scripts/pictures.py` and commit them", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
