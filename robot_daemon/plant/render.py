"""The simulated camera: the view from the head's camera, drawn with numpy and OpenCV.

Every pixel's ray is cast once against the ground plane (field, lines, carpet, the ball's
shadow) and the sky/walls; goal posts are drawn as projected bars and the ball as a shaded
sphere on top. Then lighting varies slowly, a light blur and sensor noise are added, so the ball
finder sees something closer to a webcam image than to a flat disc. The camera's axes and lens:
:mod:`robot_daemon.plant.camera_model`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_daemon.plant.camera_model import CameraModel, CameraPose, FieldGeometry
from schemas.extras import LazyModule

cv2 = LazyModule("cv2", "the simulated camera")

_GRASS = np.array([40, 140, 50], dtype=np.float32)  # BGR
_CARPET = np.array([35, 95, 40], dtype=np.float32)
_LINE = np.array([235, 235, 235], dtype=np.float32)
_WALL = np.array([175, 170, 160], dtype=np.float32)
_WALL_TOP = np.array([215, 205, 195], dtype=np.float32)
_POST = (240, 240, 240)
# Channel-major (3, 4): the ground is cast as three planes of pixels, since numpy's loops over
# a last axis of 3 (one pixel's channels) cost several times those over a plane.
_PALETTE_PLANES = np.ascontiguousarray(np.stack([_WALL, _CARPET, _GRASS, _LINE]).T)
_WALL_RISE = (_WALL_TOP - _WALL)[:, None]


@dataclass
class BallView:
    """The ball as the renderer draws it: field position, radius and colour."""

    x: float
    y: float
    radius: float
    color_rgb: tuple[int, int, int] = (210, 28, 28)


class Renderer:
    # The floor and walls are smooth: cast them at 1/GROUND_SCALE resolution and scale up.
    GROUND_SCALE = 2
    NOISE_FRAMES = 8

    def __init__(
        self,
        camera: CameraModel | None = None,
        field: FieldGeometry | None = None,
        noise: float = 3.0,
        light_variation: float = 0.12,
        blur: bool = True,
        seed: int | None = None,
    ) -> None:
        self.camera = camera or CameraModel()
        self.field = field or FieldGeometry()
        self.noise = noise
        self.light_variation = light_variation
        self.blur = blur
        self.rng = np.random.default_rng(seed)
        cam = self.camera
        small = CameraModel(
            cam.width // self.GROUND_SCALE,
            cam.height // self.GROUND_SCALE,
            cam.fov_h_deg,
            cam.fov_v_deg,
        )
        self._small = small
        rays = small.rays()
        self._rays = (rays / np.linalg.norm(rays, axis=1, keepdims=True)).astype(np.float32)
        # Drawn at the first render (the first draws of ``rng``, as they were here): a world
        # nobody watches (`darwin up --camera none`, most simulated robots) never pays for them.
        self._noise: list[np.ndarray] | None = None
        self._light = 1.0
        self._tint = np.zeros(3, dtype=np.float32)

    def render(self, pose: CameraPose, ball: BallView | None) -> np.ndarray:
        """A BGR uint8 image of the world seen from ``pose``."""
        cam = self.camera
        if self._noise is None:
            shape = (cam.height, cam.width, 3)
            self._noise = [
                self.rng.normal(0.0, self.noise, shape).astype(np.float32)
                for _ in range(self.NOISE_FRAMES)
            ]
        d = self._rays @ pose.rotation.T.astype(np.float32)  # unit rays in the field frame
        planes = self._background(d, pose.position.astype(np.float32), ball)
        small = cv2.merge(list(planes.reshape(3, self._small.height, self._small.width)))
        img = cv2.resize(small, (cam.width, cam.height), interpolation=cv2.INTER_LINEAR)
        self._draw_posts(img, pose)
        if ball is not None:
            self._draw_ball(img, pose, ball)
        return self._finish(img)

    # -- ground and walls -------------------------------------------------------------------
    def _background(self, d: np.ndarray, p: np.ndarray, ball: BallView | None) -> np.ndarray:
        """(3, n) colour planes (B, G, R) of the n rays ``d`` cast from ``p``."""
        f = self.field
        dz = d[:, 2]
        down = dz < -1e-4
        t = -p[2] / np.where(down, dz, np.float32(-1.0))
        gx = p[0] + t * d[:, 0]
        gy = p[1] + t * d[:, 1]
        ground = (
            down & (np.abs(gx) <= f.length / 2 + f.border) & (np.abs(gy) <= f.width / 2 + f.border)
        )
        on_field = (np.abs(gx) <= f.length / 2 + f.line_width) & (
            np.abs(gy) <= f.width / 2 + f.line_width
        )
        # A palette index per pixel (0 wall, 1 carpet, 2 grass, 3 line), then a gain.
        idx = ground.astype(np.uint8) + (ground & on_field)
        idx[ground & self._lines(gx, gy)] = 3
        out = np.take(_PALETTE_PLANES, idx, axis=1)
        # Walls of the room get brighter towards the top.
        k = np.clip(dz * 2.0 + 0.5, 0.0, 1.0) * (idx == 0)
        out += k * _WALL_RISE
        # Stripes of mown grass give the ground some texture; the ball casts a soft shadow.
        band = ((gx + f.length / 2) * (1 / 0.75)).astype(np.int32) & 1
        gain = np.where((band == 0) & (idx == 2), np.float32(1.08), np.float32(1.0))
        if ball is not None:
            r2 = (gx - ball.x) ** 2 + (gy - ball.y) ** 2
            gain = gain * (1.0 - 0.45 * np.exp(-r2 / (ball.radius * 0.9) ** 2) * ground)
        out *= gain.astype(np.float32)
        return out

    def _lines(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        f = self.field
        hw = f.line_width / 2
        hl, hwid = f.length / 2, f.width / 2
        inside_x = np.abs(x) <= hl + hw
        inside_y = np.abs(y) <= hwid + hw
        m = (np.abs(np.abs(x) - hl) <= hw) & inside_y  # goal lines
        m |= (np.abs(np.abs(y) - hwid) <= hw) & inside_x  # touch lines
        m |= (np.abs(x) <= hw) & inside_y  # halfway line
        r = np.hypot(x, y)
        m |= np.abs(r - f.centre_circle_radius) <= hw
        ga_x = hl - f.goal_area_depth
        in_ga_y = np.abs(y) <= f.goal_area_width / 2 + hw
        m |= (np.abs(np.abs(x) - ga_x) <= hw) & in_ga_y
        m |= (np.abs(np.abs(y) - f.goal_area_width / 2) <= hw) & (np.abs(x) >= ga_x - hw) & inside_x
        return m

    # -- goal posts -------------------------------------------------------------------------
    def _draw_posts(self, img: np.ndarray, pose: CameraPose) -> None:
        f = self.field
        r_cw = pose.rotation.T
        posts = [(sx * f.length / 2, sy * f.goal_width / 2) for sx in (-1, 1) for sy in (-1, 1)]
        for px, py in posts:
            bottom = r_cw @ (np.array([px, py, 0.0]) - pose.position)
            top = r_cw @ (np.array([px, py, f.goal_post_height]) - pose.position)
            if bottom[0] < 0.05 or top[0] < 0.05:
                continue
            a, b = self.camera.project(bottom), self.camera.project(top)
            if a is None or b is None:
                continue
            thick = max(1, int(round(2 * f.goal_post_radius * self.camera.fx / bottom[0])))
            cv2.line(img, _pt(a), _pt(b), _POST, thick, cv2.LINE_AA)

    # -- the ball ----------------------------------------------------------------------------
    def _draw_ball(self, img: np.ndarray, pose: CameraPose, ball: BallView) -> None:
        cam = self.camera
        c = pose.rotation.T @ (np.array([ball.x, ball.y, ball.radius]) - pose.position)
        dist = float(np.linalg.norm(c))
        if c[0] <= ball.radius or dist <= ball.radius * 1.05:
            return
        centre = cam.project(c)
        if centre is None:
            return
        rad_px = cam.fx * ball.radius / math.sqrt(dist**2 - ball.radius**2)
        u0, v0 = centre
        x0, x1 = int(math.floor(u0 - rad_px - 1)), int(math.ceil(u0 + rad_px + 1))
        y0, y1 = int(math.floor(v0 - rad_px - 1)), int(math.ceil(v0 + rad_px + 1))
        x0c, x1c = max(0, x0), min(cam.width, x1 + 1)
        y0c, y1c = max(0, y0), min(cam.height, y1 + 1)
        if x0c >= x1c or y0c >= y1c:
            return
        vv, uu = np.mgrid[y0c:y1c, x0c:x1c].astype(np.float32)
        dx = (uu + 0.5 - u0) / rad_px
        dy = (vv + 0.5 - v0) / rad_px
        r2 = dx * dx + dy * dy
        inside = r2 <= 1.0
        if not inside.any():
            return
        nz = np.sqrt(np.clip(1.0 - r2, 0.0, 1.0))
        # Image axes (right, down, towards the camera): light from above left, a soft highlight.
        light = np.array([-0.35, -0.75, 0.56])
        lam = np.clip(dx * light[0] + dy * light[1] + nz * light[2], 0.0, 1.0)
        shade = 0.3 + 0.7 * lam
        spec = 0.25 * lam**12
        base = np.array(ball.color_rgb[::-1], dtype=np.float32)
        # Anti-aliased rim: blend by coverage over the last pixel.
        cover = np.clip((1.0 - np.sqrt(r2)) * rad_px + 0.5, 0.0, 1.0)
        drawn = inside | (cover > 0)
        # A channel at a time: numpy's loops over a last axis of 3 cost several times a plane's.
        for c, channel in enumerate(np.moveaxis(img[y0c:y1c, x0c:x1c], -1, 0)):
            col = base[c] * shade + 255.0 * spec
            channel[:] = np.where(drawn, channel * (1 - cover) + col * cover, channel)

    # -- sensor effects ------------------------------------------------------------------------
    def _finish(self, img: np.ndarray) -> np.ndarray:
        if self.light_variation > 0:
            # A slow random walk of brightness and white balance, like auto-exposure drifting.
            self._light += self.rng.normal(0.0, 0.01) - 0.05 * (self._light - 1.0)
            lv = self.light_variation
            self._light = float(np.clip(self._light, 1 - lv, 1 + lv))
            self._tint += self.rng.normal(0.0, 0.5, 3).astype(np.float32) - 0.05 * self._tint
            img *= np.float32(self._light)
            # As one row of pixels: adding a (3,) tint to every pixel took 0.7 ms a frame.
            rows = img.reshape(img.shape[0], -1)
            rows += np.tile(self._tint, img.shape[1])
        if self.blur:
            img = cv2.GaussianBlur(img, (3, 3), 0.7)
        if self.noise > 0 and self._noise:
            img += self._noise[int(self.rng.integers(len(self._noise)))]
        np.clip(img, 0, 255, out=img)
        return img.astype(np.uint8)


def _pt(p: tuple[float, float]) -> tuple[int, int]:
    return (int(round(p[0])), int(round(p[1])))


def look_at(position: np.ndarray, target: np.ndarray) -> CameraPose:
    """A level camera (no roll) at ``position`` looking at ``target``: handy for tests."""
    fwd = np.asarray(target, float) - np.asarray(position, float)
    fwd /= np.linalg.norm(fwd)
    left = np.cross([0.0, 0.0, 1.0], fwd)
    n = np.linalg.norm(left)
    left = left / n if n > 1e-9 else np.array([0.0, 1.0, 0.0])
    up = np.cross(fwd, left)
    return CameraPose(np.asarray(position, float), np.stack([fwd, left, up], axis=1))
